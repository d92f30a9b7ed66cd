//! The object pose CSVTO plans from: the tracker's reading as it comes, or that reading
//! fused with the contacts the executed mode holds.
//!
//! A tracker (Aruco tags on the real hand, `--noise-*` on the MuJoCo hand) reads the
//! screwdriver's roll and pitch within about a degree. A fingertip on the handle is known to
//! a fraction of a millimetre from the joint encoders, and 1° of roll moves the handle's
//! surface by about 2 mm under it: a raw reading puts the contact fingers millimetres inside
//! or off the handle, a start no plan of the mode can be consistent with. With
//! [`PoseEstimate::Contacts`] the pose is the one that best explains both the tracker and the
//! mode's contacts (every contact finger on the surface): the maximum a posteriori estimate
//! under Gaussian tracker and contact errors, solved by Gauss–Newton over the three object
//! coordinates. What the contacts cannot see (the handle's yaw, the card's position in its
//! plane) stays the tracker's.

use dips_kernel::name::UnknownValue;
use dips_world::scenes::SceneKind;
use dips_world::world::ContactReport;
use nalgebra::{Matrix3, Vector3};

use crate::problems::AllegroProblem;

/// Standard deviation of the tracker's angles assumed by the fusion (rad): about 1°, an Aruco
/// tag's at arm's length, and the MuJoCo hand's `--noise-rotation` of the transfer runs.
pub const TRACKER_SIGMA_RAD: f64 = 0.02;
/// Standard deviation of the tracker's positions assumed by the fusion (m).
pub const TRACKER_SIGMA_M: f64 = 1e-3;
/// Standard deviation of a contact finger's distance to the surface (m): the fingertip's
/// forward kinematics and the contact's compliance (the MuJoCo hand presses 0.1–0.5 mm in).
pub const CONTACT_SIGMA_M: f64 = 0.5e-3;
/// A contact finger farther than this from the surface at the tracker's pose (either side)
/// is taken as not touching and left out of the fusion (m): a finger that has slipped off
/// must not pull the object's pose to it.
pub const CONTACT_GATE_M: f64 = 6e-3;
/// The least force of a contact reading that counts its finger as touching (N): a tactile
/// pad's threshold, above the readings of a fingertip that merely grazes.
pub const TOUCH_FORCE_N: f64 = 0.05;
/// Gauss–Newton iterations at most; the fusion is three-dimensional and converges in 2–4.
const MAX_ITERS: usize = 10;

/// How the controller estimates the object's pose at each of a mode's solves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PoseEstimate {
    /// The tracker's reading as it comes (every run before the fusion existed; exact in our
    /// world and on a noiseless MuJoCo hand).
    #[default]
    Tracker,
    /// The tracker's reading fused with the mode's contacts ([`fuse_contacts`]).
    Contacts,
}

impl PoseEstimate {
    /// Both, in `--pose-estimate` order.
    pub const ALL: [Self; 2] = [Self::Tracker, Self::Contacts];
    /// Both names, in [`PoseEstimate::ALL`] order.
    pub const NAMES: [&'static str; 2] = [Self::Tracker.name(), Self::Contacts.name()];

    /// The name used by `--pose-estimate`, `eval.json`, protocols and `result.json`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Tracker => "tracker",
            Self::Contacts => "contacts",
        }
    }

    /// Whether this is the tracker's (the default, left out of files).
    pub fn is_tracker(&self) -> bool {
        *self == Self::Tracker
    }

    /// The state a solve starts from: `measured` (`[task joints, object coordinates]` in
    /// metres and radians) as it is, or with its object coordinates fused with `problem`'s
    /// contacts, of which those the hand's `readings` say touch (all when it has none).
    pub fn apply(
        self,
        problem: &AllegroProblem,
        measured: &[f64],
        readings: Option<&[ContactReport]>,
    ) -> Vec<f64> {
        match self {
            Self::Tracker => measured.to_vec(),
            Self::Contacts => {
                let touching = readings.map(|r| touching(problem.task(), r));
                fuse_contacts(problem, measured, touching.as_deref()).state
            }
        }
    }
}

impl std::str::FromStr for PoseEstimate {
    type Err = UnknownValue;

