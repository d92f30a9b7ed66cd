//! The MuJoCo hand's checks (release; run by scripts/mujoco-test.sh): the generated chain is
//! our kinematics, holding keeps both objects put, a graze does not turn the screwdriver, and
//! a missing or wrong library is an error that names scripts/fetch-mujoco.sh.

use std::path::Path;
use std::time::Instant;

use dips_cli::bench_sim::scripted_targets;
use dips_cli::sim::run_commands_on;
use dips_exec::hand_state;
use dips_mujoco::run::{HandKind, MujocoHands, run_csvto_modes};
use dips_mujoco::{
    MujocoError, MujocoHand, MujocoParams, PoseNoise, check_version, check_version_number, locate,
};
use dips_world::hand::{Hand, HandOptions, Hands, add_task_deltas};
use dips_world::kinematics::{Finger, HandJoints, HandModel};
use dips_world::scenes::{SceneKind, screwdriver};
use dips_world::world::{World, scripted};
use nalgebra::{Point3, Vector3};

/// A small deterministic generator for the random configurations.
struct Lcg(u64);

impl Lcg {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn generated_chain_matches_our_forward_kinematics() {
    let mut rng = Lcg(37);
    for scene in SceneKind::ALL {
        let mut hand = MujocoHand::new(scene).expect("MuJoCo hand");
        let model = hand.hand_model().clone();
        let base = scene.hand_base();
        let mut worst = 0.0f64;
        for _ in 0..200 {
            let q: HandJoints = Finger::ALL.map(|f| {
                model
                    .joint_limits(f)
                    .map(|(lo, hi)| lo + (hi - lo) * rng.uniform())
            });
            hand.set_joints_kinematic(&q);
            let ours = model.tip_centers(&base, &q);
            for (a, b) in hand.tip_centers().iter().zip(&ours) {
                worst = worst.max((a - b).norm());
            }
        }
        eprintln!("{}: worst fingertip difference {worst:.3e} m", scene.name());
        assert!(worst <= 1e-6, "{}: {worst} m", scene.name());
    }
}

/// Hold: 12 actions whose targets are the measured joints (zero deltas, as a controller
/// holding still sends them).
#[test]
fn holding_keeps_both_objects_put() {
    for scene in SceneKind::ALL {
        let mut hand = MujocoHand::new(scene).expect("MuJoCo hand");
        let p0 = hand.object_pose();
        let t = Instant::now();
        for _ in 0..12 {
            let q = hand.joint_positions();
            hand.command(&q).expect("hold action");
        }
        let per_action = t.elapsed().as_secs_f64() / 12.0;
        let p = hand.object_pose();
        let moved = (p.pose.translation.vector - p0.pose.translation.vector).norm();
        let turned = p.pose.rotation.angle_to(&p0.pose.rotation);
        eprintln!(
            "{} hold, 12 actions: object moved {moved:.3e} m, turned {turned:.3e} rad, coords {:?} -> {:?}; {:.1} ms per action",
            scene.name(),
            p0.coords,
            p.coords,
            per_action * 1e3
        );
        match scene {
            SceneKind::Screwdriver => {
                let r = p.pose.rotation.to_rotation_matrix();
                assert!(
                    screwdriver::is_valid(&r),
                    "cap {} m off",
                    screwdriver::cap_distance(&r)
                );
                assert!(turned < 0.05, "screwdriver turned {turned} rad");
            }
            SceneKind::Card => {
                assert!(moved < 1e-3, "card moved {moved} m");
                // The card rests on the table with its weight.
                let fz: f64 = hand
                    .contacts()
                    .iter()
                    .filter(|c| c.finger == "card" && c.part == "table")
                    .map(|c| c.force[2])
                    .sum();
                let weight = dips_world::scenes::card::MASS * dips_world::scenes::GRAVITY;
                eprintln!("card on the table: {fz:.5} N (weight {weight:.5} N)");
                assert!((fz + weight).abs() < 0.01 * weight, "card on table {fz} N");
            }
        }
    }
}

/// Grip, then hold: one squeeze action (thumb and middle 4 mm toward the shaft, the index
/// 4 mm down on the cap), then 12 actions whose targets are the measured joints (which
/// release the squeeze, as in our world's `screwdriver_gripped_then_held_stays_valid`).
#[test]
fn gripped_then_held_screwdriver_stays_valid() {
    let mut hand = MujocoHand::new(SceneKind::Screwdriver).expect("MuJoCo hand");
    let mut plan = World::new(SceneKind::Screwdriver);
    plan.set_state(&hand_state(&hand)).expect("state");
    let dq = scripted::pinch_turn_action(&plan, 0.004, 0.0);
    hand.command(&add_task_deltas(
        SceneKind::Screwdriver,
        hand.joint_positions(),
        &dq,
    ))
    .expect("grip");
    let c0 = hand.object_pose().coords;
    let mut worst = 0.0f64;
    for _ in 0..12 {
        let q = hand.joint_positions();
        hand.command(&q).expect("hold");
        assert!(hand.object_pose().valid(hand.scene()));
        worst = worst.max((hand.object_pose().coords[2] - c0[2]).abs());
    }
    let c = hand.object_pose().coords;
    eprintln!(
        "grip then hold: after the grip {c0:.4?}, after 12 holds {c:.4?}, largest |Δyaw| {worst:.4} rad"
    );
    assert!(worst < 0.05, "|Δyaw| {worst}");
}

/// Issue 10's graze, planned as a controller would (a planning world put at the hand's
/// measured state each action): the task fingers back off `gap` from the screwdriver along
/// the contact normals, then three actions move every tip 6 mm along the clockwise tangent
/// around the shaft. No finger touches it, so it must not turn.
#[test]
fn grazing_fingers_do_not_turn_the_screwdriver() {
    for gap in [0.002, 0.005] {
        let mut hand = MujocoHand::new(SceneKind::Screwdriver).expect("MuJoCo hand");
        let mut plan = World::new(SceneKind::Screwdriver);
        let scene = SceneKind::Screwdriver;
        plan.set_state(&hand_state(&hand)).expect("state");
        let dq = scripted::back_off_action(&plan, gap);
        hand.command(&add_task_deltas(scene, hand.joint_positions(), &dq))
            .expect("back off");
        let c1 = hand.object_pose().coords;
        let tips1 = hand.tip_centers();
        let pivot = screwdriver::pivot();
        let mut closest = f64::INFINITY;
        for _ in 0..3 {
            plan.set_state(&hand_state(&hand)).expect("state");
            let tips = plan.tip_centers();
            let moves: Vec<(Finger, Vector3<f64>)> = scene
                .task_fingers()
                .iter()
                .map(|f| {
                    let p: Point3<f64> = tips[f.index()];
                    let radial = Vector3::new(p.x - pivot.x, p.y - pivot.y, 0.0).normalize();
                    (*f, (-Vector3::z()).cross(&radial) * 0.006)
                })
                .collect();
            let dq = scripted::tip_moves_to_action(&plan, &moves);
            hand.command(&add_task_deltas(scene, hand.joint_positions(), &dq))
                .expect("graze");
            plan.set_state(&hand_state(&hand)).expect("state");
            for (_, phi, _) in scripted::tip_contacts(&plan) {
                closest = closest.min(phi);
            }
        }
        let c = hand.object_pose().coords;
        let travelled: Vec<f64> = hand
            .tip_centers()
            .iter()
            .zip(&tips1)
            .map(|(a, b)| (a - b).norm())
            .collect();
        let d: Vec<f64> = (0..3).map(|i| (c[i] - c1[i]).abs()).collect();
        eprintln!(
            "graze {:.0} mm: closest tip {:.2} mm after an action; |Δroll|, |Δpitch|, |Δyaw| {d:?} rad; tips moved {travelled:.4?} m; contacts now {}",
            gap * 1e3,
            closest * 1e3,
            hand.contacts().len()
        );
        for f in [Finger::Index, Finger::Middle, Finger::Thumb] {
            assert!(travelled[f.index()] > 0.015, "{f:?} moved {travelled:?}");
        }
        assert!(d[2] < 0.005, "gap {gap}: Δyaw {}", d[2]);
        assert!(d[0] < 0.005 && d[1] < 0.005, "gap {gap}: tilt {d:?}");
    }
}

/// Contact does transmit: the scripted pinch-and-turn (squeeze 4 mm, turn 6 mm along the
/// clockwise tangent, index on the cap), planned from the measured state each action, turns
/// the screwdriver clockwise and keeps it valid; the card's 3 mm press and 8 mm pushes along
/// −y move the card along −y.
#[test]
fn scripted_manipulation_moves_the_objects() {
    for scene in SceneKind::ALL {
        let mut hand = MujocoHand::new(scene).expect("MuJoCo hand");
        let mut plan = World::new(scene);
        let c0 = hand.object_pose().coords;
        let actions = match scene {
            SceneKind::Screwdriver => 4,
            SceneKind::Card => 6,
        };
        for k in 0..actions {
            let t = scripted_targets(&mut plan, &hand, true, k).expect("plan");
            hand.command(&t).expect("action");
        }
        let c = hand.object_pose().coords;
        eprintln!(
            "{} scripted manipulation, {actions} actions: {c0:.4?} -> {c:.4?}, max penetration {:.3} mm",
            scene.name(),
            hand.max_penetration() * 1e3
        );
        assert!(hand.object_pose().valid(hand.scene()));
        match scene {
            SceneKind::Screwdriver => assert!(c[2] - c0[2] < -0.2, "Δyaw {}", c[2] - c0[2]),
            SceneKind::Card => assert!(c[1] - c0[1] < -0.005, "Δy {}", c[1] - c0[1]),
        }
    }
}

/// The controller sees only `Hand`: CSVTO's closed-loop `turn` mode (re-solved from the
/// measured state every step, `dips_exec::run_mode`) runs on the MuJoCo hand as on
/// our world, and turns the screwdriver clockwise while keeping it valid.
#[test]
fn csvto_turn_mode_runs_on_the_mujoco_hand() {
    let figures = run_csvto_modes(
        HandKind::Mujoco,
        SceneKind::Screwdriver,
        &["turn".to_string()],
        1,
        &mut |_| {},
    )
    .expect("turn mode");
    let m = &figures[0];
    eprintln!(
        "CSVTO turn on the MuJoCo hand, seed 1: Δ(roll, pitch, yaw) {:.4?}, valid {}, worst contact gap {:.1} mm, {:.1} s",
        m.object_change,
        m.valid,
        m.worst_contact_gap * 1e3,
        m.seconds
    );
    assert!(m.valid);
    assert!(m.object_change[2] < -0.1, "Δyaw {}", m.object_change[2]);
}

/// The tracker's noise: seeded (same seed, same reports), of the configured size, and the
/// controller's view only (the true pose is the same as without noise).
#[test]
fn pose_noise_is_seeded_and_of_its_size() {
    let noisy = |seed| {
        let mut p = MujocoParams::for_scene(SceneKind::Card);
        p.pose_noise = Some(PoseNoise {
            position: 0.002,
            rotation: 0.01,
            seed,
        });
        MujocoHand::with_params(SceneKind::Card, HandModel::allegro_v4(), p).expect("hand")
    };
    let (mut a, mut b, mut c) = (noisy(1), noisy(1), noisy(2));
    let mut exact = MujocoHand::new(SceneKind::Card).expect("hand");
    let mut sq = 0.0;
    let n = 6;
    for _ in 0..n {
        for h in [&mut a, &mut b, &mut c, &mut exact] {
            let q = h.joint_positions();
            h.command(&q).expect("hold");
        }
        assert_eq!(a.object_pose(), b.object_pose());
        assert_ne!(a.object_pose(), c.object_pose());
        assert_eq!(a.true_pose(), exact.true_pose());
        // The scored pose is the true one, in task coordinates, noise or not.
        assert_eq!(a.true_object_pose(), exact.object_pose());
        assert_eq!(exact.true_object_pose(), exact.object_pose());
        assert_ne!(a.true_object_pose(), a.object_pose());
        let d = a.object_pose().pose.translation.vector - a.true_pose().translation.vector;
        sq += d.norm_squared();
    }
    let rms_per_axis = (sq / (3 * n) as f64).sqrt();
    assert!(
        (0.0005..0.005).contains(&rms_per_axis),
        "position noise rms {rms_per_axis}"
    );
}

/// `dips sim run`'s commands files run on both hands to the end.
#[test]
fn example_commands_run_on_both_hands() {
    for scene in SceneKind::ALL {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../../examples/{}-commands.json", scene.name()));
        let text = std::fs::read_to_string(&path).expect("examples file");
        let v: serde_json::Value = serde_json::from_str(&text).expect("json");
        let dq: Vec<Vec<f64>> = serde_json::from_value(v["dq"].clone()).expect("dq");
        for kind in [HandKind::World, HandKind::Mujoco] {
            let mut hand = MujocoHands
                .open(&kind, scene, &HandOptions::default())
                .expect("hand");
            let t = Instant::now();
            let traj = run_commands_on(hand.as_mut(), &dq, kind.clone());
            let seconds = t.elapsed().as_secs_f64();
            assert_eq!(traj.error, None);
            assert_eq!(traj.states.len(), dq.len() + 1);
            eprintln!(
                "{} {} commands: metric {:.4} -> {:.4}, {:.1} ms per action",
                scene.name(),
                kind.name(),
                traj.metric[0],
                traj.metric[dq.len()],
                1e3 * seconds / dq.len() as f64
            );
        }
    }
}

#[test]
fn missing_or_wrong_library_is_an_error_naming_the_script() {
    // The library this build linked is the right one.
    check_version().expect("the linked MuJoCo is 3.17.0");
    assert_eq!(dips_mujoco::linked_version(), locate::MUJOCO_VERSION_NUMBER);

    let wrong = check_version_number(3_016_002).unwrap_err();
    assert!(matches!(wrong, MujocoError::Library(_)));
    let text = wrong.to_string();
    assert!(text.contains("3.16.2") && text.contains("3.17.0"), "{text}");
    assert!(text.contains(locate::FETCH_SCRIPT), "{text}");

    let missing = locate::find_library(Some(Path::new("/nonexistent/mujoco/lib"))).unwrap_err();
    assert!(missing.contains("libmujoco.so.3.17.0"), "{missing}");
    assert!(missing.contains(locate::FETCH_SCRIPT), "{missing}");
    let unset = locate::find_library(None).unwrap_err();
    assert!(unset.contains(locate::LIB_DIR_VAR) && unset.contains(locate::FETCH_SCRIPT));

    // The folder this build used passes the same check.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.mujoco/3.17.0/lib");
    locate::find_library(Some(&dir)).expect("the fetched library");
}

#[test]
fn non_finite_targets_are_refused_and_change_nothing() {
    let mut hand = MujocoHand::new(SceneKind::Card).expect("MuJoCo hand");
    let before = hand.joint_positions();
    let mut q = before;
    q[1][2] = f64::NAN;
    let err = hand.command(&q).unwrap_err();
    assert!(err.to_string().contains("entry 6"), "{err}");
    assert_eq!(hand.joint_positions(), before);
}

/// Every contact pair carries our contact time constant: a `<pair>` takes its `solref` from
/// the pair defaults, not from the geoms', so until the scene wrote it on each pair MuJoCo's
/// 0.02 s applied instead of the documented 0.01 s (a 10 g card then sat 0.11 mm deep in the
/// table; now 0.03 mm).
#[test]
fn every_contact_pair_has_our_contact_time_constant() {
    for scene in [SceneKind::Screwdriver, SceneKind::Card] {
        let hand = MujocoHand::new(scene).unwrap();
        let model = mujoco_rs::prelude::MjModel::from_xml_string(hand.xml()).unwrap();
        // Friction ten times harder than the normal direction: no creep below the limit.
        assert_eq!(model.opt().impratio, 10.0, "{scene:?}");
        let solref = model.pair_solref();
        assert!(!solref.is_empty(), "{scene:?}: no contact pairs");
        for r in solref {
            assert_eq!(r[0], hand.params().contact_timeconst, "{scene:?}");
            assert_eq!(r[1], 1.0, "{scene:?}: damping ratio");
        }
    }
}
