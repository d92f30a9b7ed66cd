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

/// Wall time of a training stage summed over its runs: a resumed run starts from what the
/// checkpoint's metadata recorded, so the report gives the whole stage's time, not the last
/// run's.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RunClock {
    prior_run: f64,
    prior_loop: f64,
    prior_loss: f32,
    started: std::time::Instant,
    loop_start: std::time::Instant,
}

impl RunClock {
    const RUN: &'static str = "run_seconds";
    const LOOP: &'static str = "loop_seconds";
    const LOSS: &'static str = "train_loss_recent";

    /// Started now, with the times a checkpoint recorded (`None`: a fresh stage).
    pub(crate) fn start(
        started: std::time::Instant,
        checkpoint: Option<&std::collections::HashMap<String, String>>,
    ) -> Self {
        let get = |k: &str| {
            checkpoint
                .and_then(|m| m.get(k))
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite() && *v >= 0.0)
                .unwrap_or(0.0)
        };
        Self {
            prior_run: get(Self::RUN),
            prior_loop: get(Self::LOOP),
            prior_loss: checkpoint
                .and_then(|m| m.get(Self::LOSS))
                .and_then(|v| v.parse::<f32>().ok())
                .unwrap_or(f32::NAN),
            started,
            loop_start: std::time::Instant::now(),
        }
    }

    /// The optimiser loop starts now.
    pub(crate) fn loop_started(&mut self) {
        self.loop_start = std::time::Instant::now();
    }

    /// The mean training loss of the last steps: `recent` (this run's), else what the
    /// checkpoint recorded (NaN when neither has any).
    pub(crate) fn train_loss(&self, recent: &[f32]) -> f32 {
        if recent.is_empty() {
            self.prior_loss
        } else {
            recent.iter().sum::<f32>() / recent.len() as f32
        }
    }

    /// `meta` plus the summed times and the recent training loss, for a checkpoint written now.
    pub(crate) fn stamp(
        &self,
        meta: &std::collections::HashMap<String, String>,
        recent: &[f32],
    ) -> std::collections::HashMap<String, String> {
        let mut m = meta.clone();
        m.insert(Self::LOSS.into(), self.train_loss(recent).to_string());
        m.insert(Self::RUN.into(), self.run_seconds().to_string());
        m.insert(Self::LOOP.into(), self.loop_seconds().to_string());
        m
    }

    /// The stage's wall time so far, all runs.
    pub(crate) fn run_seconds(&self) -> f64 {
        self.prior_run + self.started.elapsed().as_secs_f64()
    }

    /// The optimiser loops' wall time so far, all runs.
    pub(crate) fn loop_seconds(&self) -> f64 {
        self.prior_loop + self.loop_start.elapsed().as_secs_f64()
    }
}
