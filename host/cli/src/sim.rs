//! `dips sim`: run actions in the quasi-static world and draw scenes or trajectories.
//!
//! `dips sim run --scene screwdriver|card --commands CMDS.json --out OUT.json` executes one
//! 1 s action per row of CMDS (`{"dq": [[...], ...]}`: joint deltas of the task fingers in
//! `docs/contracts.md` §2 order, relative to the current measured joints) and writes
//! `{"scene", "states", "valid", "contacts", "max_penetration", "flags", "metric"}` with one state row per
//! action plus the initial state first. `contacts[k]` are the contacts at the end of action k
//! (`contacts[0]` is empty): finger, part, point, normal (out of the part), force (exerted by
//! the finger on the part, N) and signed distance.
//!
//! `--hand mujoco` executes the actions on the MuJoCo hand instead (through `dips-mujoco`,
//! docs/mujoco.md): the same commands and trajectory, the contacts as the hand reads them, no
//! world flags, and `max_penetration` from those contacts. The trajectory records its `hand`.
//!
//! `dips sim render --scene S [--trajectory OUT.json] [--step K] --out FILE.svg|FILE.png`
//! draws the scene's initial state, or state K (default: last) of a trajectory with its
//! contacts and forces (green, 5 mm per N, exerted by the finger on the part) and the paths of
//! the fingertip centres and of the object's reference point over the whole trajectory.

use std::path::{Path, PathBuf};

use clap::{Args, Subcommand};
use serde::{Deserialize, Serialize};

use dips_exec::hand_state;
use dips_exec::mode_run::command_deltas;
use dips_report::render;
use dips_world::hand::{Hand, HandKind, HandOptions, Hands, Recorder, add_task_deltas};
use dips_world::kinematics::HandModel;
use dips_world::scenes::SceneKind;
use dips_world::world::{ContactReport, StepFlag, World, WorldError, WorldParams};

/// `dips sim` arguments.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: SimCommand,
}

/// `dips sim` subcommands.
#[derive(Debug, Subcommand)]
pub enum SimCommand {
    /// Execute actions from a commands file and write the trajectory.
    Run(RunArgs),
    /// Draw a scene or one state of a trajectory to SVG or PNG.
    Render(RenderArgs),
}

/// `dips sim run` arguments.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Scene: `screwdriver` or `card`.
    #[arg(long)]
    pub scene: String,
    /// Commands file: `{"dq": [[...], ...]}`, one row per 1 s action.
    #[arg(long)]
    pub commands: PathBuf,
    /// Output trajectory (JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Which hand executes the actions: `world` (our quasi-static world) or `mujoco` (the
    /// MuJoCo hand, through the dips-mujoco binary).
    #[arg(
        long,
        value_name = "HAND",
        default_value_t = HandKind::World,
        value_parser = crate::hands::parse_hand
    )]
    pub hand: HandKind,
    /// Optional hand description (default: the built-in Allegro v4 file; our world only).
    #[arg(long, value_name = "FILE")]
    pub hand_model: Option<PathBuf>,
    /// Optional hand log (JSON lines) of every step, replayable with the `hand` module (our
    /// world only).
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// Tracker noise (`--hand mujoco`): position σ (m) of the reported object pose.
    #[arg(long, value_name = "M", default_value_t = 0.0)]
    pub noise_position: f64,
    /// Tracker noise (`--hand mujoco`): rotation σ (rad per axis) of the reported object pose.
    #[arg(long, value_name = "RAD", default_value_t = 0.0)]
    pub noise_rotation: f64,
    /// Seed of the tracker noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// `dips sim render` arguments (`dips render` takes the same inputs without `--scene` and
/// also writes animations).
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene: `screwdriver` or `card`.
    #[arg(long)]
    pub scene: String,
    /// Trajectory written by `dips sim run`, or an episode's `result.json` (default: draw
    /// the initial state).
    #[arg(long)]
    pub trajectory: Option<PathBuf>,
    /// Which state row of the trajectory (default: the last).
    #[arg(long)]
    pub step: Option<usize>,
    /// Output file, `.svg` or `.png`.
    #[arg(long)]
    pub out: PathBuf,
    /// Pixels per view (three views side by side).
    #[arg(long, default_value_t = 400)]
    pub size: u32,
}

