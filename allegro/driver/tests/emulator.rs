//! The emulated hand driven through an in-process bus with raw V4 protocol frames, as the
//! driver (or the vendor's tools) would drive a real hand. Timing tolerances are wide: these
//! run on loaded machines; nothing here asserts a precise time.

use std::thread::sleep;
use std::time::{Duration, Instant};

use dips_allegro::bus::CanBus;
use dips_allegro::bus::memory::MemoryBus;
use dips_allegro::emu::{
    Emulator, EmulatorConfig, EmulatorEnd, EmulatorHandle, Fault, HOT_TEMPERATURE_C, JointModel,
    Plant, PlantError,
};
use dips_allegro_protocol::frame::{extended_id, standard_id};
use dips_allegro_protocol::message::Request;
use dips_allegro_protocol::scale::radians_to_counts;
use dips_allegro_protocol::{
    CanFrame, Command, DeviceId, HandInfo, HandReply, HostCommand, Periods,
};
use dips_world::hand::ObjectPose;
use dips_world::kinematics::{Finger, HandJoints, HandModel};
use dips_world::scenes::SceneKind;
use dips_world::world::World;
use dips_world::world::scripted::card_push_action;
use embedded_can::Frame;

const D0: DeviceId = DeviceId::DEFAULT;
/// Generous for a reply that takes a millisecond or two.
const REPLY_TIMEOUT: Duration = Duration::from_millis(500);

struct Rig {
    host: MemoryBus,
    emu: EmulatorHandle,
}

fn rig_with(plant: Box<dyn Plant>, faults: Vec<Fault>) -> Rig {
    let (host, hand) = MemoryBus::pair("test");
    let config = EmulatorConfig {
        faults,
        ..EmulatorConfig::default()
    };
    let emu = Emulator::new(Box::new(hand), plant, config)
        .spawn()
        .unwrap();
    Rig { host, emu }
}

fn card_start() -> HandJoints {
    SceneKind::Card.default_joints()
}

fn rig(faults: Vec<Fault>) -> Rig {
    rig_with(
        Box::new(JointModel::new(SceneKind::Card, card_start())),
        faults,
    )
}

impl Rig {
    fn send(&mut self, cmd: HostCommand) {
        let f: CanFrame = cmd.to_frame(D0).unwrap();
        self.host.send(&f).unwrap();
    }

    fn raw(&mut self, f: CanFrame) {
        self.host.send(&f).unwrap();
    }

    /// Every frame that arrives within `d`.
    fn frames_for(&mut self, d: Duration) -> Vec<CanFrame> {
        let end = Instant::now() + d;
        let mut out = Vec::new();
        loop {
            let now = Instant::now();
            if now >= end {
                return out;
            }
            if let Some(f) = self.host.recv(end - now).unwrap() {
                out.push(f);
            }
        }
    }

    /// The first reply that `pick` accepts, skipping others (streamed poses).
    fn wait_for<T>(&mut self, pick: impl Fn(HandReply) -> Option<T>) -> Option<T> {
        let end = Instant::now() + REPLY_TIMEOUT;
        while let Some(left) = end.checked_duration_since(Instant::now()) {
            let Some(f) = self.host.recv(left).unwrap() else {
                break;
            };
            if let Some(t) = HandReply::from_frame(&f).ok().and_then(|(r, _)| pick(r)) {
                return Some(t);
            }
        }
        None
    }

    fn hand_info(&mut self) -> Option<HandInfo> {
        self.send(HostCommand::Request(Request::HandInfo));
        self.wait_for(|r| match r {
            HandReply::HandInfo(i) => Some(i),
            _ => None,
        })
    }

    fn temperature(&mut self, finger: u8) -> Option<[u8; 4]> {
        self.send(HostCommand::Request(Request::Temperature(finger)));
        self.wait_for(|r| match r {
            HandReply::Temperature { finger: f, celsius } if f == finger => Some(celsius),
            _ => None,
        })
    }

