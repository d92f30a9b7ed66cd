//! The multi-finger contact trajectory-optimisation problem (spec `algorithms.md` §2), for
//! both tasks and every contact mode, as a CSVTO [`Problem`].
//!
//! Row `t` (0-based) is `[q_{t+1} (4·nf), o_{t+1} (3), Δq_t (4·nf), f_t (3 per contact
//! finger), f_env (3, card only)]`, so the state is the first `4·nf + 3` entries. The object
//! pose `o` is (roll, pitch, yaw) about the pivot for the screwdriver and (x, y, θ) for the
//! card; yaw is an angle here (the `(cos, sin)` form is only for learning).
//!
//! Constraints of step `t` (between `s_t` and `s_{t+1}`):
//! - contact finger: `sdf(s_{t+1}) = 0`; rolling (no slip of the contact point, 2 rows, at
//!   `s_t`); joint impedance balance `−J_cᵀf + K_p(q_t + Δq_t − q_{t+1}) = 0` (4 rows, at
//!   `s_{t+1}`); friction pyramid `k = 8` on `f` in the contact frame at `s_{t+1}` and a
//!   minimum normal force;
//! - object: screwdriver torques about the pivot with gravity (3 rows); card force balance
//!   with the table force and its sliding friction `‖f_env,xy‖ = μ_table f_env,z` (4 rows);
//!   with no finger in contact the object holds still (and the card's table force carries
//!   its weight); in the screwdriver's regrasp modes all or part of its pose is
//!   pinned as well ([`pinned_object_coords`]);
//! - regrasping finger: free motion `q_{t+1} = q_t + Δq_t` (4 rows), clearance
//!   `sdf ≥ δ = 0.015` before the last step, to the object both where the step leaves it and
//!   where it found it (2 rows), and `sdf = 0` at the last; a screwdriver finger that starts
//!   in contact lifts off along the normal in the first step ([`LIFT_OFF_CONTACT`]).
//!
//! All Jacobians are exact (forward-mode [`Dual`](crate::problems::dual::Dual) numbers through kinematics and geometry).

//! The module is split along the problem's seams: `geometry` (fingertips against the
//! object, with exact derivatives), [`rows`] (which constraint rows a step has, counted once:
//! [`StepRows`]), `constraints` (filling them) and `cost` (the cost `J` with the kernel's
//! named weights).

// Index loops over small fixed-size arrays mirror the maths (rows, joints, faces).
#![allow(clippy::needless_range_loop)]

use std::f64::consts::PI;

mod constraints;
mod cost;
mod geometry;
pub mod rows;

use super::fk::FingerChain;
use super::mode::Mode;
use cost::Weights;
use dips_csvto::{Problem, StepConstraints};
use dips_kernel::task::CostWeights;
use dips_world::kinematics::HandModel;
use dips_world::scenes::{self, SceneKind};
pub use rows::StepRows;

