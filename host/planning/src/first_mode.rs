//! Which modes a plan may begin with.
//!
//! A contact mode presupposes that its contact fingers touch the object: CSVTO's first step
//! of the mode must close any gap while its rolling rows hold the finger to the surface, and a
//! finger centimetres away cannot. In our world the fingers that end a mode in contact stay
//! there; on a hand we do not model (MuJoCo, `docs/mujoco.md`) a pushing finger can slide off
//! the card, and the paper's planner, which never looks at the fingertips, may still plan the
//! next push with it. The warm-up of such a mode does not converge and its execution moves the
//! card the wrong way. [`FirstModeRule::Touching`] leaves those modes out of the plan's first
//! mode ([`ModeSet`] in the kernel's search); later modes are unconstrained, as the search
//! cannot know where the fingers will be.

use dips_kernel::mode::{ModeSet, Task};
use dips_kernel::name::UnknownValue;
use serde::{Deserialize, Serialize};

/// A finger farther from the object than this (m) is not touching it. Chosen on the card's
/// tuning seeds 500–529 in MuJoCo (`docs/online.md`, "The first mode"): pushes whose contact
/// fingers started 1–4 mm off moved the card as far as those that started in contact
/// (−1.20 cm against −1.01 cm); those that started 4–6 mm off moved it −0.36 cm, and those
/// beyond 4 mm hold three of the four modes whose warm-up did not converge.
pub const TOUCH_TOLERANCE_M: f64 = 4e-3;

/// Which modes a planning call may begin with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FirstModeRule {
    /// Any of the task's modes: the paper's.
    #[default]
    Any,
    /// Only modes whose contact fingers are all within [`TOUCH_TOLERANCE_M`] of the object at
    /// the measured state; any mode when no mode qualifies (the screwdriver with every finger
    /// off). Our variant.
    Touching,
}

impl FirstModeRule {
    /// Both rules, in `--first-mode` order.
    pub const ALL: [Self; 2] = [Self::Any, Self::Touching];

    /// Both rules' names, in [`FirstModeRule::ALL`] order.
    pub const NAMES: [&'static str; 2] = [Self::Any.name(), Self::Touching.name()];

    /// The name used by `--first-mode`, `eval.json` and protocols.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Any => "any",
            Self::Touching => "touching",
        }
    }

    /// Whether this is the paper's rule (the default, left out of `eval.json`).
    pub fn is_paper(&self) -> bool {
        *self == Self::Any
    }

    /// The modes of `task` a plan may begin with, given each task finger's signed distance to
    /// the object (m, task-finger order; [`dips_exec::fingertip_distances`]).
    pub fn first_modes(self, task: Task, distances: &[f64]) -> ModeSet {
        let all = ModeSet::all(task);
        if self == Self::Any {
            return all;
        }
        let touching = |i: usize| distances.get(i).is_some_and(|&d| d <= TOUCH_TOLERANCE_M);
        let set = task
            .candidate_modes()
            .filter(|&id| {
                task.contact_mode(id)
                    .is_some_and(|c| (0..c.fingers()).all(|i| !c.in_contact(i) || touching(i)))
            })
            .fold(ModeSet::EMPTY, ModeSet::with);
        if set.is_empty() { all } else { set }
    }
}

impl std::str::FromStr for FirstModeRule {
    type Err = UnknownValue;

    /// A rule by its name ([`FirstModeRule::name`]); the error names the value and the rules.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        UnknownValue::find(
            "first-mode rule",
            name,
            &Self::ALL,
            &Self::NAMES,
            Self::name,
        )
    }
}

impl std::fmt::Display for FirstModeRule {
    /// The rule's name ([`FirstModeRule::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dips_kernel::mode::ModeId;

    fn names(task: Task, set: ModeSet) -> Vec<&'static str> {
        task.candidate_modes()
            .filter(|&id| set.contains(id))
            .map(|id| task.modes()[id.index()].name)
            .collect()
    }

    #[test]
    fn touching_keeps_the_modes_whose_contact_fingers_touch() {
        let card = Task::Card;
        // Index 11 mm off, middle in contact: the middle pushes or both regrasp.
        let set = FirstModeRule::Touching.first_modes(card, &[0.011, -0.0002]);
        assert_eq!(names(card, set), ["middle", "regrasp"]);
        // Both touch (within 4 mm): every mode.
        let set = FirstModeRule::Touching.first_modes(card, &[0.004, -0.001]);
        assert_eq!(set, ModeSet::all(card));
        // Both off: only the regrasp.
        let set = FirstModeRule::Touching.first_modes(card, &[0.02, 0.05]);
        assert_eq!(names(card, set), ["regrasp"]);
        // The paper's rule never looks.
        let set = FirstModeRule::Any.first_modes(card, &[0.02, 0.05]);
        assert_eq!(set, ModeSet::all(card));
    }

    #[test]
    fn the_screwdriver_with_every_finger_off_may_begin_with_any_mode() {
        let sd = Task::Screwdriver;
        // Index off: the thumb and middle hold while it regrasps.
        let set = FirstModeRule::Touching.first_modes(sd, &[0.01, 0.0, 0.0]);
        assert_eq!(names(sd, set), ["index-regrasp"]);
        assert!(!set.contains(ModeId(0)));
        // Every finger off: no mode qualifies, so none is left out.
        let set = FirstModeRule::Touching.first_modes(sd, &[0.01, 0.01, 0.01]);
        assert_eq!(set, ModeSet::all(sd));
        // A missing distance counts as off.
        let set = FirstModeRule::Touching.first_modes(sd, &[0.0, 0.0]);
        assert_eq!(names(sd, set), ["thumb-middle-regrasp"]);
    }

    #[test]
    fn names_round_trip_and_unknown_ones_are_named() {
        for r in FirstModeRule::ALL {
            assert_eq!(r.name().parse::<FirstModeRule>().unwrap(), r);
        }
        let e = "sometimes"
            .parse::<FirstModeRule>()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("sometimes") && e.contains("any") && e.contains("touching"),
            "{e}"
        );
    }
}
