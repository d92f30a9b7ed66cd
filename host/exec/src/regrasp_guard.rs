//! A guard on the commands of regrasping fingers: none touches the object before its mode's
//! last (touch-down) step.
//!
//! CSVTO's plan keeps a regrasping finger [`REGRASP_CLEARANCE`] clear of the object at every
//! step before the last, but only at the plan's knots and only where the plan is feasible.
//! When a warm-up has not converged (its free-motion rows violated), the executed `Δq₀`, each
//! joint held to the step bound, moves the finger along a path the plan never checked; and on
//! a hand whose joint driver ramps from its last *target* (the MuJoCo hand, as the Allegro's
//! driver), a finger that pressed in the previous mode still presses while it starts to move.
//! On the card either one drags the card back: friction that sticks carries a 10 g card with a
//! fingertip that touches it while moving towards its regrasp target (measured in
//! `docs/mujoco.md`, "The card's regrasping finger"). With [`RegraspGuard::Clearance`] the
//! controller checks each regrasping finger's command before it is sent, at the measured
//! joints and object pose:
//! - a finger at least [`GUARD_FLOOR`] clear whose target would come closer than that moves
//!   only as far along its command as keeps it [`GUARD_FLOOR`] clear;
//! - a finger closer than [`GUARD_FLOOR`] (it starts the mode in contact, or came down early)
//!   is lifted straight away from the surface (along the gradient of its signed distance in
//!   joint space) towards [`REGRASP_CLEARANCE`], within the step bound, instead of moving along
//!   the surface.
//!
//! The last step of a mode is never guarded: it is where the finger touches down.

use dips_kernel::name::UnknownValue;

use crate::problems::AllegroProblem;
use crate::problems::allegro::REGRASP_CLEARANCE;

/// The least clearance (m) the guard keeps a regrasping finger's target before its mode's
/// last step: half the plan's [`REGRASP_CLEARANCE`], so the guard acts only where the plan's
/// own clearance has been lost by more than half, not on a feasible plan's tracking error
/// (measured up to 0.5 mm on our world, `CLEARANCE_MARGIN`).
pub const GUARD_FLOOR: f64 = 0.5 * REGRASP_CLEARANCE;
/// Bisection steps when shortening a command (the remaining error is `2⁻²⁰` of it).
const BISECTIONS: usize = 20;

/// Whether the controller guards regrasping fingers' commands ([`guard_regrasps`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RegraspGuard {
    /// Every command as CSVTO's best particle gives it (the paper's execution; every run
    /// before the guard existed).
    #[default]
    Off,
    /// Regrasping fingers are kept [`GUARD_FLOOR`] clear of the object until their last step.
    Clearance,
}

impl RegraspGuard {
    /// Both, in `--regrasp-guard` order.
    pub const ALL: [Self; 2] = [Self::Off, Self::Clearance];
    /// Both names, in [`RegraspGuard::ALL`] order.
    pub const NAMES: [&'static str; 2] = [Self::Off.name(), Self::Clearance.name()];

    /// The name used by `--regrasp-guard`, `eval.json`, protocols and `result.json`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Off => "off",
            Self::Clearance => "clearance",
        }
    }

    /// Whether this is the paper's execution (the default, left out of files).
    pub fn is_off(&self) -> bool {
        *self == Self::Off
    }
}

impl std::str::FromStr for RegraspGuard {
    type Err = UnknownValue;

    /// A guard by its name ([`RegraspGuard::name`]); the error names the value and both.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        UnknownValue::find("regrasp guard", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl std::fmt::Display for RegraspGuard {
    /// The guard's name ([`RegraspGuard::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What the guard did to one finger's command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum GuardAction {
    /// The command was shortened to keep [`GUARD_FLOOR`].
    Shortened,
    /// The command was replaced by a lift away from the surface.
    Lifted,
}

