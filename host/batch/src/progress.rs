//! Progress of a batch for people and for logs: on a terminal, an indicatif bar of fixed width
//! with an ETA from the mean rate so far (items of one batch take about as long as each other,
//! so the mean is steadier than indicatif's recent-rate estimate); off a terminal (`nohup`, a
//! log file, a job array), one plain line when an item finishes, at most every
//! [`Progress::log_every`], and always for the first and the last. Every write to stderr ignores
//! a closed stream: progress never stops the work.

use std::io::{IsTerminal, Write};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Where progress goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgressMode {
    /// A bar on a terminal, log lines otherwise.
    Auto,
    /// Log lines, even on a terminal.
    Lines,
    /// Nothing (`--quiet`).
    Hidden,
}

/// A batch's progress: `done` of `total` items.
#[derive(Debug)]
pub struct Progress {
    label: String,
    unit: (&'static str, &'static str),
    total: u64,
    bar: Option<ProgressBar>,
    lines: bool,
    log_every: Duration,
    started: Instant,
    state: Mutex<State>,
}

#[derive(Debug)]
struct State {
    done: u64,
    last_line: Option<Instant>,
}

/// `n` seconds as `1h 02m`, `3m 20s` or `45s`.
pub fn human_duration(seconds: f64) -> String {
    if !seconds.is_finite() || seconds < 0.0 {
        return "?".into();
    }
    let s = seconds.round() as u64;
    match s {
        0..60 => format!("{s}s"),
        60..3600 => format!("{}m {:02}s", s / 60, s % 60),
        _ => format!("{}h {:02}m", s / 3600, (s % 3600) / 60),
    }
}

/// A line on stderr before a batch starts (`resuming: …`), unless progress is hidden.
pub fn note_before(mode: ProgressMode, text: &str) {
    if mode != ProgressMode::Hidden {
        let _ = writeln!(std::io::stderr().lock(), "{text}");
    }
}

impl Progress {
    /// The default interval between log lines.
    pub const DEFAULT_LOG_EVERY: Duration = Duration::from_secs(30);

    /// A batch of `total` items named `unit` (singular, plural), e.g. `("episode", "episodes")`.
    pub fn new(
        label: impl Into<String>,
        total: u64,
        unit: (&'static str, &'static str),
        mode: ProgressMode,
    ) -> Progress {
        let tty = std::io::stderr().is_terminal();
        let (bar, lines) = match mode {
            ProgressMode::Hidden => (None, false),
            ProgressMode::Auto if tty => (Some(()), false),
            ProgressMode::Auto | ProgressMode::Lines => (None, true),
        };
        let label = label.into();
        let bar = bar.map(|()| {
            let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
            bar.set_style(
                ProgressStyle::with_template(
                    "{prefix} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar.set_prefix(label.clone());
            bar.enable_steady_tick(Duration::from_secs(1));
            bar
        });
        let p = Progress {
            label,
            unit,
            total,
            bar,
            lines,
            log_every: Self::DEFAULT_LOG_EVERY,
            started: Instant::now(),
            state: Mutex::new(State {
                done: 0,
                last_line: None,
            }),
        };
        p.refresh(0, None);
        if p.lines {
            p.line(&p.status(0));
        }
        p
    }

    /// Log lines at most this often (tests and short batches use less).
    pub fn log_every(mut self, every: Duration) -> Progress {
        self.log_every = every;
        self
    }

    fn unit(&self, n: u64) -> &'static str {
        if n == 1 { self.unit.0 } else { self.unit.1 }
    }

    /// `3/10 episodes (30%), 1.2 episodes/min, elapsed 2m 30s, ETA 5m 50s`.
    fn status(&self, done: u64) -> String {
        let elapsed = self.started.elapsed().as_secs_f64();
        let mut s = format!(
            "{}: {done}/{} {}",
            self.label,
            self.total,
            self.unit(self.total)
        );
        if self.total > 0 {
            s += &format!(" ({:.0}%)", 100.0 * done as f64 / self.total as f64);
        }
        s += &format!(", elapsed {}", human_duration(elapsed));
        s += &self.rate_and_eta(done, elapsed);
        s
    }

    fn rate_and_eta(&self, done: u64, elapsed: f64) -> String {
        if done == 0 {
            return if self.total == 0 {
                String::new()
            } else {
                format!(", ETA after the first {}", self.unit.0)
            };
        }
        let per_item = elapsed / done as f64;
        let rate = if per_item >= 60.0 {
            format!("{} per {}", human_duration(per_item), self.unit.0)
        } else {
            format!("{:.1} {}/min", 60.0 / per_item.max(1e-9), self.unit.1)
        };
        let left = self.total.saturating_sub(done);
        if left == 0 {
            format!(", {rate}")
        } else {
            format!(", {rate}, ETA {}", human_duration(per_item * left as f64))
        }
    }

    fn refresh(&self, done: u64, last: Option<&str>) {
        if let Some(bar) = &self.bar {
            let elapsed = self.started.elapsed().as_secs_f64();
            let mut msg = format!(
                "{}{}",
                self.unit(self.total),
                self.rate_and_eta(done, elapsed)
            );
            if let Some(l) = last {
                msg += &format!(" · last: {l}");
            }
            bar.set_position(done);
            bar.set_message(msg);
        }
    }

    fn line(&self, text: &str) {
        let mut err = std::io::stderr().lock();
        let _ = writeln!(err, "{text}");
    }

    /// One item finished; `what` names it (`dips seed 3`).
    pub fn item_done(&self, what: Option<&str>) {
        let Ok(mut st) = self.state.lock() else {
            return;
        };
        st.done += 1;
        let done = st.done;
        self.refresh(done, what);
        if self.lines {
            let due = st.last_line.is_none_or(|t| t.elapsed() >= self.log_every);
            if due || done == self.total || done == 1 {
                st.last_line = Some(Instant::now());
                let mut s = self.status(done);
                if let Some(w) = what {
                    s += &format!(" (last: {w})");
                }
                self.line(&s);
            }
        }
    }

    /// A message for the person (a failure, a note): above the bar, or as its own line.
    pub fn note(&self, text: &str) {
        match &self.bar {
            Some(bar) => bar.suspend(|| self.line(text)),
            None if self.lines => self.line(text),
            None => {}
        }
    }

    /// Items done so far.
    pub fn done(&self) -> u64 {
        self.state.lock().map(|s| s.done).unwrap_or(0)
    }

    /// The batch is over: the bar is cleared (log mode has printed its last line).
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_and_units_read_well() {
        assert_eq!(human_duration(0.4), "0s");
        assert_eq!(human_duration(200.0), "3m 20s");
        assert_eq!(human_duration(3725.0), "1h 02m");
        assert_eq!(human_duration(f64::NAN), "?");
        let p = Progress::new(
            "eval card",
            1,
            ("episode", "episodes"),
            ProgressMode::Hidden,
        );
        assert!(p.status(0).contains("0/1 episode ("), "{}", p.status(0));
        assert!(p.status(0).ends_with("ETA after the first episode"));
        p.item_done(Some("dips seed 0"));
        assert_eq!(p.done(), 1);
        let s = p.status(1);
        assert!(
            s.contains("1/1 episode (100%)") && !s.contains("ETA"),
            "{s}"
        );
        let p = Progress::new("datagen", 4, ("demo", "demos"), ProgressMode::Hidden);
        p.item_done(None);
        let s = p.status(1);
        assert!(s.contains("1/4 demos (25%)") && s.contains("ETA"), "{s}");
    }
}