/// Regrasp clearance δ (m). A regrasping finger keeps it at every step before the last, to
/// the object both at the end of the step (`sdf(q_{t+1}, o_{t+1})`, the spec's row) and at its
/// start (`sdf(q_{t+1}, o_t)`): the world's object ends a step somewhere between where it was
/// and where the plan moves it (it follows planned tilts only in part), so clearing both poses
/// is what keeps the *executed* clearance at δ. Measured over 10 seeds of
/// `thumb-middle-regrasp` with the yaw pinned: lowest executed clearance 1.38 cm with the end
/// pose alone, 1.48 cm with both, 1.59 cm with both and [`CLEARANCE_MARGIN`].
pub const REGRASP_CLEARANCE: f64 = 0.015;
/// Extra clearance the planner keeps above [`REGRASP_CLEARANCE`] (m), for the world's
/// tracking error of the lifted fingers and the held object (measured: up to 0.5 mm).
pub const CLEARANCE_MARGIN: f64 = 0.001;
/// Friction coefficient used by the planner (spec §1.6).
pub const PLANNER_FRICTION: f64 = 0.95;
/// Number of friction-pyramid faces.
pub const PYRAMID_FACES: usize = 8;
/// Smallest normal force of a contact finger (N). Without it a finger's force can reach the
/// pyramid's apex, where all faces are active and, with squared slacks, pin the force in
/// the tangent space (the card then cannot be pushed); MFTO uses 0.1 N for its fingers.
pub const MIN_NORMAL_FORCE: f64 = 0.05;
/// Unit of the card's x and y inside the problem (m per variable unit). States given to and
/// taken from the problem are always in metres ([`AllegroProblem::to_problem_units`],
/// [`AllegroProblem::to_world_units`]). Centimetres (0.01) make the card cheap to move in
/// the projector's Euclidean metric, but measured in the world the pushes then moved the
/// card less (4 mm instead of 15 mm per single-finger mode), so metres it is.
pub const CARD_POS_UNIT: f64 = 1.0;
/// Unit of the card's heading θ inside the problem (rad per variable unit). With one or two
/// fingers on the card its rotation is nearly free kinematically and, in radians, the
/// cheapest way (in the projector's and Gauss–Newton step's Euclidean metric) to absorb any
/// finger–card mismatch: plans zig-zag in θ by ±0.03 rad from step to step, the world does not
/// follow, and the card advances only every other step. Measured per seed-0 single-finger
/// push: 0.8 cm (1 rad), 1.6 cm (0.1), 0.9 cm (0.02); three `both` modes 3.0 → 5.8 cm.
/// (Those figures were taken while the geometry still read the scaled heading as radians,
/// i.e. modelled ten times the card's real rotation; that bug is fixed and tested
/// (`planner_geometry_matches_the_world_at_moved_object_poses`), and the unit kept: with it
/// the 10-seed card figures stayed above the thresholds, see `docs/csvto.md` §4.)
pub const CARD_THETA_UNIT: f64 = 0.1;
/// Joint-limit margin for the planner's bounds.
pub const JOINT_MARGIN: f64 = 0.05;
/// Force bound per component (N).
pub const FORCE_BOUND: f64 = 10.0;
/// Largest joint command per step before the torque limit (`π/5`).
pub const DQ_BOUND: f64 = PI / 5.0;
/// Torque limit used to bound `Δq` by `τ_max / K_p`.
pub const TORQUE_LIMIT: f64 = 1.0;

/// Where a problem starts and what it aims for.
#[derive(Debug, Clone, PartialEq)]
pub struct ProblemSpec {
    /// The task.
    pub task: SceneKind,
    /// The contact mode.
    pub mode: Mode,
    /// Number of rows `H`.
    pub horizon: usize,
    /// Start state `[q (4·nf), o (3)]`.
    pub start: Vec<f64>,
    /// Object goal `o*` for the goal cost.
    pub goal: [f64; 3],
}

/// A problem specification that cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProblemError {
    /// The mode belongs to another task.
    #[error("contact mode `{mode}` is not a mode of the {task} task")]
    ModeTask {
        /// Mode name.
        mode: &'static str,
        /// Task name.
        task: &'static str,
    },
    /// The start state has the wrong length.
    #[error("start state has {got} values, the {task} task needs {expected}")]
    StartLength {
        /// Task name.
        task: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// The horizon is zero.
    #[error("the horizon must be at least one step")]
    ZeroHorizon,
    /// A start or goal value is NaN or infinite.
    #[error("{what} value {index} is not finite")]
    NotFinite {
        /// `start` or `goal`.
        what: &'static str,
        /// Index in it.
        index: usize,
    },
}