/// Errors of `dips sim`.
#[derive(Debug, thiserror::Error)]
pub enum SimCliError {
    /// Unknown scene name.
    #[error("unknown scene {0:?} (expected screwdriver or card)")]
    Scene(String),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A file is not valid JSON of the expected shape.
    #[error("{path} is not valid JSON of the expected shape: {message}")]
    Json {
        /// The file.
        path: String,
        /// Parser message.
        message: String,
    },
    /// A command row has the wrong length.
    #[error("{path}: dq row {row} has {got} numbers, the {scene} task needs {expected}")]
    RowLength {
        /// The file.
        path: String,
        /// 0-based row.
        row: usize,
        /// Scene name.
        scene: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// A command entry is NaN or infinite (JSON has no NaN, but a huge literal overflows).
    #[error(
        "{path}: dq row {row} entry {col} is not finite; every entry must be a finite joint delta in rad"
    )]
    NonFinite {
        /// The file.
        path: String,
        /// 0-based row.
        row: usize,
        /// 0-based column.
        col: usize,
    },
    /// A command entry moves its joint further than the joint's whole range: no action can
    /// mean it (the world would clamp it to the limit and report the run valid).
    #[error(
        "{path}: dq row {row} entry {col} is {value:?} rad; a joint delta must be within ±{limit:.3} rad, the range of {finger} joint {joint} ({lower} to {upper} rad)"
    )]
    OutOfLimit {
        /// The file.
        path: String,
        /// 0-based row.
        row: usize,
        /// 0-based column.
        col: usize,
        /// The entry.
        value: f64,
        /// The largest magnitude allowed (the joint's range, rad).
        limit: f64,
        /// The finger the entry moves.
        finger: &'static str,
        /// The joint of that finger (0-based).
        joint: usize,
        /// The joint's lower limit (rad).
        lower: f64,
        /// The joint's upper limit (rad).
        upper: f64,
    },
    /// The trajectory holds no state to draw.
    #[error("{path} holds no states (its `states` list is empty); nothing to render")]
    Empty {
        /// The file.
        path: String,
    },
    /// A trajectory row index is out of range.
    #[error("{path} has {len} states; --step {step} is out of range (0 ≤ step < {len})")]
    Step {
        /// The file.
        path: String,
        /// Requested row.
        step: usize,
        /// Rows present.
        len: usize,
    },
    /// The world failed an action (partial trajectory written).
    #[error("action {action} failed: {source} (the trajectory up to it was written)")]
    Action {
        /// 0-based action.
        action: usize,
        /// The world's error.
        source: WorldError,
    },
    /// Any other error from a library module.
    #[error(transparent)]
    Other(#[from] anyhow::Error),
}

/// The commands file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Commands {
    /// One row of joint deltas per action.
    pub dq: Vec<Vec<f64>>,
}

/// The trajectory file.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Trajectory {
    /// Scene name.
    pub scene: String,
    /// The hand that executed the actions (files without it ran on our world).
    #[serde(default)]
    pub hand: HandKind,
    /// Raw state rows, initial state first.
    pub states: Vec<Vec<f64>>,
    /// Validity of each state row.
    pub valid: Vec<bool>,
    /// Contacts at each state row (empty for the initial state).
    pub contacts: Vec<Vec<ContactReport>>,
    /// Deepest penetration after each action (m), 0 for the initial state.
    pub max_penetration: Vec<f64>,
    /// Flags of each action (empty for the initial state).
    pub flags: Vec<Vec<StepFlag>>,
    /// Task metric of each state row: screwdriver yaw (rad, clockwise negative, unwrapped) or
    /// the card's planar distance to its goal (m; goal = start − 6 cm in y).
    #[serde(default)]
    pub metric: Vec<f64>,
    /// Error that stopped the run early, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl Trajectory {
    /// Set [`Self::metric`] from the state rows: each row's [`task_metric`] against the first.
    fn fill_metric(&mut self, scene: SceneKind) {
        self.metric = self
            .states
            .iter()
            .map(|s| task_metric(scene, &self.states[0], s))
            .collect();
    }
}

