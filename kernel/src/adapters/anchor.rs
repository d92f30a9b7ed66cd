//! [`StartAnchor`]: how a sampled segment is made to continue from its start state.
//!
//! The diffusion sampler inpaints the start into row 0, but the models do not take everything
//! from it: measured on the screwdriver (`docs/decisions.md`, "Start anchor"),
//! row 1, the first row a model draws, puts the yaw up to 0.36 rad and the joints of the
//! fingers in contact up to 0.7 rad away from the start's, for every mode, and from row 1 on
//! the segment is right in kind. Read as sampled, that jump counts as progress the hand would
//! not make (a regrasp "turns" the screwdriver). Anchored, rows 1.. are moved as a whole so
//! that row 1 repeats the start, and a segment's progress is what it changes after row 1.

use crate::mode::{RowLayout, SegmentDims};

/// An angle the task's physics does not depend on, and the angles the model knows it at
/// (the screwdriver's yaw: [`crate::session::start_anchor`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InvariantAngle {
    /// State column of the angle's `cos` (its `sin` follows).
    pub cos_column: usize,
    /// The smallest start angle the model is asked about (radians).
    pub lo: f32,
    /// The largest start angle the model is asked about (radians).
    pub hi: f32,
}

impl InvariantAngle {
    /// Move the angle of every start in `starts` (rows of `state_dim`) into `[lo, hi]`.
    pub fn clamp_starts(&self, starts: &mut [f32], state_dim: usize) {
        let c = self.cos_column;
        for s in starts.chunks_mut(state_dim) {
            let a = libm::atan2f(s[c + 1], s[c]);
            let k = a.clamp(self.lo, self.hi);
            if k != a {
                s[c] = libm::cosf(k);
                s[c + 1] = libm::sinf(k);
            }
        }
    }

    /// Whether the angle's `(cos, sin)` columns lie inside a state of `state_dim` columns.
    pub const fn fits(&self, state_dim: usize) -> bool {
        self.cos_column + 1 < state_dim
    }
}

/// How the sampler makes each sampled segment continue from its start
/// ([`crate::adapters::DiffusionSegmentSampler::set_start_anchor`], the host's
/// initialisation of CSVTO). The default anchors nothing: segments as the model draws them.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StartAnchor {
    /// A symmetry angle of the task. Segments are sampled from their starts with the angle
    /// clamped into `[lo, hi]` ([`InvariantAngle::clamp_starts`]); afterwards rows 1.. are
    /// turned about the angle so that row 1 repeats the start's angle (which also undoes the
    /// clamp), and row 0 gets the start's exact `(cos, sin)`.
    pub angle: Option<InvariantAngle>,
    /// Shift the joints of the fingers in contact in the segment's mode (sign `+1` in its
    /// context row) over rows 1.. so that row 1 repeats the start's joints. Fingers that
    /// regrasp keep the model's rows: a regrasp moves them, in the world as in the data.
    /// Joint columns follow [`RowLayout`]: four per finger from column 0.
    pub contact_joints: bool,
}

impl StartAnchor {
    /// Anchor nothing.
    pub const NONE: Self = Self {
        angle: None,
        contact_joints: false,
    };

    /// The angle to clamp starts by, if it fits a state of `state_dim` columns.
    pub fn clamp_angle(&self, state_dim: usize) -> Option<InvariantAngle> {
        self.angle.filter(|a| a.fits(state_dim))
    }

    /// Whether [`Self::apply`] changes anything for segments of `dims`.
    pub fn is_active(&self, dims: &SegmentDims) -> bool {
        dims.horizon >= 2 && (self.clamp_angle(dims.state_dim).is_some() || self.joints_fit(dims))
    }

    fn joints_fit(&self, dims: &SegmentDims) -> bool {
        let layout = RowLayout {
            fingers: dims.fingers,
            env_force: false,
        };
        self.contact_joints && layout.joints() <= dims.state_dim
    }

