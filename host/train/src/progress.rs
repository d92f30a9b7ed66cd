//! Progress bars (drawn to stderr, hidden when stderr is not a terminal) and run options.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How a training call runs (not part of the result: changing these never changes a bit of
/// the trained models).
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Draw progress bars on stderr (only when it is a terminal).
    pub progress: bool,
    /// Simulate a kill: write a checkpoint after this optimiser step and return
    /// [`crate::TrainError::Stopped`] (tests of resumption).
    pub stop_after: Option<usize>,
    /// Start over even when a checkpoint exists (it is overwritten).
    pub fresh: bool,
}

/// A bar of `len` steps with a prefix, loss message and ETA.
pub(crate) fn bar(opts: &RunOptions, len: u64, prefix: &str) -> ProgressBar {
    let target = if opts.progress && std::io::stderr().is_terminal() {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    };
    let pb = ProgressBar::with_draw_target(Some(len), target);
    let style = ProgressStyle::with_template(
        "{prefix:>13} [{bar:30}] {pos}/{len} {msg} ({per_sec}, ETA {eta})",
    )
    .map(|s| s.progress_chars("=> "))
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    pb.set_style(style);
    pb.set_prefix(prefix.to_string());
    pb
}