/// The multi-finger contact problem.
#[derive(Debug, Clone)]
pub struct AllegroProblem {
    task: SceneKind,
    contact: Vec<bool>,
    nf: usize,
    nc: usize,
    /// Slot of each finger among the contact fingers.
    slot: Vec<Option<usize>>,
    chains: Vec<FingerChain>,
    radius: f64,
    kp: f64,
    horizon: usize,
    start: Vec<f64>,
    goal: [f64; 3],
    /// Regrasp targets: object frame with yaw zeroed (screwdriver) or world (card).
    targets: Vec<[f64; 3]>,
    /// Per-row-entry box bounds.
    lower: Vec<f64>,
    upper: Vec<f64>,
    /// Joint limits per task joint (without margin), for the `q + Δq` clamp.
    joint_lo: Vec<f64>,
    joint_hi: Vec<f64>,
    dq_bound: f64,
    /// Smallest normal force of a contact finger (N; [`MIN_NORMAL_FORCE`] unless
    /// [`AllegroProblem::with_min_normal_force`] set it).
    min_normal_force: f64,
    /// The task's cost weights (the kernel's [`CostWeights`], in `f64`).
    weights: Weights,
    /// Goal weights (terminal, running) of this mode.
    goal_weights: (f64, f64),
    /// Metres (or radians) per problem unit of each object coordinate.
    units: [f64; 3],
    /// How many object coordinates (the last of roll, pitch, yaw) are pinned, one more row
    /// per step each (see [`pinned_object_coords`]).
    pinned: usize,
    /// Regrasping fingers that start in contact (sdf below [`LIFT_OFF_CONTACT`]): their first
    /// step leaves the surface along the normal (two rolling rows at `t = 0`).
    lift_off: Vec<bool>,
}

/// A screwdriver regrasping finger whose start sdf is below this (m) is in contact and lifts
/// off along the normal in the first step: its contact point moves only along the normal
/// relative to the object (the rolling rows of a contact finger, at `t = 0`).
///
/// Without it the first step moved the lifting thumb and middle toward their targets while
/// they still touched the handle, and friction dragged the screwdriver with them: measured
/// over the ten 7-mode episodes, `thumb-middle-regrasp` changed the yaw by −0.11 … +0.25 rad
/// (median |·| 0.035); with it −0.07 … +0.07 (0.026), and the lowest executed regrasp
/// clearance rose from 1.46 to 1.54 cm. For the card's regrasping finger it made pushes
/// worse (one `index` push 0.17 cm), so the card does not use it.
pub const LIFT_OFF_CONTACT: f64 = 0.002;

