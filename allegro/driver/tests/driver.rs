//! The driver against the emulated hand over an in-process bus: start-up, the PD's tracking,
//! and every fail-safe stop with injected faults. The emulator records the last torque frames
//! it received, so each stop is checked to have left the hand with zero torques and its servo
//! off. Timing tolerances are wide: these run on loaded 2-core machines.

use std::io::Write;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use dips_allegro::bus::CanBus;
use dips_allegro::bus::echo::EchoBus;
use dips_allegro::bus::memory::MemoryBus;
use dips_allegro::controller::{Controller, ControllerConfig, OnFault};
use dips_allegro::emu::{Emulator, EmulatorConfig, EmulatorHandle, Fault, JointModel};
use dips_allegro::gains::PdGains;
use dips_allegro::safety::{SafetyLimits, Stop};
use dips_allegro_protocol::DeviceId;
use dips_world::kinematics::{HandJoints, HandModel};
use dips_world::scenes::SceneKind;

fn start_joints() -> HandJoints {
    SceneKind::Card.default_joints()
}

fn config() -> ControllerConfig {
    ControllerConfig {
        device: DeviceId::DEFAULT,
        gains: PdGains::vendor(),
        limits: SafetyLimits::default(),
        period_ms: 3,
        hand: HandModel::allegro_v4(),
        base: SceneKind::Card.hand_base(),
        on_fault: OnFault::Report,
    }
}

fn emulated(faults: Vec<Fault>) -> (Box<dyn CanBus>, EmulatorHandle) {
    let (host, hand) = MemoryBus::pair("emulated");
    let plant = JointModel::new(SceneKind::Card, start_joints());
    let emu = Emulator::new(
        Box::new(hand),
        Box::new(plant),
        EmulatorConfig {
            faults,
            ..EmulatorConfig::default()
        },
    )
    .spawn()
    .unwrap();
    (Box::new(host), emu)
}

/// After a stop the emulator must have seen zero torques last and the servo off.
fn assert_safe(emu: &EmulatorHandle) {
    // The shutdown frames reach the emulator's motors a sub-step or two after they are sent;
    // on a loaded machine its thread may wait longer for a core. Nothing is sent after them.
    let deadline = Instant::now() + Duration::from_secs(2);
    let mut s = emu.stats();
    while (s.servo_on || s.last_pwm != [[0; 4]; 4]) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
        s = emu.stats();
    }
    assert_eq!(s.last_pwm, [[0; 4]; 4], "last torques were not zero");
    assert!(!s.servo_on, "the servo was left on: {s:?}");
}

#[test]
fn start_up_reads_the_hand_and_holds_it_where_it_is() {
    let (bus, emu) = emulated(vec![]);
    let c = Controller::start(bus, config()).unwrap();
    let b = c.bring_up().unwrap();
    assert_eq!(b.info.hardware_version, 0x0402);
    assert_eq!(b.serial, Some(*b"SAH040X1"));
    c.wait_until(Instant::now() + Duration::from_millis(300))
        .unwrap();
    let q = c.joints();
    for (a, b) in q.iter().flatten().zip(start_joints().iter().flatten()) {
        assert!((a - b).abs() < 0.02, "{a} vs {b}");
    }
    let s = c.stats();
    assert!(s.pose_sets > 30, "{s:?}");
    assert_eq!(s.bad_frames, 0);
    assert!(
        s.period.p50_ms > 1.0 && s.period.p50_ms < 10.0,
        "{:?}",
        s.period
    );
    assert_eq!(c.stop(), Stop::Requested);
    assert_safe(&emu);
}

#[test]
fn the_pd_reaches_a_step_of_0_2_rad_within_one_action() {
    let (bus, emu) = emulated(vec![]);
    let c = Controller::start(bus, config()).unwrap();
    let hand = HandModel::allegro_v4();
    let mut goal = start_joints();
    // The index finger's middle joint and the thumb's roll, away from their limits.
    goal[0][2] += 0.2;
    goal[3][0] += 0.2;
    // A step of the reference (no ramp), then one action's time.
    let t0 = Instant::now();
    c.move_to(&goal, &hand, Duration::ZERO);
    c.wait_until(t0 + Duration::from_secs(1)).unwrap();
    let q = c.joints();
    // The goal as the controller clamped it to the joint limits.
    let goal = c.goal();
    // Within 0.01 rad of the goal after one action (the vendor's kp against the joint's
    // friction leaves a dead band of a few mrad).
    assert!(
        (q[0][2] - goal[0][2]).abs() < 0.01,
        "{} vs {}",
        q[0][2],
        goal[0][2]
    );
    assert!(
        (q[3][0] - goal[3][0]).abs() < 0.01,
        "{} vs {}",
        q[3][0],
        goal[3][0]
    );
    c.stop();
    assert_safe(&emu);
}

