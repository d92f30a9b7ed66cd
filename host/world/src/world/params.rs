//! The world's physical and numerical parameters, checked by [`super::WorldParams::validate`].

use super::WorldError;
use serde::{Deserialize, Serialize};

use crate::scenes::{GRAVITY, SceneKind, card, screwdriver};

/// Physical and numerical parameters of the world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorldParams {
    /// Duration of one action (s); Isaac holds each target for 1 s.
    pub action_duration: f64,
    /// Sub-steps per action (`h = action_duration / substeps`).
    pub substeps: usize,
    /// Joint stiffness of the task fingers (N·m/rad).
    pub kp: f64,
    /// Joint damping of the task fingers (N·m·s/rad). It enters as `D/h` on the joint
    /// diagonal, so a free finger closes `kp/(kp + D/h)` of its remaining error per sub-step:
    /// a first-order lag with time constant `D/kp`. Default 0 (spec §1.2: stiff impedance, a
    /// free finger reaches its command, as CSVTO's free-motion model assumes); Isaac's PD
    /// drive uses 1.0, which leaves ≈ 7 % of a screwdriver command (kp = 3) unreached after 1 s.
    pub joint_damping: f64,
    /// Mass-regularisation scale `s`: the largest object mass entry becomes `kp/s` (qsim's
    /// `unactuated_mass_scale`).
    pub mass_scale: f64,
    /// Contacts with signed distance up to this are candidates of the contact step (m).
    pub contact_margin: f64,
    /// Which candidates get friction under [`super::FrictionModel::Anitescu`] ([`ConeActivation::All`]
    /// for logs written before this field existed).
    #[serde(default = "legacy_cone_activation")]
    pub cone_activation: ConeActivation,
    /// How the joint controller's setpoint moves during an action ([`CommandProfile::Step`]
    /// for logs written before this field existed).
    #[serde(default = "legacy_command_profile")]
    pub command_profile: CommandProfile,
    /// With [`CommandProfile::Ramp`], the fraction of the action over which the setpoint
    /// moves; it holds the command for the rest (in whole sub-steps: the ramp ends at sub-step
    /// `ceil(ramp_fraction · substeps)`). A finger that slides while pressing ends each
    /// Anitescu sub-step lifted by μ·slip; the settling sub-steps bring it back onto the
    /// surface before the action ends. In (0, 1].
    #[serde(default = "full_ramp")]
    pub ramp_fraction: f64,
    /// Finger–object friction coefficient.
    pub finger_friction: f64,
    /// Card–table friction coefficient (card scene).
    pub table_friction: f64,
    /// Finger–table friction coefficient (card scene).
    pub finger_table_friction: f64,
    /// Object damping: screwdriver roll/pitch/yaw, or the card's value on all six coordinates.
    pub damping: [f64; 3],
    /// Stop the sub-steps once the increment norm falls below this.
    pub early_stop: f64,
    /// Gravity (m/s²).
    pub gravity: f64,
    /// Keep the task joints within their limits with linear constraints.
    pub enforce_joint_limits: bool,
    /// Clarabel's interior-point iteration limit per solve.
    pub solver_max_iter: u32,
    /// How friction is formulated.
    pub friction_model: FrictionModel,
    /// Most solves per sub-step for [`super::FrictionModel::Staggered`].
    pub staggered_iterations: usize,
    /// Staggered iterations stop when no normal force changes by more than
    /// `staggered_tolerance + staggered_relative_tolerance · max normal force` (N).
    pub staggered_tolerance: f64,
    /// Relative part of the staggered stopping rule.
    pub staggered_relative_tolerance: f64,
    /// Staggered iterations also require the linearised signed distances to match the true
    /// ones at the solution to within this (m).
    pub geometry_tolerance: f64,
    /// When staggered iterations do not settle, solve that sub-step with the Anitescu cone
    /// (flagged `friction_fallback`) instead of applying the last iterate (flagged
    /// `friction_not_converged`). Off by default: on the card the cone's drag is worse than
    /// an unsettled iterate (CSVTO's single-finger pushes lose their centimetre with it).
    pub staggered_fallback: bool,
}

fn legacy_cone_activation() -> ConeActivation {
    ConeActivation::All
}

fn full_ramp() -> f64 {
    1.0
}

fn legacy_command_profile() -> CommandProfile {
    CommandProfile::Step
}

/// Which contact candidates get a friction cone under [`super::FrictionModel::Anitescu`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConeActivation {
    /// Every candidate within [`super::WorldParams::contact_margin`] (the plain Anitescu model). A
    /// candidate that slides must separate by μ·slip, so a finger gliding past the object
    /// without pressing drags it along (`docs/world.md`).
    All,
    /// Only candidates that press: each sub-step is first solved with frictionless
    /// non-penetration rows, and the candidates that carry a normal force there, or carried
    /// one at the end of the previous sub-step, get the cone in the solve that is applied;
    /// the others keep their frictionless row. A finger that does not press cannot push the
    /// object sideways. Two solves per sub-step where some candidate presses, one where none
    /// does.
    Pressing,
}