/// The task metric of a state row (see [`Trajectory::metric`]); `start` is the first row.
pub fn task_metric(scene: SceneKind, start: &[f64], state: &[f64]) -> f64 {
    let a = scene.action_dim();
    match scene {
        SceneKind::Screwdriver => state[a + 2],
        SceneKind::Card => {
            let goal = dips_world::scenes::card::goal_from_start(start[a], start[a + 1]);
            dips_world::scenes::card::distance_to_goal(state[a], state[a + 1], goal)
        }
    }
}

fn parse_scene(name: &str) -> Result<SceneKind, SimCliError> {
    name.parse::<SceneKind>()
        .map_err(|_| SimCliError::Scene(name.to_string()))
}

fn read(path: &Path) -> Result<String, SimCliError> {
    std::fs::read_to_string(path).map_err(|source| SimCliError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Read and validate a commands file for a scene.
pub fn load_commands(path: &Path, scene: SceneKind) -> Result<Vec<Vec<f64>>, SimCliError> {
    let p = path.display().to_string();
    let text = read(path)?;
    let cmds: Commands = serde_json::from_str(&text).map_err(|e| SimCliError::Json {
        path: p.clone(),
        message: if ["NaN", "Infinity", "inf"].iter().any(|t| text.contains(t)) {
            format!(
                "{e}; JSON has no NaN or Infinity: every dq entry must be a finite number (rad)"
            )
        } else {
            e.to_string()
        },
    })?;
    for (row, dq) in cmds.dq.iter().enumerate() {
        if dq.len() != scene.action_dim() {
            return Err(SimCliError::RowLength {
                path: p,
                row,
                scene: scene.name(),
                expected: scene.action_dim(),
                got: dq.len(),
            });
        }
        if let Some(col) = dq.iter().position(|v| !v.is_finite()) {
            return Err(SimCliError::NonFinite { path: p, row, col });
        }
    }
    Ok(cmds.dq)
}

/// Refuse a commands entry larger in magnitude than its joint's whole range in `hand`
/// ([`SimCliError::OutOfLimit`]).
pub fn check_limits(
    path: &Path,
    dq: &[Vec<f64>],
    scene: SceneKind,
    hand: &HandModel,
) -> Result<(), SimCliError> {
    for (row, r) in dq.iter().enumerate() {
        for (i, f) in scene.task_fingers().iter().enumerate() {
            let limits = hand.joint_limits(*f);
            for (joint, &(lower, upper)) in limits.iter().enumerate() {
                let col = 4 * i + joint;
                let (value, limit) = (r[col], upper - lower);
                if value.abs() > limit {
                    return Err(SimCliError::OutOfLimit {
                        path: path.display().to_string(),
                        row,
                        col,
                        value,
                        limit,
                        finger: f.name(),
                        joint,
                        lower,
                        upper,
                    });
                }
            }
        }
    }
    Ok(())
}

/// Execute commands in a fresh world; returns the trajectory and the error that stopped it.
pub fn run_commands(
    world: &mut World,
    dq: &[Vec<f64>],
) -> (Trajectory, Option<(usize, WorldError)>) {
    let mut traj = Trajectory {
        scene: world.scene().name().into(),
        hand: HandKind::World,
        states: vec![world.state()],
        valid: vec![world.valid()],
        contacts: vec![Vec::new()],
        max_penetration: vec![world.max_penetration()],
        flags: vec![Vec::new()],
        metric: Vec::new(),
        error: None,
    };
    for (k, row) in dq.iter().enumerate() {
        match world.step_action(row) {
            Ok(rep) => {
                traj.states.push(world.state());
                traj.valid.push(world.valid());
                traj.contacts.push(rep.contacts);
                traj.max_penetration.push(rep.max_penetration);
                traj.flags.push(rep.flags);
            }
            Err(e) => {
                traj.error = Some(format!("action {k}: {e}"));
                return (traj, Some((k, e)));
            }
        }
    }
    (traj, None)
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), SimCliError> {
    let text = serde_json::to_string(value).map_err(|e| SimCliError::Json {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    dips_fs::write_atomic(path, text.as_bytes()).map_err(|source| SimCliError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Execute rows of task-joint deltas (relative to the measured joints) on any hand (`--hand`
/// other than our world): the contacts are the hand's readings, the penetration the deepest of
/// them, no world flags, and the task metric of every state row. Stops at the first failed
/// action and records its error in the trajectory.
pub fn run_commands_on(hand: &mut dyn Hand, dq: &[Vec<f64>], kind: HandKind) -> Trajectory {
    let scene = hand.scene();
    let penetration = |h: &dyn Hand| {
        h.contact_readings()
            .unwrap_or_default()
            .iter()
            .map(|c| -c.phi)
            .fold(0.0, f64::max)
    };
    let mut traj = Trajectory {
        scene: scene.name().into(),
        hand: kind,
        states: vec![hand_state(hand)],
        valid: vec![hand.object_pose().valid(scene)],
        contacts: vec![Vec::new()],
        max_penetration: vec![penetration(hand)],
        flags: vec![Vec::new()],
        metric: Vec::new(),
        error: None,
    };
    for (k, row) in dq.iter().enumerate() {
        if let Err(e) = command_deltas(hand, row) {
            traj.error = Some(format!("action {k}: {e}"));
            break;
        }
        traj.states.push(hand_state(hand));
        traj.valid.push(hand.object_pose().valid(scene));
        traj.contacts
            .push(hand.contact_readings().unwrap_or_default());
        traj.max_penetration.push(penetration(hand));
        traj.flags.push(Vec::new());
    }
    traj.fill_metric(scene);
    traj
}

/// `dips sim run --hand H` for a hand other than our world.
fn run_on(args: &RunArgs, hands: &dyn Hands) -> Result<(), SimCliError> {
    let scene = parse_scene(&args.scene)?;
    let dq = load_commands(&args.commands, scene)?;
    let kind = args.hand.clone();
    if args.hand_model.is_some() || args.log.is_some() {
        return Err(anyhow::anyhow!(
            "--hand-model and --log are for our world; --hand {kind} uses the built-in Allegro v4"
        )
        .into());
    }
    check_limits(&args.commands, &dq, scene, &HandModel::allegro_v4())?;
    let options = HandOptions {
        noise: dips_world::hand::TrackerNoise::new(args.noise_position, args.noise_rotation)
            .map_err(|e| anyhow::Error::msg(crate::words::noise(&e)))?,
        seed: args.seed,
    };
    let mut hand = hands
        .open(&kind, scene, &options)
        .map_err(|e| anyhow::Error::from(e).context(format!("--hand {kind}")))?;
    let traj = run_commands_on(&mut *hand, &dq, kind.clone());
    write_json(&args.out, &traj)?;
    if let Some(e) = &traj.error {
        return Err(anyhow::anyhow!("{e} (the trajectory up to it was written)").into());
    }
    crate::output::line(&format!(
        "{}",
        serde_json::json!({
            "scene": scene.name(),
            "hand": kind,
            "actions": dq.len(),
            "final_state": traj.states.last(),
            "valid": traj.valid.last(),
            "metric": traj.metric.last(),
        })
    ))?;
    Ok(())
}

fn run(args: &RunArgs, hands: &dyn Hands) -> Result<(), SimCliError> {
    if args.hand != HandKind::World {
        return run_on(args, hands);
    }
    let scene = parse_scene(&args.scene)?;
    let dq = load_commands(&args.commands, scene)?;
    if args.noise_position != 0.0 || args.noise_rotation != 0.0 {
        return Err(anyhow::anyhow!(
            "our world reports the exact object pose; tracker noise (--noise-position, \
             --noise-rotation) needs --hand mujoco"
        )
        .into());
    }
    let hand = match &args.hand_model {
        Some(p) => HandModel::load(p).map_err(anyhow::Error::from)?,
        None => HandModel::allegro_v4(),
    };
    check_limits(&args.commands, &dq, scene, &hand)?;
    let mut world = World::with_model(scene, hand, WorldParams::for_scene(scene))
        .map_err(anyhow::Error::from)?;
    let (traj, failure) = match &args.log {
        None => run_commands(&mut world, &dq),
        Some(log) => {
            // Route every action through the recorder so the log can be replayed.
            let params = world.params().clone();
            let mut rec =
                Recorder::create(world, log, Some(params)).map_err(anyhow::Error::from)?;
            let mut traj = Trajectory {
                scene: scene.name().into(),
                hand: HandKind::World,
                states: vec![rec.inner().state()],
                valid: vec![rec.inner().valid()],
                contacts: vec![Vec::new()],
                max_penetration: vec![rec.inner().max_penetration()],
                flags: vec![Vec::new()],
                metric: Vec::new(),
                error: None,
            };
            let mut failure = None;
            for (k, row) in dq.iter().enumerate() {
                let targets = add_task_deltas(scene, rec.inner().joints(), row);
                match rec.step_world(&targets) {
                    Ok(rep) => {
                        traj.states.push(rec.inner().state());
                        traj.valid.push(rec.inner().valid());
                        traj.contacts.push(rep.contacts);
                        traj.max_penetration.push(rep.max_penetration);
                        traj.flags.push(rep.flags);
                    }
                    Err(dips_world::hand::HandError::World(e)) => {
                        traj.error = Some(format!("action {k}: {e}"));
                        failure = Some((k, e));
                        break;
                    }
                    Err(e) => return Err(anyhow::Error::from(e).into()),
                }
            }
            rec.finish().map_err(anyhow::Error::from)?;
            (traj, failure)
        }
    };
    let mut traj = traj;
    traj.fill_metric(scene);
    write_json(&args.out, &traj)?;
    if let Some((action, source)) = failure {
        return Err(SimCliError::Action { action, source });
    }
    let last = traj.states.last().cloned().unwrap_or_default();
    crate::output::line(&format!(
        "{}",
        serde_json::json!({
            "scene": scene.name(),
            "actions": dq.len(),
            "final_state": last,
            "valid": traj.valid.last(),
            "metric": traj.metric.last(),
        })
    ))?;
    Ok(())
}

fn render_cmd(args: &RenderArgs) -> anyhow::Result<()> {
    let scene = parse_scene(&args.scene)?;
    crate::render::picture_kind(&args.out, false)?;
    crate::render::check_out_dir(&args.out)?;
    let Some(path) = &args.trajectory else {
        let world = World::new(scene);
        let figure = render::figure(
            &world,
            &render::Overlay::default(),
            &format!("{} initial state", scene.name()),
            args.size,
        );
        render::write(&figure, &args.out)?;
        crate::note!("wrote {}", args.out.display());
        return Ok(());
    };
    let rec = dips_report::Recording::read(path)?;
    if rec.scene != scene {
        return Err(SimCliError::Json {
            path: path.display().to_string(),
            message: format!("trajectory is for scene {:?}", rec.scene.name()),
        }
        .into());
    }
    crate::render::draw_state(&rec, args.step, &args.out, args.size)?;
    crate::note!("wrote {}", args.out.display());
    Ok(())
}

/// Run `dips sim`.
pub fn main(args: SimArgs, hands: &dyn Hands) -> anyhow::Result<()> {
    match args.command {
        SimCommand::Run(a) => run(&a, hands)?,
        SimCommand::Render(a) => render_cmd(&a)?,
    }
    Ok(())
}