/// How many of the object's coordinates a mode's problem pins (`o_{t+1,k} = o_{t,k}` at
/// every step, for the last `n` of (roll, pitch, yaw)) on top of its wrench balance: the
/// screwdriver's regrasp modes, whose goal is to hold it. `index-regrasp` pins all three;
/// `thumb-middle-regrasp` pins the yaw only.
///
/// Without pins the plans move the held screwdriver freely, and the world does not follow.
/// With the index finger alone on the cap (`thumb-middle-regrasp`) the yaw is unobservable
/// to the constraints (the contact sits on the axis): measured over 10 seeds, the plans swung
/// it by up to ±0.5 rad from step to step, and the lifted thumb and middle came as close as
/// 1.08 cm to the handle (δ = 1.5 cm). With thumb and middle holding the handle
/// (`index-regrasp`), planned tilts of 0.03–0.04 rad per step made the world's screwdriver
/// slip back by up to 0.19 rad of yaw. Roll and pitch stay free under the index alone:
/// pinning them there as well (tried) leaves a tilted screwdriver to fall under the one
/// finger, because the plan can no longer steer it upright (two of ten 7-mode episodes went
/// invalid).
pub fn pinned_object_coords(task: SceneKind, mode: Mode) -> usize {
    match (task, mode) {
        (SceneKind::Screwdriver, Mode::IndexRegrasp) => 3,
        (SceneKind::Screwdriver, Mode::ThumbMiddleRegrasp) => 1,
        _ => 0,
    }
}
impl AllegroProblem {
    /// Build the problem for `spec` with the hand `hand`.
    pub fn new(hand: &HandModel, spec: &ProblemSpec) -> Result<Self, ProblemError> {
        let task = spec.task;
        let fingers = task.task_fingers();
        let nf = fingers.len();
        let contact: Vec<bool> = (0..nf).map(|i| spec.mode.in_contact(i)).collect();
        if spec.mode.task() != task {
            return Err(ProblemError::ModeTask {
                mode: spec.mode.name(),
                task: task.name(),
            });
        }
        if spec.start.len() != 4 * nf + 3 {
            return Err(ProblemError::StartLength {
                task: task.name(),
                expected: 4 * nf + 3,
                got: spec.start.len(),
            });
        }
        if spec.horizon == 0 {
            return Err(ProblemError::ZeroHorizon);
        }
        if let Some(index) = spec.start.iter().position(|v| !v.is_finite()) {
            return Err(ProblemError::NotFinite {
                what: "start",
                index,
            });
        }
        if let Some(index) = spec.goal.iter().position(|v| !v.is_finite()) {
            return Err(ProblemError::NotFinite {
                what: "goal",
                index,
            });
        }
        let mut slot = Vec::with_capacity(nf);
        let mut nc = 0;
        for &c in &contact {
            slot.push(if c {
                nc += 1;
                Some(nc - 1)
            } else {
                None
            });
        }
        let base = task.hand_base();
        let chains: Vec<FingerChain> = fingers
            .iter()
            .map(|&f| FingerChain::new(hand, &base, f))
            .collect();
        let default = task.default_joints();
        let targets = fingers
            .iter()
            .zip(&chains)
            .map(|(&f, ch)| {
                let c = ch.tip(&default[f.index()]).val();
                match task {
                    SceneKind::Screwdriver => {
                        let p = scenes::screwdriver::PIVOT;
                        [c[0] - p[0], c[1] - p[1], c[2] - p[2]]
                    }
                    SceneKind::Card => c,
                }
            })
            .collect();
        let kp = task.kp();
        let dq_bound = DQ_BOUND.min(TORQUE_LIMIT / kp);
        let mut joint_lo = Vec::new();
        let mut joint_hi = Vec::new();
        for ch in &chains {
            for &(lo, hi) in &ch.limits {
                joint_lo.push(lo);
                joint_hi.push(hi);
            }
        }
        let n = 8 * nf + 3 + 3 * nc + if task == SceneKind::Card { 3 } else { 0 };
        let mut lower = vec![0.0; n];
        let mut upper = vec![0.0; n];
        for j in 0..4 * nf {
            lower[j] = joint_lo[j] - JOINT_MARGIN;
            upper[j] = joint_hi[j] + JOINT_MARGIN;
            lower[4 * nf + 3 + j] = -dq_bound;
            upper[4 * nf + 3 + j] = dq_bound;
        }
        let obj_bound = match task {
            SceneKind::Screwdriver => [10.0 * PI; 3],
            SceneKind::Card => [1.0 / CARD_POS_UNIT, 1.0 / CARD_POS_UNIT, 10.0 * PI],
        };
        for k in 0..3 {
            lower[4 * nf + k] = -obj_bound[k];
            upper[4 * nf + k] = obj_bound[k];
        }
        for j in 8 * nf + 3..n {
            lower[j] = -FORCE_BOUND;
            upper[j] = FORCE_BOUND;
        }
        let (terminal, running) = CostWeights::of(task.task()).goal_weights(nc > 0);
        let goal_weights = (f64::from(terminal), f64::from(running));
        let units = match task {
            SceneKind::Screwdriver => [1.0; 3],
            SceneKind::Card => [CARD_POS_UNIT, CARD_POS_UNIT, CARD_THETA_UNIT],
        };
        let mut start = spec.start.clone();
        let mut goal = spec.goal;
        for k in 0..3 {
            start[4 * nf + k] /= units[k];
            goal[k] /= units[k];
        }
        Ok(Self {
            task,
            contact,
            nf,
            nc,
            slot,
            chains,
            radius: hand.tip_radius,
            kp,
            horizon: spec.horizon,
            start,
            goal,
            units,
            targets,
            lower,
            upper,
            joint_lo,
            joint_hi,
            dq_bound,
            min_normal_force: MIN_NORMAL_FORCE,
            weights: Weights::of(task),
            goal_weights,
            pinned: pinned_object_coords(task, spec.mode),
            lift_off: vec![false; nf],
        }
        .with_lift_off())
    }

