//! Candidate contacts of one sub-step with their Jacobians: fingertip spheres against the
//! object (and, in the card scene, the table), and the card–table patch at the vertices of the
//! clipped card-bottom/table-top polygon.

use nalgebra::{Isometry3, Matrix3, Matrix3xX, Point2, Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::socp::ConeRow;
use crate::geometry::Body;
use crate::kinematics::{FingerFrames, HandModel, jacobian_from_frames};
use crate::scenes::{SceneKind, card};

/// One contact as reported after a step (world frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactReport {
    /// The pushing body: a finger name (`index`, `middle`, `thumb`) or `card` for card–table.
    pub finger: String,
    /// The part touched (`shaft`, `handle`, `cap`, `card`, `table`).
    pub part: String,
    /// Contact point on the part's surface (m).
    pub point: [f64; 3],
    /// Unit normal out of the part, toward `finger`.
    pub normal: [f64; 3],
    /// Force exerted by `finger` on `part` (N).
    pub force: [f64; 3],
    /// Signed distance at the start of the solve (m).
    pub phi: f64,
}

/// A contact candidate: geometry plus the relative-velocity Jacobian.
#[derive(Debug, Clone)]
pub(crate) struct Candidate {
    pub finger: &'static str,
    pub part: &'static str,
    /// Stable identity across sub-steps: (pushing body, touched body, index within the pair).
    pub key: (&'static str, &'static str, usize),
    /// Signed distance at the configuration the candidate was computed at (before any shift).
    pub phi_at_trial: f64,
    pub point: Point3<f64>,
    pub row: ConeRow,
}

/// `[v]×`, the cross-product matrix.
pub(crate) fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// What the object's generalized coordinates are.
#[derive(Debug, Clone, Copy)]
pub(crate) enum ObjectDofs {
    /// Rotation increment ω (3) about a fixed pivot.
    Pivot { pivot: Point3<f64> },
    /// Translation δp (3) then rotation increment ω (3) about the body origin.
    Free { origin: Point3<f64> },
}

impl ObjectDofs {
    pub(crate) fn count(self) -> usize {
        match self {
            ObjectDofs::Pivot { .. } => 3,
            ObjectDofs::Free { .. } => 6,
        }
    }

    /// 3 × n_u Jacobian of the velocity of a point attached to the object.
    fn point_jacobian(self, p: &Point3<f64>) -> Matrix3xX<f64> {
        let mut j = Matrix3xX::zeros(self.count());
        match self {
            ObjectDofs::Pivot { pivot } => {
                j.fixed_columns_mut::<3>(0)
                    .copy_from(&(-skew(&(p - pivot))));
            }
            ObjectDofs::Free { origin } => {
                j.fixed_columns_mut::<3>(0).copy_from(&Matrix3::identity());
                j.fixed_columns_mut::<3>(3)
                    .copy_from(&(-skew(&(p - origin))));
            }
        }
        j
    }
}

/// Inputs shared by the candidate builders.
pub(crate) struct ContactInputs<'a> {
    pub scene: SceneKind,
    pub hand: &'a HandModel,
    /// Frames of the task fingers, in task order.
    pub frames: &'a [FingerFrames],
    pub finger_names: &'a [&'static str],
    pub object: &'a Body,
    pub object_pose: &'a Isometry3<f64>,
    pub dofs: ObjectDofs,
    pub table: Option<&'a Body>,
    pub margin: f64,
    /// Margin for fingertip–table pairs (smaller: the card usually lies in between).
    pub table_margin: f64,
    pub finger_friction: f64,
    pub finger_table_friction: f64,
    pub table_friction: f64,
}

