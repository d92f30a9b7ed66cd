//! `dips-report`: pictures of dips for people. An episode (`result.json`) or a `dips sim run`
//! trajectory becomes a [`Recording`] of world states; from it come a three-view drawing of
//! any state ([`render`], [`pictures::frame_figure`]), a GIF animation ([`pictures::write_animation`]),
//! plots over time ([`pictures::timeline`]), a 3D scene a person can turn
//! ([`scene3d`]) and a self-contained `report.html` ([`write_episode_report`]; the
//! evaluation's page is built by `dips-eval` with [`html`]).

pub mod html;
pub mod pictures;
pub mod recording;
pub mod render;
pub mod scene3d;

use std::path::Path;

pub use recording::{EpisodeFile, Frame, Recording};

/// Why a picture or report could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// An input file is not what it should be.
    #[error("{path}: {reason}")]
    Input {
        /// The file.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A figure could not be drawn or encoded.
    #[error("cannot draw {path}: {source}")]
    Plot {
        /// The file.
        path: String,
        /// The underlying error.
        source: dips_plot::PlotError,
    },
}

/// Write `bytes` to `path` atomically.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    dips_fs::write_atomic(path, bytes).map_err(|source| ReportError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// File names of an episode's report, inside its directory.
pub const EPISODE_GIF: &str = "episode.gif";
/// The plots over time (SVG; a PNG of the same name beside it).
pub const TIMELINE_SVG: &str = "timeline.svg";
/// The report page.
pub const REPORT_HTML: &str = "report.html";

/// Write an episode's plots over time as `dir/<stem>.svg` and `.png`.
pub fn write_timeline(rec: &Recording, dir: &Path, stem: &str) -> Result<(), ReportError> {
    let Some(t) = pictures::timeline(rec) else {
        return Ok(());
    };
    let svg_path = dir.join(format!("{stem}.svg"));
    let png_path = dir.join(format!("{stem}.png"));
    let err = |path: &Path| {
        let path = path.display().to_string();
        move |source| ReportError::Plot { path, source }
    };
    write_file(&svg_path, t.svg().map_err(err(&svg_path))?.as_bytes())?;
    write_file(&png_path, &t.png().map_err(err(&png_path))?)
}

/// The executed modes and the planning calls of an episode, as tables on `page`.
pub fn episode_tables(page: &mut html::Page, ep: &EpisodeFile) {
    use html::Cell;
    let coord = |s: &[f64]| -> String {
        match (ep.task.as_str(), s.len().checked_sub(3)) {
            ("screwdriver", Some(i)) => format!("yaw {} rad", recording::fixed(s[i + 2], 3)),
            (_, Some(i)) => format!("y {} cm", recording::fixed(100.0 * s[i + 1], 2)),
            _ => "—".into(),
        }
    };
    let rows: Vec<Vec<Cell>> = ep
        .mode_runs
        .iter()
        .enumerate()
        .map(|(m, r)| {
            let end = r.steps.last().map_or(&r.start_state, |s| &s.state);
            vec![
                format!("{}", m + 1).into(),
                r.mode.clone().into(),
                format!("{}", r.steps.len()).into(),
                coord(&r.start_state).into(),
                coord(end).into(),
                match ep.scene() {
                    Ok(scene) => recording::goal_words(scene, r.goal),
                    Err(_) => format!("{:.3} / {:.3} / {:.3}", r.goal[0], r.goal[1], r.goal[2]),
                }
                .into(),
                (if r.steps.iter().all(|s| s.valid) {
                    "yes"
                } else {
                    "no"
                })
                .into(),
            ]
        })
        .collect();
    page.heading(2, "modes", "Executed modes").table(
        &[
            "#",
            "mode",
            "steps",
            "start",
            "end",
            "mode goal (task coordinates)",
            "valid",
        ],
        &rows,
    );
    if !ep.plans.is_empty() {
        let rows: Vec<Vec<Cell>> = ep
            .plans
            .iter()
            .enumerate()
            .map(|(i, p)| {
                vec![
                    format!("{}", i + 1).into(),
                    p.status.clone().into(),
                    format!("{}", p.nodes_expanded).into(),
                    format!("{:.2}", p.seconds).into(),
                    p.modes.join(" → ").into(),
                ]
            })
            .collect();
        page.heading(2, "plans", "Planning calls").table(
            &["#", "status", "expansions", "seconds", "planned modes"],
            &rows,
        );
    }
}

/// Write an episode's report into `dir` (where its `result.json` is): the plots over time,
/// the animation when `animate` (`progress(done, total)` per frame), and `report.html` with
/// the 3D view ([`scene3d`]).
pub fn write_episode_report(
    dir: &Path,
    rec: &Recording,
    animate: bool,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(), ReportError> {
    let ep = rec.episode.as_ref().ok_or_else(|| ReportError::Input {
        path: dir.display().to_string(),
        reason: "a report needs an episode's result.json".into(),
    })?;
    let stem = TIMELINE_SVG.trim_end_matches(".svg");
    write_timeline(rec, dir, stem)?;
    if animate {
        pictures::write_animation(
            rec,
            &dir.join(EPISODE_GIF),
            pictures::ANIMATION_PANEL_PX,
            progress,
        )?;
    }
    let mut page = html::Page::new(&rec.title);
    page.paragraph(&format!(
        "Outcome: {}.{}",
        ep.outcome(),
        ep.success_rule
            .as_deref()
            .map(|r| format!(" Success rule: {r}."))
            .unwrap_or_default()
    ));
    page.links(&[("result.json".into(), "result.json".into())]);
    let scene = scene3d::scene_data(rec)?;
    page.heading(2, "scene3d", "3D view")
        .raw(&scene3d::scene_html(&scene))
        .note(
            "Drag to turn, scroll to zoom, right-drag to pan; the slider chooses the state and \
             play runs the episode at the animation's pace. The hand's links and fingertips \
             (task fingers coloured, the others grey-blue) come from our forward kinematics; \
             red dots are contacts and green arrows the forces exerted on the object (5 cm per N); \
             the grey ghost is the goal; purple lines are the paths of the task fingertips and \
             the object so far. Units are metres.",
        );
    if dir.join(EPISODE_GIF).exists() {
        page.heading(2, "animation", "Animation").image(
            EPISODE_GIF,
            "the episode, one frame per executed action: three views of the hand and the object",
        );
        page.note(
            "Front (x–z), side (y–z) and top (x–y) views in cm. Fingertips of the task fingers \
             are named; red dots are contacts, green arrows the forces the fingers exert; dashed \
             black outlines are goals. The front view draws everything on top of each other: a \
             finger drawn over the table is in front of it or behind it, as the side view shows.",
        );
    } else {
        page.note("No animation: run `dips episode ... --render` or `dips render` for one.");
    }
    page.heading(2, "timeline", "Plots over time")
        .image(TIMELINE_SVG, "plots over the episode's time");
    episode_tables(&mut page, ep);
    write_file(&dir.join(REPORT_HTML), page.render().as_bytes())
}