    /// Flag the regrasping fingers that start in contact (screwdriver only).
    fn with_lift_off(mut self) -> Self {
        if self.task != SceneKind::Screwdriver {
            return self;
        }
        let nq = 4 * self.nf;
        let o = [self.start[nq], self.start[nq + 1], self.start[nq + 2]];
        for i in 0..self.nf {
            if self.slot[i].is_none() {
                let q = [
                    self.start[4 * i],
                    self.start[4 * i + 1],
                    self.start[4 * i + 2],
                    self.start[4 * i + 3],
                ];
                self.lift_off[i] = self.contact(i, &q, &o).sdf < LIFT_OFF_CONTACT;
            }
        }
        self
    }

    /// The task.
    pub fn task(&self) -> SceneKind {
        self.task
    }

    /// Number of task fingers.
    pub fn fingers(&self) -> usize {
        self.nf
    }

    /// Number of contact fingers.
    pub fn contact_fingers(&self) -> usize {
        self.nc
    }

    /// Whether finger `i` is in contact in this mode.
    pub fn in_contact(&self, i: usize) -> bool {
        self.contact[i]
    }

    /// Column of `Δq` of finger `i`, joint `k` in a row.
    pub fn dq_col(&self, i: usize, k: usize) -> usize {
        4 * self.nf + 3 + 4 * i + k
    }

    /// Column of the force of contact slot `s`, component `k`.
    pub fn force_col(&self, s: usize, k: usize) -> usize {
        8 * self.nf + 3 + 3 * s + k
    }

    /// Column of the card's table force component `k`.
    pub fn env_col(&self, k: usize) -> usize {
        8 * self.nf + 3 + 3 * self.nc + k
    }

    /// Whether the rows carry a table force.
    pub fn has_env_force(&self) -> bool {
        self.task == SceneKind::Card
    }

    /// The joint-position bound used for `Δq`.
    pub fn dq_bound(&self) -> f64 {
        self.dq_bound
    }
    /// A state `[q, o]` in metres and radians converted to problem units.
    pub fn to_problem_units(&self, state: &[f64]) -> Vec<f64> {
        let mut s = state.to_vec();
        let nq = 4 * self.nf;
        for k in 0..3 {
            s[nq + k] /= self.units[k];
        }
        s
    }

    /// A state `[q, o]` in problem units converted to metres and radians.
    pub fn to_world_units(&self, state: &[f64]) -> Vec<f64> {
        let mut s = state.to_vec();
        let nq = 4 * self.nf;
        for k in 0..3 {
            s[nq + k] *= self.units[k];
        }
        s
    }

    /// Outward object normal at finger `i`'s contact at `(q, o)` (world frame; `o` in metres).
    pub fn contact_normal(&self, i: usize, q: &[f64; 4], o: &[f64; 3]) -> [f64; 3] {
        self.contact(i, q, &self.obj_units(o)).normal.0
    }

    /// Index of task finger `i` among the contact fingers, if it is in contact.
    pub fn contact_slot(&self, i: usize) -> Option<usize> {
        self.slot[i]
    }

    /// The same problem with each contact finger pressing with at least `newtons` (N) instead
    /// of [`MIN_NORMAL_FORCE`]: the `--press firm` execution setting
    /// ([`Press`](crate::press::Press)).
    pub fn with_min_normal_force(mut self, newtons: f64) -> Self {
        self.min_normal_force = newtons;
        self
    }

