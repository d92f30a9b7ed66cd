//! The hand's firmware as a state machine, one physics sub-step per tick; the
//! real-time thread around it is [`super::Emulator`].
//!
//! What one tick at emulated time `t = k·dt` does, in order:
//!
//! 1. Read every frame the host has sent since the last tick and act on it: servo on/off,
//!    torques (applied only while the servo is on; `SYSTEM_OFF` zeroes them), streaming
//!    periods, `CONFIG` (counted, otherwise ignored), remote requests (answered at once).
//!    A frame that does not decode, or is addressed to another device id, is counted and
//!    dropped; nothing the host sends can stop or crash the firmware.
//! 2. At a stream tick (every `position_ms` of emulated time while it is non-zero) send the
//!    four `FINGER_POSE` frames, fingers 0..3, of the plant's joints at `t`, each quantised to
//!    the encoder's counts ([`radians_to_counts`]); likewise temperatures and the IMU at their
//!    periods. A pose set is timestamped and sent at its tick.
//! 3. Step the plant by `dt`, holding the torques the host's frames set.
//!
//! Time here is emulated time, sub-steps × `dt`: stream periods and fault times ([`Fault`],
//! counted from the first `SYSTEM_ON`) follow it, whatever the wall clock does.
//!
//! Bus latency. Classic CAN at 1 Mbit/s takes ≈ 111 bits, [`WIRE_TIME_S`] = 0.111 ms, to
//! carry an 8-byte data frame. An in-process bus delivers at once, so a torque takes effect
//! no earlier than one wire time after the tick that read it: `max(1, ⌈wire/dt⌉)` sub-steps
//! later (one sub-step, 1 ms, at the default `dt`): between one and two sub-steps after the
//! host sent it. The hand's replies are not delayed here (a real bus adds their wire time).

use std::collections::VecDeque;
use std::time::Duration;

use dips_allegro_protocol::frame::{extended_id, standard_id};
use dips_allegro_protocol::message::Request;
use dips_allegro_protocol::scale::radians_to_counts;
use dips_allegro_protocol::{
    CanFrame, Command, DecodeError, DeviceId, HandInfo, HandReply, HandType, HostCommand, Periods,
    Status,
};
use dips_world::kinematics::HandJoints;
use embedded_can::Frame;

use super::{Fault, Plant, PlantError};
use crate::bus::{BusError, CanBus};
use crate::units::pwm_to_newton_metres;

/// Time (s) an 8-byte classic CAN data frame takes at 1 Mbit/s (≈ 111 bits with stuffing).
pub const WIRE_TIME_S: f64 = 111e-6;
/// `HAND_INFO`'s hardware version: a V4.
pub const HARDWARE_VERSION: u16 = 0x0402;
/// What the temperatures read under [`Fault::HotAt`] (°C).
pub const HOT_TEMPERATURE_C: u8 = 95;
/// Most host frames read in one tick (a host flooding the bus cannot stall the physics).
const MAX_FRAMES_PER_TICK: usize = 1024;

/// How the emulated hand presents itself and runs.
#[derive(Debug, Clone, PartialEq)]
pub struct EmulatorConfig {
    /// The device id it answers to (0 leaving the factory).
    pub device: DeviceId,
    /// `SERIAL`'s eight ASCII bytes.
    pub serial: [u8; 8],
    /// `HAND_INFO`'s firmware version (an arbitrary 0x0100: no real hand's was copied).
    pub firmware_version: u16,
    /// Faults to inject.
    pub faults: Vec<Fault>,
    /// Physics sub-step (s), default 1 ms; between 10 µs and 10 ms. Streams tick on sub-step
    /// boundaries, so it should not exceed the pose period.
    pub physics_dt: f64,
    /// Every joint's temperature (°C), default 40.
    pub joint_temperature_c: u8,
    /// The hand's temperature in `HAND_INFO` (°C), default 45.
    pub hand_temperature_c: u8,
}

impl Default for EmulatorConfig {
    fn default() -> Self {
        EmulatorConfig {
            device: DeviceId::DEFAULT,
            serial: *b"SAH040X1",
            firmware_version: 0x0100,
            faults: Vec::new(),
            physics_dt: 1e-3,
            joint_temperature_c: 40,
            hand_temperature_c: 45,
        }
    }
}