    /// The driver's start-up: flush, servo off, hand info, serial, stream poses, servo on.
    fn start_up(&mut self) -> (HandInfo, [u8; 8]) {
        self.host.flush().unwrap();
        self.send(HostCommand::SystemOff);
        let info = self.hand_info().expect("HAND_INFO answered");
        self.send(HostCommand::Request(Request::Serial));
        let serial = self
            .wait_for(|r| match r {
                HandReply::Serial(s) => Some(s),
                _ => None,
            })
            .expect("SERIAL answered");
        self.send(HostCommand::SetPeriod(Periods::STREAM_POSES));
        self.send(HostCommand::SystemOn);
        (info, serial)
    }
}

/// The pose frames among `frames`, as (finger, counts).
fn poses(frames: &[CanFrame]) -> Vec<(u8, [i16; 4])> {
    frames
        .iter()
        .filter_map(|f| match HandReply::from_frame(f) {
            Ok((HandReply::FingerPose { finger, counts }, _)) => Some((finger, counts)),
            _ => None,
        })
        .collect()
}

fn torque(finger: u8, pwm: [i16; 4]) -> HostCommand {
    HostCommand::SetTorque { finger, pwm }
}

#[test]
fn start_up_is_answered_and_poses_stream_at_about_333_hz() {
    let mut r = rig(vec![]);
    let (info, serial) = r.start_up();
    assert_eq!(info.hardware_version, 0x0402);
    assert_eq!(info.temperature_c, 45);
    assert!(!info.status.servo_on(), "SYSTEM_OFF came first");
    assert!(!info.status.high_temperature());
    assert_eq!(&serial, b"SAH040X1");
    // The reply is exactly 7 bytes on the wire.
    r.send(HostCommand::Request(Request::HandInfo));
    let raw = r
        .frames_for(Duration::from_millis(50))
        .into_iter()
        .find(|f| f.raw_id() == u32::from(Command::HandInfo.id(D0)))
        .expect("a HAND_INFO frame");
    assert_eq!(raw.data().len(), 7);
    assert_eq!(&raw.data()[..2], &[0x02, 0x04]);
    assert_eq!(raw.data()[6] & 1, 1, "servo on now");

    r.frames_for(Duration::from_millis(20));
    let frames = r.frames_for(Duration::from_millis(300));
    let p = poses(&frames);
    assert_eq!(p.len(), frames.len(), "only poses stream");
    // Whole sets, fingers 0..3 in order (the window may open in the middle of a set).
    let first = p
        .iter()
        .position(|(f, _)| *f == 0)
        .expect("a finger-0 frame");
    for (i, (finger, _)) in p[first..].iter().enumerate() {
        assert_eq!(usize::from(*finger), i % 4, "frame {i}");
    }
    let sets = p.iter().filter(|(f, _)| *f == 0).count();
    assert!((60..=120).contains(&sets), "{sets} pose sets in 0.3 s");
    let s = r.emu.stats();
    assert!(s.servo_on);
    assert!(s.since_servo_on.is_some());
    assert_eq!(s.bad_frames, 0);
}

#[test]
fn a_constant_torque_moves_its_joint_only_while_the_servo_is_on() {
    let mut r = rig(vec![]);
    let q0 = r.emu.joints();
    // Servo off: torques are recorded but not applied.
    r.send(torque(0, [0, 300, 0, 0]));
    r.send(torque(1, [-300, 0, 0, 0]));
    sleep(Duration::from_millis(80));
    assert_eq!(r.emu.joints(), q0);
    assert_eq!(r.emu.stats().last_pwm[0], [0, 300, 0, 0]);
    // Servo on: the held torques move index joint 1 up and middle joint 0 down.
    r.send(HostCommand::SystemOn);
    r.send(torque(0, [0, 300, 0, 0]));
    r.send(torque(1, [-300, 0, 0, 0]));
    sleep(Duration::from_millis(80));
    let q1 = r.emu.joints();
    assert!(q1[0][1] > q0[0][1] + 0.01, "{} -> {}", q0[0][1], q1[0][1]);
    assert!(q1[1][0] < q0[1][0] - 0.01, "{} -> {}", q0[1][0], q1[1][0]);
    assert_eq!(q1[2], q0[2]);
    assert_eq!(q1[0][0], q0[0][0]);
    // Servo off: the motors are free, friction stops the joints and they stay.
    r.send(HostCommand::SystemOff);
    sleep(Duration::from_millis(150));
    let q2 = r.emu.joints();
    sleep(Duration::from_millis(80));
    assert_eq!(r.emu.joints(), q2, "stopped after SYSTEM_OFF");
    assert!(!r.emu.stats().servo_on);
    let lim = HandModel::allegro_v4().joint_limits(Finger::Index);
    assert!(q2[0][1] <= lim[1].1);
}

