//! The in-process planner's capacities, chosen at run time.
//!
//! The kernel's planner has its capacities in its type ([`dips_kernel::search::Planner`]).
//! [`PaperSession`] has the firmware's (`PaperPlanner`: 512 nodes, 256 open), which the
//! controller's memory budget sets. On the host that budget does not bind, and a search whose
//! heuristic runs breadth first (the card under the paper's α/β: each mode adds β·ln 4 ≈ 1 386
//! to `h`, `docs/search.md`) fills 256 open entries after 85 expansions, before it pops a node
//! deep enough to reach the goal. [`PlannerSize::Host`] gives it room for every node of depth
//! five over the card's four modes.

use dips_kernel::budget::Clock;
use dips_kernel::name::UnknownValue;
use dips_kernel::search::ParticleDiagnostics;
use dips_kernel::session::PlanSpec;
use serde::{Deserialize, Serialize};

use crate::{Models, PAPER_K, PaperSession, PlanCallError, PlanOutcome, PlanService, Session};

/// Nodes of [`HostSession`]'s planner: every node of depth ≤ 5 over 4 modes (1 365) and more.
pub const HOST_NODES: usize = 4096;

/// Open entries of [`HostSession`]'s planner: the 1 024 nodes of depth 5 over 4 modes and more.
pub const HOST_OPEN: usize = 2048;

/// A session with the host's capacities ([`PlannerSize::Host`]): k = 16, [`HOST_NODES`] nodes,
/// [`HOST_OPEN`] open entries, the paper's segment size.
pub type HostSession = Session<PAPER_K, HOST_NODES, HOST_OPEN, 481>;

/// The capacities of an in-process planning session.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PlannerSize {
    /// The firmware's `PaperPlanner` (512 nodes, 256 open): what the controller runs, and the
    /// default, so that a plan made on the host is the one the hand's controller makes.
    #[default]
    Paper,
    /// [`HostSession`]'s ([`HOST_NODES`] nodes, [`HOST_OPEN`] open; about 2.4 MB): a search
    /// ends at its goal, its budget or its time, not at its memory.
    Host,
}

impl PlannerSize {
    /// Both sizes, in `--planner-size` order.
    pub const ALL: [Self; 2] = [Self::Paper, Self::Host];

    /// Both sizes' names, in [`PlannerSize::ALL`] order.
    pub const NAMES: [&'static str; 2] = [Self::Paper.name(), Self::Host.name()];

    /// The name used by `--planner-size`, `eval.json` and protocols.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Host => "host",
        }
    }

    /// Whether this is the firmware's size (the default, left out of `eval.json`).
    pub fn is_paper(&self) -> bool {
        *self == Self::Paper
    }

    /// A session of this size over `models`.
    pub fn session(self, models: Models) -> SizedSession {
        match self {
            Self::Paper => SizedSession::Paper(PaperSession::new(models)),
            Self::Host => SizedSession::Host(HostSession::new(models)),
        }
    }
}

impl std::str::FromStr for PlannerSize {
    type Err = UnknownValue;

    /// A size by its name ([`PlannerSize::name`]); the error names the value and the sizes.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        UnknownValue::find("planner size", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl std::fmt::Display for PlannerSize {
    /// The size's name ([`PlannerSize::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A planning session of either size ([`PlannerSize::session`]).
#[derive(Debug)]
pub enum SizedSession {
    /// The firmware's capacities.
    Paper(PaperSession),
    /// The host's.
    Host(HostSession),
}

impl SizedSession {
    /// The models.
    pub fn models_mut(&mut self) -> &mut Models {
        match self {
            Self::Paper(s) => s.models_mut(),
            Self::Host(s) => s.models_mut(),
        }
    }
}

impl PlanService for SizedSession {
    fn plan_call(
        &mut self,
        spec: &PlanSpec,
        clock: &mut dyn Clock,
    ) -> Result<PlanOutcome, PlanCallError> {
        match self {
            Self::Paper(s) => s.plan_call(spec, clock),
            Self::Host(s) => s.plan_call(spec, clock),
        }
    }

    fn location(&self) -> String {
        match self {
            Self::Paper(s) => s.location(),
            Self::Host(s) => s.location(),
        }
    }

    fn last_diagnostics(&self) -> Option<ParticleDiagnostics> {
        match self {
            Self::Paper(s) => s.last_diagnostics(),
            Self::Host(s) => s.last_diagnostics(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_by_name_and_the_host_planner_holds_depth_five_of_the_card() {
        for size in PlannerSize::ALL {
            assert_eq!(size.name().parse::<PlannerSize>(), Ok(size));
        }
        let e = "big".parse::<PlannerSize>().unwrap_err().to_string();
        assert!(e.contains("paper") && e.contains("host"), "{e}");
        // Every node of depth ≤ 5 over 4 modes, and the 4^5 of depth 5 open at once.
        assert!(HOST_NODES >= (0..=5).map(|d| 4usize.pow(d)).sum::<usize>());
        assert!(HOST_OPEN >= 4usize.pow(5));
    }
}