/// What the firmware has seen and done so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EmulatorStats {
    /// Frames read from the bus, good or bad.
    pub frames_received: u64,
    /// Frames that did not decode as host commands.
    pub bad_frames: u64,
    /// Why the last bad frame did not decode.
    pub last_bad: Option<DecodeError>,
    /// Good frames addressed to another device id (ignored).
    pub foreign_frames: u64,
    /// `SET_TORQUE` frames received (whether or not the servo was on).
    pub torque_frames: u64,
    /// `CONFIG` frames received (ignored).
    pub config_frames: u64,
    /// Remote requests answered.
    pub requests_answered: u64,
    /// Pose sets (four `FINGER_POSE` frames) streamed.
    pub pose_sets_sent: u64,
    /// Malformed frames sent under [`Fault::Garbage`].
    pub garbage_frames_sent: u64,
    /// Sends the bus refused (other than a closed bus).
    pub bus_errors: u64,
    /// Whether the servo is on.
    pub servo_on: bool,
    /// The last PWM received per joint, bus order, as received (servo on or off).
    pub last_pwm: [[i16; 4]; 4],
    /// Emulated time since the servo first came on (`None` before).
    pub since_servo_on: Option<Duration>,
    /// The streaming periods in force.
    pub periods: Periods,
    /// Physics sub-steps run.
    pub substeps: u64,
    /// Emulated time (s): sub-steps × `dt`.
    pub emulated_s: f64,
    /// Times the real-time loop fell too far behind and skipped ahead instead of catching
    /// up (the emulated time then lags the wall clock).
    pub resyncs: u64,
    /// Whether the hand has stopped sending (a silence fault, or a plant error).
    pub silent: bool,
}

/// The firmware's state.
#[derive(Debug)]
pub(crate) struct Firmware {
    config: EmulatorConfig,
    dt: f64,
    step: u64,
    servo_first_on: Option<u64>,
    /// PWM set by the host and applicable now (zero while the servo is off).
    commanded: [[i16; 4]; 4],
    /// Torques read but not yet on the motors (the wire time), oldest first.
    in_flight: VecDeque<[[i16; 4]; 4]>,
    next_pose: Option<f64>,
    next_temperature: Option<f64>,
    next_imu: Option<f64>,
    stats: EmulatorStats,
    failed: Option<PlantError>,
}

/// Whether the bus is still there after a tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Tick {
    /// Go on.
    Continue,
    /// The other end closed: the firmware's run is over.
    BusClosed,
}

fn add_period(next: Option<f64>, ms: u16, t: f64) -> Option<f64> {
    let period = f64::from(ms) * 1e-3;
    next.map(|n| {
        if n + period <= t {
            t + period
        } else {
            n + period
        }
    })
}

impl Firmware {
    /// A firmware at rest: servo off, nothing streaming. `config.physics_dt` must be valid.
    pub(crate) fn new(config: EmulatorConfig) -> Firmware {
        let dt = config.physics_dt;
        let delay_steps = ((WIRE_TIME_S / dt).ceil() as usize).max(1);
        Firmware {
            config,
            dt,
            step: 0,
            servo_first_on: None,
            commanded: [[0; 4]; 4],
            in_flight: VecDeque::from(vec![[[0; 4]; 4]; delay_steps]),
            next_pose: None,
            next_temperature: None,
            next_imu: None,
            stats: EmulatorStats::default(),
            failed: None,
        }
    }

    pub(crate) fn stats(&self) -> EmulatorStats {
        self.stats
    }

    pub(crate) fn stats_mut(&mut self) -> &mut EmulatorStats {
        &mut self.stats
    }

    pub(crate) fn failure(&self) -> Option<&PlantError> {
        self.failed.as_ref()
    }

    fn now(&self) -> f64 {
        self.step as f64 * self.dt
    }

    /// Emulated seconds since the servo first came on.
    fn since_servo_on(&self) -> Option<f64> {
        self.servo_first_on
            .map(|k| self.step.saturating_sub(k) as f64 * self.dt)
    }

    fn fault_active(&self, which: impl Fn(&Fault) -> Option<Duration>) -> bool {
        let Some(since) = self.since_servo_on() else {
            return false;
        };
        self.config
            .faults
            .iter()
            .filter_map(which)
            .any(|at| since + 1e-9 >= at.as_secs_f64())
    }

    fn silent(&self) -> bool {
        self.failed.is_some()
            || self.fault_active(|f| match f {
                Fault::SilenceAt(at) => Some(*at),
                _ => None,
            })
    }