#[test]
fn reported_counts_are_the_plants_joints_quantised() {
    let start = [
        [0.123_456_7, 0.333_333, 0.5, -0.1],
        [-0.2, 0.2, 0.3, 0.4],
        [0.01, 0.02, 0.03, 0.04],
        [1.111_111, 0.3, 0.2, 0.876_543],
    ];
    let mut r = rig_with(Box::new(JointModel::new(SceneKind::Card, start)), vec![]);
    let truth = r.emu.joints();
    assert_eq!(truth, start);
    for finger in 0..4u8 {
        r.send(HostCommand::Request(Request::FingerPose(finger)));
        let counts = r
            .wait_for(|rep| match rep {
                HandReply::FingerPose { finger: f, counts } if f == finger => Some(counts),
                _ => None,
            })
            .expect("FINGER_POSE answered");
        assert_eq!(counts, truth[usize::from(finger)].map(radians_to_counts));
    }
    r.send(HostCommand::SetPeriod(Periods::STREAM_POSES));
    let p = poses(&r.frames_for(Duration::from_millis(30)));
    assert!(p.len() >= 4);
    for (finger, counts) in p {
        assert_eq!(counts, truth[usize::from(finger)].map(radians_to_counts));
    }
}

#[test]
fn set_period_zero_stops_the_stream() {
    let mut r = rig(vec![]);
    r.start_up();
    assert!(!poses(&r.frames_for(Duration::from_millis(30))).is_empty());
    r.send(HostCommand::SetPeriod(Periods::STOPPED));
    r.frames_for(Duration::from_millis(20));
    assert!(r.frames_for(Duration::from_millis(100)).is_empty());
    assert_eq!(r.emu.stats().periods, Periods::STOPPED);
}

#[test]
fn garbage_from_the_host_is_counted_and_ignored() {
    let mut r = rig(vec![]);
    let pose0 = standard_id(Command::FingerPose(0).id(D0));
    r.raw(CanFrame::new(standard_id(0x7FC), &[1, 2, 3]).unwrap()); // unknown command
    r.raw(CanFrame::new(standard_id(0x180), &[1, 2, 3, 4, 5, 6, 7]).unwrap()); // 7-byte torque
    r.raw(CanFrame::new(extended_id(0x180), &[0; 8]).unwrap()); // extended id
    r.raw(CanFrame::new(pose0, &[0; 8]).unwrap()); // a reply, not a request
    r.raw(CanFrame::new(standard_id(0x100), &[1]).unwrap()); // SYSTEM_ON with data
    r.raw(CanFrame::new_remote(standard_id(0x180), 8).unwrap()); // remote torque
    let info = r.hand_info().expect("still answering");
    assert!(!info.status.servo_on());
    // The counters are published at the end of the tick that answered.
    sleep(Duration::from_millis(20));
    let s = r.emu.stats();
    assert_eq!(s.bad_frames, 6);
    assert_eq!(s.frames_received, 7);
    assert!(r.emu.is_running());
    let report = r.emu.shutdown().unwrap();
    assert_eq!(report.end, EmulatorEnd::Stopped);
    assert_eq!(report.stats.bad_frames, 6);
}

#[test]
fn silence_stops_every_frame_but_torques_are_still_recorded() {
    let mut r = rig(vec![Fault::SilenceAt(Duration::from_millis(100))]);
    r.start_up();
    assert!(!r.frames_for(Duration::from_millis(30)).is_empty());
    // Emulated time, which a starved machine may let lag the wall clock: wait well past it.
    sleep(Duration::from_millis(300));
    r.frames_for(Duration::from_millis(10));
    r.send(HostCommand::Request(Request::HandInfo));
    r.send(torque(2, [5, 6, 7, 8]));
    r.send(torque(2, [0, 0, 0, 0]));
    assert!(r.frames_for(Duration::from_millis(100)).is_empty());
    let s = r.emu.stats();
    assert!(s.silent);
    assert_eq!(s.last_pwm[2], [0; 4]);
    assert_eq!(s.torque_frames, 2);
}

