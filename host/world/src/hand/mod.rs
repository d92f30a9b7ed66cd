//! Hand I/O: the [`Hand`] trait is what a controller sees (joint positions, an object pose
//! estimate) and does (joint position targets, each held for one action). The quasi-static
//! [`World`] implements it; a [`Recorder`] wraps any hand and logs every step to a JSON-lines
//! file, and [`replay`] re-executes a log in a fresh world and checks that it reproduces the
//! recorded states.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

use crate::kinematics::{HandJoints, HandModel};
use crate::scenes::SceneKind;
use crate::world::{ObjectState, StepReport, World, WorldError, WorldParams};

pub mod allegro;
mod kind;
pub use allegro::{
    AllegroBus, AllegroOptions, BadAllegro, EmulatedPlant, EmulatorFault, GainsChoice, PoseSource,
};
pub use kind::{
    BadNoise, HandKind, HandOptions, Hands, NoiseAxis, TrackerNoise, UnknownHand, WorldHands,
    open_world,
};

/// The object's pose as a controller sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectPose {
    /// Pose of the object frame in the world (screwdriver: at its pivot).
    pub pose: Isometry3<f64>,
    /// Task coordinates: `(roll, pitch, yaw)` or `(x, y, θ)`, angles unwrapped.
    pub coords: [f64; 3],
}

impl ObjectPose {
    /// Task validity of this pose in `scene` ([`SceneKind::pose_valid`]).
    pub fn valid(&self, scene: SceneKind) -> bool {
        scene.pose_valid(&self.pose)
    }
}

/// Joint targets `q` plus a row of the task fingers' joint deltas (4 per task finger, in
/// `scene`'s task-finger order, `docs/contracts.md` §2); the other fingers keep `q`. A row too
/// short leaves NaN in the missing entries, which every hand refuses with an error.
pub fn add_task_deltas(scene: SceneKind, mut q: HandJoints, dq: &[f64]) -> HandJoints {
    for (i, f) in scene.task_fingers().iter().enumerate() {
        for (j, t) in q[f.index()].iter_mut().enumerate() {
            *t += dq.get(4 * i + j).copied().unwrap_or(f64::NAN);
        }
    }
    q
}

/// What a controller can read from and send to a hand.
pub trait Hand {
    /// Which hand this is, as `result.json`'s `hand` records it: `"world"` for our
    /// quasi-static world, `"mujoco"` for the MuJoCo hand (`host/mujoco`), `"allegro"` for
    /// the Allegro driver (`dips-allegro`).
    fn name(&self) -> &'static str;
    /// The task scene.
    fn scene(&self) -> SceneKind;
    /// Measured joint positions of all sixteen joints.
    fn joint_positions(&self) -> HandJoints;
    /// Current estimate of the object pose.
    fn object_pose(&self) -> ObjectPose;
    /// The object's true pose, where the hand knows it (a simulator with a noisy tracker):
    /// what an episode's outcome is scored on. A real hand knows only its tracker's estimate,
    /// the default.
    fn true_object_pose(&self) -> ObjectPose {
        self.object_pose()
    }
    /// Send joint position targets and hold them for one action. A hand reports only
    /// whether it did; the new state is read back with [`Hand::joint_positions`] and
    /// [`Hand::object_pose`]. (The simulated world's solver details, [`StepReport`], come
    /// from the world itself: [`World::step_targets`], or [`Recorder::step_world`].)
    fn command(&mut self, targets: &HandJoints) -> Result<(), HandError>;
    /// The contacts with their forces after the last command, where the hand can sense them
    /// (tactile fingertips, or the simulated world's solver); `None` where it cannot.
    fn contact_readings(&self) -> Option<Vec<crate::world::ContactReport>> {
        None
    }
    /// What the hand measured of itself so far, for `result.json` (a driver's loop period
    /// statistics and frame counts); `None` for simulated hands.
    fn report(&self) -> Option<serde_json::Value> {
        None
    }
}

/// Errors from hand I/O, recording and replay.
#[derive(Debug, thiserror::Error)]
pub enum HandError {
    /// The world rejected or failed the step.
    #[error(transparent)]
    World(#[from] WorldError),
    /// A log file could not be read or written.
    #[error("hand log {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A log line is not what the format expects.
    #[error("hand log {path} line {line}: {message}")]
    Format {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Another hand (a physics engine such as the MuJoCo hand, a driver) could not execute
    /// the command.
    #[error("{hand} hand: {message}")]
    Other {
        /// Which hand.
        hand: &'static str,
        /// What went wrong.
        message: String,
    },
    /// Tracker noise was asked of a hand that reports the exact object pose (our world).
    #[error(
        "{hand} hand: our world reports the exact object pose; tracker noise needs a hand with \
         a simulated tracker (mujoco)"
    )]
    NoTracker {
        /// The hand asked for.
        hand: HandKind,
    },
    /// The hand is not in this binary (`dips` has our world only).
    #[error(
        "world hand: hand {kind} is not in this binary (it has our world only); run it through \
         dips-mujoco"
    )]
    NotInBinary {
        /// The hand asked for.
        kind: HandKind,
    },
    /// Replay diverged from the recording.
    #[error(
        "replay diverged at step {step}: state differs by {deviation:e} (tolerance {tolerance:e})"
    )]
    Diverged {
        /// 0-based step.
        step: usize,
        /// Largest absolute difference in joints or object coordinates.
        deviation: f64,
        /// The tolerance used.
        tolerance: f64,
    },
}

