//! [`AllegroHand`]: the Allegro Hand V4 as a [`Hand`]. Its [`Controller`] runs the joint PD
//! on its own thread; [`Hand::command`] moves the PD's reference linearly from the last
//! target to the new one over one action (1 s) and waits for it, as every hand does; the
//! object pose comes from a [`PoseFeed`]. Opened from `--hand allegro:…`
//! ([`AllegroHand::open`]) on a SocketCAN interface, or on the emulated hand.

use std::time::{Duration, Instant};

use dips_allegro_protocol::DeviceId;
use dips_world::hand::{
    AllegroBus, AllegroOptions, BadAllegro, GainsChoice, Hand, HandError, ObjectPose, PoseSource,
};
use dips_world::kinematics::{HandJoints, HandModel, first_non_finite, max_joint_difference};
use dips_world::scenes::SceneKind;
use dips_world::world::{World, WorldError};
use serde_json::json;

use crate::bus::echo::EchoBus;
use crate::bus::memory::MemoryBus;
use crate::bus::{BusError, CanBus};
use crate::controller::{Controller, ControllerConfig, OnFault};
use crate::emu::{Emulator, EmulatorConfig, EmulatorHandle, Plant, PlantError};
use crate::gains::{GainsError, PdGains};
use crate::pose::{FileFeed, PoseError, PoseFeed, TruthFeed, UdpFeed};
use crate::safety::{SafetyLimits, Stop, install_interrupt_handler};

/// One action's duration: the reference's move from the last target to the next.
pub const ACTION: Duration = Duration::from_secs(1);
/// How long a pose from a UDP tracker stays fresh.
pub const POSE_MAX_AGE: Duration = Duration::from_millis(500);
/// The speed of a move to the start pose (rad/s of the joint that moves most), at least 1 s.
pub const HOMING_RAD_PER_S: f64 = 0.5;