#[test]
fn garbage_fault_interleaves_malformed_frames_with_the_poses() {
    let mut r = rig(vec![Fault::Garbage]);
    r.start_up();
    let frames = r.frames_for(Duration::from_millis(60));
    let good = poses(&frames).len();
    let bad = frames
        .iter()
        .filter(|f| HandReply::from_frame(*f).is_err())
        .count();
    assert!(good >= 8, "{good} good frames");
    assert!(bad >= good / 2, "{bad} bad frames beside {good} good");
    assert!(frames.iter().any(|f| f.is_extended()));
    assert!(frames.iter().any(|f| f.is_remote_frame()));
    assert!(
        frames
            .iter()
            .any(|f| f.raw_id() == u32::from(Command::FingerPose(0).id(D0)) && f.dlc() == 3)
    );
    assert!(r.emu.stats().garbage_frames_sent >= bad as u64);
}

#[test]
fn hot_fault_reads_95_degrees_and_sets_the_status_bit() {
    let mut r = rig(vec![Fault::HotAt(Duration::from_millis(100))]);
    r.start_up();
    let info = r.hand_info().unwrap();
    assert!(!info.status.high_temperature());
    assert_eq!(r.temperature(1).unwrap(), [40; 4]);
    // Emulated time, which a starved machine may let lag the wall clock: wait well past it.
    sleep(Duration::from_millis(300));
    let info = r.hand_info().unwrap();
    assert!(info.status.high_temperature());
    assert!(info.status.servo_on());
    assert_eq!(info.temperature_c, HOT_TEMPERATURE_C);
    assert_eq!(r.temperature(3).unwrap(), [HOT_TEMPERATURE_C; 4]);
}

/// A plant that fails after `ok` steps.
struct Failing {
    steps: usize,
    ok: usize,
}

impl Plant for Failing {
    fn name(&self) -> &'static str {
        "failing"
    }
    fn joints(&self) -> HandJoints {
        [[0.0; 4]; 4]
    }
    fn step(&mut self, _: &HandJoints, _: f64) -> Result<(), PlantError> {
        self.steps += 1;
        if self.steps > self.ok {
            return Err(PlantError {
                plant: "failing",
                message: "diverged".into(),
            });
        }
        Ok(())
    }
    fn object_pose(&self) -> Option<ObjectPose> {
        None
    }
}

#[test]
fn a_plant_error_silences_the_hand_and_join_reports_it() {
    let mut r = rig_with(Box::new(Failing { steps: 0, ok: 100 }), vec![]);
    r.start_up();
    sleep(Duration::from_millis(300));
    r.frames_for(Duration::from_millis(10));
    assert!(r.frames_for(Duration::from_millis(60)).is_empty());
    assert!(r.emu.failure().is_some());
    assert!(
        r.emu.is_running(),
        "silent, not gone: the driver's watchdog must see it"
    );
    let e = r.emu.shutdown().unwrap_err();
    assert_eq!(e.to_string(), "failing plant: diverged");
}

#[test]
fn closing_the_hosts_end_ends_the_run() {
    let Rig { host, emu } = rig(vec![]);
    drop(host);
    let report = emu.join().unwrap();
    assert_eq!(report.end, EmulatorEnd::BusClosed);
    assert_eq!(report.plant, "joint-model");
    assert_eq!(report.joints, card_start());
    assert!(report.truth.is_none());
}

#[test]
fn a_bad_physics_step_is_refused() {
    let (_host, hand) = MemoryBus::pair("test");
    let config = EmulatorConfig {
        physics_dt: 0.0,
        ..EmulatorConfig::default()
    };
    let plant = Box::new(JointModel::new(SceneKind::Card, card_start()));
    let e = Emulator::new(Box::new(hand), plant, config)
        .spawn()
        .unwrap_err();
    assert!(e.to_string().contains("physics_dt"), "{e}");
}