impl Hand for World {
    fn name(&self) -> &'static str {
        "world"
    }

    fn scene(&self) -> SceneKind {
        World::scene(self)
    }

    fn joint_positions(&self) -> HandJoints {
        self.joints()
    }

    fn object_pose(&self) -> ObjectPose {
        ObjectPose {
            pose: self.object().pose(),
            coords: self.object().coords(),
        }
    }

    fn command(&mut self, targets: &HandJoints) -> Result<(), HandError> {
        self.step_targets(targets)?;
        Ok(())
    }

    fn contact_readings(&self) -> Option<Vec<crate::world::ContactReport>> {
        Some(self.last_contacts().to_vec())
    }
}

/// Serializable object pose (exact: translation, unit quaternion `w, x, y, z`, unwrapped angle).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectRecord {
    /// Translation of the object frame.
    pub translation: [f64; 3],
    /// Rotation as a unit quaternion `[w, x, y, z]`.
    pub rotation_wxyz: [f64; 4],
    /// Task coordinates `(roll, pitch, yaw)` or `(x, y, θ)`.
    pub coords: [f64; 3],
}

impl ObjectRecord {
    fn from_pose(p: &ObjectPose) -> ObjectRecord {
        let q = p.pose.rotation.quaternion();
        ObjectRecord {
            translation: p.pose.translation.vector.into(),
            rotation_wxyz: [q.w, q.i, q.j, q.k],
            coords: p.coords,
        }
    }

    fn to_state(&self, scene: SceneKind) -> ObjectState {
        let [w, x, y, z] = self.rotation_wxyz;
        let rot = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
        match scene {
            SceneKind::Screwdriver => ObjectState::Screwdriver {
                orientation: rot,
                yaw: self.coords[2],
            },
            SceneKind::Card => ObjectState::Card {
                pose: Isometry3::from_parts(
                    Translation3::from(nalgebra::Vector3::from(self.translation)),
                    rot,
                ),
                theta: self.coords[2],
            },
        }
    }
}

/// First line of a log.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct LogHeader {
    format: String,
    scene: String,
    params: Option<WorldParams>,
    joints: HandJoints,
    object: ObjectRecord,
}

/// One step of a log.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct LogStep {
    step: usize,
    targets: HandJoints,
    joints: HandJoints,
    object: ObjectRecord,
    /// The world's solver report, when the recorded hand is the simulated world.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    report: Option<StepReport>,
}

const LOG_FORMAT: &str = "dips-hand-log-1";

/// Wraps a hand and writes every step to a JSON-lines log. The log is written to
/// `PATH.partial` and renamed to `PATH` by [`Recorder::finish`].
#[derive(Debug)]
pub struct Recorder<H: Hand> {
    inner: H,
    out: BufWriter<File>,
    partial: PathBuf,
    path: PathBuf,
    steps: usize,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> HandError + '_ {
    move |source| HandError::Io {
        path: path.display().to_string(),
        source,
    }
}

impl<H: Hand> Recorder<H> {
    /// Start a log at `path` from the hand's current state. `params` (the world's parameters,
    /// when the hand is a simulated world) lets [`replay`] rebuild the same world.
    pub fn create(
        inner: H,
        path: &Path,
        params: Option<WorldParams>,
    ) -> Result<Recorder<H>, HandError> {
        let mut partial = path.as_os_str().to_owned();
        partial.push(".partial");
        let partial = PathBuf::from(partial);
        let file = File::create(&partial).map_err(io_err(&partial))?;
        let mut out = BufWriter::new(file);
        let header = LogHeader {
            format: LOG_FORMAT.into(),
            scene: inner.scene().name().into(),
            params,
            joints: inner.joint_positions(),
            object: ObjectRecord::from_pose(&inner.object_pose()),
        };
        let line = serde_json::to_string(&header).map_err(|e| HandError::Format {
            path: partial.display().to_string(),
            line: 1,
            message: e.to_string(),
        })?;
        writeln!(out, "{line}").map_err(io_err(&partial))?;
        Ok(Recorder {
            inner,
            out,
            partial,
            path: path.to_path_buf(),
            steps: 0,
        })
    }

    /// The wrapped hand.
    pub fn inner(&self) -> &H {
        &self.inner
    }

    /// Flush, move the log into place and return the wrapped hand.
    pub fn finish(mut self) -> Result<H, HandError> {
        self.out.flush().map_err(io_err(&self.partial))?;
        std::fs::rename(&self.partial, &self.path).map_err(io_err(&self.path))?;
        Ok(self.inner)
    }
}

