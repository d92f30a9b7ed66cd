//! Search settings ([`SearchConfig`]) and their validation.

use core::fmt;

use crate::mode::Task;

/// The longest mode sequence a plan can hold (beyond an executed root mode).
pub const MAX_PLAN_LEN: usize = 16;

/// How the cost-to-come `g` of a node is formed from its segments' expected costs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CostToCome {
    /// `g = Σ` of the expected segment costs along the sequence (the paper's Eq. for `g`).
    #[default]
    Cumulative,
    /// `g` = the expected cost of the last segment only (what the authors' code computes).
    LastSegment,
}

impl CostToCome {
    /// Both forms.
    pub const ALL: [CostToCome; 2] = [CostToCome::Cumulative, CostToCome::LastSegment];

    /// The form's name in settings files and on the command line: `cumulative` or
    /// `last-segment`.
    pub const fn name(self) -> &'static str {
        match self {
            CostToCome::Cumulative => "cumulative",
            CostToCome::LastSegment => "last-segment",
        }
    }

    /// Both forms' names, in [`CostToCome::ALL`] order.
    pub const NAMES: [&'static str; 2] = [
        CostToCome::Cumulative.name(),
        CostToCome::LastSegment.name(),
    ];
}

impl core::str::FromStr for CostToCome {
    type Err = crate::name::UnknownValue;

    /// A form by its name ([`CostToCome::name`]); the error names the value and the forms.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        crate::name::UnknownValue::find("cost-to-come", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl fmt::Display for CostToCome {
    /// The form's name ([`CostToCome::name`]).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Which node representation the search uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SearchVariant {
    /// `k` particles per node, resampled by score (Algorithm 1).
    #[default]
    Particles,
    /// Ablation 5: one stored trajectory per node; `k` segments are diffused per mode from
    /// it and the highest-scoring one is kept.
    MaxLikelihood,
}

/// Settings of one planning call. The fields mirror the wire's `SearchSettings`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchConfig {
    /// Particles per node (`k`); with [`SearchVariant::MaxLikelihood`] the number of
    /// segments diffused per mode. Must not exceed the planner's capacity `K`.
    pub k: u16,
    /// Largest number of modes appended to the root (the search depth).
    pub max_depth: u8,
    /// Score discount `γ` in `(0, 1]`.
    pub gamma: f32,
    /// Weight `α` of the terminal cost `φ` in the heuristic.
    pub alpha: f32,
    /// Weight `β` of the prior's negative log-likelihood in the heuristic.
    pub beta: f32,
    /// Minimum transition probability enforced on the prior, in `[0, 1)`.
    pub p_min: f32,
    /// Largest number of node expansions (sampler batches); 0 = limited only by capacity.
    pub node_budget: u32,
    /// Wall-clock budget in milliseconds, read from the injected clock; 0 = none.
    pub time_budget_ms: u32,
    /// Seed of the planner's random stream (resampling and the sampler's noise).
    pub seed: u64,
    /// How `g` is formed.
    pub cost_to_come: CostToCome,
    /// Particle or max-likelihood nodes.
    pub variant: SearchVariant,
}

/// The screwdriver's expansions per planning call ([`SearchConfig::screwdriver`]).
pub const SCREWDRIVER_NODE_BUDGET: u32 = 13;

impl Default for SearchConfig {
    /// The paper's settings: `k = 16`, `γ = 0.9`, `α = 1e4`, `β = 1e3`, `p_min = 0.1`,
    /// depth 7, 300 s timeout, no node budget, cumulative `g`, particle nodes.
    fn default() -> Self {
        Self {
            k: 16,
            max_depth: 7,
            gamma: 0.9,
            alpha: 1e4,
            beta: 1e3,
            p_min: 0.1,
            node_budget: 0,
            time_budget_ms: 300_000,
            seed: 0,
            cost_to_come: CostToCome::Cumulative,
            variant: SearchVariant::Particles,
        }
    }
}

impl SearchConfig {
    /// The authors' card settings (their `GraphSearchCard`): the heuristic is
    /// `1e5 · (ȳ − goal)²` with no prior term (`α = 1e5`, `β = 0`), depth = modes remaining
    /// (5 at the start of a trial), and `g` the expected cost of the last segment
    /// ([`CostToCome::LastSegment`]), as their code computes it.
    ///
    /// With the cumulative `g` of the paper's equation, a push costs about as much in `g` as
    /// it gains in `h`, so `f` is nearly flat along the pushes and a call from the card's start
    /// expands 52–68 nodes; with the last segment's cost it expands 5–27 and plans as well
    /// (`docs/search.md`, "The card's cost-to-come").
    pub fn card() -> Self {
        Self {
            alpha: 1e5,
            beta: 0.0,
            max_depth: 5,
            cost_to_come: CostToCome::LastSegment,
            ..Self::default()
        }
    }

