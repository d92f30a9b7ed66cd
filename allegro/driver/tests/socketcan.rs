//! The driver and the emulated hand over Linux SocketCAN, on `vcan0` where it exists: two
//! sockets on one virtual interface see each other's frames, so the emulator answers on one
//! and the controller drives it on the other, frames through the kernel's CAN stack.
//! Most CI machines and containers cannot create `vcan0` (it needs the `vcan` kernel module
//! and CAP_NET_ADMIN), so the test says why it skips there; on a lab machine:
//! `sudo modprobe vcan && sudo ip link add vcan0 type vcan && sudo ip link set vcan0 up`.

#![cfg(target_os = "linux")]

use std::time::{Duration, Instant};

use dips_allegro::bus::BusError;
use dips_allegro::bus::socketcan::SocketCanBus;
use dips_allegro::controller::{Controller, ControllerConfig, OnFault};
use dips_allegro::emu::{Emulator, EmulatorConfig, JointModel};
use dips_allegro::gains::PdGains;
use dips_allegro::safety::{SafetyLimits, Stop};
use dips_allegro_protocol::DeviceId;
use dips_world::kinematics::HandModel;
use dips_world::scenes::SceneKind;

#[test]
fn the_driver_drives_the_emulated_hand_over_vcan0() {
    let (host, hand) = match (SocketCanBus::open("vcan0"), SocketCanBus::open("vcan0")) {
        (Ok(a), Ok(b)) => (a, b),
        (Err(e), _) | (_, Err(e)) => {
            eprintln!(
                "skipping: no vcan0 here ({e}); create it with `modprobe vcan; ip link add \
                 vcan0 type vcan; ip link set vcan0 up` to run this test"
            );
            return;
        }
    };
    let scene = SceneKind::Card;
    let emu = Emulator::new(
        Box::new(hand),
        Box::new(JointModel::new(scene, scene.default_joints())),
        EmulatorConfig::default(),
    )
    .spawn()
    .unwrap();
    let config = ControllerConfig {
        device: DeviceId::DEFAULT,
        gains: PdGains::vendor(),
        limits: SafetyLimits::default(),
        period_ms: 3,
        hand: HandModel::allegro_v4(),
        base: scene.hand_base(),
        on_fault: OnFault::Report,
    };
    let c = Controller::start(Box::new(host), config).unwrap();
    c.wait_until(Instant::now() + Duration::from_millis(300))
        .unwrap();
    assert!(c.stats().pose_sets > 30);
    assert_eq!(c.stop(), Stop::Requested);
    std::thread::sleep(Duration::from_millis(30));
    assert_eq!(emu.stats().last_pwm, [[0; 4]; 4]);
}

#[test]
fn a_missing_interface_names_itself_and_the_fix() {
    let e = SocketCanBus::open("nosuchcan7").unwrap_err();
    assert!(matches!(e, BusError::Open { .. }), "{e}");
    let text = e.to_string();
    assert!(text.starts_with("CAN interface nosuchcan7:"), "{text}");
    assert!(text.contains("bitrate 1000000"), "{text}");
}