/// All candidates within the margin. Variables are `[δq_task (4 per finger) ; object dofs]`.
pub(crate) fn candidates(inp: &ContactInputs<'_>) -> Vec<Candidate> {
    let n_a = 4 * inp.frames.len();
    let n = n_a + inp.dofs.count();
    let r = inp.hand.tip_radius;
    let mut out = Vec::new();
    for (k, frames) in inp.frames.iter().enumerate() {
        let center = frames.tip_center;
        if let Some(c) = inp
            .object
            .sphere_contact(inp.object_pose, &center, r, inp.margin)
        {
            let mut jac = Matrix3xX::zeros(n);
            let jf = jacobian_from_frames(frames, &c.point_on_sphere);
            jac.fixed_columns_mut::<4>(4 * k).copy_from(&jf);
            let jo = inp.dofs.point_jacobian(&c.point_on_body);
            jac.columns_mut(n_a, inp.dofs.count()).copy_from(&(-jo));
            out.push(Candidate {
                finger: inp.finger_names[k],
                part: c.part,
                key: (inp.finger_names[k], inp.object.name, 0),
                phi_at_trial: c.phi,
                point: c.point_on_body,
                row: ConeRow {
                    phi: c.phi,
                    mu: inp.finger_friction,
                    normal: c.normal,
                    jac,
                },
            });
        }
        if let Some(table) = inp.table
            && let Some(c) =
                table.sphere_contact(&Isometry3::identity(), &center, r, inp.table_margin)
        {
            let mut jac = Matrix3xX::zeros(n);
            let jf = jacobian_from_frames(frames, &c.point_on_sphere);
            jac.fixed_columns_mut::<4>(4 * k).copy_from(&jf);
            out.push(Candidate {
                finger: inp.finger_names[k],
                part: c.part,
                key: (inp.finger_names[k], table.name, 0),
                phi_at_trial: c.phi,
                point: c.point_on_body,
                row: ConeRow {
                    phi: c.phi,
                    mu: inp.finger_table_friction,
                    normal: c.normal,
                    jac,
                },
            });
        }
    }
    if inp.scene == SceneKind::Card && inp.table.is_some() {
        for (index, p) in card_table_vertices(inp.object_pose).into_iter().enumerate() {
            let phi = p.z - card::TABLE_TOP;
            if phi > inp.margin {
                continue;
            }
            let mut jac = Matrix3xX::zeros(n);
            jac.columns_mut(n_a, inp.dofs.count())
                .copy_from(&inp.dofs.point_jacobian(&p));
            out.push(Candidate {
                finger: "card",
                part: "table",
                key: ("card", "table", index),
                phi_at_trial: phi,
                point: Point3::new(p.x, p.y, card::TABLE_TOP),
                row: ConeRow {
                    phi,
                    mu: inp.table_friction,
                    normal: Vector3::z(),
                    jac,
                },
            });
        }
    }
    out
}

/// Points of the card's bottom face above the vertices of (card bottom face ∩ table top),
/// clipped in the horizontal plane.
pub(crate) fn card_table_vertices(card_pose: &Isometry3<f64>) -> Vec<Point3<f64>> {
    let [hx, hy, hz] = card::HALF_EXTENTS;
    let corners: Vec<Point3<f64>> = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]
        .iter()
        .map(|&(x, y)| card_pose * Point3::new(x, y, -hz))
        .collect();
    let mut poly: Vec<Point2<f64>> = corners.iter().map(|p| Point2::new(p.x, p.y)).collect();
    // Keep the polygon counter-clockwise for the clipper (a flipped card reverses it).
    let area: f64 = (0..poly.len())
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            a.x * b.y - b.x * a.y
        })
        .sum();
    if area < 0.0 {
        poly.reverse();
    }
    let [tx, ty, _] = card::TABLE_CENTER;
    let [thx, thy, _] = card::TABLE_HALF_EXTENTS;
    let clipped = clip_to_rect(&poly, tx - thx, tx + thx, ty - thy, ty + thy);
    // Bottom plane: points p with m·(p − c) = 0, m the card's z axis, c the bottom centre.
    let m = card_pose.rotation * Vector3::z();
    let c = card_pose * Point3::new(0.0, 0.0, -hz);
    if m.z.abs() < 1e-6 {
        return Vec::new();
    }
    clipped
        .into_iter()
        .map(|v| {
            let z = c.z - (m.x * (v.x - c.x) + m.y * (v.y - c.y)) / m.z;
            Point3::new(v.x, v.y, z)
        })
        .collect()
}

