//! The Allegro driver against the emulated hand on MuJoCo's dynamics (issue 53): the driver's
//! PD holds and moves the hand under gravity in MuJoCo, the card's pose comes from the
//! simulated object, and a silent hand is stopped by the watchdog with zero torques last.

use std::time::{Duration, Instant};

use dips_allegro::controller::OnFault;
use dips_allegro::hand::{AllegroHand, Connection};
use dips_mujoco::plant::mujoco_plant;
use dips_world::hand::{AllegroOptions, Hand};
use dips_world::scenes::SceneKind;

#[test]
fn the_driver_moves_the_mujoco_hand_and_reports_its_loop() {
    let options = AllegroOptions::parse("emulated,gains=paper,plant=mujoco").unwrap();
    let mut hand =
        AllegroHand::open(&options, SceneKind::Card, &mujoco_plant, OnFault::Report).unwrap();
    let start = hand.joint_positions();
    let c0 = hand.object_pose().coords;
    let mut target = start;
    target[0][2] += 0.1;
    hand.command(&target).unwrap();
    hand.command(&target).unwrap();
    let q = hand.joint_positions();
    assert!(
        (q[0][2] - target[0][2]).abs() < 0.03,
        "{} vs {}",
        q[0][2],
        target[0][2]
    );
    let c1 = hand.object_pose().coords;
    assert!(c0.iter().chain(&c1).all(|x| x.is_finite()));
    let r = hand.report().unwrap();
    assert_eq!(r["plant"], "mujoco");
    assert!(r["loop"]["pose_sets"].as_u64().unwrap() > 300);
    eprintln!(
        "mujoco emulated: period {}, tracking {}",
        r["loop"]["period"], r["tracking"]
    );
}

#[test]
fn a_silent_mujoco_hand_is_stopped_by_the_watchdog() {
    let options = AllegroOptions::parse("emulated,plant=mujoco,fault=silence@0.5").unwrap();
    let c = Connection::open(&options, SceneKind::Card, &mujoco_plant, OnFault::Report).unwrap();
    let err = c
        .controller
        .wait_until(Instant::now() + Duration::from_secs(5))
        .unwrap_err();
    assert!(err.to_string().starts_with("watchdog:"), "{err}");
    let emu = c.emulator.as_ref().unwrap();
    let deadline = Instant::now() + Duration::from_secs(2);
    while (emu.stats().servo_on || emu.stats().last_pwm != [[0; 4]; 4]) && Instant::now() < deadline
    {
        std::thread::sleep(Duration::from_millis(5));
    }
    assert_eq!(emu.stats().last_pwm, [[0; 4]; 4]);
    assert!(!emu.stats().servo_on);
}
