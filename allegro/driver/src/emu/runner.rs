//! [`Emulator`]: the firmware ([`super::firmware`]) on its own real-time thread, and the
//! [`EmulatorHandle`] a test or the driver's `allegro:emulated` hand holds.
//!
//! The thread runs one firmware tick per physics sub-step and sleeps until the next
//! sub-step's deadline, `start + k·dt` (deadlines do not drift with the time a tick takes).
//! A late tick is caught up by running the next ones back to back; a tick more than
//! [`MAX_LAG`] late (a debugger, a starved machine, a slow world step in a debug build) skips
//! ahead instead, counted in [`EmulatorStats::resyncs`]: the emulated time then lags the wall
//! clock by the time skipped, and the hand simply sends nothing meanwhile.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use dips_world::hand::ObjectPose;
use dips_world::kinematics::HandJoints;

use super::firmware::{EmulatorConfig, EmulatorStats, Firmware, Tick};
use super::{Plant, PlantError};
use crate::bus::CanBus;

/// A tick this late skips ahead instead of catching up.
pub const MAX_LAG: Duration = Duration::from_millis(20);

/// Why an emulator's run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EmulatorEnd {
    /// [`EmulatorHandle::stop`] (or the handle was dropped).
    Stopped,
    /// The host's end of the bus closed.
    BusClosed,
}

/// What a finished run did.
#[derive(Debug, Clone, PartialEq)]
pub struct EmulatorReport {
    /// The plant's name.
    pub plant: &'static str,
    /// Why it ended.
    pub end: EmulatorEnd,
    /// The firmware's counters at the end.
    pub stats: EmulatorStats,
    /// The plant's joints at the end (rad, bus order).
    pub joints: HandJoints,
    /// The object's true pose at the end, where the plant has one.
    pub truth: Option<ObjectPose>,
}

/// The emulated hand, ready to run: a bus end, a plant and a configuration.
pub struct Emulator {
    bus: Box<dyn CanBus>,
    plant: Box<dyn Plant>,
    config: EmulatorConfig,
}

impl std::fmt::Debug for Emulator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Emulator")
            .field("bus", &self.bus.name())
            .field("plant", &self.plant.name())
            .field("config", &self.config)
            .finish()
    }
}

/// What the thread shares with the handle, refreshed every sub-step.
#[derive(Debug)]
struct Shared {
    truth: Option<ObjectPose>,
    joints: HandJoints,
    stats: EmulatorStats,
    failure: Option<PlantError>,
}

impl Emulator {
    /// An emulator answering on `bus` (the hand's end) and moving `plant`.
    pub fn new(bus: Box<dyn CanBus>, plant: Box<dyn Plant>, config: EmulatorConfig) -> Emulator {
        Emulator { bus, plant, config }
    }

    /// Start the firmware on its own thread. It runs until [`EmulatorHandle::stop`], the
    /// handle's drop, or the host's end of the bus closing. An error (named after the plant)
    /// when `physics_dt` is not finite or not within 10 µs to 10 ms, or the thread cannot
    /// start.
    pub fn spawn(self) -> Result<EmulatorHandle, PlantError> {
        let Emulator { bus, plant, config } = self;
        let name = plant.name();
        let dt = config.physics_dt;
        if !(dt.is_finite() && (1e-5..=1e-2).contains(&dt)) {
            return Err(PlantError {
                plant: name,
                message: format!(
                    "emulator physics_dt = {dt} s: it must be between 1e-5 and 1e-2 s"
                ),
            });
        }
        let shared = Arc::new(Mutex::new(Shared {
            truth: plant.object_pose(),
            joints: plant.joints(),
            stats: EmulatorStats::default(),
            failure: None,
        }));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (shared, stop) = (shared.clone(), stop.clone());
            std::thread::Builder::new()
                .name(format!("allegro-emulator-{name}"))
                .spawn(move || run(bus, plant, config, &shared, &stop))
                .map_err(|e| PlantError {
                    plant: name,
                    message: format!("the emulator's thread did not start: {e}"),
                })?
        };
        Ok(EmulatorHandle {
            plant: name,
            shared,
            stop,
            thread: Some(thread),
        })
    }
}

fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    // A poisoned lock only means a reader panicked; the data is plain values.
    shared.lock().unwrap_or_else(|p| p.into_inner())
}

fn publish(shared: &Mutex<Shared>, fw: &Firmware, plant: &dyn Plant) {
    let truth = plant.object_pose();
    let mut s = lock(shared);
    s.truth = truth;
    s.joints = plant.joints();
    s.stats = fw.stats();
    if s.failure.is_none() {
        s.failure = fw.failure().cloned();
    }
}

