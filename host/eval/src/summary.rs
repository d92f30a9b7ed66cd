//! `results.json`, `results.md` and the box plots of an evaluation directory, from every
//! finished episode in it (all shards).

use std::path::{Path, PathBuf};

use dips_exec::episode::episode_success;
use dips_fs::write_atomic;
use dips_planning::online::Method;
use dips_plot::{BoxPlot, BoxSeries, PlotError};
use dips_report::EpisodeFile;
use dips_world::scenes::SceneKind;
use serde::Serialize;

use crate::protocol::{ProtocolError, Registration, RegistrationStatus, read_registration};
use crate::run::{EpisodeWall, WALL_FILE};
use crate::settings::{EVAL_FILE, EvalFile, EvalFileError, episode_dir, read_eval_file};

/// Why an evaluation directory cannot be summarised. Each message names the file.
#[derive(Debug, thiserror::Error)]
pub enum SummaryError {
    /// The directory holds no evaluation.
    #[error("{} holds no {EVAL_FILE}", dir.display())]
    NoEvalFile {
        /// The directory.
        dir: PathBuf,
    },
    /// An episode's `wall.json` is not one.
    #[error("{} is not a wall-time file", file.display())]
    Wall {
        /// The file.
        file: PathBuf,
        /// What serde found.
        #[source]
        source: serde_json::Error,
    },
    /// An episode's `result.json` cannot be read.
    #[error("reading {}", file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// An episode's `result.json` is not one.
    #[error("{} is not an episode result", file.display())]
    Result {
        /// The file.
        file: PathBuf,
        /// What serde found.
        #[source]
        source: serde_json::Error,
    },
    /// A summary file cannot be written.
    #[error("writing {}", file.display())]
    Write {
        /// The file.
        file: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A figure cannot be drawn.
    #[error("drawing {name}")]
    Draw {
        /// The figure (`outcome`, `planning`).
        name: &'static str,
        /// Why.
        #[source]
        source: PlotError,
    },
    /// `eval.json` cannot be read.
    #[error(transparent)]
    EvalFile(#[from] EvalFileError),
    /// `registration.json` cannot be read.
    #[error(transparent)]
    Protocol(#[from] ProtocolError),
    /// `results.json` cannot be written as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// One trial in `results.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Trial {
    /// The method.
    #[serde(with = "crate::by_name")]
    pub method: Method,
    /// Seed.
    pub seed: u64,
    /// The outcome (final yaw in rad, or distance to the goal in cm); `None` when the episode
    /// ended with an error.
    pub outcome: Option<f64>,
    /// Whether the object stayed valid (false for an error).
    pub valid: bool,
    /// Whether the trial succeeded (`dips_exec::episode::episode_success`).
    pub success: bool,
    /// Executed modes.
    pub modes: Vec<String>,
    /// Planning calls (s).
    pub planning_s: Vec<f64>,
    /// Median CSVTO step time (s).
    pub csvto_step_median_s: Option<f64>,
    /// Wall time of the episode (s).
    pub wall_s: f64,
    /// The error that ended the episode, if one did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Mean, spread and order statistics of some values.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Stats {
    /// How many values.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (0 for one value).
    pub std: f64,
    /// Median.
    pub median: f64,
    /// 90th percentile (linear interpolation).
    pub p90: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
}

impl Stats {
    /// The statistics of the finite values; `None` when there is none.
    pub fn of(values: &[f64]) -> Option<Stats> {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = if n > 1 {
            v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64
        } else {
            0.0
        };
        Some(Stats {
            n,
            mean,
            std: var.sqrt(),
            median: quantile(&v, 0.5),
            p90: quantile(&v, 0.9),
            min: v[0],
            max: v[n - 1],
        })
    }
}

/// Quantile `q` of sorted values (linear interpolation between order statistics).
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let pos = q * (sorted.len() - 1) as f64;
    let (i, frac) = (pos.floor() as usize, pos - pos.floor());
    let next = sorted[(i + 1).min(sorted.len() - 1)];
    sorted[i] + frac * (next - sorted[i])
}

/// One method's row.
#[derive(Debug, Clone, Serialize)]
pub struct MethodSummary {
    /// The method.
    #[serde(with = "crate::by_name")]
    pub method: Method,
    /// Finished trials.
    pub trials: usize,
    /// Trials that ended with an error.
    pub errors: usize,
    /// Trials in which the object stayed valid.
    pub valid: usize,
    /// Trials that succeeded.
    pub success: usize,
    /// The outcome over the trials with one.
    pub outcome: Option<Stats>,
    /// Every planning call of every trial (s).
    pub planning_s: Option<Stats>,
    /// Per-trial median CSVTO step time (s).
    pub csvto_step_s: Option<Stats>,
    /// Episode wall time (s).
    pub wall_s: Option<Stats>,
}

/// `results.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// The task.
    #[serde(with = "crate::by_name")]
    pub task: SceneKind,
    /// The evaluation's settings.
    pub eval: EvalFile,
    /// Its registration under a protocol (`registration.json`), if it ran under one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub registration: Option<Registration>,
    /// What the outcome is, with its unit.
    pub outcome: &'static str,
    /// Whether a lower outcome is better (both tasks: yes).
    pub lower_is_better: bool,
    /// One row per method, in `eval.json`'s order.
    pub methods: Vec<MethodSummary>,
    /// Every finished trial.
    pub trials: Vec<Trial>,
    /// Sum of the episodes' wall times (s); divide by the jobs for the elapsed time.
    pub episode_wall_total_s: f64,
}

fn read_trial(
    dir: &Path,
    method: Method,
    seed: u64,
    scene: SceneKind,
) -> Result<Option<Trial>, SummaryError> {
    let ep = episode_dir(dir, method, seed);
    let Ok(text) = std::fs::read_to_string(ep.join(WALL_FILE)) else {
        return Ok(None);
    };
    let wall: EpisodeWall = serde_json::from_str(&text).map_err(|source| SummaryError::Wall {
        file: ep.join(WALL_FILE),
        source,
    })?;
    if let Some(error) = wall.error {
        return Ok(Some(Trial {
            method,
            seed,
            outcome: None,
            valid: false,
            success: false,
            modes: Vec::new(),
            planning_s: Vec::new(),
            csvto_step_median_s: None,
            wall_s: wall.seconds,
            error: Some(error),
        }));
    }
    let file = ep.join("result.json");
    let text = match std::fs::read_to_string(&file) {
        Ok(text) => text,
        Err(source) => return Err(SummaryError::Read { file, source }),
    };
    let r: EpisodeFile = match serde_json::from_str(&text) {
        Ok(r) => r,
        Err(source) => return Err(SummaryError::Result { file, source }),
    };
    let outcome = match scene {
        SceneKind::Screwdriver => r.final_yaw,
        SceneKind::Card => r.final_distance_m.map(|d| d * 100.0),
    };
    let planning_s = r.planning_times();
    Ok(Some(Trial {
        method,
        seed: r.seed,
        outcome,
        valid: r.valid,
        success: episode_success(scene, r.valid, r.final_yaw, r.final_distance_m),
        modes: r.modes,
        planning_s,
        csvto_step_median_s: Stats::of(&r.csvto_step_s).map(|s| s.median),
        wall_s: wall.seconds,
        error: None,
    }))
}

/// Read every finished episode of `dir` and write `results.json`, `results.md` and the box
/// plots (`outcome.svg/png`, `planning.svg/png`).
pub fn summarize(dir: &Path) -> Result<Summary, SummaryError> {
    let eval = read_eval_file(dir)?.ok_or_else(|| SummaryError::NoEvalFile {
        dir: dir.to_path_buf(),
    })?;
    let task = eval.episode.task;
    let registration = read_registration(dir)?;
    let mut trials = Vec::new();
    let mut methods = Vec::new();
    for m in &eval.methods {
        let mine: Vec<Trial> = (0..eval.trials)
            .map(|i| read_trial(dir, *m, eval.first_seed + i as u64, task))
            .filter_map(Result::transpose)
            .collect::<Result<_, _>>()?;
        let outcomes: Vec<f64> = mine.iter().filter_map(|t| t.outcome).collect();
        let planning: Vec<f64> = mine.iter().flat_map(|t| t.planning_s.clone()).collect();
        let csvto: Vec<f64> = mine.iter().filter_map(|t| t.csvto_step_median_s).collect();
        let wall: Vec<f64> = mine.iter().map(|t| t.wall_s).collect();
        methods.push(MethodSummary {
            method: *m,
            trials: mine.len(),
            errors: mine.iter().filter(|t| t.error.is_some()).count(),
            valid: mine.iter().filter(|t| t.valid).count(),
            success: mine.iter().filter(|t| t.success).count(),
            outcome: Stats::of(&outcomes),
            planning_s: Stats::of(&planning),
            csvto_step_s: Stats::of(&csvto),
            wall_s: Stats::of(&wall),
        });
        trials.extend(mine);
    }
    let summary = Summary {
        outcome: match task {
            SceneKind::Screwdriver => "final yaw (rad; clockwise is negative, the goal is to turn)",
            SceneKind::Card => "final distance of the card to its goal (cm)",
        },
        lower_is_better: true,
        episode_wall_total_s: trials.iter().map(|t| t.wall_s).sum(),
        task,
        eval,
        registration,
        methods,
        trials,
    };
    let write = |name: &str, bytes: &[u8]| {
        write_atomic(&dir.join(name), bytes).map_err(|source| SummaryError::Write {
            file: dir.join(name),
            source,
        })
    };
    write(
        "results.json",
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    write("results.md", markdown(&summary).as_bytes())?;
    for (name, plot) in figures(&summary) {
        match (plot.svg(), plot.png()) {
            (Ok(svg), Ok(png)) => {
                write(&format!("{name}.svg"), svg.as_bytes())?;
                write(&format!("{name}.png"), &png)?;
            }
            // Nothing finished yet: no figure, the table says so.
            (Err(dips_plot::PlotError::Empty(_)), _) | (_, Err(dips_plot::PlotError::Empty(_))) => {
            }
            (Err(source), _) | (_, Err(source)) => {
                return Err(SummaryError::Draw { name, source });
            }
        }
    }
    Ok(summary)
}

fn figures(s: &Summary) -> Vec<(&'static str, BoxPlot)> {
    let screwdriver = s.task == SceneKind::Screwdriver;
    let per_method = |f: &dyn Fn(&Trial) -> Vec<f64>| -> Vec<BoxSeries> {
        s.methods
            .iter()
            .map(|m| BoxSeries {
                label: m.method.to_string(),
                values: s
                    .trials
                    .iter()
                    .filter(|t| t.method == m.method)
                    .flat_map(f)
                    .collect(),
            })
            .collect()
    };
    let n = s.eval.trials;
    vec![
        (
            "outcome",
            BoxPlot {
                title: if screwdriver {
                    format!("Screwdriver: final yaw per trial ({n} trials per method)")
                } else {
                    format!("Card: distance to the goal per trial ({n} trials per method)")
                },
                x_label: "method".into(),
                y_label: if screwdriver {
                    "final yaw (rad), lower = turned further".into()
                } else {
                    "final distance to goal (cm)".into()
                },
                series: per_method(&|t| t.outcome.into_iter().collect()),
                reference: if screwdriver {
                    None
                } else {
                    Some((0.0, "goal".into()))
                },
                size: (960, 540),
            },
        ),
        (
            "planning",
            BoxPlot {
                title: format!(
                    "{}: planning-call wall time (every call of every trial)",
                    if screwdriver { "Screwdriver" } else { "Card" }
                ),
                x_label: "method".into(),
                y_label: "planning call (s)".into(),
                series: per_method(&|t| t.planning_s.clone()),
                reference: None,
                size: (960, 540),
            },
        ),
    ]
}

fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "–".to_string(), |x| format!("{x:.digits$}"))
}