    /// The smallest normal force of a contact finger (N).
    pub fn min_normal_force(&self) -> f64 {
        self.min_normal_force
    }

    /// Finger `i`'s four joint angles (rad) in a state `[q (4·nf), o (3)]`.
    pub fn finger_joints(state: &[f64], i: usize) -> [f64; 4] {
        std::array::from_fn(|k| state[4 * i + k])
    }

    /// The object's pose (metres and radians) in a state `[q (4·nf), o (3)]`.
    pub fn object_pose(&self, state: &[f64]) -> [f64; 3] {
        std::array::from_fn(|k| state[4 * self.nf + k])
    }

    /// Each finger's signed distance (m) at a state `[q (4·nf), o (3)]`, in task-finger order;
    /// negative is penetration.
    pub fn finger_sdfs(&self, state: &[f64]) -> Vec<f64> {
        let o = self.object_pose(state);
        (0..self.nf)
            .map(|i| self.finger_sdf(i, &Self::finger_joints(state, i), &o))
            .collect()
    }

    /// Signed distance of finger `i`'s sphere at `(q, o)` (`o` in metres and radians).
    pub fn finger_sdf(&self, i: usize, q: &[f64; 4], o: &[f64; 3]) -> f64 {
        self.contact(i, q, &self.obj_units(o)).sdf
    }

    /// [`Self::finger_sdf`] with its exact derivatives: `(sdf, ∂sdf/∂q, ∂sdf/∂o)`, the object's
    /// per metre or radian (`o` in metres and radians).
    pub fn finger_sdf_gradient(
        &self,
        i: usize,
        q: &[f64; 4],
        o: &[f64; 3],
    ) -> (f64, [f64; 4], [f64; 3]) {
        let (sdf, _) = self.regrasp_sdf(i, q, &self.obj_units(o), 0, 4);
        let dq = std::array::from_fn(|k| sdf.d[k]);
        let d_o = std::array::from_fn(|k| sdf.d[4 + k] / self.units[k]);
        (sdf.v, dq, d_o)
    }

    fn obj_units(&self, o: &[f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| o[k] / self.units[k])
    }
}

impl Problem for AllegroProblem {
    fn horizon(&self) -> usize {
        self.horizon
    }

    fn row_dim(&self) -> usize {
        self.lower.len()
    }

    fn state_dim(&self) -> usize {
        4 * self.nf + 3
    }

    fn start_state(&self) -> &[f64] {
        &self.start
    }

    fn n_eq(&self, t: usize) -> usize {
        self.step_rows(t).eq
    }

    fn n_ineq(&self, t: usize) -> usize {
        self.step_rows(t).ineq
    }

    fn step_constraints(&self, t: usize, prev: &[f64], row: &[f64], out: &mut StepConstraints) {
        self.fill_step(t, prev, row, out);
    }

    fn cost(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        self.cost_and_gradient(x, grad)
    }

    fn clamp(&self, x: &mut [f64]) {
        let n = self.row_dim();
        let nq = 4 * self.nf;
        for t in 0..self.horizon {
            let (before, rest) = x.split_at_mut(t * n);
            let prev_q: &[f64] = if t == 0 {
                &self.start[..nq]
            } else {
                &before[(t - 1) * n..(t - 1) * n + nq]
            };
            let row = &mut rest[..n];
            for c in 0..n {
                row[c] = row[c].clamp(self.lower[c], self.upper[c]);
            }
            // q_t + Δq_t stays within the joint limits.
            for k in 0..nq {
                let lo = self.joint_lo[k] - prev_q[k];
                let hi = self.joint_hi[k] - prev_q[k];
                let c = nq + 3 + k;
                let (a, b) = (lo.max(-self.dq_bound), hi.min(self.dq_bound));
                row[c] = if a <= b {
                    row[c].clamp(a, b)
                } else {
                    0.5 * (a + b)
                };
            }
        }
    }
}