/// Guard the regrasping fingers' commands `dq` (4 per task finger, contract order) of a step
/// that starts at the measured `state` (`[task joints, object coordinates]`, metres and
/// radians); `last` is the mode's last step, which is left alone. Returns, per task finger,
/// what was done to its command (`None`: contact fingers, and commands that keep the floor).
pub fn guard_regrasps(
    problem: &AllegroProblem,
    state: &[f64],
    dq: &mut [f64],
    last: bool,
) -> Vec<Option<GuardAction>> {
    let nf = problem.fingers();
    let mut actions = vec![None; nf];
    if last {
        return actions;
    }
    let o = problem.object_pose(state);
    let bound = problem.dq_bound();
    for (i, action) in actions.iter_mut().enumerate() {
        if problem.in_contact(i) {
            continue;
        }
        let q = AllegroProblem::finger_joints(state, i);
        let step = AllegroProblem::finger_joints(dq, i);
        let sdf = |s: f64| {
            let t: [f64; 4] = std::array::from_fn(|k| q[k] + s * step[k]);
            problem.finger_sdf(i, &t, &o)
        };
        let now = sdf(0.0);
        if sdf(1.0) >= GUARD_FLOOR {
            continue;
        }
        let new = if now >= GUARD_FLOOR {
            // The largest share of the command that keeps the floor (the start keeps it).
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..BISECTIONS {
                let mid = 0.5 * (lo + hi);
                if sdf(mid) >= GUARD_FLOOR {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            *action = Some(GuardAction::Shortened);
            step.map(|d| lo * d)
        } else {
            *action = Some(GuardAction::Lifted);
            lift(problem, i, &q, &o, now, bound)
        };
        dq[4 * i..4 * i + 4].copy_from_slice(&new);
    }
    actions
}

/// The joint step that lifts finger `i` at `q` (signed distance `now`) straight away from the
/// object towards [`REGRASP_CLEARANCE`] to first order (`Δq = g·(δ − sdf)/‖g‖²` with `g` the
/// sdf's joint gradient), scaled as a whole so that no joint moves more than `bound`.
fn lift(
    problem: &AllegroProblem,
    i: usize,
    q: &[f64; 4],
    o: &[f64; 3],
    now: f64,
    bound: f64,
) -> [f64; 4] {
    let (_, g, _) = problem.finger_sdf_gradient(i, q, o);
    let norm2: f64 = g.iter().map(|v| v * v).sum();
    if norm2 < 1e-12 {
        // No joint moves the tip away (a singular pose): hold the finger where it is.
        return [0.0; 4];
    }
    let mut step = g.map(|v| v * (REGRASP_CLEARANCE - now) / norm2);
    let largest = step.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if largest > bound {
        step = step.map(|v| v * bound / largest);
    }
    step
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::{Mode, ProblemSpec};
    use dips_world::kinematics::HandModel;
    use dips_world::scenes::SceneKind;
    use dips_world::world::World;

    /// A card `index` problem (the middle finger regrasps) from the world's start, where
    /// both fingers rest on the card.
    fn card_problem() -> (AllegroProblem, Vec<f64>) {
        let world = World::new(SceneKind::Card);
        let start = crate::hand_state(&world);
        let spec = ProblemSpec {
            task: SceneKind::Card,
            mode: Mode::CardIndex,
            horizon: 8,
            start: start.clone(),
            goal: [0.0, -0.02, 0.0],
        };
        (
            AllegroProblem::new(&HandModel::allegro_v4(), &spec).unwrap(),
            start,
        )
    }

    #[test]
    fn a_finger_in_contact_is_lifted_not_dragged() {
        let (problem, start) = card_problem();
        let middle = 1;
        assert!(!problem.in_contact(middle));
        let q = AllegroProblem::finger_joints(&start, middle);
        let o = problem.object_pose(&start);
        let before = problem.finger_sdf(middle, &q, &o);
        assert!(
            before < GUARD_FLOOR,
            "the scene starts with the finger on the card"
        );
        // A command that drives the finger into and along the card.
        let mut dq = vec![0.0; 8];
        dq[4..8].copy_from_slice(&[0.05, 0.1, 0.1, 0.1]);
        let actions = guard_regrasps(&problem, &start, &mut dq, false);
        assert_eq!(actions, vec![None, Some(GuardAction::Lifted)]);
        let t: [f64; 4] = std::array::from_fn(|k| q[k] + dq[4 + k]);
        let after = problem.finger_sdf(middle, &t, &o);
        assert!(after > before + 2e-3, "lifted from {before} to {after}");
        assert!(
            dq[4..8]
                .iter()
                .all(|v| v.abs() <= problem.dq_bound() + 1e-12)
        );
        // The contact finger's command is untouched.
        assert_eq!(&dq[..4], &[0.0; 4]);
    }

    #[test]
    fn a_clear_finger_stops_at_the_floor_and_the_last_step_is_free() {
        let (problem, start) = card_problem();
        let middle = 1;
        let o = problem.object_pose(&start);
        let q0 = AllegroProblem::finger_joints(&start, middle);
        // Lift the finger well clear first, with the guard's own lift.
        let up = lift(
            &problem,
            middle,
            &q0,
            &o,
            problem.finger_sdf(middle, &q0, &o),
            1.0,
        );
        let mut state = start.clone();
        for k in 0..4 {
            state[4 * middle + k] += up[k];
        }
        let q = AllegroProblem::finger_joints(&state, middle);
        assert!(problem.finger_sdf(middle, &q, &o) > GUARD_FLOOR);
        // Then command it straight back down.
        let down: Vec<f64> = up.iter().map(|v| -v).collect();
        let mut dq = vec![0.0; 8];
        dq[4..8].copy_from_slice(&down);
        let mut last = dq.clone();
        assert_eq!(
            guard_regrasps(&problem, &state, &mut dq, false),
            vec![None, Some(GuardAction::Shortened)]
        );
        let t: [f64; 4] = std::array::from_fn(|k| q[k] + dq[4 + k]);
        assert!((problem.finger_sdf(middle, &t, &o) - GUARD_FLOOR).abs() < 1e-5);
        assert_eq!(
            guard_regrasps(&problem, &state, &mut last, true),
            vec![None, None]
        );
        assert_eq!(&last[4..8], &down[..]);
    }

    #[test]
    fn names_round_trip_and_unknown_names_are_refused() {
        for g in RegraspGuard::ALL {
            assert_eq!(g.name().parse::<RegraspGuard>(), Ok(g));
        }
        let err = "always".parse::<RegraspGuard>().unwrap_err().to_string();
        assert!(err.contains("always") && err.contains("off") && err.contains("clearance"));
    }
}
