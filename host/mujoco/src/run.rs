//! The hands of the `dips-mujoco` binary ([`MujocoHands`]: our world and the MuJoCo hand,
//! opened for `dips … --hand world|mujoco`), and what the tests run on either hand: a
//! commands file ([`run_commands`], `dips sim run`'s trajectory shape), the scripted targets
//! that `dips bench sim --hand mujoco` times, and CSVTO modes ([`run_csvto_modes`]). The
//! controller side sees only [`Hand`].

use std::time::Instant;

use dips_world::hand::{Hand, HandError, HandOptions, Hands, open_world};
use dips_world::kinematics::HandJoints;
use dips_world::scenes::{SceneKind, card};
use dips_world::world::{ContactReport, ObjectState, StepFlag, World, scripted};
use serde::{Deserialize, Serialize};

use crate::{MujocoError, MujocoHand, MujocoParams, PoseNoise};

/// Which hand executes the actions: `dips_world`'s type (one owner), re-exported here.
pub use dips_world::hand::HandKind;

/// The hands of the `dips-mujoco` binary: our world and the MuJoCo hand. Its `main` runs the
/// `dips` command line with them (`dips_cli::main_with`), so `--hand mujoco` works on
/// `dips episode`, `dips eval`, `dips sim run` and `dips bench sim`.
#[derive(Debug, Clone, Copy, Default)]
pub struct MujocoHands;

impl Hands for MujocoHands {
    fn has(&self, _kind: HandKind) -> bool {
        true
    }

    fn open(
        &self,
        kind: HandKind,
        scene: SceneKind,
        options: &HandOptions,
    ) -> Result<Box<dyn Hand>, HandError> {
        match kind {
            HandKind::World => open_world(scene, options),
            HandKind::Mujoco => {
                let noise = options.noise.map(|n| PoseNoise {
                    position: n.position,
                    rotation: n.rotation,
                    seed: options.seed,
                });
                let mut params = MujocoParams::for_scene(scene);
                params.pose_noise = noise;
                let hand = MujocoHand::with_params(
                    scene,
                    dips_world::kinematics::HandModel::allegro_v4(),
                    params,
                )
                .map_err(|e| HandError::Other {
                    hand: "MuJoCo",
                    message: e.to_string(),
                })?;
                Ok(Box::new(hand))
            }
        }
    }
}

/// Either hand, behind the [`Hand`] trait, with the little the trajectory file needs besides.
#[derive(Debug)]
pub enum AnyHand {
    /// Our world.
    World(Box<World>),
    /// The MuJoCo hand.
    Mujoco(Box<MujocoHand>),
}

impl AnyHand {
    /// A fresh hand of `kind` for `scene`; `noise` applies to the MuJoCo hand's tracker only.
    pub fn new(
        kind: HandKind,
        scene: SceneKind,
        noise: Option<PoseNoise>,
    ) -> Result<AnyHand, MujocoError> {
        Ok(match kind {
            HandKind::World => AnyHand::World(Box::new(World::new(scene))),
            HandKind::Mujoco => {
                let mut params = MujocoParams::for_scene(scene);
                params.pose_noise = noise;
                AnyHand::Mujoco(Box::new(MujocoHand::with_params(
                    scene,
                    dips_world::kinematics::HandModel::allegro_v4(),
                    params,
                )?))
            }
        })
    }

    /// The hand as a controller sees it.
    pub fn hand(&mut self) -> &mut dyn Hand {
        match self {
            AnyHand::World(w) => w.as_mut(),
            AnyHand::Mujoco(m) => m.as_mut(),
        }
    }

    /// The hand, read-only.
    pub fn hand_ref(&self) -> &dyn Hand {
        match self {
            AnyHand::World(w) => w.as_ref(),
            AnyHand::Mujoco(m) => m.as_ref(),
        }
    }

    /// Deepest penetration now (m).
    pub fn max_penetration(&self) -> f64 {
        match self {
            AnyHand::World(w) => w.max_penetration(),
            AnyHand::Mujoco(m) => m.max_penetration(),
        }
    }
}

