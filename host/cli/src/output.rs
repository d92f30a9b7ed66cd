//! Writing results to stdout without panicking: `println!` panics when stdout is a closed
//! pipe (`dips … | head -1`) or a full disk; these return the error instead, and the binary
//! turns a closed pipe into a quiet exit.

use std::io::Write;

/// Write `text` and a newline to stdout and flush.
pub fn line(text: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush())
        .map_err(|e| anyhow::Error::new(e).context("cannot write to stdout"))
}

/// Whether `e` is (caused by) a closed pipe.
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
