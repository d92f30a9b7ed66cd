//! The pictures: one frame as a three-view drawing, the whole recording as a GIF, an
//! episode's plots over time.

use std::path::Path;

use crate::render::{self, Overlay};
use dips_exec::episode::SCREWDRIVER_SUCCESS_YAW;
use dips_exec::problems::allegro::REGRASP_CLEARANCE;
use dips_plot::{GifWriter, SceneFigure, Series, SeriesStyle, TimePanel, Timeline};
use dips_world::kinematics::Finger;
use dips_world::scenes::SceneKind;
use dips_world::world::World;
use nalgebra::Point3;

use crate::recording::Recording;
use crate::{ReportError, write_file};

/// Pixels per view of animation frames.
pub const ANIMATION_PANEL_PX: u32 = 340;

/// Colours of the task fingers in plots (index, middle, ring, thumb).
pub(crate) fn finger_color(f: Finger) -> [u8; 3] {
    match f {
        Finger::Index => [31, 119, 180],
        Finger::Middle => [255, 127, 14],
        Finger::Ring => [148, 103, 189],
        Finger::Thumb => [44, 160, 44],
    }
}

/// Frame `k`'s drawing, with the paths of the fingertips and the object up to it.
pub fn frame_figure(
    rec: &Recording,
    world: &mut World,
    paths: &[Vec<Point3<f64>>],
    k: usize,
    panel_px: u32,
) -> Result<SceneFigure, ReportError> {
    let frame = &rec.frames[k];
    world
        .set_state(&frame.state)
        .map_err(|e| ReportError::Input {
            path: rec.title.clone(),
            reason: format!("frame {k}: {e}"),
        })?;
    let upto: Vec<Vec<Point3<f64>>> = paths
        .iter()
        .map(|p| p[..(k + 1).min(p.len())].to_vec())
        .collect();
    let overlay = Overlay {
        contacts: &frame.contacts,
        paths: &upto,
        goals: &frame.goals,
    };
    Ok(render::figure(
        world,
        &overlay,
        &format!("{}\n{}", rec.title, frame.label),
        panel_px,
    ))
}

/// Every frame's drawing, the views' ranges shared so the picture holds still.
pub fn all_figures(rec: &Recording, panel_px: u32) -> Result<Vec<SceneFigure>, ReportError> {
    let mut world = World::new(rec.scene);
    let states: Vec<Vec<f64>> = rec.frames.iter().map(|f| f.state.clone()).collect();
    let paths = render::trajectory_paths(&world, &states);
    let mut figures = (0..rec.frames.len())
        .map(|k| frame_figure(rec, &mut world, &paths, k, panel_px))
        .collect::<Result<Vec<_>, _>>()?;
    SceneFigure::share_ranges(&mut figures);
    Ok(figures)
}

