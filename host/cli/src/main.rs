//! The `dips` binary.

fn main() -> anyhow::Result<()> {
    dips_cli::main()
}