#[test]
fn a_joint_under_constant_torque_reaches_its_hard_stop_and_stays_within_limits() {
    let model = HandModel::allegro_v4();
    let mut plant = JointModel::new(SceneKind::Screwdriver, [[0.0; 4]; 4]);
    let tau = [[0.1, -0.1, 0.1, -0.1]; 4];
    for _ in 0..1500 {
        plant.step(&tau, 1e-3).unwrap();
        for f in Finger::ALL {
            let lim = model.joint_limits(f);
            for (j, q) in plant.joints()[f.index()].iter().enumerate() {
                assert!((lim[j].0..=lim[j].1).contains(q), "{f:?} {j} {q}");
            }
        }
    }
    for f in Finger::ALL {
        let lim = model.joint_limits(f);
        let q = plant.joints()[f.index()];
        assert_eq!(q, [lim[0].1, lim[1].0, lim[2].1, lim[3].0], "{f:?}");
    }
}

#[test]
fn with_the_card_world_pushing_fingers_move_the_card_and_stay_within_limits() {
    let world = World::new(SceneKind::Card);
    let dq = card_push_action(&world, 0.02, 0.004);
    let mut plant = JointModel::new(SceneKind::Card, world.joints()).with_world_inline(world);
    let start = plant.object_pose().expect("the world's card");
    let q0 = plant.joints();
    let mut target = q0;
    for (k, f) in SceneKind::Card.task_fingers().iter().enumerate() {
        for j in 0..4 {
            target[f.index()][j] += dq[4 * k + j];
        }
    }
    // A stiff joint PD in the test (the card's kp, critically damped with the inertia).
    let (kp, kd) = (10.0, 2.0 * (10.0f64 * 1e-3).sqrt());
    let model = HandModel::allegro_v4();
    for _ in 0..300 {
        let q = plant.joints();
        let v = plant.velocities();
        let tau: HandJoints = std::array::from_fn(|f| {
            std::array::from_fn(|j| kp * (target[f][j] - q[f][j]) - kd * v[f][j])
        });
        plant.step(&tau, 1e-3).unwrap();
    }
    assert_eq!(plant.world_steps(), 6);
    let end = plant.object_pose().unwrap();
    assert!(end.valid(SceneKind::Card));
    let moved = (end.pose.translation.vector - start.pose.translation.vector).norm();
    let turned = (end.coords[2] - start.coords[2]).abs();
    assert!(
        moved > 1e-4 || turned > 1e-3,
        "card moved {moved} m, turned {turned} rad"
    );
    for f in Finger::ALL {
        let lim = model.joint_limits(f);
        for (j, q) in plant.joints()[f.index()].iter().enumerate() {
            assert!((lim[j].0..=lim[j].1).contains(q));
        }
    }
    // The non-task fingers were left alone.
    assert_eq!(
        plant.joints()[Finger::Ring.index()],
        q0[Finger::Ring.index()]
    );
}

#[test]
fn an_emulator_with_the_world_publishes_the_objects_truth() {
    let plant =
        JointModel::new(SceneKind::Card, card_start()).with_world(World::new(SceneKind::Card));
    let mut r = rig_with(Box::new(plant), vec![]);
    let truth = r.emu.truth().expect("a pose");
    assert!(truth.valid(SceneKind::Card));
    let read = r.emu.truth_reader();
    // Index and middle press down (joint 1 flexes) against the card under a held torque.
    r.start_up();
    r.send(torque(0, [0, 200, 100, 0]));
    r.send(torque(1, [0, 200, 100, 0]));
    sleep(Duration::from_millis(300));
    let truth = read().expect("a pose");
    assert!(truth.valid(SceneKind::Card));
    assert!(truth.coords.iter().all(|c| c.is_finite()));
    let model = HandModel::allegro_v4();
    let q = r.emu.joints();
    for f in Finger::ALL {
        let lim = model.joint_limits(f);
        for (j, q) in q[f.index()].iter().enumerate() {
            assert!((lim[j].0..=lim[j].1).contains(q));
        }
    }
    assert!(r.emu.failure().is_none());
    assert!(r.emu.stats_json()["substeps"].as_u64().unwrap() > 0);
    assert_eq!(r.emu.plant_name(), "joint-model");
    let report = r.emu.shutdown().unwrap();
    assert_eq!(report.truth, read());
}