/// Sutherland–Hodgman clip of a convex CCW polygon to an axis-aligned rectangle.
fn clip_to_rect(poly: &[Point2<f64>], x0: f64, x1: f64, y0: f64, y1: f64) -> Vec<Point2<f64>> {
    // Each edge: inside test value f(p) ≥ 0.
    let edges: [(f64, f64, f64); 4] = [
        (1.0, 0.0, -x0),
        (-1.0, 0.0, x1),
        (0.0, 1.0, -y0),
        (0.0, -1.0, y1),
    ];
    let mut out: Vec<Point2<f64>> = poly.to_vec();
    for (a, b, c) in edges {
        if out.is_empty() {
            break;
        }
        let f = |p: &Point2<f64>| a * p.x + b * p.y + c;
        let input = std::mem::take(&mut out);
        for i in 0..input.len() {
            let cur = input[i];
            let prev = input[(i + input.len() - 1) % input.len()];
            let (fc, fp) = (f(&cur), f(&prev));
            if fc >= 0.0 {
                if fp < 0.0 {
                    out.push(prev + (cur - prev) * (fp / (fp - fc)));
                }
                out.push(cur);
            } else if fp >= 0.0 {
                out.push(prev + (cur - prev) * (fp / (fp - fc)));
            }
        }
    }
    // Drop near-duplicate vertices (a corner exactly on the table edge).
    let mut dedup: Vec<Point2<f64>> = Vec::with_capacity(out.len());
    for p in out {
        if dedup.last().is_none_or(|q| (p - q).norm() > 1e-9) {
            dedup.push(p);
        }
    }
    if dedup.len() > 1 && (dedup[0] - dedup[dedup.len() - 1]).norm() <= 1e-9 {
        dedup.pop();
    }
    dedup
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn card_on_table_has_four_vertices_and_overhang_clips() {
        let pose = Isometry3::translation(0.0, 0.0, 0.130);
        let v = card_table_vertices(&pose);
        assert_eq!(v.len(), 4);
        assert!(v.iter().all(|p| (p.z - 0.125).abs() < 1e-12));
        // Slid 6 cm toward −y: the −y vertices sit on the table edge y = −0.1.
        let pose = Isometry3::translation(0.0, -0.06, 0.130);
        let v = card_table_vertices(&pose);
        assert_eq!(v.len(), 4);
        let ys: Vec<f64> = v.iter().map(|p| p.y).collect();
        assert!(ys.iter().any(|y| (y + 0.1).abs() < 1e-12), "{ys:?}");
        assert!(ys.iter().all(|y| *y >= -0.1 - 1e-12), "{ys:?}");
        // Rotated and overhanging: the clipped polygon has two vertices on the edge line.
        let pose = Isometry3::new(Vector3::new(0.0, -0.06, 0.130), Vector3::new(0.0, 0.0, 0.3));
        let v = card_table_vertices(&pose);
        assert_eq!(
            v.iter().filter(|p| (p.y + 0.1).abs() < 1e-12).count(),
            2,
            "{v:?}"
        );
        // A small turn without overhang keeps all four corners (none cut).
        let pose = Isometry3::new(Vector3::new(0.0, 0.05, 0.130), Vector3::new(0.0, 0.0, 0.1));
        assert_eq!(card_table_vertices(&pose).len(), 4);
        let pose = Isometry3::new(Vector3::new(0.0, 0.0, 0.130), Vector3::new(0.0, 0.0, 0.05));
        let v = card_table_vertices(&pose);
        assert_eq!(v.len(), 5, "{v:?}");
        assert!(
            v.iter()
                .all(|p| p.y >= -0.1 - 1e-12 && (p.z - 0.125).abs() < 1e-12)
        );
    }
}
