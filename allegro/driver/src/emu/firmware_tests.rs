//! The firmware ticked by hand, without a thread: exact, timing-free checks.

use super::*;
use crate::bus::memory::MemoryBus;
use crate::emu::JointModel;
use dips_world::scenes::SceneKind;

/// A plant that records the torques it is stepped with and never moves.
#[derive(Debug, Default)]
struct Recorder {
    torques: Vec<HandJoints>,
    fail_at: Option<usize>,
}

impl Plant for Recorder {
    fn name(&self) -> &'static str {
        "recorder"
    }
    fn joints(&self) -> HandJoints {
        [[0.1, -0.2, 0.3, 0.012_345]; 4]
    }
    fn step(&mut self, torques_nm: &HandJoints, _dt: f64) -> Result<(), PlantError> {
        if self.fail_at == Some(self.torques.len()) {
            return Err(PlantError {
                plant: "recorder",
                message: "failed on purpose".into(),
            });
        }
        self.torques.push(*torques_nm);
        Ok(())
    }
    fn object_pose(&self) -> Option<dips_world::hand::ObjectPose> {
        None
    }
}

fn send(host: &mut MemoryBus, cmd: HostCommand) {
    let f: CanFrame = cmd.to_frame(DeviceId::DEFAULT).unwrap();
    host.send(&f).unwrap();
}

fn drain(host: &mut MemoryBus) -> Vec<CanFrame> {
    std::iter::from_fn(|| host.recv(Duration::ZERO).unwrap()).collect()
}

fn torque(finger: u8, pwm: [i16; 4]) -> HostCommand {
    HostCommand::SetTorque { finger, pwm }
}

#[test]
fn torques_reach_the_motors_one_sub_step_after_they_are_read_and_only_with_the_servo_on() {
    let (mut host, mut hand) = MemoryBus::pair("t");
    let mut plant = Recorder::default();
    let mut fw = Firmware::new(EmulatorConfig::default());
    send(&mut host, torque(1, [600, 0, 0, 0]));
    fw.tick(&mut hand, &mut plant);
    send(&mut host, HostCommand::SystemOn);
    send(&mut host, torque(1, [600, -300, 0, 0]));
    fw.tick(&mut hand, &mut plant); // read at tick 1
    fw.tick(&mut hand, &mut plant); // applied from tick 2
    send(&mut host, HostCommand::SystemOff);
    fw.tick(&mut hand, &mut plant);
    fw.tick(&mut hand, &mut plant);
    let t = &plant.torques;
    assert_eq!(t[0], [[0.0; 4]; 4]);
    assert_eq!(t[1], [[0.0; 4]; 4], "not before one sub-step");
    assert_eq!(t[2][1], [0.35, -0.175, 0.0, 0.0]);
    assert_eq!(
        t[3][1],
        [0.35, -0.175, 0.0, 0.0],
        "SYSTEM_OFF takes a sub-step too"
    );
    assert_eq!(t[4], [[0.0; 4]; 4]);
    let s = fw.stats();
    assert_eq!((s.torque_frames, s.frames_received), (2, 4));
    assert_eq!(s.last_pwm[1], [600, -300, 0, 0]);
    assert!(!s.servo_on);
    assert_eq!(s.since_servo_on, Some(Duration::from_millis(4)));
}

#[test]
fn streamed_poses_are_the_plants_joints_quantised_at_the_tick() {
    let (mut host, mut hand) = MemoryBus::pair("t");
    let start = [
        [0.123_456_7, 0.3, 0.4, 0.5],
        [-0.1, 0.2, 0.301, 0.2],
        [0.0, 0.7, 0.8, 0.9],
        [1.1, 0.3, 0.2, 0.8],
    ];
    let mut plant = JointModel::new(SceneKind::Card, start);
    let mut fw = Firmware::new(EmulatorConfig::default());
    send(&mut host, HostCommand::SetPeriod(Periods::STREAM_POSES));
    send(&mut host, HostCommand::SystemOn);
    send(&mut host, torque(0, [900, 900, -900, 900]));
    let mut sets = 0;
    for k in 0..60 {
        let before = plant.joints();
        fw.tick(&mut hand, &mut plant);
        let frames = drain(&mut host);
        if frames.is_empty() {
            continue;
        }
        assert_eq!(k % 3, 0, "tick {k}: a set every 3 ms");
        assert_eq!(frames.len(), 4);
        for (f, frame) in frames.iter().enumerate() {
            let (reply, _) = HandReply::from_frame(frame).unwrap();
            let want = before[f].map(radians_to_counts);
            assert_eq!(
                reply,
                HandReply::FingerPose {
                    finger: f as u8,
                    counts: want
                }
            );
        }
        sets += 1;
    }
    // The first set one period after SET_PERIOD, at 3 ms; then every 3 ms.
    assert_eq!(sets, 19);
    assert_eq!(fw.stats().pose_sets_sent, 19);
    // The torqued finger moved, the others did not.
    assert!(plant.joints()[0][0] > start[0][0]);
    assert_eq!(plant.joints()[2], start[2]);
}