    fn hot(&self) -> bool {
        self.fault_active(|f| match f {
            Fault::HotAt(at) => Some(*at),
            _ => None,
        })
    }

    fn send(&mut self, bus: &mut dyn CanBus, frame: Option<CanFrame>) -> Tick {
        let Some(frame) = frame else {
            self.stats.bus_errors += 1;
            return Tick::Continue;
        };
        match bus.send(&frame) {
            Ok(()) => Tick::Continue,
            Err(BusError::Closed(_)) => Tick::BusClosed,
            Err(_) => {
                self.stats.bus_errors += 1;
                Tick::Continue
            }
        }
    }

    fn reply(&mut self, bus: &mut dyn CanBus, reply: HandReply) -> Tick {
        let frame = reply.to_frame::<CanFrame>(self.config.device);
        self.send(bus, frame)
    }

    fn temperatures(&self) -> [u8; 4] {
        [if self.hot() {
            HOT_TEMPERATURE_C
        } else {
            self.config.joint_temperature_c
        }; 4]
    }

    fn answer(&mut self, bus: &mut dyn CanBus, request: Request, plant: &dyn Plant) -> Tick {
        let reply = match request {
            Request::HandInfo => {
                let hot = self.hot();
                let status = u8::from(self.stats.servo_on) | if hot { 0x02 } else { 0 };
                HandReply::HandInfo(HandInfo {
                    hardware_version: HARDWARE_VERSION,
                    firmware_version: self.config.firmware_version,
                    hand_type: HandType::Right,
                    temperature_c: if hot {
                        HOT_TEMPERATURE_C
                    } else {
                        self.config.hand_temperature_c
                    },
                    status: Status(status),
                })
            }
            Request::Serial => HandReply::Serial(self.config.serial),
            Request::FingerPose(f) => pose_reply(&plant.joints(), f),
            Request::Imu => HandReply::Imu([0; 3]),
            Request::Temperature(f) => HandReply::Temperature {
                finger: f,
                celsius: self.temperatures(),
            },
        };
        if self.silent() {
            return Tick::Continue;
        }
        self.stats.requests_answered += 1;
        self.reply(bus, reply)
    }

    fn apply(&mut self, bus: &mut dyn CanBus, cmd: HostCommand, plant: &dyn Plant) -> Tick {
        let t = self.now();
        match cmd {
            HostCommand::SystemOn => {
                self.stats.servo_on = true;
                self.servo_first_on.get_or_insert(self.step);
            }
            HostCommand::SystemOff => {
                self.stats.servo_on = false;
                self.commanded = [[0; 4]; 4];
            }
            HostCommand::SetTorque { finger, pwm } => {
                self.stats.torque_frames += 1;
                let f = usize::from(finger) % 4;
                self.stats.last_pwm[f] = pwm;
                if self.stats.servo_on {
                    self.commanded[f] = pwm;
                }
            }
            HostCommand::SetPeriod(p) => {
                self.stats.periods = p;
                let first = |ms: u16| (ms > 0).then(|| t + f64::from(ms) * 1e-3);
                self.next_pose = first(p.position_ms);
                self.next_imu = first(p.imu_ms);
                self.next_temperature = first(p.temperature_ms);
            }
            HostCommand::Config(_) => self.stats.config_frames += 1,
            HostCommand::Request(r) => return self.answer(bus, r, plant),
        }
        Tick::Continue
    }

    /// Read and act on every frame waiting on the bus.
    fn read(&mut self, bus: &mut dyn CanBus, plant: &dyn Plant) -> Tick {
        // A reply that finds the host gone does not end the read: the frames the host sent
        // before it went (its shutdown's zero torques and SYSTEM_OFF) are still applied.
        let mut closed = false;
        for _ in 0..MAX_FRAMES_PER_TICK {
            let frame = match bus.recv(Duration::ZERO) {
                Ok(Some(f)) => f,
                Ok(None) => break,
                Err(BusError::Closed(_)) => return Tick::BusClosed,
                Err(_) => {
                    self.stats.bus_errors += 1;
                    break;
                }
            };
            self.stats.frames_received += 1;
            match HostCommand::from_frame(&frame) {
                Err(e) => {
                    self.stats.bad_frames += 1;
                    self.stats.last_bad = Some(e);
                }
                Ok((_, device)) if device != self.config.device => {
                    self.stats.foreign_frames += 1;
                }
                Ok((cmd, _)) => closed |= self.apply(bus, cmd, plant) == Tick::BusClosed,
            }
        }
        if closed {
            Tick::BusClosed
        } else {
            Tick::Continue
        }
    }