/// The raw state row a controller measures: task joints, then the object coordinates.
pub fn state_row(hand: &dyn Hand) -> Vec<f64> {
    let scene = hand.scene();
    let q = hand.joint_positions();
    let mut row: Vec<f64> = scene
        .task_fingers()
        .iter()
        .flat_map(|f| q[f.index()])
        .collect();
    row.extend(hand.object_pose().coords);
    row
}

/// Task validity of the measured object pose (our world's rule).
pub fn measured_valid(hand: &dyn Hand) -> bool {
    let pose = hand.object_pose();
    let state = match hand.scene() {
        SceneKind::Screwdriver => ObjectState::Screwdriver {
            orientation: pose.pose.rotation,
            yaw: pose.coords[2],
        },
        SceneKind::Card => ObjectState::Card {
            pose: pose.pose,
            theta: pose.coords[2],
        },
    };
    state.valid()
}

/// The task metric of a state row: screwdriver yaw (rad), or the card's planar distance to
/// its goal (m; goal = start − 6 cm in y), as `dips sim run` writes it.
pub fn task_metric(scene: SceneKind, start: &[f64], state: &[f64]) -> f64 {
    let a = scene.action_dim();
    match scene {
        SceneKind::Screwdriver => state[a + 2],
        SceneKind::Card => {
            let goal = card::goal_from_start(start[a], start[a + 1]);
            card::distance_to_goal(state[a], state[a + 1], goal)
        }
    }
}

/// The trajectory file: `dips sim run`'s shape (so `dips sim render` draws it) plus the
/// hand that made it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Trajectory {
    /// Scene name.
    pub scene: String,
    /// `world` or `mujoco`.
    pub hand: String,
    /// Raw state rows as measured (joints, tracked object coordinates), initial state first.
    pub states: Vec<Vec<f64>>,
    /// Validity of each state row.
    pub valid: Vec<bool>,
    /// Contacts at each state row (empty for the initial state).
    pub contacts: Vec<Vec<ContactReport>>,
    /// Deepest penetration after each action (m).
    pub max_penetration: Vec<f64>,
    /// Our world's flags of each action (always empty for the MuJoCo hand).
    pub flags: Vec<Vec<StepFlag>>,
    /// Task metric of each state row ([`task_metric`]).
    pub metric: Vec<f64>,
    /// Wall time of each action (s).
    pub action_seconds: Vec<f64>,
    /// Error that stopped the run early, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Run rows of joint deltas (task order, relative to the measured joints, as `dips sim run`)
/// on a hand. Stops at the first failed action and records its error in the trajectory.
pub fn run_commands(hand: &mut AnyHand, kind: HandKind, dq: &[Vec<f64>]) -> Trajectory {
    let scene = hand.hand_ref().scene();
    let first = state_row(hand.hand_ref());
    let mut traj = Trajectory {
        scene: scene.name().into(),
        hand: kind.name().into(),
        states: vec![first.clone()],
        valid: vec![measured_valid(hand.hand_ref())],
        contacts: vec![Vec::new()],
        max_penetration: vec![hand.max_penetration()],
        flags: vec![Vec::new()],
        metric: vec![task_metric(scene, &first, &first)],
        action_seconds: Vec::new(),
        error: None,
    };
    for (k, row) in dq.iter().enumerate() {
        let targets = add_deltas(scene, hand.hand_ref().joint_positions(), row);
        let t = Instant::now();
        let result: Result<(), HandError> = hand.hand().command(&targets);
        traj.action_seconds.push(t.elapsed().as_secs_f64());
        if let Err(e) = result {
            traj.error = Some(format!("action {k}: {e}"));
            break;
        }
        let s = state_row(hand.hand_ref());
        traj.metric.push(task_metric(scene, &first, &s));
        traj.states.push(s);
        traj.valid.push(measured_valid(hand.hand_ref()));
        traj.contacts
            .push(hand.hand_ref().contact_readings().unwrap_or_default());
        traj.max_penetration.push(hand.max_penetration());
        traj.flags.push(Vec::new());
    }
    traj
}

/// Measured joints plus a row of task-joint deltas (`docs/contracts.md` §2 order); a row too
/// short leaves NaN, which the hand refuses.
pub fn add_deltas(scene: SceneKind, mut q: HandJoints, dq: &[f64]) -> HandJoints {
    for (i, f) in scene.task_fingers().iter().enumerate() {
        for (j, t) in q[f.index()].iter_mut().enumerate() {
            *t += dq.get(4 * i + j).copied().unwrap_or(f64::NAN);
        }
    }
    q
}

