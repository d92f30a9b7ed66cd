//! `report.html` of an evaluation directory: the summary table and box plots, then one
//! section per method with its median trial's animation and plots over time and a table of
//! every trial linking to that trial's own report (written beside its `result.json`).

use std::path::{Path, PathBuf};

use dips_planning::online::Method;
use dips_report::html::{Cell, Page};
use dips_report::{EPISODE_GIF, REPORT_HTML, Recording, ReportError, TIMELINE_SVG};
use dips_world::scenes::SceneKind;

/// Why an evaluation's report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum EvalReportError {
    /// A trial's own report could not be written.
    #[error("writing the report of {}", episode.display())]
    Episode {
        /// The trial's directory.
        episode: PathBuf,
        /// Why.
        #[source]
        source: ReportError,
    },
    /// A trial's result could not be read, or the page could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
}

use crate::settings::episode_dir;
use crate::summary::{MethodSummary, Summary, Trial};

/// The trial whose outcome is the method's median (the lower middle one for an even count).
pub fn median_trial(s: &Summary, method: Method) -> Option<&Trial> {
    let mut mine: Vec<&Trial> = s
        .trials
        .iter()
        .filter(|t| t.method == method && t.outcome.is_some_and(f64::is_finite))
        .collect();
    mine.sort_by(|a, b| {
        a.outcome
            .unwrap_or(f64::NAN)
            .total_cmp(&b.outcome.unwrap_or(f64::NAN))
            .then(a.seed.cmp(&b.seed))
    });
    mine.get(mine.len().saturating_sub(1) / 2).copied()
}

fn rel(method: Method, seed: u64, file: &str) -> String {
    format!("episodes/{method}/seed-{seed}/{file}")
}

fn stats_cell(v: Option<crate::summary::Stats>, digits: usize, spread: bool) -> Cell {
    match v {
        Some(s) if spread => format!("{:.digits$} ± {:.digits$}", s.mean, s.std).into(),
        Some(s) => format!("{:.digits$}", s.median).into(),
        None => "–".into(),
    }
}

fn summary_row(m: &MethodSummary, digits: usize) -> Vec<Cell> {
    vec![
        Cell::Link(m.method.to_string(), format!("#method-{}", m.method)),
        format!("{}", m.trials).into(),
        format!("{}/{}", m.valid, m.trials).into(),
        format!("{}/{}", m.success, m.trials).into(),
        stats_cell(m.outcome, digits, true),
        stats_cell(m.outcome, digits, false),
        match m.planning_s {
            Some(p) => format!("{:.2} / {:.2}", p.median, p.p90).into(),
            None => "–".into(),
        },
        stats_cell(m.csvto_step_s, 3, false),
    ]
}

/// Which trials get their own report (plots over time and a page beside `result.json`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EpisodeReports {
    /// Every finished trial.
    All,
    /// Each method's median trial only (a small report to copy or publish).
    Medians,
}

/// What goes into an evaluation's report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReportOptions {
    /// Which trials get their own report.
    pub episodes: EpisodeReports,
    /// Methods whose median trial is animated (empty: none).
    pub animate: Vec<Method>,
}

