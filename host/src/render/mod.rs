//! Drawings of a world state for people: three orthographic views (front x–z, side y–z,
//! top x–y) of the hand (links and fingertip spheres), the object, the table, the contacts and
//! their forces, written as SVG or PNG (a small rasterizer of our own, encoded with `png`).

mod raster;
mod svg;

use std::path::Path;

use nalgebra::{Point3, Vector3};

use crate::geometry::PartShape;
use crate::kinematics::Finger;
use crate::scenes::card;
use crate::world::{ContactReport, World};

/// An RGB colour.
pub type Rgb = [u8; 3];

/// One 2-D drawing primitive in panel coordinates (metres; y up).
#[derive(Debug, Clone, PartialEq)]
pub enum Prim {
    /// A line segment.
    Line {
        /// Start.
        a: [f64; 2],
        /// End.
        b: [f64; 2],
        /// Colour.
        color: Rgb,
        /// Width in pixels.
        width: f64,
    },
    /// A circle.
    Circle {
        /// Centre.
        c: [f64; 2],
        /// Radius (m).
        r: f64,
        /// Colour.
        color: Rgb,
        /// Filled or outline.
        fill: bool,
    },
    /// A closed polygon outline.
    Polygon {
        /// Vertices.
        pts: Vec<[f64; 2]>,
        /// Colour.
        color: Rgb,
    },
}

/// A panel: a title, a view and its primitives.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Title (SVG only).
    pub title: String,
    /// Primitives.
    pub prims: Vec<Prim>,
}

/// A whole drawing: panels side by side.
#[derive(Debug, Clone)]
pub struct Drawing {
    /// Heading line (SVG only).
    pub heading: String,
    /// The panels.
    pub panels: Vec<Panel>,
}

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
    /// PNG encoding failed.
    #[error("PNG encoding of {path} failed: {message}")]
    Png {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
}

const HAND: Rgb = [60, 60, 200];
const TIP: Rgb = [30, 30, 140];
const OBJECT: Rgb = [200, 120, 20];
const TABLE: Rgb = [120, 120, 120];
const CONTACT: Rgb = [210, 20, 20];
const FORCE: Rgb = [20, 150, 40];
const PATH: Rgb = [170, 60, 170];

/// Metres of arrow per newton of contact force.
pub const FORCE_SCALE: f64 = 0.005;

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
        let pose = w.object().pose();
        let reference = match world.scene() {
            crate::scenes::SceneKind::Screwdriver => {
                pose * Point3::from(crate::scenes::screwdriver::CAP_ORIGIN)
            }
            crate::scenes::SceneKind::Card => pose * Point3::origin(),
        };
        paths[fingers.len()].push(reference);
    }
    paths
}

/// Draw a world state with the given contacts (e.g. from a trajectory file).
pub fn draw(world: &World, contacts: &[ContactReport], heading: &str) -> Drawing {
    draw_with_paths(world, contacts, &[], heading)
}

/// Like [`draw`], plus polylines (e.g. [`trajectory_paths`]) with a dot at each sample.
pub fn draw_with_paths(
    world: &World,
    contacts: &[ContactReport],
    paths: &[Vec<Point3<f64>>],
    heading: &str,
) -> Drawing {
    let views: [(&str, [usize; 2]); 3] = [
        ("front (x, z)", [0, 2]),
        ("side (y, z)", [1, 2]),
        ("top (x, y)", [0, 1]),
    ];
    let panels = views
        .iter()
        .map(|(title, axes)| {
            let proj = |p: &Point3<f64>| [p[axes[0]], p[axes[1]]];
            let mut prims = Vec::new();
            object_prims(world, &proj, &mut prims);
            hand_prims(world, &proj, &mut prims);
            for path in paths {
                for pair in path.windows(2) {
                    prims.push(Prim::Line {
                        a: proj(&pair[0]),
                        b: proj(&pair[1]),
                        color: PATH,
                        width: 1.5,
                    });
                }
                for p in path {
                    prims.push(Prim::Circle {
                        c: proj(p),
                        r: 0.0006,
                        color: PATH,
                        fill: true,
                    });
                }
            }
            for c in contacts {
                let p = Point3::from(c.point);
                prims.push(Prim::Circle {
                    c: proj(&p),
                    r: 0.0015,
                    color: CONTACT,
                    fill: true,
                });
                let f = Vector3::from(c.force);
                if f.norm() > 1e-6 {
                    let tip = p + f * FORCE_SCALE;
                    prims.push(Prim::Line {
                        a: proj(&p),
                        b: proj(&tip),
                        color: FORCE,
                        width: 2.0,
                    });
                }
            }
            Panel {
                title: (*title).to_string(),
                prims,
            }
        })
        .collect();
    Drawing {
        heading: heading.to_string(),
        panels,
    }
}