impl<H: Hand> Hand for Recorder<H> {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn scene(&self) -> SceneKind {
        self.inner.scene()
    }

    fn joint_positions(&self) -> HandJoints {
        self.inner.joint_positions()
    }

    fn object_pose(&self) -> ObjectPose {
        self.inner.object_pose()
    }

    fn command(&mut self, targets: &HandJoints) -> Result<(), HandError> {
        self.inner.command(targets)?;
        self.log_step(targets, None)
    }

    fn contact_readings(&self) -> Option<Vec<crate::world::ContactReport>> {
        self.inner.contact_readings()
    }

    fn report(&self) -> Option<serde_json::Value> {
        self.inner.report()
    }
}

impl Recorder<World> {
    /// Step the recorded world to `targets` and log it with the world's solver report, which
    /// is returned.
    pub fn step_world(&mut self, targets: &HandJoints) -> Result<StepReport, HandError> {
        let report = self.inner.step_targets(targets)?;
        self.log_step(targets, Some(report.clone()))?;
        Ok(report)
    }
}

impl<H: Hand> Recorder<H> {
    /// Append the step just taken to the log.
    fn log_step(
        &mut self,
        targets: &HandJoints,
        report: Option<StepReport>,
    ) -> Result<(), HandError> {
        let step = LogStep {
            step: self.steps,
            targets: *targets,
            joints: self.inner.joint_positions(),
            object: ObjectRecord::from_pose(&self.inner.object_pose()),
            report,
        };
        let line = serde_json::to_string(&step).map_err(|e| HandError::Format {
            path: self.partial.display().to_string(),
            line: self.steps + 2,
            message: e.to_string(),
        })?;
        writeln!(self.out, "{line}").map_err(io_err(&self.partial))?;
        self.steps += 1;
        Ok(())
    }
}

/// Outcome of a replay.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayReport {
    /// The scene.
    pub scene: SceneKind,
    /// Steps replayed.
    pub steps: usize,
    /// Largest absolute difference between replayed and recorded joints/object coordinates.
    pub max_deviation: f64,
    /// Replayed raw state rows (initial state first).
    pub states: Vec<Vec<f64>>,
}

/// Replay tolerance: JSON numbers round-trip f64 to within an ulp, and the world is smooth, so
/// a faithful replay agrees to ~1e-12; anything above this is a divergence.
pub const REPLAY_TOLERANCE: f64 = 1e-9;

/// Re-run a log in a fresh world built from its header (default hand model) and check every
/// recorded state.
pub fn replay(path: &Path) -> Result<ReplayReport, HandError> {
    let p = path.display().to_string();
    let file = File::open(path).map_err(io_err(path))?;
    let mut lines = BufReader::new(file).lines();
    let fmt = |line: usize, message: String| HandError::Format {
        path: p.clone(),
        line,
        message,
    };
    let first = lines
        .next()
        .ok_or_else(|| fmt(1, "empty log".into()))?
        .map_err(io_err(path))?;
    let header: LogHeader = serde_json::from_str(&first).map_err(|e| fmt(1, e.to_string()))?;
    if header.format != LOG_FORMAT {
        return Err(fmt(
            1,
            format!("format {:?}, expected {LOG_FORMAT:?}", header.format),
        ));
    }
    let scene = header
        .scene
        .parse::<SceneKind>()
        .map_err(|_| fmt(1, format!("unknown scene {:?}", header.scene)))?;
    let params = header
        .params
        .clone()
        .unwrap_or_else(|| WorldParams::for_scene(scene));
    let mut world = World::with_model(scene, HandModel::allegro_v4(), params)
        .map_err(|e| fmt(1, e.to_string()))?;
    world.set_joints(&header.joints);
    world.set_object(header.object.to_state(scene));
    let mut states = vec![world.state()];
    let mut max_deviation: f64 = 0.0;
    let mut steps = 0;
    for (i, line) in lines.enumerate() {
        let line = line.map_err(io_err(path))?;
        if line.trim().is_empty() {
            continue;
        }
        let rec: LogStep = serde_json::from_str(&line).map_err(|e| fmt(i + 2, e.to_string()))?;
        world.command(&rec.targets)?;
        let mut dev: f64 = 0.0;
        for (a, b) in world
            .joints()
            .as_flattened()
            .iter()
            .zip(rec.joints.as_flattened())
        {
            dev = dev.max((a - b).abs());
        }
        for (a, b) in world.object().coords().iter().zip(&rec.object.coords) {
            dev = dev.max((a - b).abs());
        }
        if dev > REPLAY_TOLERANCE {
            return Err(HandError::Diverged {
                step: rec.step,
                deviation: dev,
                tolerance: REPLAY_TOLERANCE,
            });
        }
        max_deviation = max_deviation.max(dev);
        states.push(world.state());
        steps += 1;
    }
    Ok(ReplayReport {
        scene,
        steps,
        max_deviation,
        states,
    })
}
