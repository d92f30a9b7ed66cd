//! Drawings of a world state for people: three orthographic views (front x–z, side y–z,
//! top x–y, in centimetres) of the hand (links, fingertip spheres, finger names), the object
//! (with the screwdriver's yaw marker: a line across its cap along the handle's x axis), the
//! table, the contacts and their forces, the paths of the fingertips and the object, and the
//! goal, with a heading and a legend. Drawn by `dips-plot` (plotters) as SVG or PNG, and
//! frame by frame into an episode's animation ([`crate::pictures`]).

use std::path::Path;

use dips_plot::{LegendEntry, Mark, Rgb, SceneFigure, ScenePanel};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use dips_world::geometry::PartShape;
use dips_world::kinematics::Finger;
use dips_world::scenes::{SceneKind, card, screwdriver};
use dips_world::world::{ContactReport, World};

/// Errors writing a drawing.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The output extension is neither `.svg` nor `.png`.
    #[error("output {0} must end in .svg or .png")]
    Format(String),
    /// Writing failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Drawing or encoding failed.
    #[error("cannot draw {path}: {source}")]
    Plot {
        /// The file.
        path: String,
        /// The underlying error.
        source: dips_plot::PlotError,
    },
}

const HAND: Rgb = [60, 60, 200];
const TIP: Rgb = [30, 30, 140];
const OBJECT: Rgb = [205, 120, 20];
const TABLE: Rgb = [150, 150, 150];
const CONTACT: Rgb = [210, 20, 20];
const FORCE: Rgb = [20, 150, 40];
const PATH: Rgb = [170, 60, 170];
const GOAL: Rgb = [0, 0, 0];
const MARKER: Rgb = [200, 0, 90];

/// Metres of arrow per newton of contact force.
pub const FORCE_SCALE: f64 = 0.005;

/// Centimetres per metre: the views' unit.
const CM: f64 = 100.0;

/// A goal pose of the object in task coordinates (`(roll, pitch, yaw)` for the screwdriver,
/// `(x, y, θ)` for the card), drawn dashed with its label.
#[derive(Debug, Clone, PartialEq)]
pub struct Goal {
    /// Task coordinates of the goal.
    pub coords: [f64; 3],
    /// What the goal is (e.g. "mode goal", "task goal").
    pub label: String,
}

/// What is drawn over the world state besides the hand and the object.
#[derive(Debug, Clone, Default)]
pub struct Overlay<'a> {
    /// Contacts with their forces (drawn at their points, forces as arrows).
    pub contacts: &'a [ContactReport],
    /// Polylines (e.g. [`trajectory_paths`]) with a dot at each sample.
    pub paths: &'a [Vec<Point3<f64>>],
    /// Goal poses of the object.
    pub goals: &'a [Goal],
}

/// Paths of the task fingertip centres and of the object's reference point (screwdriver cap
/// origin, card centre) over a sequence of states of `world`'s scene.
pub fn trajectory_paths(world: &World, states: &[Vec<f64>]) -> Vec<Vec<Point3<f64>>> {
    let mut w = world.clone();
    let fingers = world.scene().task_fingers();
    let mut paths = vec![Vec::with_capacity(states.len()); fingers.len() + 1];
    for s in states {
        if w.set_state(s).is_err() {
            continue;
        }
        let tips = w.tip_centers();
        for (k, f) in fingers.iter().enumerate() {
            paths[k].push(tips[f.index()]);
        }
        paths[fingers.len()].push(reference_point(world.scene(), &w.object().pose()));
    }
    paths
}

fn reference_point(scene: SceneKind, pose: &Isometry3<f64>) -> Point3<f64> {
    match scene {
        SceneKind::Screwdriver => pose * Point3::from(screwdriver::CAP_ORIGIN),
        SceneKind::Card => pose * Point3::origin(),
    }
}

/// The object pose of task coordinates `coords` (the card at its resting height).
fn goal_pose(scene: SceneKind, coords: [f64; 3]) -> Isometry3<f64> {
    match scene {
        SceneKind::Screwdriver => Isometry3::from_parts(
            Translation3::from(screwdriver::pivot().coords),
            UnitQuaternion::from_rotation_matrix(&screwdriver::rotation(
                coords[0], coords[1], coords[2],
            )),
        ),
        SceneKind::Card => Isometry3::from_parts(
            Translation3::new(coords[0], coords[1], card::INITIAL_CENTER[2]),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), coords[2]),
        ),
    }
}