    /// Anchor each segment of `out` (`dims` segments, raw §2 rows) at its start in `starts`
    /// (`state_dim` floats each) for the mode in its row of `context` (`fingers` signs each).
    /// Segments with one row, and parts that do not fit `dims`, are left as they are.
    pub fn apply(&self, out: &mut [f32], starts: &[f32], context: &[f32], dims: &SegmentDims) {
        if dims.horizon < 2 {
            return;
        }
        let d = dims.dim();
        let sd = dims.state_dim;
        let fingers = dims.fingers.max(1);
        let joints = self.joints_fit(dims);
        let angle = self.clamp_angle(sd);
        for ((seg, start), signs) in out
            .chunks_exact_mut(dims.floats())
            .zip(starts.chunks_exact(sd))
            .zip(context.chunks_exact(fingers))
        {
            if let Some(a) = angle {
                anchor_angle(seg, start, a.cos_column, d);
            }
            if joints {
                for (i, &sign) in signs.iter().enumerate().take(dims.fingers) {
                    if sign > 0.0 {
                        anchor_columns(seg, start, 4 * i..4 * i + 4, d);
                    }
                }
            }
        }
    }
}

/// Turn rows 1.. of `seg` about the angle in columns `(c, c + 1)` so that row 1's angle is
/// the start's; row 0 gets the start's exact `(cos, sin)`.
fn anchor_angle(seg: &mut [f32], start: &[f32], c: usize, d: usize) {
    let (cs, ss) = (start[c], start[c + 1]);
    let (c1, s1) = (seg[d + c], seg[d + c + 1]);
    // The rotation from row 1's angle to the start's.
    let n = libm::sqrtf((cs * cs + ss * ss) * (c1 * c1 + s1 * s1)).max(f32::MIN_POSITIVE);
    let c0 = (cs * c1 + ss * s1) / n;
    let s0 = (ss * c1 - cs * s1) / n;
    for row in seg.chunks_exact_mut(d).skip(1) {
        let (cr, sr) = (row[c], row[c + 1]);
        row[c] = cr * c0 - sr * s0;
        row[c + 1] = sr * c0 + cr * s0;
    }
    seg[c] = cs;
    seg[c + 1] = ss;
}

