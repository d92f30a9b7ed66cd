//! When an online episode stops before its mode limit.
//!
//! The paper's loop executes the first mode of every plan until the mode limit or until a plan
//! holds no mode (the goal test passes at the root). With a one-sided goal test (the card's
//! `ȳ ≤ o_G`) that makes the loop push once more whenever the card is short of the goal, even
//! when every push in the models' experience overshoots by more than the card is short
//! (`docs/search.md`, "The registered run (10300–10329)"). [`StopRule::NoGain`] lets "stop
//! here" compete: the episode stops when the plan's expected end is no better, by the task's
//! terminal cost `φ`, than the state it would start from.

use dips_kernel::mode::Task;
use dips_kernel::name::UnknownValue;
use dips_kernel::search::TaskObjective;
use dips_kernel::task::{CardGoals, Objective};
use serde::{Deserialize, Serialize};

/// When an online episode of a searching method stops before its mode limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StopRule {
    /// When a plan holds no mode (its root passes the goal test): the paper's.
    #[default]
    GoalReached,
    /// Also when the plan's expected end is no better than the current state by the task's
    /// terminal cost `φ` (card `(ȳ − o_G)²`, screwdriver `max(0, ȳ − o_G)`): our variant.
    NoGain,
}

impl StopRule {
    /// Both rules, in `--stop-rule` order.
    pub const ALL: [Self; 2] = [Self::GoalReached, Self::NoGain];

    /// Both rules' names, in [`StopRule::ALL`] order.
    pub const NAMES: [&'static str; 2] = [Self::GoalReached.name(), Self::NoGain.name()];

    /// The name used by `--stop-rule`, `eval.json` and protocols.
    pub const fn name(self) -> &'static str {
        match self {
            Self::GoalReached => "goal-reached",
            Self::NoGain => "no-gain",
        }
    }

    /// Whether this is the paper's rule (the default, left out of `eval.json`).
    pub fn is_paper(&self) -> bool {
        *self == Self::GoalReached
    }
}

impl std::str::FromStr for StopRule {
    type Err = UnknownValue;

    /// A rule by its name ([`StopRule::name`]); the error names the value and the rules.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        UnknownValue::find("stop rule", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl std::fmt::Display for StopRule {
    /// The rule's name ([`StopRule::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The terminal costs that [`StopRule::NoGain`] compares for one plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanGain {
    /// `φ` of the state the plan starts from.
    pub now: f32,
    /// `φ` of the plan's expected end.
    pub planned: f32,
}

impl PlanGain {
    /// The costs of a plan from the raw `start` state (contract layout) towards `goal`
    /// (screwdriver yaw in rad, card y in m) whose expected end has progress
    /// `expected_progress`; `None` when the objective cannot be formed (a short start, a
    /// goal that is not finite).
    pub fn of(
        task: Task,
        start: &[f32],
        goal: f32,
        card_goals: CardGoals,
        expected_progress: f32,
    ) -> Option<Self> {
        let objective = Objective::for_goal(task, start, goal, card_goals)?;
        Some(Self {
            now: objective.terminal_cost(objective.progress(start)),
            planned: objective.terminal_cost(expected_progress),
        })
    }

    /// Whether the plan promises less than stopping here: its expected end's cost is not
    /// below the current state's (a cost that is not finite promises nothing).
    pub fn no_gain(&self) -> bool {
        self.planned.partial_cmp(&self.now) != Some(std::cmp::Ordering::Less)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn card_state(y: f32) -> [f32; 12] {
        let mut s = [0.0; 12];
        s[Task::Card.layout().object() + 1] = y;
        s
    }

    #[test]
    fn a_push_that_overshoots_more_than_the_card_is_short_is_no_gain() {
        let goal = -0.06;
        // 5.4 cm pushed, one more push expected to end at -7.2 cm: 1.2 cm past, 0.6 short.
        let g = PlanGain::of(
            Task::Card,
            &card_state(-0.054),
            goal,
            CardGoals::Paper,
            -0.072,
        )
        .unwrap();
        assert!(g.no_gain(), "{g:?}");
        // 3.6 cm pushed, two more expected to end at -7.2 cm: still better than 2.4 cm short.
        let g = PlanGain::of(
            Task::Card,
            &card_state(-0.036),
            goal,
            CardGoals::Paper,
            -0.072,
        )
        .unwrap();
        assert!(!g.no_gain(), "{g:?}");
        // A cost that is not finite promises nothing.
        let g = PlanGain::of(
            Task::Card,
            &card_state(-0.036),
            goal,
            CardGoals::Paper,
            f32::NAN,
        )
        .unwrap();
        assert!(g.no_gain());
    }

    #[test]
    fn the_screwdriver_stops_only_on_a_plan_that_does_not_turn() {
        let mut s = [0.0f32; 16];
        let c = Task::Screwdriver.layout().angle_cos();
        s[c] = 1.0; // yaw 0
        let goal = -core::f32::consts::FRAC_PI_3;
        let turn = PlanGain::of(Task::Screwdriver, &s, goal, CardGoals::default(), -0.2).unwrap();
        assert!(!turn.no_gain(), "{turn:?}");
        let back = PlanGain::of(Task::Screwdriver, &s, goal, CardGoals::default(), 0.1).unwrap();
        assert!(back.no_gain(), "{back:?}");
    }

    #[test]
    fn rules_parse_by_name_and_name_the_allowed_ones() {
        for rule in StopRule::ALL {
            assert_eq!(rule.name().parse::<StopRule>(), Ok(rule));
            assert_eq!(rule.to_string(), rule.name());
        }
        let e = "never".parse::<StopRule>().unwrap_err().to_string();
        assert!(e.contains("goal-reached") && e.contains("no-gain"), "{e}");
        assert_eq!(
            serde_json::to_string(&StopRule::NoGain).unwrap(),
            "\"no-gain\""
        );
    }
}