#[test]
fn silence_fires_the_watchdog_and_the_last_torques_are_zero() {
    let (bus, emu) = emulated(vec![Fault::SilenceAt(Duration::from_millis(300))]);
    let c = Controller::start(bus, config()).unwrap();
    let t0 = Instant::now();
    let err = c
        .wait_until(t0 + Duration::from_secs(5))
        .expect_err("the watchdog must stop the loop");
    let waited = t0.elapsed();
    assert!(matches!(err, Stop::Watchdog { .. }), "{err}");
    assert!(err.to_string().starts_with("watchdog:"), "{err}");
    // Silence at 0.3 s after servo on, the watchdog 30 ms later: well inside a second.
    assert!(waited < Duration::from_secs(1), "{waited:?}");
    // The emulator is silent but still records what it receives.
    assert_safe(&emu);
}

#[test]
fn garbage_frames_are_counted_and_ignored() {
    let (bus, emu) = emulated(vec![Fault::Garbage]);
    let c = Controller::start(bus, config()).unwrap();
    c.wait_until(Instant::now() + Duration::from_millis(300))
        .unwrap();
    let s = c.stats();
    assert!(s.bad_frames > 10, "{s:?}");
    assert!(s.pose_sets > 30, "{s:?}");
    assert!(c.stopped().is_none());
    c.stop();
    assert_safe(&emu);
}

#[test]
fn a_hot_hand_is_stopped_by_the_temperature_limit() {
    let (bus, emu) = emulated(vec![Fault::HotAt(Duration::from_millis(100))]);
    let c = Controller::start(bus, config()).unwrap();
    let err = c
        .wait_until(Instant::now() + Duration::from_secs(3))
        .expect_err("the temperature limit must stop the loop");
    assert!(matches!(err, Stop::Temperature { .. }), "{err}");
    assert!(
        err.to_string().contains("95 °C") || err.to_string().contains("status"),
        "{err}"
    );
    assert_safe(&emu);
}

#[test]
fn no_hand_on_the_bus_is_a_clear_error() {
    let (host, _hand) = MemoryBus::pair("can9");
    let mut cfg = config();
    cfg.limits.startup_timeout = Duration::from_millis(100);
    let err = Controller::start(Box::new(host), cfg).unwrap_err();
    assert!(matches!(err, Stop::NoHand { .. }), "{err}");
    assert!(
        err.to_string().contains("no Allegro hand answered on can9"),
        "{err}"
    );
}

#[test]
fn a_panic_in_the_thread_that_owns_the_controller_zeroes_the_torques() {
    let (bus, emu) = emulated(vec![]);
    let c = Controller::start(bus, config()).unwrap();
    let hand = HandModel::allegro_v4();
    let mut goal = start_joints();
    goal[0][1] += 0.3;
    c.move_to(&goal, &hand, Duration::from_secs(1));
    let owner = std::thread::spawn(move || {
        let _c = c;
        std::thread::sleep(Duration::from_millis(200));
        panic!("injected fault in the program");
    });
    assert!(owner.join().is_err());
    assert_safe(&emu);
}

/// A writer the test reads back.
#[derive(Clone, Default)]
struct Capture(Arc<Mutex<Vec<u8>>>);

impl Write for Capture {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_dry_run_prints_the_torque_frames_it_sends() {
    let (host, hand) = MemoryBus::pair("emulated");
    let emu = Emulator::new(
        Box::new(hand),
        Box::new(JointModel::new(SceneKind::Card, start_joints())),
        EmulatorConfig::default(),
    )
    .spawn()
    .unwrap();
    let out = Capture::default();
    let bus = EchoBus::new(host, "can0", Box::new(out.clone()));
    let c = Controller::start(Box::new(bus), config()).unwrap();
    c.wait_until(Instant::now() + Duration::from_millis(100))
        .unwrap();
    c.stop();
    let text = String::from_utf8(out.0.lock().unwrap().clone()).unwrap();
    for id in ["180", "184", "188", "18C"] {
        assert!(
            text.contains(&format!(" can0 {id} [8] ")),
            "no {id} in\n{text}"
        );
    }
    // Start-up and shutdown as the vendor's drivers do them.
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].ends_with("can0 104 [0]"), "{}", lines[0]);
    assert!(
        lines
            .last()
            .unwrap()
            .ends_with("can0 204 [6] 00 00 00 00 00 00")
    );
    assert_safe(&emu);
}
