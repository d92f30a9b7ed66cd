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
//! All Jacobians are exact (forward-mode [`Dual`] numbers through kinematics and geometry).

// Index loops over small fixed-size arrays mirror the maths (rows, joints, faces).
#![allow(clippy::needless_range_loop)]

use std::f64::consts::PI;

use super::dual::{Dual, M3, Scalar, V3};
use super::fk::FingerChain;
use super::mode::Mode;
use super::sdf;
use crate::csvto::{Problem, StepConstraints};
use crate::kinematics::HandModel;
use crate::scenes::{self, SceneKind};
use dips_kernel::task::CostWeights;

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

/// The kernel's [`CostWeights`] of a task in `f64` (exact: every weight is an integer).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Weights {
    scale: f64,
    joint_step: f64,
    joint_delta: f64,
    object_step: f64,
    contact_force: f64,
    upright: f64,
    regrasp_target: f64,
}

impl Weights {
    fn of(task: SceneKind) -> Self {
        let w = CostWeights::of(task.task());
        Self {
            scale: f64::from(w.scale),
            joint_step: f64::from(w.joint_step),
            joint_delta: f64::from(w.joint_delta),
            object_step: f64::from(w.object_step),
            contact_force: f64::from(w.contact_force),
            upright: f64::from(w.upright),
            regrasp_target: f64::from(w.regrasp_target),
        }
    }
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

/// Object rotation and origin for the object coordinates `o`, given in problem units
/// (`units[k]` metres or radians per unit).
fn object_pose<S: Scalar>(task: SceneKind, units: &[f64; 3], o: &[S; 3]) -> (M3<S>, V3<S>) {
    let o: [S; 3] = std::array::from_fn(|k| o[k] * units[k]);
    match task {
        SceneKind::Screwdriver => (
            M3::rot_x(o[0]).mul(&M3::rot_y(o[1])).mul(&M3::rot_z(o[2])),
            V3::cst(scenes::screwdriver::PIVOT),
        ),
        SceneKind::Card => (
            M3::rot_z(o[2]),
            V3([o[0], o[1], S::cst(scenes::card::INITIAL_CENTER[2])]),
        ),
    }
}

/// Unit tangents `t1, t2` completing the normal `n` to a right-handed frame.
fn tangents<S: Scalar>(n: &V3<S>) -> (V3<S>, V3<S>) {
    let helper = if n.z().val().abs() < 0.9 {
        V3::cst([0.0, 0.0, 1.0])
    } else {
        V3::cst([1.0, 0.0, 0.0])
    };
    let t = helper.cross(n);
    let t1 = t.scale(S::cst(1.0) / t.norm());
    let t2 = n.cross(&t1);
    (t1, t2)
}

/// Geometry of one fingertip against the object.
struct Contact<S> {
    /// Sphere signed distance (centre distance minus radius).
    sdf: S,
    /// Outward object normal (world).
    normal: V3<S>,
    /// Closest point on the object surface (world).
    surface: V3<S>,
    /// Point of the sphere nearest the object (world).
    finger_point: V3<S>,
    frames: super::fk::Frames<S>,
}

/// The parts of a [`Contact`] the step terms need, in the caller's scalar: signed distance,
/// normal, surface point and the Jacobian of the finger's contact point.
struct Lifted<S> {
    sdf: S,
    normal: V3<S>,
    surface: V3<S>,
    jac: [V3<S>; 4],
}

/// Terms of a contact finger at `s_{t+1}`, over `[q_{t+1}, o_{t+1}, f]`.
struct NextTerms {
    sdf: Dual<10>,
    /// `−J_cᵀf − K_p q_{t+1}`; the caller adds `K_p(q_t + Δq_t)`.
    balance: [Dual<10>; 4],
    wrench: [Dual<10>; 3],
    friction: [Dual<10>; PYRAMID_FACES],
    /// `f_min + n·f` (≤ 0: the finger presses with at least `f_min`).
    min_normal: Dual<10>,
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