/// How the task fingers' setpoint moves within one action.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CommandProfile {
    /// The setpoint moves linearly from the joints measured at the start of the action to the
    /// command, reaching it at the last sub-step, as a position controller tracks an
    /// interpolated target. A free finger still ends the action at its command.
    Ramp,
    /// The setpoint jumps to the command at the first sub-step (a step input): a free finger
    /// makes its whole move in the first sub-step.
    Step,
}

/// Friction formulation of the contact step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrictionModel {
    /// One Anitescu cone per contact (spec §1.2, qsim's SOCP). Convex and one solve per
    /// sub-step, but sliding forces a separation of μ·slip: a finger dragged across a light
    /// object without pressing drags the object along (measured in `docs/world.md`).
    Anitescu,
    /// Non-penetration rows plus maximum-dissipation friction bounded by μ times a normal
    /// force estimate, re-solved with the new normal forces until they agree (staggered
    /// projections, warm-started from the previous sub-step), with the contact geometry
    /// re-linearised at each iterate. No hover; a few solves per sub-step. Converges for
    /// moderate μ; where it does not, the step is flagged.
    Staggered,
}

impl WorldParams {
    /// Defaults for a scene (spec §3 and §4).
    pub fn for_scene(scene: SceneKind) -> WorldParams {
        // Friction: the card (μ ≤ 1, a 10 g object) needs the hover-free staggered form, or a
        // grazing finger drags it; the screwdriver (μ = 2.5) uses the single convex Anitescu
        // cone, because staggered iterations can diverge there (wedging: more friction needs
        // more normal force). See docs/world.md.
        let (damping, table, friction_model) = match scene {
            SceneKind::Screwdriver => (screwdriver::DAMPING, 0.0, FrictionModel::Anitescu),
            SceneKind::Card => (
                [card::DAMPING; 3],
                card::TABLE_FRICTION,
                FrictionModel::Staggered,
            ),
        };
        WorldParams {
            action_duration: 1.0,
            substeps: 10,
            kp: scene.kp(),
            joint_damping: 0.0,
            mass_scale: 5.0,
            contact_margin: 0.02,
            cone_activation: ConeActivation::Pressing,
            command_profile: CommandProfile::Ramp,
            ramp_fraction: 0.8,
            finger_friction: scene.finger_friction(),
            table_friction: table,
            finger_table_friction: card::FINGER_TABLE_FRICTION,
            damping,
            early_stop: 1e-6,
            gravity: GRAVITY,
            enforce_joint_limits: true,
            solver_max_iter: 100,
            friction_model,
            staggered_iterations: 12,
            staggered_tolerance: 1e-3,
            staggered_relative_tolerance: 0.02,
            geometry_tolerance: 2e-5,
            staggered_fallback: false,
        }
    }

    /// Sub-steps over which a ramped setpoint moves (at least 1, at most `substeps`).
    pub fn ramp_substeps(&self) -> usize {
        ((self.ramp_fraction * self.substeps as f64).ceil() as usize).clamp(1, self.substeps)
    }

    /// Sub-step length (s).
    pub fn h(&self) -> f64 {
        self.action_duration / self.substeps as f64
    }

    /// Check that every parameter is usable: positive durations, counts and stiffness,
    /// non-negative margins, damping and friction, finite numbers.
    pub fn validate(&self) -> Result<(), WorldError> {
        let bad = |name: &'static str, value: f64, allowed: &'static str| {
            Err(WorldError::Params {
                name,
                value,
                allowed,
            })
        };
        let positive = [
            ("action_duration", self.action_duration),
            ("kp", self.kp),
            ("early_stop", self.early_stop),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, v, "a finite number > 0");
            }
        }
        let non_negative = [
            ("joint_damping", self.joint_damping),
            ("contact_margin", self.contact_margin),
            ("finger_friction", self.finger_friction),
            ("table_friction", self.table_friction),
            ("finger_table_friction", self.finger_table_friction),
            ("damping[0]", self.damping[0]),
            ("damping[1]", self.damping[1]),
            ("damping[2]", self.damping[2]),
            ("gravity", self.gravity),
            ("staggered_tolerance", self.staggered_tolerance),
            (
                "staggered_relative_tolerance",
                self.staggered_relative_tolerance,
            ),
            ("geometry_tolerance", self.geometry_tolerance),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, v, "a finite number ≥ 0");
            }
        }
        // The Anitescu cone divides by μ.
        if self.finger_friction == 0.0 {
            return bad("finger_friction", 0.0, "a finite number > 0");
        }
        // `mass_scale` ≤ 0 means "true mass" (see `regulariser`); only NaN is meaningless.
        if self.mass_scale.is_nan() {
            return bad("mass_scale", self.mass_scale, "a number (≤ 0: true mass)");
        }
        let counts = [
            ("substeps", self.substeps),
            ("staggered_iterations", self.staggered_iterations),
            ("solver_max_iter", self.solver_max_iter as usize),
        ];
        for (name, v) in counts {
            if v == 0 {
                return bad(name, 0.0, "a whole number ≥ 1");
            }
        }
        if !(self.ramp_fraction > 0.0 && self.ramp_fraction <= 1.0) {
            return bad("ramp_fraction", self.ramp_fraction, "a number in (0, 1]");
        }
        Ok(())
    }
}