#[test]
fn requests_are_answered_and_bad_or_foreign_frames_only_counted() {
    let (mut host, mut hand) = MemoryBus::pair("t");
    let mut plant = Recorder::default();
    let mut fw = Firmware::new(EmulatorConfig::default());
    let rtr = |cmd: Command, dev: u16| {
        CanFrame::new_remote(standard_id(cmd.id(DeviceId::DEFAULT) | dev), 0).unwrap()
    };
    host.send(&rtr(Command::Temperature(2), 0)).unwrap();
    host.send(&rtr(Command::Imu, 0)).unwrap();
    host.send(&rtr(Command::FingerPose(3), 0)).unwrap();
    host.send(&rtr(Command::Serial, 1)).unwrap(); // device 1: not us
    host.send(&CanFrame::new(standard_id(0x7FF), &[1]).unwrap())
        .unwrap();
    host.send(&CanFrame::new(standard_id(0x180), &[1, 2]).unwrap())
        .unwrap();
    send(&mut host, HostCommand::Config([0x81, 0, 0, 0, 0, 0]));
    fw.tick(&mut hand, &mut plant);
    let replies: Vec<HandReply> = drain(&mut host)
        .iter()
        .map(|f| HandReply::from_frame(f).unwrap().0)
        .collect();
    assert_eq!(
        replies,
        vec![
            HandReply::Temperature {
                finger: 2,
                celsius: [40; 4]
            },
            HandReply::Imu([0; 3]),
            HandReply::FingerPose {
                finger: 3,
                counts: plant.joints()[3].map(radians_to_counts)
            },
        ]
    );
    let s = fw.stats();
    assert_eq!(s.frames_received, 7);
    assert_eq!(s.bad_frames, 2);
    assert_eq!(s.foreign_frames, 1);
    assert_eq!(s.config_frames, 1);
    assert_eq!(s.requests_answered, 3);
    assert!(matches!(s.last_bad, Some(DecodeError::BadLength { .. })));
}

#[test]
fn faults_count_from_the_servos_first_on_in_emulated_time() {
    let (mut host, mut hand) = MemoryBus::pair("t");
    let mut plant = Recorder::default();
    let config = EmulatorConfig {
        faults: vec![
            Fault::HotAt(Duration::from_millis(5)),
            Fault::SilenceAt(Duration::from_millis(10)),
        ],
        ..EmulatorConfig::default()
    };
    let mut fw = Firmware::new(config);
    let info = HostCommand::Request(Request::HandInfo);
    let info_of = |frames: Vec<CanFrame>| match HandReply::from_frame(&frames[0]).unwrap().0 {
        HandReply::HandInfo(i) => i,
        other => panic!("{other:?}"),
    };
    for _ in 0..20 {
        fw.tick(&mut hand, &mut plant);
    }
    send(&mut host, info);
    fw.tick(&mut hand, &mut plant);
    let i = info_of(drain(&mut host));
    assert_eq!(
        (i.hardware_version, i.temperature_c, i.status.0),
        (0x0402, 45, 0)
    );
    send(&mut host, HostCommand::SystemOn);
    send(&mut host, info);
    fw.tick(&mut hand, &mut plant);
    let i = info_of(drain(&mut host));
    assert_eq!((i.temperature_c, i.status.0), (45, 0x01));
    for _ in 0..5 {
        fw.tick(&mut hand, &mut plant);
    }
    send(&mut host, info);
    fw.tick(&mut hand, &mut plant);
    let i = info_of(drain(&mut host));
    assert_eq!((i.temperature_c, i.status.0), (HOT_TEMPERATURE_C, 0x03));
    for _ in 0..5 {
        fw.tick(&mut hand, &mut plant);
    }
    send(&mut host, info);
    send(&mut host, torque(3, [0, 0, 0, 7]));
    fw.tick(&mut hand, &mut plant);
    assert!(drain(&mut host).is_empty(), "silent from 10 ms");
    assert_eq!(fw.stats().last_pwm[3], [0, 0, 0, 7]);
    assert!(fw.stats().silent);
}

#[test]
fn a_plant_error_silences_the_hand_but_frames_are_still_recorded() {
    let (mut host, mut hand) = MemoryBus::pair("t");
    let mut plant = Recorder {
        fail_at: Some(3),
        ..Recorder::default()
    };
    let mut fw = Firmware::new(EmulatorConfig::default());
    send(&mut host, HostCommand::SetPeriod(Periods::STREAM_POSES));
    for _ in 0..10 {
        fw.tick(&mut hand, &mut plant);
    }
    assert_eq!(plant.torques.len(), 3);
    let before = drain(&mut host).len();
    assert_eq!(before, 4, "one pose set at 3 ms, before the failure");
    send(&mut host, torque(0, [1, 2, 3, 4]));
    send(&mut host, HostCommand::Request(Request::Serial));
    for _ in 0..10 {
        fw.tick(&mut hand, &mut plant);
    }
    assert!(drain(&mut host).is_empty());
    assert_eq!(fw.stats().last_pwm[0], [1, 2, 3, 4]);
    assert!(
        fw.failure()
            .is_some_and(|e| e.message == "failed on purpose")
    );
    drop(host);
    assert_eq!(fw.tick(&mut hand, &mut plant), Tick::BusClosed);
}

#[test]
fn garbage_frames_decode_as_no_reply() {
    for device in [DeviceId::DEFAULT, DeviceId::new(3).unwrap()] {
        let junk = garbage(device);
        assert_eq!(junk.len(), 4);
        // What the host reads: none is a reply (the remote pose frame is a request).
        for f in &junk {
            assert!(HandReply::from_frame(f).is_err(), "{f}");
        }
    }
}