    /// Geometry of finger `i` at joints `q` and object pose `o`.
    fn contact<S: Scalar>(&self, i: usize, q: &[S; 4], o: &[S; 3]) -> Contact<S> {
        let frames = self.chains[i].frames(q);
        let (r, origin) = object_pose(self.task, &self.units, o);
        let local = r.tmul_v(&frames.tip.sub(&origin));
        let sd = match self.task {
            SceneKind::Screwdriver => sdf::screwdriver(&local),
            SceneKind::Card => sdf::card(&local),
        };
        let normal = r.mul_v(&sd.normal);
        let surface = frames.tip.sub(&normal.scale(sd.dist));
        let finger_point = frames.tip.sub(&normal.scalef(self.radius));
        Contact {
            sdf: sd.dist - self.radius,
            normal,
            surface,
            finger_point,
            frames,
        }
    }

    /// Geometry of finger `i` at joints `vals[..4]` and object pose `vals[4..]`, computed in
    /// 7-wide dual numbers (the expensive kinematics and distance) and lifted into the
    /// caller's wider dual, whose joints start at column `oq` and object pose at `oo`.
    fn lifted_contact<S: Lift>(
        &self,
        i: usize,
        vals: &[f64; 7],
        oq: usize,
        oo: usize,
    ) -> Lifted<S> {
        let d: [Dual<7>; 7] = seed(vals);
        let c = self.contact(i, &[d[0], d[1], d[2], d[3]], &[d[4], d[5], d[6]]);
        let jac = c.frames.point_jacobian(&c.finger_point);
        let l = |x: Dual<7>| S::lift(x, oq, oo);
        let lv = |x: &V3<Dual<7>>| V3(x.0.map(l));
        Lifted {
            sdf: l(c.sdf),
            normal: lv(&c.normal),
            surface: lv(&c.surface),
            jac: jac.each_ref().map(lv),
        }
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

    /// Signed distance of finger `i`'s sphere at `(q, o)` (`o` in metres and radians).
    pub fn finger_sdf(&self, i: usize, q: &[f64; 4], o: &[f64; 3]) -> f64 {
        self.contact(i, q, &self.obj_units(o)).sdf
    }

    fn obj_units(&self, o: &[f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| o[k] / self.units[k])
    }

    /// Displacement of the object material point at `p` from pose `ot` to `on`.
    fn object_motion<S: Scalar>(&self, ot: &[S; 3], on: &[S; 3], p: &V3<S>) -> V3<S> {
        match self.task {
            SceneKind::Screwdriver => {
                let (rt, origin) = object_pose(self.task, &self.units, ot);
                let (rn, _) = object_pose(self.task, &self.units, on);
                let m = rn.mul_t(&rt);
                let half = 0.5;
                let w = V3([
                    (m.0[2][1] - m.0[1][2]) * half,
                    (m.0[0][2] - m.0[2][0]) * half,
                    (m.0[1][0] - m.0[0][1]) * half,
                ]);
                w.cross(&p.sub(&origin))
            }
            SceneKind::Card => {
                let (_, origin) = object_pose(self.task, &self.units, ot);
                let u = &self.units;
                let w = V3([S::cst(0.0), S::cst(0.0), (on[2] - ot[2]) * u[2]]);
                let v = V3([(on[0] - ot[0]) * u[0], (on[1] - ot[1]) * u[1], S::cst(0.0)]);
                v.add(&w.cross(&p.sub(&origin)))
            }
        }
    }

    /// Rolling rows of contact finger `i` over `[q_t (4), o_t (3), q_{t+1} (4), o_{t+1} (3)]`:
    /// the finger's contact point moves with the object's material point (tangentially).
    fn rolling_terms(&self, i: usize, vals: &[f64; 14]) -> [Dual<14>; 2] {
        let v: [Dual<14>; 14] = seed(vals);
        let qt = [v[0], v[1], v[2], v[3]];
        let ot = [v[4], v[5], v[6]];
        let qn = [v[7], v[8], v[9], v[10]];
        let on = [v[11], v[12], v[13]];
        let at_t: [f64; 7] = std::array::from_fn(|k| vals[k]);
        let ct: Lifted<Dual<14>> = self.lifted_contact(i, &at_t, 0, 4);
        let mut dfinger = V3::zero();
        for k in 0..4 {
            dfinger = dfinger.add(&ct.jac[k].scale(qn[k] - qt[k]));
        }
        let rel = dfinger.sub(&self.object_motion(&ot, &on, &ct.surface));
        let (t1, t2) = tangents(&ct.normal);
        [t1.dot(&rel), t2.dot(&rel)]
    }

    /// Write finger `i`'s two rolling rows ([`Self::rolling_terms`]) of the step from `prev`
    /// through `row` into equality rows `e` and `e + 1`.
    fn rolling_rows(
        &self,
        i: usize,
        prev: &[f64],
        row: &[f64],
        e: usize,
        out: &mut StepConstraints,
    ) {
        let (ds, nf) = (self.state_dim(), self.nf);
        let width = ds + self.row_dim();
        // Columns: q_t, o_t (previous state), q_{t+1}, o_{t+1} (row).
        let map: [usize; 14] = std::array::from_fn(|k| match k {
            0..4 => 4 * i + k,
            4..7 => 4 * nf + k - 4,
            7..11 => ds + 4 * i + k - 7,
            _ => ds + 4 * nf + k - 11,
        });
        let vals: [f64; 14] = std::array::from_fn(|k| step_value(prev, row, ds, map[k]));
        for (r, term) in self.rolling_terms(i, &vals).iter().enumerate() {
            out.eq[e + r] = term.v;
            scatter(
                &mut out.jac_eq[(e + r) * width..(e + r + 1) * width],
                &map,
                &term.d,
                1.0,
            );
        }
    }

    /// Terms of contact finger `i` at `s_{t+1}` over `[q_{t+1} (4), o_{t+1} (3), f (3)]`.
    fn next_terms(&self, i: usize, vals: &[f64; 10]) -> NextTerms {
        let v: [Dual<10>; 10] = seed(vals);
        let qn = [v[0], v[1], v[2], v[3]];
        let f = V3([v[7], v[8], v[9]]);
        let at_n: [f64; 7] = std::array::from_fn(|k| vals[k]);
        let cn: Lifted<Dual<10>> = self.lifted_contact(i, &at_n, 0, 4);
        // Joint impedance balance without its `K_p(q_t + Δq_t)` part (added by the caller).
        let balance = std::array::from_fn(|k| -cn.jac[k].dot(&f) - qn[k] * self.kp);
        let wrench = match self.task {
            SceneKind::Screwdriver => {
                cn.surface
                    .sub(&V3::cst(scenes::screwdriver::PIVOT))
                    .cross(&f)
                    .0
            }
            SceneKind::Card => f.0,
        };
        let (n1, n2) = tangents(&cn.normal);
        let (a, b, c) = (n1.dot(&f), n2.dot(&f), cn.normal.dot(&f));
        let friction = std::array::from_fn(|j| {
            let th = 2.0 * PI * j as f64 / PYRAMID_FACES as f64;
            a * th.cos() + b * th.sin() + c * PLANNER_FRICTION
        });
        NextTerms {
            sdf: cn.sdf,
            balance,
            wrench,
            friction,
            min_normal: c + MIN_NORMAL_FORCE,
        }
    }

    /// Total equality rows of step `t` and the layout offsets.
    fn eq_count(&self, t: usize) -> usize {
        let nr = self.nf - self.nc;
        let object = if self.nc > 0 {
            match self.task {
                SceneKind::Screwdriver => 3,
                SceneKind::Card => 4,
            }
        } else {
            match self.task {
                SceneKind::Screwdriver => 3,
                SceneKind::Card => 6,
            }
        };
        let hold = self.pinned;
        let lift = if t == 0 {
            2 * self.lift_off.iter().filter(|&&l| l).count()
        } else {
            0
        };
        7 * self.nc + object + hold + 4 * nr + lift + if t + 1 == self.horizon { nr } else { 0 }
    }

    fn ineq_count(&self, t: usize) -> usize {
        let nr = self.nf - self.nc;
        (PYRAMID_FACES + 1) * self.nc + if t + 1 < self.horizon { 2 * nr } else { 0 }
    }

    /// Signed distance of regrasping finger `i` at joints `q` (4) and object pose `o`, with its
    /// derivatives and the step columns they belong to (joints from `qcol`, object from `ocol`).
    fn regrasp_sdf(
        &self,
        i: usize,
        q: &[f64],
        o: &[f64; 3],
        qcol: usize,
        ocol: usize,
    ) -> (Dual<7>, [usize; 7]) {
        let v: [Dual<7>; 7] = seed(&[q[0], q[1], q[2], q[3], o[0], o[1], o[2]]);
        let c = self.contact(i, &[v[0], v[1], v[2], v[3]], &[v[4], v[5], v[6]]);
        let map = std::array::from_fn(|k| if k < 4 { qcol + k } else { ocol + k - 4 });
        (c.sdf, map)
    }

    /// The rows `o_{t+1,k} − o_{t,k} = 0` for object coordinates `k ≥ first`, from equality
    /// row `r`.
    fn hold_rows(
        &self,
        r: usize,
        first: usize,
        prev: &[f64],
        on: &[f64; 3],
        width: usize,
        out: &mut StepConstraints,
    ) {
        let ds = self.state_dim();
        let oc = 4 * self.nf;
        for k in first..3 {
            let rr = r + k - first;
            out.eq[rr] = on[k] - prev[oc + k];
            out.jac_eq[rr * width + ds + oc + k] = 1.0;
            out.jac_eq[rr * width + oc + k] = -1.0;
        }
    }

    /// Regrasp target cost of finger `i` at `(q, o)`: `‖p^obj − p̄‖²` with the object frame
    /// yaw zeroed (screwdriver) or in the world (card).
    fn target_error<S: Scalar>(&self, i: usize, q: &[S; 4], o: &[S; 3]) -> S {
        let c = self.chains[i].tip(q);
        let p = match self.task {
            SceneKind::Screwdriver => {
                let r = M3::rot_x(o[0] * self.units[0]).mul(&M3::rot_y(o[1] * self.units[1]));
                r.tmul_v(&c.sub(&V3::cst(scenes::screwdriver::PIVOT)))
            }
            SceneKind::Card => c,
        };
        let d = p.sub(&V3::cst(self.targets[i]));
        d.dot(&d)
    }

    /// Regrasp target distance (m) of finger `i` at `(q, o)`.
    pub fn target_distance(&self, i: usize, q: &[f64; 4], o: &[f64; 3]) -> f64 {
        self.target_error(i, q, &self.obj_units(o)).sqrt()
    }
}

/// Scalars that can take a 7-wide dual computed on `(q, o)` at column offsets
/// `(oq, oo)` of their own seeding.
trait Lift: Scalar {
    fn lift(x: Dual<7>, oq: usize, oo: usize) -> Self;
}

impl<const N: usize> Lift for Dual<N> {
    fn lift(x: Dual<7>, oq: usize, oo: usize) -> Self {
        let mut d = [0.0; N];
        d[oq..oq + 4].copy_from_slice(&x.d[..4]);
        d[oo..oo + 3].copy_from_slice(&x.d[4..]);
        Dual { v: x.v, d }
    }
}

/// Add `w·d[j]` to `row[map[j]]`.
/// The value of step column `c` (the previous state's `ds` columns, then the row's).
fn step_value(prev: &[f64], row: &[f64], ds: usize, c: usize) -> f64 {
    if c < ds { prev[c] } else { row[c - ds] }
}

fn scatter(row: &mut [f64], map: &[usize], d: &[f64], w: f64) {
    for (&c, &v) in map.iter().zip(d) {
        row[c] += w * v;
    }
}

fn seed<const N: usize>(vals: &[f64]) -> [Dual<N>; N] {
    std::array::from_fn(|i| Dual::var(vals[i], i))
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
        self.eq_count(t)
    }

