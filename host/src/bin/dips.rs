//! The `dips` binary.

fn main() -> anyhow::Result<()> {
    dips_host::cli::main()
}
