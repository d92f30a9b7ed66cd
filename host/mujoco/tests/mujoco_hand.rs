//! The MuJoCo hand's checks (release; run by scripts/mujoco-test.sh): the generated chain is
//! our kinematics, holding keeps both objects put, a graze does not turn the screwdriver, and
//! a missing or wrong library is an error that names scripts/fetch-mujoco.sh.

use std::path::Path;
use std::time::Instant;

use dips_mujoco::{MujocoError, MujocoHand, check_version, check_version_number, locate};
use dips_world::hand::Hand;
use dips_world::kinematics::{Finger, HandJoints};
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
            SceneKind::Card => assert!(moved < 1e-3, "card moved {moved} m"),
        }
    }
}

/// Issue 10's graze, planned in our world and executed on the MuJoCo hand: the task fingers
/// back off `gap` from the screwdriver along the contact normals, then three actions move
/// every tip 6 mm along the clockwise tangent around the shaft. No finger touches it.
#[test]
fn grazing_fingers_do_not_turn_the_screwdriver() {
    for gap in [0.002, 0.005] {
        let mut plan = World::new(SceneKind::Screwdriver);
        let mut targets = Vec::new();
        let dq = scripted::back_off_action(&plan, gap);
        plan.step_action(&dq).expect("back off");
        targets.push(plan.joints());
        let pivot = screwdriver::pivot();
        for _ in 0..3 {
            let tips = plan.tip_centers();
            let moves: Vec<(Finger, Vector3<f64>)> = plan
                .scene()
                .task_fingers()
                .iter()
                .map(|f| {
                    let p: Point3<f64> = tips[f.index()];
                    let radial = Vector3::new(p.x - pivot.x, p.y - pivot.y, 0.0).normalize();
                    (*f, (-Vector3::z()).cross(&radial) * 0.006)
                })
                .collect();
            let dq = scripted::tip_moves_to_action(&plan, &moves);
            plan.step_action(&dq).expect("graze");
            targets.push(plan.joints());
        }
        let mut hand = MujocoHand::new(SceneKind::Screwdriver).expect("MuJoCo hand");
        let tips0 = hand.tip_centers();
        let c0 = hand.object_pose().coords;
        hand.command(&targets[0]).expect("back off");
        let c1 = hand.object_pose().coords;
        for t in &targets[1..] {
            hand.command(t).expect("graze");
        }
        let c = hand.object_pose().coords;
        let travelled: Vec<f64> = hand
            .tip_centers()
            .iter()
            .zip(&tips0)
            .map(|(a, b)| (a - b).norm())
            .collect();
        let d: Vec<f64> = (0..3).map(|i| (c[i] - c1[i]).abs()).collect();
        eprintln!(
            "graze {:.0} mm: back-off moved the screwdriver by {:?} rad; graze |Δroll|, |Δpitch|, |Δyaw| {d:.3?} rad; tips moved {travelled:.4?} m",
            gap * 1e3,
            [c1[0] - c0[0], c1[1] - c0[1], c1[2] - c0[2]]
        );
        for f in [Finger::Index, Finger::Middle, Finger::Thumb] {
            assert!(travelled[f.index()] > 0.01, "{f:?} moved {travelled:?}");
        }
        assert!(d[2] < 0.005, "gap {gap}: Δyaw {}", d[2]);
        assert!(d[0] < 0.005 && d[1] < 0.005, "gap {gap}: tilt {d:?}");
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