    /// The screwdriver's settings: the paper's ([`SearchConfig::default`]) with a budget of
    /// [`SCREWDRIVER_NODE_BUDGET`] expansions per call.
    ///
    /// The episodes search the modes they have left (`docs/online.md`, "Search depth"). A late
    /// call's goal (the yaw − π/3) is then out of reach, so without a budget the search expands
    /// its whole tree before it answers with its best node: 40 expansions at depth 4, 15–34 s
    /// on 2 cores. 13 is the whole tree of three modes left (1 + 3 + 9); a deeper call stops
    /// there with its best node so far, as the paper's time budget does, but counted in
    /// expansions, so the plan does not depend on the machine. Measured on seeds 500–509
    /// (tuning seeds): the same final yaw as without a budget (−2.610 against −2.577 rad,
    /// paired difference 0.033 ± 0.037; 7 of 10 episodes identical), and calls from the
    /// task's start are not cut (they meet the goal within 3–10 expansions).
    pub fn screwdriver() -> Self {
        Self {
            node_budget: SCREWDRIVER_NODE_BUDGET,
            ..Self::default()
        }
    }

    /// Each task's settings, the one place they come from: the screwdriver's
    /// [`SearchConfig::screwdriver`] (the paper's, with a node budget), the card's
    /// [`SearchConfig::card`] (the authors' code's).
    pub fn for_task(task: Task) -> Self {
        match task {
            Task::Screwdriver => Self::screwdriver(),
            Task::Card => Self::card(),
        }
    }

    /// Check every field; the first bad one is named.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.k == 0 {
            return Err(ConfigError::K);
        }
        if self.max_depth == 0 || usize::from(self.max_depth) > MAX_PLAN_LEN {
            return Err(ConfigError::MaxDepth);
        }
        if !(self.gamma.is_finite() && self.gamma > 0.0 && self.gamma <= 1.0) {
            return Err(ConfigError::Gamma);
        }
        if !(self.alpha.is_finite() && self.alpha >= 0.0) {
            return Err(ConfigError::Alpha);
        }
        if !(self.beta.is_finite() && self.beta >= 0.0) {
            return Err(ConfigError::Beta);
        }
        if !(self.p_min.is_finite() && self.p_min >= 0.0 && self.p_min < 1.0) {
            return Err(ConfigError::PMin);
        }
        Ok(())
    }
}

/// The search settings a caller may set over a task's own (command-line flags, an
/// evaluation's settings): each `None` leaves the task's ([`SearchConfig::for_task`]).
/// [`SearchOverrides::resolve`] is the one place where "not given" becomes the task's value;
/// the call's seed and wall-clock budget are always given by the caller.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SearchOverrides {
    /// Particles per node (`k`; `None`: 16).
    pub k: Option<u16>,
    /// The search depth (`None`: the task's mode limit, screwdriver 7, card 5).
    pub max_depth: Option<u8>,
    /// Most node expansions per call (0: the planner's capacity; `None`: the task's,
    /// screwdriver [`SCREWDRIVER_NODE_BUDGET`], card 0).
    pub node_budget: Option<u32>,
    /// How `g` is formed (`None`: the task's, screwdriver cumulative, card last segment).
    pub cost_to_come: Option<CostToCome>,
    /// Particle or max-likelihood nodes (`None`: particles).
    pub variant: Option<SearchVariant>,
    /// Weight `α` of the terminal cost in the heuristic (`None`: the task's, screwdriver
    /// 1e4 as in the paper, card 1e5 as in the authors' code).
    pub alpha: Option<f32>,
    /// Weight `β` of the prior's negative log-likelihood in the heuristic (`None`: the
    /// task's, screwdriver 1e3 as in the paper, card 0 as in the authors' code).
    pub beta: Option<f32>,
}

impl SearchOverrides {
    /// The settings of one planning call for `task`: the task's own with every given
    /// override, the call's `seed` and its wall-clock budget `time_budget_ms` (0: none).
    pub fn resolve(&self, task: Task, seed: u64, time_budget_ms: u32) -> SearchConfig {
        let base = SearchConfig::for_task(task);
        SearchConfig {
            k: self.k.unwrap_or(base.k),
            max_depth: self.max_depth.unwrap_or(base.max_depth),
            node_budget: self.node_budget.unwrap_or(base.node_budget),
            time_budget_ms,
            seed,
            cost_to_come: self.cost_to_come.unwrap_or(base.cost_to_come),
            variant: self.variant.unwrap_or(base.variant),
            alpha: self.alpha.unwrap_or(base.alpha),
            beta: self.beta.unwrap_or(base.beta),
            ..base
        }
    }
}