/// Why an Allegro hand could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The gains file.
    #[error(transparent)]
    Gains(#[from] GainsError),
    /// The bus.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The controller stopped during start-up.
    #[error("allegro start-up: {0}")]
    Start(#[from] Stop),
    /// The pose source.
    #[error(transparent)]
    Pose(#[from] PoseError),
    /// The emulated plant.
    #[error(transparent)]
    Plant(#[from] PlantError),
    /// The options cannot open a hand.
    #[error("hand allegro: {0}")]
    Spec(#[from] BadAllegro),
    /// Tracker noise asked of the Allegro hand.
    #[error(
        "allegro hand: tracker noise is simulated by the mujoco hand only; a real hand's tracker has its own"
    )]
    Noise,
}

impl From<OpenError> for HandError {
    fn from(e: OpenError) -> HandError {
        HandError::Other {
            hand: "allegro",
            message: e.to_string(),
        }
    }
}

/// Builds the emulated hand's plant for a scene and its start joints (the main workspace's
/// joint model with our world, or MuJoCo in `host/mujoco`).
pub type PlantFactory<'a> = &'a dyn Fn(SceneKind, HandJoints) -> Result<Box<dyn Plant>, PlantError>;

/// Tracking of the reference at the end of each action.
#[derive(Debug, Clone, Copy, Default)]
struct Tracking {
    actions: u64,
    sum_max: f64,
    worst: f64,
}

/// The Allegro Hand V4 through its CAN driver.
pub struct AllegroHand {
    scene: SceneKind,
    model: HandModel,
    options: AllegroOptions,
    gains: String,
    bus_name: String,
    controller: Controller,
    pose: Box<dyn PoseFeed>,
    emulator: Option<EmulatorHandle>,
    tracking: Tracking,
    last_pose: ObjectPose,
}

impl std::fmt::Debug for AllegroHand {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AllegroHand")
            .field("options", &self.options.to_string())
            .field("bus", &self.bus_name)
            .finish()
    }
}

fn gains_of(choice: &GainsChoice) -> Result<PdGains, GainsError> {
    match choice {
        GainsChoice::Vendor => Ok(PdGains::vendor()),
        GainsChoice::Paper => Ok(PdGains::paper()),
        GainsChoice::File(p) => PdGains::load(p),
    }
}

/// A running controller on its bus, with the emulated hand behind it when there is one: what
/// `dips hand info|monitor|home` use, and what [`AllegroHand`] adds a pose source to.
#[derive(Debug)]
pub struct Connection {
    /// The controller (dropped first: its shutdown frames reach the emulator).
    pub controller: Controller,
    /// The emulated hand, when the bus is the in-process one.
    pub emulator: Option<EmulatorHandle>,
    /// The bus's name.
    pub bus_name: String,
    /// The gains' name.
    pub gains: String,
    /// The hand's kinematic model.
    pub model: HandModel,
}

impl Connection {
    /// Open the bus of `options` (or the emulated hand, whose plant `plant` builds for
    /// `scene`, also under `dry-run`) and start the controller, which then holds the joints
    /// where it found them.
    pub fn open(
        options: &AllegroOptions,
        scene: SceneKind,
        plant: PlantFactory<'_>,
        on_fault: OnFault,
    ) -> Result<Connection, OpenError> {
        let gains = gains_of(&options.gains)?;
        gains.validate()?;
        let model = HandModel::allegro_v4();
        let start = World::new(scene).joints();
        let emulated = options.dry_run || options.bus == AllegroBus::Emulated;
        let label = match &options.bus {
            AllegroBus::Emulated => "emulated".to_string(),
            AllegroBus::Interface(i) => i.clone(),
        };
        // Ctrl-C stops every loop and zeroes the torques; a handler that cannot be installed
        // (another library took SIGINT) leaves the other exits safe.
        if let Err(e) = install_interrupt_handler() {
            eprintln!("dips-allegro: no Ctrl-C handler ({e}); other stops still zero the torques");
        }
        let (bus, emulator): (Box<dyn CanBus>, Option<EmulatorHandle>) = if emulated {
            let (host, hand) = MemoryBus::pair(&label);
            let config = EmulatorConfig {
                faults: options.faults.clone(),
                ..EmulatorConfig::default()
            };
            let emu = Emulator::new(Box::new(hand), plant(scene, start)?, config).spawn()?;
            let bus: Box<dyn CanBus> = if options.dry_run {
                Box::new(EchoBus::new(host, &label, Box::new(std::io::stdout())))
            } else {
                Box::new(host)
            };
            (bus, Some(emu))
        } else {
            (open_interface(&label)?, None)
        };
        let bus_name = bus.name().to_string();
        let config = ControllerConfig {
            device: DeviceId::DEFAULT,
            gains: gains.clone(),
            limits: SafetyLimits::default(),
            period_ms: 3,
            hand: model.clone(),
            base: scene.hand_base(),
            on_fault,
        };
        let controller = Controller::start(bus, config)?;
        Ok(Connection {
            controller,
            emulator,
            bus_name,
            gains: gains.name,
            model,
        })
    }

    /// Move slowly to `q` (at most [`HOMING_RAD_PER_S`] on the joint that moves most, at least
    /// 1 s) and wait for it.
    pub fn home(&self, q: &HandJoints) -> Result<(), Stop> {
        let far = max_joint_difference(&self.controller.joints(), q);
        let duration = Duration::from_secs_f64((far / HOMING_RAD_PER_S).max(1.0));
        self.controller.move_to(q, &self.model, duration);
        self.controller.wait_until(Instant::now() + duration)
    }

    /// Stop the loop (zero torques, servo off) and then the emulator; why the loop stopped.
    pub fn close(self) -> Stop {
        let stop = self.controller.stop();
        if let Some(e) = self.emulator {
            e.stop();
        }
        stop
    }
}

impl AllegroHand {
    /// Open the hand of `options` for `scene` ([`Connection::open`]), its pose source, and
    /// move slowly to the scene's start joints.
    pub fn open(
        options: &AllegroOptions,
        scene: SceneKind,
        plant: PlantFactory<'_>,
        on_fault: OnFault,
    ) -> Result<AllegroHand, OpenError> {
        let connection = Connection::open(options, scene, plant, on_fault)?;
        let start = World::new(scene).joints();
        let pose: Box<dyn PoseFeed> = match (&options.pose, &connection.emulator) {
            (Some(PoseSource::File(p)), _) => Box::new(FileFeed::open(p, scene)?),
            (Some(PoseSource::Udp(a)), _) => Box::new(UdpFeed::open(*a, scene, POSE_MAX_AGE)?),
            (_, Some(emu)) => {
                let truth = emu.truth_reader();
                Box::new(TruthFeed::new(truth))
            }
            (_, None) => {
                return Err(OpenError::Spec(BadAllegro::NoPose(
                    connection.bus_name.clone(),
                )));
            }
        };
        connection.home(&start)?;
        let last_pose = pose.pose()?;
        let Connection {
            controller,
            emulator,
            bus_name,
            gains,
            model,
        } = connection;
        Ok(AllegroHand {
            scene,
            model,
            options: options.clone(),
            gains,
            bus_name,
            controller,
            pose,
            emulator,
            tracking: Tracking::default(),
            last_pose,
        })
    }

    /// The controller (bring-up, statistics, joints).
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    /// The emulated hand, when this is one.
    pub fn emulator(&self) -> Option<&EmulatorHandle> {
        self.emulator.as_ref()
    }

    /// Stop the loop (zero torques, servo off) and the emulator; why the loop stopped.
    pub fn close(self) -> Stop {
        let AllegroHand {
            controller,
            emulator,
            ..
        } = self;
        let stop = controller.stop();
        if let Some(e) = emulator {
            e.stop();
        }
        stop
    }
}

/// A SocketCAN interface (Linux), or the error that says why not.
fn open_interface(iface: &str) -> Result<Box<dyn CanBus>, BusError> {
    #[cfg(target_os = "linux")]
    {
        Ok(Box::new(crate::bus::socketcan::SocketCanBus::open(iface)?))
    }
    #[cfg(not(target_os = "linux"))]
    {
        Err(BusError::Unsupported(iface.to_string()))
    }
}

fn stop_error(stop: Stop) -> HandError {
    HandError::Other {
        hand: "allegro",
        message: stop.to_string(),
    }
}

impl Hand for AllegroHand {
    fn name(&self) -> &'static str {
        "allegro"
    }

    fn scene(&self) -> SceneKind {
        self.scene
    }

    fn joint_positions(&self) -> HandJoints {
        self.controller.joints()
    }

    fn object_pose(&self) -> ObjectPose {
        self.last_pose.clone()
    }

    fn command(&mut self, targets: &HandJoints) -> Result<(), HandError> {
        if let Some((index, value)) = first_non_finite(targets) {
            return Err(HandError::World(WorldError::NonFinite {
                what: "joint target",
                index,
                value,
            }));
        }
        let t0 = Instant::now();
        self.controller.move_to(targets, &self.model, ACTION);
        self.controller
            .wait_until(t0 + ACTION)
            .map_err(stop_error)?;
        let goal = self.controller.goal();
        let q = self.controller.joints();
        let err = max_joint_difference(&goal, &q);
        self.tracking.actions += 1;
        self.tracking.sum_max += err;
        self.tracking.worst = self.tracking.worst.max(err);
        self.last_pose = self.pose.pose().map_err(|e| HandError::Other {
            hand: "allegro",
            message: e.to_string(),
        })?;
        Ok(())
    }

    fn report(&self) -> Option<serde_json::Value> {
        let bring_up = self.controller.bring_up().map(|b| {
            json!({
                "hardware_version": format!("{:#06x}", b.info.hardware_version),
                "firmware_version": format!("{:#06x}", b.info.firmware_version),
                "serial": b.serial.map(|s| String::from_utf8_lossy(&s).into_owned()),
                "temperature_c": b.info.temperature_c,
            })
        });
        let t = self.tracking;
        Some(json!({
            "driver": "dips-allegro",
            "hand": format!("allegro:{}", self.options),
            "bus": self.bus_name,
            "gains": self.gains,
            "pose_source": self.pose.name(),
            "plant": self.emulator.as_ref().map(|e| e.plant_name()),
            "bring_up": bring_up,
            "loop": self.controller.stats(),
            "tracking": {
                "actions": t.actions,
                "mean_max_error_rad": if t.actions > 0 { t.sum_max / t.actions as f64 } else { 0.0 },
                "worst_error_rad": t.worst,
            },
            "emulator": self.emulator.as_ref().map(|e| e.stats_json()),
        }))
    }
}