/// The three views of `world` with `overlay`, under `heading` (`\n` separates lines), each
/// view `panel_px` pixels wide.
pub fn figure(world: &World, overlay: &Overlay<'_>, heading: &str, panel_px: u32) -> SceneFigure {
    let views: [(&str, [usize; 2]); 3] = [
        ("front (x–z)", [0, 2]),
        ("side (y–z)", [1, 2]),
        ("top (x–y)", [0, 1]),
    ];
    let axis = ["x (cm)", "y (cm)", "z (cm)"];
    let scene = world.scene();
    let panels = views
        .iter()
        .map(|(title, axes)| {
            let proj = |p: &Point3<f64>| [CM * p[axes[0]], CM * p[axes[1]]];
            let mut marks = Vec::new();
            table_marks(scene, &proj, &mut marks);
            for goal in overlay.goals {
                object_marks(
                    world,
                    &goal_pose(scene, goal.coords),
                    &proj,
                    true,
                    &mut marks,
                );
            }
            object_marks(world, &world.object().pose(), &proj, false, &mut marks);
            if *axes == [0, 1] {
                // Goal labels in the top view only, one line each.
                for (i, goal) in overlay.goals.iter().enumerate() {
                    goal_label(scene, goal, i, &proj, &mut marks);
                }
            }
            hand_marks(world, &proj, &mut marks);
            path_marks(overlay.paths, &proj, &mut marks);
            contact_marks(overlay.contacts, &proj, &mut marks);
            ScenePanel {
                title: (*title).to_string(),
                x_label: axis[axes[0]].to_string(),
                y_label: axis[axes[1]].to_string(),
                marks,
                range: None,
            }
        })
        .collect();
    let mut legend = vec![
        entry("hand", HAND),
        entry(
            match scene {
                SceneKind::Screwdriver => "screwdriver",
                SceneKind::Card => "card",
            },
            OBJECT,
        ),
    ];
    if scene == SceneKind::Screwdriver {
        legend.push(entry("yaw marker", MARKER));
    } else {
        legend.push(entry("table", TABLE));
    }
    legend.push(entry("contact", CONTACT));
    legend.push(entry(
        &format!("force ({:.1} cm per N)", FORCE_SCALE * CM),
        FORCE,
    ));
    if !overlay.paths.is_empty() {
        legend.push(entry("paths", PATH));
    }
    if !overlay.goals.is_empty() {
        legend.push(entry("goal (dashed)", GOAL));
    }
    SceneFigure {
        heading: heading.to_string(),
        panels,
        legend,
        panel_px,
    }
}

fn entry(label: &str, color: Rgb) -> LegendEntry {
    LegendEntry {
        label: label.to_string(),
        color,
    }
}

type Proj<'a> = dyn Fn(&Point3<f64>) -> [f64; 2] + 'a;

fn line(a: [f64; 2], b: [f64; 2], color: Rgb, width: u32, dashed: bool) -> Mark {
    Mark::Line {
        a,
        b,
        color,
        width,
        dashed,
    }
}

fn hand_marks(world: &World, proj: &Proj<'_>, out: &mut Vec<Mark>) {
    let hand = world.hand_model();
    let base = world.hand_base();
    let q = world.joints();
    let base_p = Point3::from(base.translation.vector);
    let task = world.scene().task_fingers();
    for f in Finger::ALL {
        let frames = hand.finger_frames(&base, f, &q[f.index()]);
        let mut prev = base_p;
        for o in frames
            .joint_origins
            .iter()
            .chain(std::iter::once(&frames.tip_center))
        {
            out.push(line(proj(&prev), proj(o), HAND, 2, false));
            prev = *o;
        }
        let tip = proj(&frames.tip_center);
        out.push(Mark::Circle {
            c: tip,
            r: CM * hand.tip_radius,
            color: TIP,
            fill: false,
        });
        if task.contains(&f) {
            out.push(Mark::Circle {
                c: tip,
                r: 0.15,
                color: TIP,
                fill: true,
            });
            out.push(Mark::Text {
                at: tip,
                offset_px: (8, -8),
                text: f.name().to_string(),
                color: TIP,
                size: 11,
            });
        }
    }
}

/// The 8 corners and 12 edges of a box given by its centre frame and half extents.
fn box_edges(
    pose: &Isometry3<f64>,
    center: [f64; 3],
    h: [f64; 3],
) -> Vec<(Point3<f64>, Point3<f64>)> {
    let corner = |i: usize| {
        let s = |bit: usize| if i & bit != 0 { 1.0 } else { -1.0 };
        pose * Point3::new(
            center[0] + s(1) * h[0],
            center[1] + s(2) * h[1],
            center[2] + s(4) * h[2],
        )
    };
    let mut edges = Vec::with_capacity(12);
    for i in 0..8 {
        for bit in [1, 2, 4] {
            if i & bit == 0 {
                edges.push((corner(i), corner(i | bit)));
            }
        }
    }
    edges
}

/// The convex hull of the box's projected corners (its silhouette in a view).
fn box_outline(
    pose: &Isometry3<f64>,
    center: [f64; 3],
    h: [f64; 3],
    proj: &Proj<'_>,
) -> Vec<[f64; 2]> {
    convex_hull(
        box_edges(pose, center, h)
            .iter()
            .flat_map(|(a, b)| [proj(a), proj(b)])
            .collect(),
    )
}