/// What a summary lacks ([`shortfall`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Shortfall {
    /// More trials per method were asked of the summary than the evaluation was run for.
    MoreAsked {
        /// The trials asked of the summary.
        asked: usize,
        /// The trials per method `eval.json` holds.
        recorded: usize,
    },
    /// A method has fewer finished trials than expected.
    Unfinished {
        /// The method.
        method: Method,
        /// Its finished trials.
        finished: usize,
        /// The trials expected.
        expected: usize,
    },
}

impl std::fmt::Display for Shortfall {
    /// One sentence: what is asked, what there is, and what the summary covers.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::MoreAsked { asked, recorded } => write!(
                f,
                "{asked} trials asked for: this evaluation was asked for {recorded} trials per \
                 method (eval.json); the summary covers those (run the evaluation to add the \
                 rest)"
            ),
            Self::Unfinished {
                method,
                finished,
                expected,
            } => write!(
                f,
                "{method}: {finished} of {expected} trials finished; the summary covers those \
                 {finished}"
            ),
        }
    }
}

/// What a summary lacks: each method with fewer finished trials than `asked` (default: the
/// trials `eval.json` holds), so a summary of part of an evaluation never passes for the
/// whole. Empty when every trial is there.
pub fn shortfall(s: &Summary, asked: Option<usize>) -> Vec<Shortfall> {
    let expected = asked.unwrap_or(s.eval.trials);
    let mut lines = Vec::new();
    if expected > s.eval.trials {
        lines.push(Shortfall::MoreAsked {
            asked: expected,
            recorded: s.eval.trials,
        });
    }
    for m in &s.methods {
        if m.trials < expected {
            lines.push(Shortfall::Unfinished {
                method: m.method,
                finished: m.trials,
                expected,
            });
        }
    }
    lines
}