/// Write the chosen trials' episode reports (plots over time and their page; the animation
/// for the median trial of each method in `options.animate`) and the evaluation's
/// `report.html`, which links a trial's report where one exists. `progress(done, total)`
/// after each trial.
pub fn write_report(
    dir: &Path,
    s: &Summary,
    options: &ReportOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(), EvalReportError> {
    let screwdriver = s.task == SceneKind::Screwdriver;
    let digits = if screwdriver { 3 } else { 2 };
    let medians: Vec<(Method, u64)> = s
        .methods
        .iter()
        .filter_map(|m| median_trial(s, m.method).map(|t| (m.method, t.seed)))
        .collect();
    let chosen: Vec<&Trial> = s
        .trials
        .iter()
        .filter(|t| t.error.is_none())
        .filter(|t| {
            options.episodes == EpisodeReports::All || medians.contains(&(t.method, t.seed))
        })
        .collect();
    for (k, t) in chosen.iter().enumerate() {
        let ep = episode_dir(dir, t.method, t.seed);
        let rec = Recording::read(&ep.join("result.json"))?;
        let animate = medians.contains(&(t.method, t.seed)) && options.animate.contains(&t.method);
        dips_report::write_episode_report(&ep, &rec, animate, &mut |_, _| {}).map_err(
            |source| EvalReportError::Episode {
                episode: ep.clone(),
                source,
            },
        )?;
        progress(k + 1, chosen.len());
    }
    let e = &s.eval.episode;
    let mut page = Page::new(&format!("dips eval: {}", s.task));
    page.paragraph(&format!(
        "{} methods × {} trials on seeds {}…{}; sampler {}, planning budget {} s per call, \
         cost-to-come {}, search depth {}, engine {}. Outcome: {}; lower is better.",
        s.methods.len(),
        s.eval.trials,
        s.eval.first_seed,
        s.eval.first_seed + s.eval.trials.saturating_sub(1) as u64,
        e.sampler,
        e.time_budget_s,
        e.cost_to_come,
        e.search_depth,
        e.engine,
        s.outcome
    ));
    page.links(&[
        ("results.md".into(), "results.md".into()),
        ("results.json".into(), "results.json".into()),
        ("eval.json".into(), "eval.json".into()),
    ]);
    let unit = if screwdriver { "rad" } else { "cm" };
    let what = if screwdriver {
        "final yaw"
    } else {
        "distance to goal"
    };
    page.heading(2, "summary", "Summary").table(
        &[
            "method",
            "trials",
            "valid",
            "success",
            &format!("{what} mean ± std ({unit})"),
            &format!("median ({unit})"),
            "planning median / p90 (s)",
            "CSVTO step median (s)",
        ],
        &s.methods
            .iter()
            .map(|m| summary_row(m, digits))
            .collect::<Vec<_>>(),
    );
    for (file, alt) in [
        ("outcome.svg", "box plot of each method's per-trial outcome"),
        (
            "planning.svg",
            "box plot of each method's planning-call times",
        ),
    ] {
        if dir.join(file).exists() {
            page.image(file, alt);
        }
    }
    for m in &s.methods {
        page.heading(2, &format!("method-{}", m.method), m.method.name());
        let mine: Vec<&Trial> = s.trials.iter().filter(|t| t.method == m.method).collect();
        if let Some(t) = median_trial(s, m.method) {
            page.paragraph(&format!(
                "Median trial: seed {} ({what} {:.digits$} {unit}).",
                t.seed,
                t.outcome.unwrap_or(f64::NAN)
            ));
            let gif = rel(m.method, t.seed, EPISODE_GIF);
            if dir.join(&gif).exists() {
                page.image(&gif, &format!("animation of {} seed {}", m.method, t.seed));
            }
            let timeline = rel(m.method, t.seed, TIMELINE_SVG);
            if dir.join(&timeline).exists() {
                page.image(
                    &timeline,
                    &format!("plots over time of {} seed {}", m.method, t.seed),
                );
            }
        }
        let rows: Vec<Vec<Cell>> = mine
            .iter()
            .map(|t| {
                let report = rel(t.method, t.seed, REPORT_HTML);
                vec![
                    format!("{}", t.seed).into(),
                    t.outcome
                        .map_or_else(|| "–".to_string(), |o| format!("{o:.digits$}"))
                        .into(),
                    (if t.valid { "yes" } else { "no" }).into(),
                    (if t.success { "yes" } else { "no" }).into(),
                    t.modes.join(" → ").into(),
                    if dir.join(&report).exists() {
                        Cell::Link("report".into(), report)
                    } else {
                        t.error.clone().unwrap_or_else(|| "–".into()).into()
                    },
                ]
            })
            .collect();
        page.table(
            &[
                "seed",
                &format!("{what} ({unit})"),
                "valid",
                "success",
                "executed modes",
                "episode",
            ],
            &rows,
        );
    }
    dips_report::write_file(&dir.join(REPORT_HTML), page.render().as_bytes())?;
    Ok(())
}