/// Write the recording as an endlessly looping GIF; `progress(done, total)` after each frame.
pub fn write_animation(
    rec: &Recording,
    path: &Path,
    panel_px: u32,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(), ReportError> {
    let figures = all_figures(rec, panel_px)?;
    let (w, h) = figures[0].size();
    let plot = |source| ReportError::Plot {
        path: path.display().to_string(),
        source,
    };
    let mut gif = GifWriter::new(Vec::new(), w, h).map_err(plot)?;
    for (k, (fig, frame)) in figures.iter().zip(&rec.frames).enumerate() {
        let delay = (frame.hold_s * 100.0).round().clamp(1.0, 65535.0) as u16;
        gif.frame(&fig.rgb().map_err(plot)?, delay).map_err(plot)?;
        progress(k + 1, figures.len());
    }
    write_file(path, &gif.finish().map_err(plot)?)
}

/// An episode's plots over time: the object against its goals, contact force per finger,
/// lifted fingers' distance to the object against the clearance δ, and solve and planning
/// times. `None` when the recording is not an episode.
pub fn timeline(rec: &Recording) -> Option<Timeline> {
    let ep = rec.episode.as_ref()?;
    let fingers = rec.scene.task_fingers();
    let mut phases = Vec::new();
    let mut object = Vec::new();
    let mut goal = Vec::new();
    let mut forces = vec![Vec::new(); fingers.len()];
    let mut sdf = vec![Vec::new(); fingers.len()];
    let mut solve = Vec::new();
    let mut planning = Vec::new();
    let scale = match rec.scene {
        SceneKind::Screwdriver => 1.0,
        SceneKind::Card => 100.0,
    };
    let coord = match rec.scene {
        SceneKind::Screwdriver => 2,
        SceneKind::Card => 1,
    };
    let mut t = 0.0;
    for (m, run) in ep.mode_runs.iter().enumerate() {
        phases.push((t, run.mode.clone()));
        let lifted = rec
            .lifted(&run.mode)
            .unwrap_or_else(|| vec![false; fingers.len()]);
        if let Some(&s) = ep.planning_s.get(m) {
            planning.push((t, s));
        }
        if let Some(o) = run
            .start_state
            .len()
            .checked_sub(3)
            .map(|i| run.start_state[i + coord])
        {
            object.push((t, scale * o));
        }
        goal.push((t, scale * run.goal[coord]));
        for s in &mut sdf {
            // Break the line between modes; a finger's clearance matters only while lifted.
            s.push((t, f64::NAN));
        }
        for step in &run.steps {
            t += 1.0;
            if let Some(i) = step.state.len().checked_sub(3) {
                object.push((t, scale * step.state[i + coord]));
            }
            solve.push((t, step.solve_s));
            for (i, f) in fingers.iter().enumerate() {
                let total: [f64; 3] = step
                    .contacts
                    .iter()
                    .filter(|c| c.finger == f.name())
                    .fold([0.0; 3], |a, c| {
                        [a[0] + c.force[0], a[1] + c.force[1], a[2] + c.force[2]]
                    });
                let norm = (total[0].powi(2) + total[1].powi(2) + total[2].powi(2)).sqrt();
                forces[i].push((t, norm));
                let d = step.tip_sdf.get(i).copied().unwrap_or(f64::NAN);
                sdf[i].push((
                    t,
                    if lifted.get(i).copied().unwrap_or(false) {
                        1e3 * d
                    } else {
                        f64::NAN
                    },
                ));
            }
        }
    }
    goal.push((t, goal.last().map_or(f64::NAN, |g| g.1)));
    let has_contacts = ep
        .mode_runs
        .iter()
        .any(|r| r.steps.iter().any(|s| !s.contacts.is_empty()));
    let mut object_series = vec![
        Series {
            label: match rec.scene {
                SceneKind::Screwdriver => "yaw".into(),
                SceneKind::Card => "card y".into(),
            },
            color: [31, 119, 180],
            style: SeriesStyle::Line,
            points: object,
        },
        Series {
            label: "mode goal".into(),
            color: [0, 0, 0],
            style: SeriesStyle::Steps,
            points: goal,
        },
    ];
    let (threshold, threshold_label) = match rec.scene {
        SceneKind::Screwdriver => (SCREWDRIVER_SUCCESS_YAW, "success: yaw ≤ −π/3"),
        SceneKind::Card => (
            100.0 * f64::from(dips_kernel::task::CARD_GOAL_Y),
            "task goal",
        ),
    };
    object_series.push(Series {
        label: threshold_label.into(),
        color: [214, 39, 40],
        style: SeriesStyle::Dashed,
        points: vec![(0.0, threshold), (t, threshold)],
    });
    let per_finger = |values: Vec<Vec<(f64, f64)>>| -> Vec<Series> {
        fingers
            .iter()
            .zip(values)
            .map(|(f, points)| Series {
                label: f.name().to_string(),
                color: finger_color(*f),
                style: SeriesStyle::Line,
                points,
            })
            .collect()
    };
    // No finger lifted (no regrasp mode ran): a sentence instead of a dashed δ line alone on
    // an axis around it.
    let any_lifted = sdf.iter().flatten().any(|p| p.1.is_finite());
    let mut sdf_series = per_finger(sdf);
    sdf_series.push(Series {
        label: "clearance δ".into(),
        color: [0, 0, 0],
        style: SeriesStyle::Dashed,
        points: vec![(0.0, 1e3 * REGRASP_CLEARANCE), (t, 1e3 * REGRASP_CLEARANCE)],
    });
    let panels = vec![
        TimePanel {
            title: match rec.scene {
                SceneKind::Screwdriver => "screwdriver yaw against its goals".into(),
                SceneKind::Card => "card position against its goals".into(),
            },
            y_label: match rec.scene {
                SceneKind::Screwdriver => "yaw (rad)".into(),
                SceneKind::Card => "y (cm)".into(),
            },
            series: object_series,
        },
        TimePanel {
            title: "contact force per finger (norm of the sum over its contacts)".into(),
            y_label: "force (N)".into(),
            series: if has_contacts {
                per_finger(forces)
            } else {
                Vec::new()
            },
        },
        if any_lifted {
            TimePanel {
                title: "lifted fingers: fingertip distance to the object".into(),
                y_label: "sdf (mm)".into(),
                series: sdf_series,
            }
        } else {
            TimePanel {
                title: "lifted fingers: none in this episode (every mode kept its fingers in \
                        contact), so no clearance to plot"
                    .into(),
                y_label: "sdf (mm)".into(),
                series: Vec::new(),
            }
        },
        TimePanel {
            title: "time spent: CSVTO solve per step, planning per mode".into(),
            y_label: "seconds".into(),
            series: vec![
                Series {
                    label: "CSVTO solve".into(),
                    color: [140, 86, 75],
                    style: SeriesStyle::Line,
                    points: solve,
                },
                Series {
                    label: "planning call".into(),
                    color: [227, 119, 194],
                    style: SeriesStyle::Points,
                    points: planning,
                },
            ],
        },
    ];
    Some(Timeline {
        title: format!("{} · {}", rec.title, ep.outcome()),
        x_label: "time (s; one action per second)".into(),
        panels,
        phases,
        panel_size: (900, 230),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A committed episode of the card's second model version (`tests/fixtures/`).
    fn committed(name: &str) -> Recording {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
        Recording::read(&root.join(name)).unwrap()
    }

    #[test]
    fn no_lifted_finger_is_a_sentence_not_an_empty_axis() {
        let lifted = |rec: &Recording| {
            let t = timeline(rec).unwrap();
            t.panels
                .into_iter()
                .find(|p| p.title.starts_with("lifted fingers"))
                .unwrap()
        };
        // The policy's modes lift no finger.
        let none = lifted(&committed("card-v2-diffusion-policy-seed-3003.json"));
        assert!(none.series.is_empty(), "{:?}", none.series);
        assert!(
            none.title.contains("none in this episode"),
            "{}",
            none.title
        );
        // `index` lifts the middle finger.
        let some = lifted(&committed("card-v2-dips-seed-3008.json"));
        assert!(!some.series.is_empty());
        assert_eq!(
            some.title,
            "lifted fingers: fingertip distance to the object"
        );
    }
}