/// What a registration makes of the results, as a paragraph of `results.md`.
fn registration_line(r: &Registration) -> String {
    let what = match r.status {
        RegistrationStatus::Registered => "the registered run of this protocol".to_string(),
        RegistrationStatus::Rerun => format!(
            "a rerun on a spent range (spent by {}); it never replaces the registered result",
            r.spent_by.join(", ")
        ),
        RegistrationStatus::Tuning => "a tuning run (seeds below 1000), never registered".into(),
        RegistrationStatus::Unregistered => {
            "a run of an uncommitted protocol, not registered".into()
        }
    };
    format!(
        "**{}**: {what}. Protocol `{}` (`{}`, sha256 `{}`), commit {}{}, CPU {}.\n\n",
        r.status.name(),
        r.name,
        r.protocol,
        r.protocol_sha256,
        r.stamp.commit.as_deref().unwrap_or("none"),
        if r.stamp.dirty == Some(true) {
            " (tree dirty)"
        } else {
            ""
        },
        r.stamp.cpu,
    )
}

/// The Markdown table of a summary.
pub fn markdown(s: &Summary) -> String {
    let screwdriver = s.task == SceneKind::Screwdriver;
    let (what, unit, digits) = if screwdriver {
        ("final yaw", "rad", 3)
    } else {
        ("distance to goal", "cm", 2)
    };
    let e = &s.eval.episode;
    let mut out = format!(
        "# dips eval: {}\n\nSampler `{}`, planning budget {} s / {} expansions, cost-to-come \
         `{}`, search depth `{}`, engine {}, seeds {}…{}. Lower is better. Every trial's `result.json` is under `episodes/`.\n\n",
        s.task,
        e.sampler,
        e.time_budget_s,
        if e.node_budget == 0 {
            "unlimited".to_string()
        } else {
            e.node_budget.to_string()
        },
        e.cost_to_come,
        e.search_depth,
        e.engine,
        s.eval.first_seed,
        s.eval.first_seed + s.eval.trials.saturating_sub(1) as u64,
    );
    if let Some(r) = &s.registration {
        out.push_str(&registration_line(r));
    }
    out.push_str(&format!(
        "| method | trials | valid | success | {what} mean ± std ({unit}) | median | planning call median / p90 (s) | CSVTO step median (s) | episode wall median (s) |\n\
         |---|---|---|---|---|---|---|---|---|\n"
    ));
    for m in &s.methods {
        let o = m.outcome;
        out.push_str(&format!(
            "| {} | {}{} | {}/{} | {}/{} | {} | {} | {} / {} | {} | {} |\n",
            m.method,
            m.trials,
            if m.errors > 0 {
                format!(" ({} errors)", m.errors)
            } else {
                String::new()
            },
            m.valid,
            m.trials,
            m.success,
            m.trials,
            o.map_or_else(
                || "–".into(),
                |o| format!("{:.digits$} ± {:.digits$}", o.mean, o.std)
            ),
            fmt_opt(o.map(|o| o.median), digits),
            fmt_opt(m.planning_s.map(|p| p.median), 2),
            fmt_opt(m.planning_s.map(|p| p.p90), 2),
            fmt_opt(m.csvto_step_s.map(|c| c.median), 3),
            fmt_opt(m.wall_s.map(|w| w.median), 0),
        ));
    }
    if screwdriver && let Some(dips) = s.methods.iter().find(|m| m.method == Method::Dips) {
        let turned = |m: &MethodSummary| m.outcome.map(|o| -o.mean);
        if let Some(d) = turned(dips) {
            out.push_str("\nTurned by `dips` relative to each other method (mean −yaw): ");
            let parts: Vec<String> = s
                .methods
                .iter()
                .filter(|m| m.method != Method::Dips)
                .filter_map(|m| turned(m).map(|t| (m, t)))
                .map(|(m, t)| format!("{:+.0} % vs {}", 100.0 * (d - t) / t.abs(), m.method))
                .collect();
            out.push_str(&parts.join(", "));
            out.push_str(".\n");
        }
    }
    let missing: Vec<String> = shortfall(s, None).iter().map(ToString::to_string).collect();
    if !missing.is_empty() {
        out.push_str(&format!("\nNot finished: {}.\n", missing.join("; ")));
    }
    out.push_str(&format!(
        "\nEpisode wall times sum to {:.0} s. Figures: `outcome.svg` / `outcome.png` (per-trial \
         outcome), `planning.svg` / `planning.png` (planning-call times; a call that found the \
         episode already at its goal plans nothing and is left out). Methods with fewer than \
         5 trials are drawn as points only.\n",
        s.episode_wall_total_s
    ));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_of_known_values() {
        let s = Stats::of(&[4.0, 1.0, 3.0, 2.0, f64::NAN]).unwrap();
        assert_eq!(s.n, 4);
        assert_eq!(s.mean, 2.5);
        assert_eq!(s.median, 2.5);
        assert!((s.p90 - 3.7).abs() < 1e-12);
        assert!((s.std - (5.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!((s.min, s.max), (1.0, 4.0));
        assert!(Stats::of(&[f64::NAN]).is_none());
        assert_eq!(Stats::of(&[2.0]).unwrap().std, 0.0);
    }
}
