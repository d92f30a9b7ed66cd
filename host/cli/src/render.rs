//! `dips render --input FILE --out OUT.gif|OUT.svg|OUT.png [--step K] [--size PX]`: pictures
//! of an episode's `result.json` (from `dips episode` or `dips eval`) or of a `dips sim run`
//! trajectory. A `.gif` is the animation of every state (each mode's start and every executed
//! action, with contacts, forces, goals and the paths so far); `.svg`/`.png` draws one state,
//! `--step K` (default: the last). Frames show three labelled views in cm, the mode and step,
//! the object's coordinate against its goal and a legend.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Args;
use dips_report::render;
use dips_report::{Recording, pictures};
use dips_world::world::World;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// `dips render` arguments.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// An episode's `result.json` or a `dips sim run` trajectory.
    #[arg(long)]
    pub input: PathBuf,
    /// Output: `.gif` (animation of every state), `.svg` or `.png` (one state).
    #[arg(long)]
    pub out: PathBuf,
    /// The state to draw into an `.svg`/`.png` (0-based; default: the last).
    #[arg(long)]
    pub step: Option<usize>,
    /// Pixels per view (three views side by side; default 400, animations 340).
    #[arg(long)]
    pub size: Option<u32>,
}

/// What kind of picture an output path asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Picture {
    /// A GIF animation.
    Animation,
    /// One state as SVG or PNG.
    Still,
}

/// The picture kind of `out`, or an error naming the allowed extensions.
pub fn picture_kind(out: &Path, animation_allowed: bool) -> anyhow::Result<Picture> {
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("gif") if animation_allowed => Ok(Picture::Animation),
        Some("svg" | "png") => Ok(Picture::Still),
        _ => bail!(
            "--out {} must end in {}",
            out.display(),
            if animation_allowed {
                ".gif (animation), .svg or .png (one state)"
            } else {
                ".svg or .png"
            }
        ),
    }
}

/// Check that `out`'s directory exists, before any work.
pub fn check_out_dir(out: &Path) -> anyhow::Result<()> {
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty());
    if let Some(p) = parent
        && p.exists()
        && !p.is_dir()
    {
        bail!(
            "--out {}: {} is a file, not a directory",
            out.display(),
            p.display()
        );
    }
    if let Some(p) = parent
        && !p.is_dir()
    {
        bail!(
            "--out {}: the directory {} does not exist",
            out.display(),
            p.display()
        );
    }
    Ok(())
}

/// Draw state `step` (default: the last) of `rec` to `out` (`.svg`/`.png`).
pub fn draw_state(
    rec: &Recording,
    step: Option<usize>,
    out: &Path,
    size: u32,
) -> anyhow::Result<()> {
    let len = rec.frames.len();
    let step = step.unwrap_or(len - 1);
    if step >= len {
        bail!(
            "{} has {len} states; --step {step} is out of range (0 ≤ step < {len})",
            rec.title
        );
    }
    let mut world = World::new(rec.scene);
    let states: Vec<Vec<f64>> = rec.frames.iter().map(|f| f.state.clone()).collect();
    let paths = render::trajectory_paths(&world, &states);
    let figure = pictures::frame_figure(rec, &mut world, &paths, step, size)?;
    render::write(&figure, out)?;
    Ok(())
}

/// A progress bar on stderr for `total` things called `unit`, with an ETA.
pub fn progress_bar(total: usize, what: &str, unit: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(total as u64), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix} [{elapsed_precise}] {wide_bar} {pos}/{len} {msg}, ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_prefix(what.to_string());
    bar.set_message(unit.to_string());
    bar
}

/// Write the animation of `rec` to `out` with a progress bar.
pub fn animate(rec: &Recording, out: &Path, size: u32) -> anyhow::Result<()> {
    let bar = progress_bar(rec.frames.len(), "animation", "frames");
    pictures::write_animation(rec, out, size, &mut |done, _| bar.set_position(done as u64))?;
    bar.finish_and_clear();
    Ok(())
}

/// Run the command.
pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    let kind = picture_kind(&args.out, true)?;
    check_out_dir(&args.out)?;
    if args.size == Some(0) {
        bail!("--size must be at least 1 pixel");
    }
    let rec = Recording::read(&args.input)?;
    match kind {
        Picture::Animation => {
            if args.step.is_some() {
                bail!("--step selects one state; an animation (.gif) shows all of them");
            }
            animate(
                &rec,
                &args.out,
                args.size.unwrap_or(pictures::ANIMATION_PANEL_PX),
            )
        }
        Picture::Still => draw_state(&rec, args.step, &args.out, args.size.unwrap_or(400)),
    }
    .with_context(|| format!("rendering {}", args.input.display()))?;
    crate::note!("wrote {}", args.out.display());
    Ok(())
}
