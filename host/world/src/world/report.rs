//! What a step reports: flags that did not stop it, the step report, and the errors that did.

use super::ContactReport;
use serde::{Deserialize, Serialize};

/// Something noteworthy about a step that did not stop it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StepFlag {
    /// Clarabel returned `AlmostSolved` (reduced accuracy) at this sub-step; the step was applied.
    ReducedAccuracy {
        /// Sub-step index within the action.
        substep: usize,
    },
    /// The screwdriver's roll or pitch passed its ±1.57 joint limit (not modelled as a stop).
    TiltLimit,
    /// Staggered friction iterations hit their limit before the normal forces (and the
    /// re-linearised geometry) settled; the last iterate was applied.
    FrictionNotConverged {
        /// Sub-step index within the action.
        substep: usize,
        /// Largest remaining normal-force change (N) or signed-distance mismatch (m).
        change: f64,
    },
    /// Staggered friction did not settle and this sub-step used the Anitescu cone instead
    /// ([`super::WorldParams::staggered_fallback`]).
    FrictionFallback {
        /// Sub-step index within the action.
        substep: usize,
        /// Largest remaining normal-force change (N) or signed-distance mismatch (m).
        change: f64,
    },
}

/// What one action did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepReport {
    /// Sub-steps solved (fewer than `substeps` when stopped early).
    pub substeps_run: usize,
    /// Contacts of the last solved sub-step with their forces.
    pub contacts: Vec<ContactReport>,
    /// Deepest penetration among fingertip/object/table pairs after the action (m, ≥ 0).
    pub max_penetration: f64,
    /// Interior-point iterations summed over all solves.
    pub iterations: u32,
    /// Clarabel solves (more than one per sub-step with staggered friction).
    pub solves: u32,
    /// Warnings that did not stop the step.
    pub flags: Vec<StepFlag>,
}

/// Errors from the world.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// The action has the wrong length for the scene.
    #[error("action has {got} numbers but the {scene} task needs {expected}")]
    ActionLength {
        /// Scene name.
        scene: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// A state row has the wrong length for the scene.
    #[error("state has {got} numbers but the {scene} task needs {expected}")]
    StateLength {
        /// Scene name.
        scene: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// A number in an action, target or state is NaN or infinite.
    #[error("{what} entry {index} is not finite ({value})")]
    NonFinite {
        /// Which input.
        what: &'static str,
        /// Index in it.
        index: usize,
        /// The value.
        value: f64,
    },
    /// Clarabel did not solve a sub-step; the world is left as it was before the action.
    #[error("contact solve failed at sub-step {substep}: Clarabel status {status}")]
    Solver {
        /// Sub-step index within the action.
        substep: usize,
        /// Clarabel's status.
        status: String,
    },
    /// A world parameter is out of range.
    #[error("world parameter {name} = {value} is not allowed: it must be {allowed}")]
    Params {
        /// Parameter name (a [`super::WorldParams`] field).
        name: &'static str,
        /// The given value.
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
    /// Clarabel rejected the problem data (a defect in the world).
    #[error("contact program rejected by Clarabel: {0}")]
    Setup(String),
}