/// The targets of action `k` of a scripted scenario, planned as a controller would: a
/// planning world is put at the hand's measured state and the script's joint deltas are added
/// to the measured joints. `hold` sends the measured joints; `manipulate` is the pinch-and-turn
/// (squeeze 4 mm, turn 6 mm) or the card's 3 mm press then 8 mm pushes along −y.
pub fn scripted_targets(
    plan: &mut World,
    hand: &dyn Hand,
    manipulate: bool,
    k: usize,
) -> Result<HandJoints, HandError> {
    let scene = hand.scene();
    let q = hand.joint_positions();
    if !manipulate {
        return Ok(q);
    }
    plan.set_state(&state_row(hand))?;
    let dq = match scene {
        SceneKind::Screwdriver => scripted::pinch_turn_action(plan, 0.004, 0.006),
        SceneKind::Card if k == 0 => scripted::card_push_action(plan, 0.0, 0.003),
        SceneKind::Card => scripted::card_push_action(plan, -0.008, 0.0),
    };
    Ok(add_deltas(scene, q, &dq))
}

/// One CSVTO mode executed closed-loop on a hand ([`dips_exec::run_mode`]: a
/// re-solve from the measured state at every step, the best particle's first step commanded).
#[derive(Debug, Clone, Serialize)]
pub struct ModeFigures {
    /// The mode's name.
    pub mode: String,
    /// Measured state row at the start of the mode.
    pub start_state: Vec<f64>,
    /// Measured state row at its end.
    pub end_state: Vec<f64>,
    /// Change of the object coordinates over the mode.
    pub object_change: [f64; 3],
    /// Each step's measured validity, all true when the object stayed valid.
    pub valid: bool,
    /// Largest distance (m) of a contact finger from the object after any step (CSVTO's
    /// `tip_sdf`, measured through our geometry at the measured state).
    pub worst_contact_gap: f64,
    /// Wall time of the whole mode (s): CSVTO's solves and the hand's actions.
    pub seconds: f64,
}

/// Run CSVTO `modes` (names of the scene's modes) one after the other on a fresh hand of
/// `kind`, with the task's execution settings and seed `seed` (the same as
/// `dips episode --method csvto-sampled` uses for each mode).
pub fn run_csvto_modes(
    kind: HandKind,
    scene: SceneKind,
    modes: &[String],
    seed: u64,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<ModeFigures>, Box<dyn std::error::Error>> {
    use dips_exec::problems::mode::parse_mode;
    use dips_exec::{ExecSettings, run_mode};
    let parsed = modes
        .iter()
        .map(|m| parse_mode(scene, m))
        .collect::<Result<Vec<_>, _>>()?;
    let mut hand = AnyHand::new(kind, scene, None)?;
    let model = dips_world::kinematics::HandModel::allegro_v4();
    let settings = ExecSettings::for_task(scene);
    let mut rng = dips_kernel::rng::KernelRng::seed_from_u64(seed);
    let mut out = Vec::new();
    for mode in parsed {
        let t = Instant::now();
        let run = run_mode(
            hand.hand(),
            &model,
            mode,
            &settings,
            None,
            &mut rng,
            progress,
        )?;
        let a = scene.action_dim();
        let object_change = std::array::from_fn(|i| run.end_state[a + i] - run.start_state[a + i]);
        let contact: Vec<usize> = (0..scene.task_fingers().len())
            .filter(|&i| mode.contact_mode().in_contact(i))
            .collect();
        let worst_contact_gap = run
            .steps
            .iter()
            .flat_map(|s| {
                contact
                    .iter()
                    .map(|&i| s.tip_sdf.get(i).copied().unwrap_or(0.0))
            })
            .fold(0.0, f64::max);
        out.push(ModeFigures {
            mode: run.mode.to_string(),
            start_state: run.start_state.clone(),
            end_state: run.end_state.clone(),
            object_change,
            valid: run.steps.iter().all(|s| s.valid),
            worst_contact_gap,
            seconds: t.elapsed().as_secs_f64(),
        });
    }
    Ok(out)
}