    fn n_ineq(&self, t: usize) -> usize {
        self.ineq_count(t)
    }

    fn step_constraints(&self, t: usize, prev: &[f64], row: &[f64], out: &mut StepConstraints) {
        let ds = self.state_dim();
        let width = ds + self.row_dim();
        let nf = self.nf;
        let mut e = 0; // equality row
        let mut q = 0; // inequality row
        // Object rows are filled after the fingers; remember where they go.
        let n_obj = match (self.nc > 0, self.task) {
            (true, SceneKind::Screwdriver) => 3,
            (true, SceneKind::Card) => 4,
            (false, SceneKind::Screwdriver) => 3,
            (false, SceneKind::Card) => 6,
        } + self.pinned;
        let obj_row = 7 * self.nc;
        let mut wrench_rows = [0.0f64; 3];
        for i in 0..nf {
            let Some(s) = self.slot[i] else { continue };
            // Columns: q_{t+1}, o_{t+1}, f (row).
            let mut map10 = [0usize; 10];
            for k in 0..4 {
                map10[k] = ds + 4 * i + k;
            }
            for k in 0..3 {
                map10[4 + k] = ds + 4 * nf + k;
                map10[7 + k] = ds + self.force_col(s, k);
            }
            let v10: [f64; 10] = std::array::from_fn(|k| step_value(prev, row, ds, map10[k]));
            let next = self.next_terms(i, &v10);
            let put =
                |out: &mut StepConstraints, r: usize, value: f64, map: &[usize], d: &[f64]| {
                    out.eq[r] = value;
                    scatter(&mut out.jac_eq[r * width..(r + 1) * width], map, d, 1.0);
                };
            put(out, e, next.sdf.v, &map10, &next.sdf.d);
            self.rolling_rows(i, prev, row, e + 1, out);
            for k in 0..4 {
                let r = e + 3 + k;
                let (qc, dqc) = (4 * i + k, ds + self.dq_col(i, k));
                put(
                    out,
                    r,
                    next.balance[k].v + self.kp * (prev[qc] + row[dqc - ds]),
                    &map10,
                    &next.balance[k].d,
                );
                out.jac_eq[r * width + qc] += self.kp;
                out.jac_eq[r * width + dqc] += self.kp;
            }
            e += 7;
            for k in 0..3 {
                let r = obj_row + k;
                wrench_rows[k] += next.wrench[k].v;
                scatter(
                    &mut out.jac_eq[r * width..(r + 1) * width],
                    &map10,
                    &next.wrench[k].d,
                    1.0,
                );
            }
            for term in next.friction.iter().chain([&next.min_normal]) {
                out.ineq[q] = term.v;
                scatter(
                    &mut out.jac_ineq[q * width..(q + 1) * width],
                    &map10,
                    &term.d,
                    1.0,
                );
                q += 1;
            }
        }
        debug_assert_eq!(e, obj_row);
        // Object rows.
        let on = [row[4 * nf], row[4 * nf + 1], row[4 * nf + 2]];
        if self.nc > 0 {
            match self.task {
                SceneKind::Screwdriver => {
                    // Gravity torque about the pivot: (R·r_com) × (0, 0, −m g).
                    let od: [Dual<3>; 3] = seed(&on);
                    let (r, _) = object_pose(self.task, &self.units, &od);
                    let com = r.mul_v(&V3::cst([0.0, 0.0, scenes::screwdriver::COM_HEIGHT]));
                    let g = V3::cst([0.0, 0.0, -scenes::screwdriver::MASS * scenes::GRAVITY]);
                    let tg = com.cross(&g);
                    for k in 0..3 {
                        let rr = obj_row + k;
                        out.eq[rr] = wrench_rows[k] + tg.0[k].v;
                        for j in 0..3 {
                            out.jac_eq[rr * width + ds + 4 * nf + j] += tg.0[k].d[j];
                        }
                    }
                    if self.pinned > 0 {
                        self.hold_rows(obj_row + 3, 3 - self.pinned, prev, &on, width, out);
                    }
                }
                SceneKind::Card => {
                    let fe = [
                        row[self.env_col(0)],
                        row[self.env_col(1)],
                        row[self.env_col(2)],
                    ];
                    let weight = [0.0, 0.0, -scenes::card::MASS * scenes::GRAVITY];
                    for k in 0..3 {
                        let rr = obj_row + k;
                        out.eq[rr] = wrench_rows[k] + fe[k] + weight[k];
                        out.jac_eq[rr * width + ds + self.env_col(k)] += 1.0;
                    }
                    // Sliding friction of the table (spec §2.2): ‖f_xy‖ − μ f_z = 0. Its
                    // direction is left free: rows tying it to the displacement Δ are
                    // degenerate at Δ = 0 and pin the card in the tangent space (see
                    // docs/csvto.md).
                    let rr = obj_row + 3;
                    let nxy = (fe[0] * fe[0] + fe[1] * fe[1] + 1e-12).sqrt();
                    let mu = scenes::card::TABLE_FRICTION;
                    out.eq[rr] = nxy - mu * fe[2];
                    out.jac_eq[rr * width + ds + self.env_col(0)] = fe[0] / nxy;
                    out.jac_eq[rr * width + ds + self.env_col(1)] = fe[1] / nxy;
                    out.jac_eq[rr * width + ds + self.env_col(2)] = -mu;
                }
            }
        } else {
            // No finger in contact: the object holds still.
            self.hold_rows(obj_row, 0, prev, &on, width, out);
            if self.task == SceneKind::Card {
                let weight = scenes::card::MASS * scenes::GRAVITY;
                for k in 0..3 {
                    let rr = obj_row + 3 + k;
                    out.eq[rr] = row[self.env_col(k)] - if k == 2 { weight } else { 0.0 };
                    out.jac_eq[rr * width + ds + self.env_col(k)] = 1.0;
                }
            }
        }
        e = obj_row + n_obj;
        // Regrasping fingers: free motion, clearance, terminal contact.
        let last = t + 1 == self.horizon;
        for i in 0..nf {
            if self.slot[i].is_some() {
                continue;
            }
            for k in 0..4 {
                let r = e + k;
                out.eq[r] = row[4 * i + k] - prev[4 * i + k] - row[self.dq_col(i, k)];
                let jr = &mut out.jac_eq[r * width..(r + 1) * width];
                jr[ds + 4 * i + k] = 1.0;
                jr[4 * i + k] = -1.0;
                jr[ds + self.dq_col(i, k)] = -1.0;
            }
            e += 4;
        }
        if t == 0 {
            // Lift-off along the normal: the finger's contact point has no tangential motion
            // relative to the object in the first step (the rolling rows of a contact finger).
            for i in (0..nf).filter(|&i| self.lift_off[i]) {
                self.rolling_rows(i, prev, row, e, out);
                e += 2;
            }
        }
        for i in 0..nf {
            if self.slot[i].is_some() {
                continue;
            }
            let qn = &row[4 * i..4 * i + 4];
            let (qcol, ocol) = (ds + 4 * i, ds + 4 * nf);
            if last {
                let (sdf, map) = self.regrasp_sdf(i, qn, &on, qcol, ocol);
                out.eq[e] = sdf.v;
                scatter(
                    &mut out.jac_eq[e * width..(e + 1) * width],
                    &map,
                    &sdf.d,
                    1.0,
                );
                e += 1;
            } else {
                // Clearance to the object where the step leaves it and where it found it (see
                // [`REGRASP_CLEARANCE`]).
                let before = [prev[4 * nf], prev[4 * nf + 1], prev[4 * nf + 2]];
                for (o, ocol) in [(&on, ocol), (&before, 4 * nf)] {
                    let (sdf, map) = self.regrasp_sdf(i, qn, o, qcol, ocol);
                    out.ineq[q] = REGRASP_CLEARANCE + CLEARANCE_MARGIN - sdf.v;
                    scatter(
                        &mut out.jac_ineq[q * width..(q + 1) * width],
                        &map,
                        &sdf.d,
                        -1.0,
                    );
                    q += 1;
                }
            }
        }
        debug_assert_eq!(e, out.eq.len());
        debug_assert_eq!(q, out.ineq.len());
    }