/// Shift `columns` over rows 1.. of `seg` so that row 1 repeats the start's values.
fn anchor_columns(seg: &mut [f32], start: &[f32], columns: core::ops::Range<usize>, d: usize) {
    for col in columns {
        let delta = start[col] - seg[d + col];
        for row in seg.chunks_exact_mut(d).skip(1) {
            row[col] += delta;
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    fn yaw(row: &[f32], c: usize) -> f32 {
        libm::atan2f(row[c + 1], row[c])
    }

    const ANGLE: InvariantAngle = InvariantAngle {
        cos_column: 4,
        lo: -0.6,
        hi: 0.0,
    };

    /// Two fingers of four joints, then the angle's (cos, sin), one action column.
    const DIMS: SegmentDims = SegmentDims {
        horizon: 3,
        state_dim: 10,
        action_dim: 1,
        fingers: 2,
    };

    fn row(q: f32, y: f32, u: f32) -> [f32; 11] {
        let mut r = [q; 11];
        r[4..8].copy_from_slice(&[q + 1.0; 4]);
        r[8] = libm::cosf(y);
        r[9] = libm::sinf(y);
        r[10] = u;
        r
    }

    fn state(q: f32, y: f32) -> Vec<f32> {
        row(q, y, 0.0)[..10].to_vec()
    }

    #[test]
    fn an_angle_outside_the_models_range_is_clamped_and_only_the_angle_moves() {
        let a = InvariantAngle {
            cos_column: 8,
            ..ANGLE
        };
        let starts: Vec<f32> = [state(0.1, -0.3), state(0.2, -1.4)].concat();
        let mut clamped = starts.clone();
        a.clamp_starts(&mut clamped, 10);
        assert_eq!(
            clamped[..10],
            starts[..10],
            "inside the range nothing moves"
        );
        assert!((yaw(&clamped[10..], 8) - -0.6).abs() < 1e-6);
        assert_eq!(clamped[10..18], starts[10..18], "only the angle moves");
        assert!(a.fits(10) && !a.fits(9));
    }

    /// Segments as a model returns them: row 0 the (clamped) start, row 1 off the start by
    /// `level` in angle and `jump` in every joint, row 2 a further −0.3 rad and +0.1 joints.
    fn sampled(starts: &[(f32, f32)], level: f32, jump: f32) -> Vec<f32> {
        starts
            .iter()
            .flat_map(|&(q, y)| {
                let y0 = y.max(-0.6);
                [
                    row(q, y0, 0.5),
                    row(q + jump, y0 + level, 0.6),
                    row(q + jump + 0.1, y0 + level - 0.3, 0.7),
                ]
                .concat()
            })
            .collect()
    }

    #[test]
    fn the_angle_and_the_contact_fingers_joints_continue_from_the_start() {
        let starts_q = [(0.1, -0.3), (0.2, -1.4)];
        let starts: Vec<f32> = starts_q.iter().flat_map(|&(q, y)| state(q, y)).collect();
        let mut out = sampled(&starts_q, 0.2, 0.25);
        let before = out.clone();
        let anchor = StartAnchor {
            angle: Some(InvariantAngle {
                cos_column: 8,
                ..ANGLE
            }),
            contact_joints: true,
        };
        assert!(anchor.is_active(&DIMS));
        // Segment 0: finger 0 in contact, finger 1 regrasps; segment 1: both in contact.
        anchor.apply(&mut out, &starts, &[1.0, -1.0, 1.0, 1.0], &DIMS);
        for (i, seg) in out.chunks(33).enumerate() {
            let start = &starts[i * 10..(i + 1) * 10];
            let old = &before[i * 33..(i + 1) * 33];
            assert_eq!(seg[..10], start[..], "row 0 is exactly the start");
            let y0 = yaw(start, 8);
            assert!(
                (yaw(&seg[11..], 8) - y0).abs() < 1e-5,
                "row 1 repeats the angle"
            );
            assert!(
                (yaw(&seg[22..], 8) - (y0 - 0.3)).abs() < 1e-5,
                "later change kept"
            );
            for r in 1..3 {
                let (new, old) = (&seg[r * 11..(r + 1) * 11], &old[r * 11..(r + 1) * 11]);
                for j in 0..4 {
                    let want = start[j] + 0.1 * (r - 1) as f32;
                    assert!((new[j] - want).abs() < 1e-6, "a contact finger's joint");
                }
                let moved = if i == 0 { 0.0 } else { -0.25 };
                for j in 4..8 {
                    assert!(
                        (new[j] - (old[j] + moved)).abs() < 1e-6,
                        "finger 1, seg {i}"
                    );
                }
                assert_eq!(new[10], old[10], "controls are left alone");
            }
        }
    }

    #[test]
    fn nothing_moves_without_an_anchor_or_with_one_row() {
        let starts = state(0.1, -0.3);
        let mut out = sampled(&[(0.1, -0.3)], 0.2, 0.25);
        let before = out.clone();
        StartAnchor::NONE.apply(&mut out, &starts, &[1.0, 1.0], &DIMS);
        assert_eq!(out, before);
        assert!(!StartAnchor::NONE.is_active(&DIMS));
        let one_row = SegmentDims { horizon: 1, ..DIMS };
        let mut first = out[..11].to_vec();
        let anchor = StartAnchor {
            angle: Some(InvariantAngle {
                cos_column: 8,
                ..ANGLE
            }),
            contact_joints: true,
        };
        anchor.apply(&mut first, &starts, &[1.0, 1.0], &one_row);
        assert_eq!(first, before[..11]);
        assert!(!anchor.is_active(&one_row));
        // An angle column past the state, joints past the state: nothing applies.
        let narrow = SegmentDims {
            state_dim: 7,
            action_dim: 4,
            ..DIMS
        };
        assert!(!anchor.is_active(&narrow));
    }
}