/// The [`SearchConfig`] field that is out of range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ConfigError {
    /// `k` is zero.
    K,
    /// `max_depth` is zero or above [`MAX_PLAN_LEN`].
    MaxDepth,
    /// `gamma` is not in `(0, 1]`.
    Gamma,
    /// `alpha` is negative or not finite.
    Alpha,
    /// `beta` is negative or not finite.
    Beta,
    /// `p_min` is not in `[0, 1)`, or too large for the task's mode count (`p_min · modes > 1`).
    PMin,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ConfigError::K => "search config: k must be at least 1",
            ConfigError::MaxDepth => "search config: max_depth must be in 1..=16",
            ConfigError::Gamma => "search config: gamma must be in (0, 1]",
            ConfigError::Alpha => "search config: alpha must be finite and >= 0",
            ConfigError::Beta => "search config: beta must be finite and >= 0",
            ConfigError::PMin => "search config: p_min must be in [0, 1) with p_min*modes <= 1",
        })
    }
}

impl core::error::Error for ConfigError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_the_paper_and_valid() {
        let c = SearchConfig::default();
        assert_eq!((c.k, c.max_depth, c.time_budget_ms), (16, 7, 300_000));
        assert_eq!((c.gamma, c.alpha, c.beta, c.p_min), (0.9, 1e4, 1e3, 0.1));
        assert_eq!(c.validate(), Ok(()));
        assert_eq!(SearchConfig::card().validate(), Ok(()));
        assert_eq!(c.node_budget, 0, "the paper's: no node budget");
        let screwdriver = SearchConfig::for_task(Task::Screwdriver);
        assert_eq!(
            screwdriver,
            SearchConfig {
                node_budget: 13,
                ..c
            },
            "the paper's with the whole tree of three modes as its node budget"
        );
        assert_eq!(screwdriver.validate(), Ok(()));
        let card = SearchConfig::for_task(Task::Card);
        assert_eq!((card.alpha, card.beta, card.max_depth), (1e5, 0.0, 5));
        assert_eq!(card.node_budget, 0);
        assert_eq!(card.cost_to_come, CostToCome::LastSegment);
        assert_eq!(c.cost_to_come, CostToCome::Cumulative);
    }

    #[test]
    fn overrides_resolve_over_the_tasks_settings() {
        for task in Task::ALL {
            let own = SearchOverrides::default().resolve(task, 9, 300_000);
            assert_eq!(
                own,
                SearchConfig {
                    seed: 9,
                    ..SearchConfig::for_task(task)
                }
            );
        }
        let given = SearchOverrides {
            k: Some(4),
            max_depth: Some(3),
            node_budget: Some(0),
            cost_to_come: Some(CostToCome::Cumulative),
            variant: Some(SearchVariant::MaxLikelihood),
            alpha: None,
            beta: None,
        };
        let c = given.resolve(Task::Card, 1, 250);
        assert_eq!((c.k, c.max_depth, c.node_budget), (4, 3, 0));
        assert_eq!((c.time_budget_ms, c.seed), (250, 1));
        assert_eq!(c.cost_to_come, CostToCome::Cumulative);
        assert_eq!(c.variant, SearchVariant::MaxLikelihood);
        assert_eq!((c.alpha, c.beta), (1e5, 0.0), "the card's own weights stay");
        let paper = SearchOverrides {
            alpha: Some(1e4),
            beta: Some(1e3),
            ..given
        };
        let c = paper.resolve(Task::Card, 1, 250);
        assert_eq!(
            (c.alpha, c.beta),
            (1e4, 1e3),
            "the paper's weights for the card"
        );
    }

    #[test]
    fn names_round_trip() {
        use core::str::FromStr;
        use std::string::ToString;
        for c in CostToCome::ALL {
            assert_eq!(CostToCome::from_str(&c.to_string()), Ok(c));
        }
        let e = CostToCome::from_str("sum").unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown cost-to-come `sum` (expected cumulative or last-segment)"
        );
        for t in Task::ALL {
            assert_eq!(Task::from_str(&t.to_string()), Ok(t));
        }
        let e = Task::from_str("pen").unwrap_err().to_string();
        assert_eq!(e, "unknown task `pen` (expected screwdriver or card)");
    }

    #[test]
    fn each_bad_field_is_named() {
        let ok = SearchConfig::default();
        let cases = [
            (SearchConfig { k: 0, ..ok }, ConfigError::K),
            (SearchConfig { max_depth: 0, ..ok }, ConfigError::MaxDepth),
            (
                SearchConfig {
                    max_depth: 17,
                    ..ok
                },
                ConfigError::MaxDepth,
            ),
            (SearchConfig { gamma: 0.0, ..ok }, ConfigError::Gamma),
            (SearchConfig { gamma: 1.5, ..ok }, ConfigError::Gamma),
            (
                SearchConfig {
                    alpha: f32::NAN,
                    ..ok
                },
                ConfigError::Alpha,
            ),
            (SearchConfig { beta: -1.0, ..ok }, ConfigError::Beta),
            (SearchConfig { p_min: 1.0, ..ok }, ConfigError::PMin),
        ];
        for (c, e) in cases {
            assert_eq!(c.validate(), Err(e));
        }
    }
}