    /// An estimate by its name ([`PoseEstimate::name`]); the error names the value and both.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        UnknownValue::find("pose estimate", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl std::fmt::Display for PoseEstimate {
    /// The estimate's name ([`PoseEstimate::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A fused state and what went into it.
#[derive(Debug, Clone, PartialEq)]
pub struct Fused {
    /// `[task joints, object coordinates]`: the joints as measured, the object fused.
    pub state: Vec<f64>,
    /// How many contact fingers were within [`CONTACT_GATE_M`] and used.
    pub contacts_used: usize,
}

/// Which task fingers of `task` the hand's contact `readings` say touch the object: a
/// reading of the finger on any part but the table carrying more than [`TOUCH_FORCE_N`].
pub fn touching(task: SceneKind, readings: &[ContactReport]) -> Vec<bool> {
    task.task_fingers()
        .iter()
        .map(|f| {
            readings.iter().any(|r| {
                r.finger == f.name()
                    && r.part != "table"
                    && r.force.iter().map(|v| v * v).sum::<f64>().sqrt() > TOUCH_FORCE_N
            })
        })
        .collect()
}

/// The tracker's standard deviation of each object coordinate of `task`.
fn tracker_sigma(task: SceneKind) -> [f64; 3] {
    match task {
        SceneKind::Screwdriver => [TRACKER_SIGMA_RAD; 3],
        SceneKind::Card => [TRACKER_SIGMA_M, TRACKER_SIGMA_M, TRACKER_SIGMA_RAD],
    }
}

/// The object coordinates `o` minimising
/// `Σ_k ((o_k − m_k)/σ_k)² + Σ_i (sdf_i(q, o)/σ_c)²` over the contact fingers `i` of
/// `problem`'s mode that touch (`touching[i]`, from the hand's contact readings; every one
/// when `None`) and lie within [`CONTACT_GATE_M`] of the surface at the measured `m`
/// (σ: [`TRACKER_SIGMA_RAD`], [`TRACKER_SIGMA_M`], [`CONTACT_SIGMA_M`]). Gauss–Newton with the
/// problem's exact sdf derivatives ([`AllegroProblem::finger_sdf_gradient`]); a step that does not lower the cost is halved, and a non-finite one
/// leaves the measurement as it is. With no contact finger in reach the state is returned
/// unchanged.
pub fn fuse_contacts(
    problem: &AllegroProblem,
    measured: &[f64],
    touching: Option<&[bool]>,
) -> Fused {
    let nq = 4 * problem.fingers();
    let m = problem.object_pose(measured);
    let joints = |i: usize| AllegroProblem::finger_joints(measured, i);
    let used: Vec<(usize, [f64; 4])> = (0..problem.fingers())
        .filter(|&i| problem.in_contact(i) && touching.is_none_or(|t| t[i]))
        .map(|i| (i, joints(i)))
        .filter(|(i, q)| problem.finger_sdf(*i, q, &m).abs() <= CONTACT_GATE_M)
        .collect();
    let unchanged = |contacts_used| Fused {
        state: measured.to_vec(),
        contacts_used,
    };
    if used.is_empty() {
        return unchanged(0);
    }
    let sigma = tracker_sigma(problem.task());
    let residuals = |o: &[f64; 3]| -> Vec<f64> {
        let mut r: Vec<f64> = (0..3).map(|k| (o[k] - m[k]) / sigma[k]).collect();
        r.extend(
            used.iter()
                .map(|(i, q)| problem.finger_sdf(*i, q, o) / CONTACT_SIGMA_M),
        );
        r
    };
    let cost = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let mut o = m;
    let mut r = residuals(&o);
    for _ in 0..MAX_ITERS {
        // J's rows, in `residuals`' order: the prior's (1/σ_k on the diagonal), then each
        // contact's sdf gradient over the object coordinates.
        let rows: Vec<[f64; 3]> = (0..3)
            .map(|k| std::array::from_fn(|c| if c == k { 1.0 / sigma[k] } else { 0.0 }))
            .chain(used.iter().map(|(i, q)| {
                let (_, _, d_o) = problem.finger_sdf_gradient(*i, q, &o);
                d_o.map(|v| v / CONTACT_SIGMA_M)
            }))
            .collect();
        let jtj = Matrix3::from_fn(|a, b| rows.iter().map(|j| j[a] * j[b]).sum::<f64>());
        let jtr = Vector3::from_fn(|a, _| rows.iter().zip(&r).map(|(j, v)| j[a] * v).sum::<f64>());
        // The prior rows make JᵀJ positive definite (at least 1/σ² on the diagonal).
        let Some(step) = jtj.cholesky().map(|c| -c.solve(&jtr)) else {
            break;
        };
        if !step.iter().all(|v| v.is_finite()) {
            break;
        }
        let mut scale = 1.0;
        let mut accepted = false;
        for _ in 0..8 {
            let trial: [f64; 3] = std::array::from_fn(|k| o[k] + scale * step[k]);
            let rt = residuals(&trial);
            if rt.iter().all(|v| v.is_finite()) && cost(&rt) < cost(&r) {
                o = trial;
                r = rt;
                accepted = true;
                break;
            }
            scale *= 0.5;
        }
        let small = (0..3).all(|k| (scale * step[k]).abs() < 1e-9 * sigma[k].max(1.0));
        if !accepted || small {
            break;
        }
    }
    if !o.iter().all(|v| v.is_finite()) {
        return unchanged(used.len());
    }
    let mut state = measured.to_vec();
    state[nq..nq + 3].copy_from_slice(&o);
    Fused {
        state,
        contacts_used: used.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::{Mode, ProblemSpec};
    use dips_world::kinematics::HandModel;
    use dips_world::world::World;

    /// The screwdriver's `turn` problem at the world's initial grasp and that state: the
    /// index and thumb on the handle (0 and 0.7 mm), the middle finger 3.9 mm off it.
    fn turn_at_grasp() -> (AllegroProblem, Vec<f64>) {
        let world = World::new(SceneKind::Screwdriver);
        let state = crate::hand_state(&world);
        let spec = ProblemSpec {
            task: SceneKind::Screwdriver,
            mode: Mode::Turn,
            horizon: 4,
            start: state.clone(),
            goal: [0.0, 0.0, -0.5],
        };
        let problem = AllegroProblem::new(&HandModel::allegro_v4(), &spec).unwrap();
        (problem, state)
    }

    /// The index and thumb touch; the middle finger does not.
    const TOUCHING: [bool; 3] = [true, false, true];

    fn contact_gaps(problem: &AllegroProblem, state: &[f64]) -> Vec<f64> {
        let sdfs = problem.finger_sdfs(state);
        (0..problem.fingers())
            .filter(|&i| problem.in_contact(i) && TOUCHING[i])
            .map(|i| sdfs[i].abs())
            .collect()
    }

    #[test]
    fn a_tilted_reading_is_pulled_back_onto_the_contacts() {
        let (problem, truth) = turn_at_grasp();
        let nq = 4 * problem.fingers();
        let true_gap = contact_gaps(&problem, &truth);
        // A reading 0.02 rad off in roll and pitch (one σ of the tracker, each) and in yaw.
        let mut noisy = truth.clone();
        noisy[nq] += 0.02;
        noisy[nq + 1] -= 0.02;
        noisy[nq + 2] += 0.02;
        let noisy_gap = contact_gaps(&problem, &noisy);
        let fused = fuse_contacts(&problem, &noisy, Some(&TOUCHING));
        assert_eq!(fused.contacts_used, 2);
        let fused_gap = contact_gaps(&problem, &fused.state);
        let worst = |g: &[f64]| g.iter().cloned().fold(0.0, f64::max);
        assert!(
            worst(&noisy_gap) > 1e-3 + worst(&true_gap),
            "the tilt must move the handle under the fingers: {noisy_gap:?} vs {true_gap:?}"
        );
        assert!(
            worst(&fused_gap) < 0.5 * worst(&noisy_gap),
            "fused gaps {fused_gap:?}, noisy {noisy_gap:?}"
        );
        // Two opposed contacts see the tilt towards either finger, not the one along the line
        // between them: the roll–pitch error shrinks, though not to nothing. Joints are
        // untouched.
        let tilt_error = |s: &[f64]| (s[nq] - truth[nq]).hypot(s[nq + 1] - truth[nq + 1]);
        let (err_noisy, err_fused) = (tilt_error(&noisy), tilt_error(&fused.state));
        eprintln!(
            "tilt error {err_noisy:.4} -> {err_fused:.4} rad; gaps {noisy_gap:?} -> {fused_gap:?}"
        );
        assert!(err_fused < 0.75 * err_noisy, "{err_fused} vs {err_noisy}");
        assert_eq!(fused.state[..nq], noisy[..nq]);
    }

    #[test]
    fn the_tracker_estimate_and_an_exact_reading_change_nothing_much() {
        let (problem, truth) = turn_at_grasp();
        assert_eq!(PoseEstimate::Tracker.apply(&problem, &truth, None), truth);
        // At the true grasp the fused pose stays within a small fraction of the tracker's σ.
        let fused = fuse_contacts(&problem, &truth, Some(&TOUCHING)).state;
        let nq = 4 * problem.fingers();
        for k in 0..3 {
            assert!(
                (fused[nq + k] - truth[nq + k]).abs() < 0.25 * TRACKER_SIGMA_RAD,
                "{fused:?}"
            );
        }
    }

    #[test]
    fn a_finger_off_the_surface_is_left_out() {
        let (problem, truth) = turn_at_grasp();
        let nq = 4 * problem.fingers();
        let mut far = truth.clone();
        far[nq] += 0.5; // half a radian of roll: every fingertip centimetres from the handle
        let fused = fuse_contacts(&problem, &far, None);
        assert_eq!(fused.contacts_used, 0);
        assert_eq!(fused.state, far);
        // A finger the readings say does not touch is left out, however near it is.
        let fused = fuse_contacts(&problem, &truth, Some(&[false; 3]));
        assert_eq!((fused.contacts_used, fused.state), (0, truth));
    }

    #[test]
    fn readings_touch_above_the_threshold_and_never_on_the_table() {
        let reading = |finger: &str, part: &str, force: f64| ContactReport {
            finger: finger.into(),
            part: part.into(),
            point: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
            force: [0.0, 0.0, force],
            phi: 0.0,
        };
        let readings = [
            reading("index", "handle", 1.0),
            reading("middle", "handle", 0.01),
            reading("thumb", "table", 1.0),
        ];
        assert_eq!(
            touching(SceneKind::Screwdriver, &readings),
            vec![true, false, false]
        );
    }

    #[test]
    fn estimates_read_and_write_their_names() {
        for p in PoseEstimate::ALL {
            assert_eq!(p.name().parse::<PoseEstimate>(), Ok(p));
            assert_eq!(serde_json::to_value(p).unwrap(), p.name());
        }
        let err = "aruco".parse::<PoseEstimate>().unwrap_err().to_string();
        assert!(err.contains("aruco") && err.contains("tracker") && err.contains("contacts"));
    }
}