fn table_marks(scene: SceneKind, proj: &Proj<'_>, out: &mut Vec<Mark>) {
    if scene == SceneKind::Card {
        out.push(Mark::Polygon {
            pts: box_outline(
                &Isometry3::identity(),
                card::TABLE_CENTER,
                card::TABLE_HALF_EXTENTS,
                proj,
            ),
            color: TABLE,
            fill_alpha: 0.12,
            dashed: false,
        });
    }
}

fn object_marks(
    world: &World,
    pose: &Isometry3<f64>,
    proj: &Proj<'_>,
    goal: bool,
    out: &mut Vec<Mark>,
) {
    let (color, fill_alpha) = if goal { (GOAL, 0.0) } else { (OBJECT, 0.25) };
    for part in &world.object_body().parts {
        let pts = match part.shape {
            PartShape::Box {
                center,
                half_extents,
            } => box_outline(pose, center, half_extents, proj),
            PartShape::Cylinder { radius, z0, z1 } => {
                if goal {
                    continue; // the goal of a screwdriver is its yaw marker, below
                }
                let ring = |z: f64| -> Vec<[f64; 2]> {
                    (0..32)
                        .map(|k| {
                            let a = std::f64::consts::TAU * f64::from(k) / 32.0;
                            proj(&(pose * Point3::new(radius * a.cos(), radius * a.sin(), z)))
                        })
                        .collect()
                };
                let mut pts = ring(z0);
                pts.extend(ring(z1));
                convex_hull(pts)
            }
        };
        out.push(Mark::Polygon {
            pts,
            color,
            fill_alpha,
            dashed: goal,
        });
    }
    if world.scene() == SceneKind::Screwdriver {
        // The yaw marker: a line across the cap along the handle's x axis, with a dot at +x.
        let z = screwdriver::CAP_Z1;
        let r = screwdriver::CAP_RADIUS;
        let a = proj(&(pose * Point3::new(-r, 0.0, z)));
        let b = proj(&(pose * Point3::new(r, 0.0, z)));
        let color = if goal { GOAL } else { MARKER };
        out.push(line(a, b, color, 3, goal));
        out.push(Mark::Circle {
            c: b,
            r: 0.25,
            color,
            fill: !goal,
        });
    }
}

fn goal_label(scene: SceneKind, goal: &Goal, line: usize, proj: &Proj<'_>, out: &mut Vec<Mark>) {
    let pose = goal_pose(scene, goal.coords);
    let (at, text) = match scene {
        SceneKind::Screwdriver => (
            pose * Point3::new(screwdriver::CAP_RADIUS, 0.0, screwdriver::CAP_Z1),
            format!("{} {:.2} rad", goal.label, goal.coords[2]),
        ),
        SceneKind::Card => (
            pose * Point3::new(card::HALF_EXTENTS[0], 0.0, 0.0),
            format!("{} y {:.1} cm", goal.label, CM * goal.coords[1]),
        ),
    };
    out.push(Mark::Text {
        at: proj(&at),
        offset_px: (6, 10 + 13 * line as i32),
        text,
        color: GOAL,
        size: 11,
    });
}

fn path_marks(paths: &[Vec<Point3<f64>>], proj: &Proj<'_>, out: &mut Vec<Mark>) {
    for path in paths {
        for pair in path.windows(2) {
            out.push(line(proj(&pair[0]), proj(&pair[1]), PATH, 1, false));
        }
        for p in path {
            out.push(Mark::Circle {
                c: proj(p),
                r: 0.06,
                color: PATH,
                fill: true,
            });
        }
    }
}

fn contact_marks(contacts: &[ContactReport], proj: &Proj<'_>, out: &mut Vec<Mark>) {
    for c in contacts {
        let p = Point3::from(c.point);
        out.push(Mark::Circle {
            c: proj(&p),
            r: 0.15,
            color: CONTACT,
            fill: true,
        });
        let f = Vector3::from(c.force);
        if f.norm() > 1e-6 {
            out.push(Mark::Arrow {
                from: proj(&p),
                to: proj(&(p + f * FORCE_SCALE)),
                color: FORCE,
                width: 2,
            });
        }
    }
}

/// Monotone-chain convex hull (counter-clockwise).
fn convex_hull(mut pts: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let ordered: Vec<[f64; 2]> = if pass == 0 {
            pts.clone()
        } else {
            pts.iter().rev().copied().collect()
        };
        for p in ordered {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// Write a figure to `path` (`.svg` or `.png`), atomically (temporary file, then rename).
pub fn write(fig: &SceneFigure, path: &Path) -> Result<(), RenderError> {
    let name = path.display().to_string();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let plot = |source| RenderError::Plot {
        path: name.clone(),
        source,
    };
    let bytes = match ext.as_deref() {
        Some("svg") => fig.svg().map_err(plot)?.into_bytes(),
        Some("png") => fig.png().map_err(plot)?,
        _ => return Err(RenderError::Format(name)),
    };
    dips_fs::write_atomic(path, &bytes).map_err(|source| RenderError::Io {
        path: path.display().to_string(),
        source,
    })
}