    fn cost(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        let n = self.row_dim();
        let nf = self.nf;
        let nq = 4 * nf;
        let h = self.horizon;
        let mut j = 0.0;
        let (wt, wr) = self.goal_weights;
        let w = self.weights;
        for t in 0..h {
            let row = &x[t * n..(t + 1) * n];
            let prev: &[f64] = if t == 0 {
                &self.start
            } else {
                &x[(t - 1) * n..t * n]
            };
            // Smoothness on q_t − q_{t−1} and on Δq; object smoothness and goal.
            let w_goal = if t + 1 == h { wt } else { wr };
            let mut dprev = [0.0; 15];
            {
                let g = &mut grad[t * n..(t + 1) * n];
                let (ws, wd, wo) = (w.joint_step, w.joint_delta, w.object_step);
                for k in 0..nq {
                    let d = row[k] - prev[k];
                    j += ws * d * d;
                    g[k] += 2.0 * ws * d;
                    dprev[k] = -2.0 * ws * d;
                    let dq = row[nq + 3 + k];
                    j += wd * dq * dq;
                    g[nq + 3 + k] += 2.0 * wd * dq;
                }
                for k in 0..3 {
                    let u2 = self.units[k] * self.units[k];
                    let d = row[nq + k] - prev[nq + k];
                    j += wo * u2 * d * d;
                    g[nq + k] += 2.0 * wo * u2 * d;
                    dprev[nq + k] = -2.0 * wo * u2 * d;
                    let e = row[nq + k] - self.goal[k];
                    j += u2 * w_goal * e * e;
                    g[nq + k] += 2.0 * u2 * w_goal * e;
                }
            }
            if t > 0 {
                for k in 0..nq + 3 {
                    grad[(t - 1) * n + k] += dprev[k];
                }
            }
            let g = &mut grad[t * n..(t + 1) * n];
            if w.upright != 0.0 {
                for k in 0..2 {
                    let u2 = self.units[k] * self.units[k];
                    let a = row[nq + k];
                    j += w.upright * u2 * a * a;
                    g[nq + k] += 2.0 * w.upright * u2 * a;
                }
            }
            // Finger forces.
            for s in 0..self.nc {
                for k in 0..3 {
                    let f = row[self.force_col(s, k)];
                    j += w.contact_force * f * f;
                    g[self.force_col(s, k)] += 2.0 * w.contact_force * f;
                }
            }
            // Regrasp targets.
            for i in 0..nf {
                if self.slot[i].is_some() {
                    continue;
                }
                let mut vals = [0.0; 7];
                vals[..4].copy_from_slice(&row[4 * i..4 * i + 4]);
                vals[4..].copy_from_slice(&row[nq..nq + 3]);
                let v: [Dual<7>; 7] = seed(&vals);
                let err = self.target_error(i, &[v[0], v[1], v[2], v[3]], &[v[4], v[5], v[6]]);
                j += w.regrasp_target * err.v;
                for k in 0..4 {
                    g[4 * i + k] += w.regrasp_target * err.d[k];
                }
                for k in 0..3 {
                    g[nq + k] += w.regrasp_target * err.d[4 + k];
                }
            }
        }
        for v in grad.iter_mut() {
            *v *= w.scale;
        }
        w.scale * j
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