/// The thread's body: ticks at their deadlines until stopped or the bus closes.
fn run(
    mut bus: Box<dyn CanBus>,
    mut plant: Box<dyn Plant>,
    config: EmulatorConfig,
    shared: &Mutex<Shared>,
    stop: &AtomicBool,
) -> Result<EmulatorReport, PlantError> {
    // Real time like the hand's own firmware: a late sub-step is a late pose set.
    let _ = crate::realtime::make_realtime(crate::realtime::EMULATOR_PRIORITY);
    let dt = Duration::from_secs_f64(config.physics_dt);
    let mut fw = Firmware::new(config);
    let mut origin = Instant::now();
    let mut k: u32 = 0;
    let end = loop {
        if stop.load(Ordering::Relaxed) {
            break EmulatorEnd::Stopped;
        }
        if fw.tick(&mut *bus, &mut *plant) == Tick::BusClosed {
            break EmulatorEnd::BusClosed;
        }
        publish(shared, &fw, &*plant);
        // Deadlines from a fixed origin; the origin moves only on a skip ahead, and every
        // ~ 4·10⁹ ticks (to keep the multiplier in range), both without drift.
        k = match k.checked_add(1) {
            Some(k) => k,
            None => {
                origin += dt * u32::MAX;
                1
            }
        };
        let deadline = origin + dt * k;
        let now = Instant::now();
        if deadline > now {
            std::thread::sleep(deadline - now);
        } else if now - deadline > MAX_LAG {
            origin += now - deadline;
            fw.stats_mut().resyncs += 1;
        }
    };
    publish(shared, &fw, &*plant);
    if let Some(e) = fw.failure() {
        return Err(e.clone());
    }
    Ok(EmulatorReport {
        plant: plant.name(),
        end,
        stats: fw.stats(),
        joints: plant.joints(),
        truth: plant.object_pose(),
    })
}

/// The counters as JSON (`failure`: the plant's error, if any).
fn stats_json(s: &EmulatorStats, failure: Option<String>) -> serde_json::Value {
    serde_json::json!({
        "frames_received": s.frames_received,
        "bad_frames": s.bad_frames,
        "last_bad": s.last_bad.map(|e| e.to_string()),
        "foreign_frames": s.foreign_frames,
        "torque_frames": s.torque_frames,
        "config_frames": s.config_frames,
        "requests_answered": s.requests_answered,
        "pose_sets_sent": s.pose_sets_sent,
        "garbage_frames_sent": s.garbage_frames_sent,
        "bus_errors": s.bus_errors,
        "servo_on": s.servo_on,
        "last_pwm": s.last_pwm,
        "since_servo_on_s": s.since_servo_on.map(|d| d.as_secs_f64()),
        "periods_ms": {
            "position": s.periods.position_ms,
            "imu": s.periods.imu_ms,
            "temperature": s.periods.temperature_ms,
        },
        "substeps": s.substeps,
        "emulated_s": s.emulated_s,
        "resyncs": s.resyncs,
        "silent": s.silent,
        "failure": failure,
    })
}

/// A running emulator: what the plant truly does, the firmware's counters, and the stop.
/// Dropping it stops the thread and waits for it.
#[derive(Debug)]
pub struct EmulatorHandle {
    plant: &'static str,
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<EmulatorReport, PlantError>>>,
}

impl EmulatorHandle {
    /// The plant's true object pose after the last sub-step (`None` for a plant without an
    /// object).
    pub fn truth(&self) -> Option<ObjectPose> {
        lock(&self.shared).truth.clone()
    }

    /// [`EmulatorHandle::truth`] as a function that outlives the handle (a pose source's
    /// ground truth); after the run it reads the last pose.
    pub fn truth_reader(&self) -> impl Fn() -> Option<ObjectPose> + Send + Sync + 'static {
        let shared = self.shared.clone();
        move || lock(&shared).truth.clone()
    }

    /// The plant's name (`joint-model`, `mujoco`).
    pub fn plant_name(&self) -> &'static str {
        self.plant
    }

    /// [`EmulatorHandle::stats`] as JSON, for run reports.
    pub fn stats_json(&self) -> serde_json::Value {
        let failure = self.failure().map(|e| e.to_string());
        stats_json(&self.stats(), failure)
    }

    /// The plant's true joint angles after the last sub-step (rad, bus order), unquantised.
    pub fn joints(&self) -> HandJoints {
        lock(&self.shared).joints
    }

    /// The firmware's counters after the last sub-step.
    pub fn stats(&self) -> EmulatorStats {
        lock(&self.shared).stats
    }

    /// The plant's error, once it has failed (the hand has then gone silent).
    pub fn failure(&self) -> Option<PlantError> {
        lock(&self.shared).failure.clone()
    }

    /// Whether the firmware's thread is still running.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Ask the thread to stop after its current sub-step (it does not wait).
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// Wait for the thread to end (after [`EmulatorHandle::stop`], or once the host's end of
    /// the bus closes; without either this waits for ever) and report the run: the plant's
    /// error if it failed.
    pub fn join(mut self) -> Result<EmulatorReport, PlantError> {
        self.wait()
    }

    /// [`EmulatorHandle::stop`] then [`EmulatorHandle::join`].
    pub fn shutdown(self) -> Result<EmulatorReport, PlantError> {
        self.stop();
        self.join()
    }

    fn wait(&mut self) -> Result<EmulatorReport, PlantError> {
        match self.thread.take() {
            Some(t) => t.join().unwrap_or_else(|_| {
                Err(PlantError {
                    plant: self.plant,
                    message: "the emulator's thread panicked".into(),
                })
            }),
            None => Err(PlantError {
                plant: self.plant,
                message: "the emulator was already joined".into(),
            }),
        }
    }
}

impl Drop for EmulatorHandle {
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.stop();
            let _ = self.wait();
        }
    }
}