fn hand_prims(world: &World, proj: &dyn Fn(&Point3<f64>) -> [f64; 2], out: &mut Vec<Prim>) {
    let hand = world.hand_model();
    let base = world.hand_base();
    let q = world.joints();
    let base_p = Point3::from(base.translation.vector);
    for f in Finger::ALL {
        let frames = hand.finger_frames(&base, f, &q[f.index()]);
        let mut prev = base_p;
        for o in frames
            .joint_origins
            .iter()
            .chain(std::iter::once(&frames.tip_center))
        {
            out.push(Prim::Line {
                a: proj(&prev),
                b: proj(o),
                color: HAND,
                width: 2.0,
            });
            prev = *o;
        }
        let task = world.scene().task_fingers().contains(&f);
        out.push(Prim::Circle {
            c: proj(&frames.tip_center),
            r: hand.tip_radius,
            color: TIP,
            fill: false,
        });
        if task {
            out.push(Prim::Circle {
                c: proj(&frames.tip_center),
                r: 0.002,
                color: TIP,
                fill: true,
            });
        }
    }
}

/// The 8 corners and 12 edges of a box given by its centre frame and half extents.
fn box_edges(
    pose: &nalgebra::Isometry3<f64>,
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

fn object_prims(world: &World, proj: &dyn Fn(&Point3<f64>) -> [f64; 2], out: &mut Vec<Prim>) {
    if world.scene() == crate::scenes::SceneKind::Card {
        let id = nalgebra::Isometry3::identity();
        for (a, b) in box_edges(&id, card::TABLE_CENTER, card::TABLE_HALF_EXTENTS) {
            out.push(Prim::Line {
                a: proj(&a),
                b: proj(&b),
                color: TABLE,
                width: 1.0,
            });
        }
    }
    let pose = world.object().pose();
    for part in &world.object_body().parts {
        match part.shape {
            PartShape::Box {
                center,
                half_extents,
            } => {
                for (a, b) in box_edges(&pose, center, half_extents) {
                    out.push(Prim::Line {
                        a: proj(&a),
                        b: proj(&b),
                        color: OBJECT,
                        width: 1.5,
                    });
                }
            }
            PartShape::Cylinder { radius, z0, z1 } => {
                // Outline of the projected cylinder: rims as sampled circles plus the hull sides.
                let ring = |z: f64| -> Vec<[f64; 2]> {
                    (0..24)
                        .map(|k| {
                            let a = std::f64::consts::TAU * k as f64 / 24.0;
                            proj(&(pose * Point3::new(radius * a.cos(), radius * a.sin(), z)))
                        })
                        .collect()
                };
                let mut pts = ring(z0);
                pts.extend(ring(z1));
                out.push(Prim::Polygon {
                    pts: convex_hull(pts),
                    color: OBJECT,
                });
            }
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
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
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

/// Bounding box of a panel's primitives, padded.
pub(crate) fn bounds(prims: &[Prim]) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut add = |p: [f64; 2], r: f64| {
        for i in 0..2 {
            lo[i] = lo[i].min(p[i] - r);
            hi[i] = hi[i].max(p[i] + r);
        }
    };
    for p in prims {
        match p {
            Prim::Line { a, b, .. } => {
                add(*a, 0.0);
                add(*b, 0.0);
            }
            Prim::Circle { c, r, .. } => add(*c, *r),
            Prim::Polygon { pts, .. } => pts.iter().for_each(|q| add(*q, 0.0)),
        }
    }
    if !lo[0].is_finite() {
        return ([0.0, 0.0], [1.0, 1.0]);
    }
    let pad = 0.05 * (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-3);
    ([lo[0] - pad, lo[1] - pad], [hi[0] + pad, hi[1] + pad])
}

/// Write a drawing to `path` (`.svg` or `.png`), each panel `panel_px` pixels square,
/// atomically (temporary file, then rename).
pub fn write(drawing: &Drawing, path: &Path, panel_px: u32) -> Result<(), RenderError> {
    let name = path.display().to_string();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let bytes = match ext.as_deref() {
        Some("svg") => svg::to_svg(drawing, panel_px).into_bytes(),
        Some("png") => raster::to_png(drawing, panel_px).map_err(|message| RenderError::Png {
            path: name.clone(),
            message,
        })?,
        _ => return Err(RenderError::Format(name)),
    };
    crate::atomic_write::write_atomic(path, &bytes)
        .map_err(|source| RenderError::Io { path: name, source })
}