    /// Send what the streams owe at this tick.
    fn stream(&mut self, bus: &mut dyn CanBus, plant: &dyn Plant) -> Tick {
        let t = self.now() + 1e-9;
        let p = self.stats.periods;
        let mut frames: Vec<Option<CanFrame>> = Vec::new();
        let device = self.config.device;
        if self.next_pose.is_some_and(|n| n <= t) {
            let q = plant.joints();
            frames.extend((0..4).map(|f| pose_reply(&q, f).to_frame(device)));
            self.stats.pose_sets_sent += 1;
            self.next_pose = add_period(self.next_pose, p.position_ms, t);
            if self.config.faults.contains(&Fault::Garbage) {
                let junk = garbage(device);
                self.stats.garbage_frames_sent += junk.len() as u64;
                frames.extend(junk.into_iter().map(Some));
            }
        }
        if self.next_temperature.is_some_and(|n| n <= t) {
            let celsius = self.temperatures();
            frames.extend(
                (0..4).map(|finger| HandReply::Temperature { finger, celsius }.to_frame(device)),
            );
            self.next_temperature = add_period(self.next_temperature, p.temperature_ms, t);
        }
        if self.next_imu.is_some_and(|n| n <= t) {
            frames.push(HandReply::Imu([0; 3]).to_frame(device));
            self.next_imu = add_period(self.next_imu, p.imu_ms, t);
        }
        for frame in frames {
            if self.send(bus, frame) == Tick::BusClosed {
                return Tick::BusClosed;
            }
        }
        Tick::Continue
    }

    /// One sub-step: read the host's frames, stream, step the plant (see the module
    /// documentation). After a plant error the firmware only reads (and records) frames.
    pub(crate) fn tick(&mut self, bus: &mut dyn CanBus, plant: &mut dyn Plant) -> Tick {
        if self.read(bus, plant) == Tick::BusClosed {
            return Tick::BusClosed;
        }
        self.stats.silent = self.silent();
        if !self.stats.silent && self.stream(bus, plant) == Tick::BusClosed {
            // The host went between the read and the stream: what it sent before going (its
            // shutdown) is still in the queue, and still applied.
            let _ = self.read(bus, plant);
            return Tick::BusClosed;
        }
        // The queue holds `delay_steps` entries between ticks: what was read at this tick
        // reaches the motors `delay_steps` ticks later.
        self.in_flight.push_back(self.commanded);
        let applied = self.in_flight.pop_front().unwrap_or([[0; 4]; 4]);
        if self.failed.is_none() {
            let torques: HandJoints = applied.map(|row| row.map(pwm_to_newton_metres));
            if let Err(e) = plant.step(&torques, self.dt) {
                self.failed = Some(e);
                self.stats.silent = true;
            }
        }
        self.step += 1;
        self.stats.substeps = self.step;
        self.stats.emulated_s = self.now();
        self.stats.since_servo_on = self
            .since_servo_on()
            .map(|s| Duration::from_secs_f64(s.max(0.0)));
        Tick::Continue
    }
}

/// One finger's encoder reading of joints `q`.
fn pose_reply(q: &HandJoints, finger: u8) -> HandReply {
    let f = usize::from(finger) % 4;
    HandReply::FingerPose {
        finger,
        counts: q[f].map(radians_to_counts),
    }
}

/// The malformed frames of [`Fault::Garbage`]: an unknown command, a `FINGER_POSE` with 3
/// bytes, an extended id, a remote frame of a pose id. None decodes as a [`HandReply`].
pub fn garbage(device: DeviceId) -> Vec<CanFrame> {
    let pose = |f: u8| standard_id(Command::FingerPose(f).id(device));
    let unknown = standard_id((0x7F << 2) | u16::from(device.get()));
    let junk = [0xDE, 0xAD, 0xBE, 0xEF, 0xDE, 0xAD, 0xBE, 0xEF];
    let extended = extended_id(0x0100_0000 | u32::from(pose(1).as_raw()));
    [
        CanFrame::new(unknown, &junk),
        CanFrame::new(pose(0), &[1, 2, 3]),
        CanFrame::new(extended, &junk),
        CanFrame::new_remote(pose(2), 8),
    ]
    .into_iter()
    .flatten()
    .collect()
}

#[cfg(test)]
#[path = "firmware_tests.rs"]
mod tests;
