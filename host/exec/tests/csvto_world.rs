//! CSVTO executed closed-loop in the quasi-static world (issue 4).
//!
//! Each test runs the 10 seeds by default (`DIPS_CSVTO_SEEDS=N` overrides; the
//! whole-episode statistic always runs at least 10). The file takes about four and a half
//! minutes on the 2-core machine, most of it the ten 7-mode screwdriver episodes.

use dips_exec::problems::Mode;
use dips_exec::problems::allegro::REGRASP_CLEARANCE;
use dips_exec::{ExecSettings, ModeRun, run_episode, run_mode, sample_prior_sequence};
use dips_kernel::rng::KernelRng;
use dips_world::kinematics::HandModel;
use dips_world::scenes::SceneKind;
use dips_world::world::World;

fn seeds() -> u64 {
    std::env::var("DIPS_CSVTO_SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10)
}

/// Run `modes` from the task's start with seed `seed`, returning the per-mode runs.
fn run(task: SceneKind, modes: &[Mode], seed: u64) -> Vec<ModeRun> {
    let hand = HandModel::allegro_v4();
    let mut world = World::new(task);
    let settings = ExecSettings::for_task(task);
    let mut rng = KernelRng::seed_from_u64(seed);
    let mut quiet = |_: &str| {};
    modes
        .iter()
        .map(|&m| {
            run_mode(&mut world, &hand, m, &settings, None, &mut rng, &mut quiet)
                .expect("world step failed")
        })
        .collect()
}

fn yaw(state: &[f64]) -> f64 {
    state[state.len() - 1]
}

#[test]
fn turn_mode_turns_clockwise_and_keeps_the_screwdriver_valid() {
    let mut turned = Vec::new();
    for seed in 0..seeds() {
        let runs = run(SceneKind::Screwdriver, &[Mode::Turn], seed);
        let r = &runs[0];
        let dyaw = yaw(&r.end_state) - yaw(&r.start_state);
        assert!(r.steps.iter().all(|s| s.valid), "seed {seed}: invalid");
        // Every contact finger stays in contact (world sdf within 2 mm) throughout.
        for s in &r.steps {
            assert!(
                s.tip_sdf.iter().all(|d| d.abs() < 2e-3),
                "seed {seed}: {:?}",
                s.tip_sdf
            );
        }
        turned.push(dyaw);
    }
    eprintln!("turn Δyaw per seed: {turned:?}");
    assert!(turned.iter().all(|&d| d <= -0.3), "{turned:?}");
}

fn check_regrasp(mode: Mode, fingers: &[usize]) {
    for seed in 0..seeds() {
        let runs = run(SceneKind::Screwdriver, &[mode], seed);
        let r = &runs[0];
        assert!(r.steps.iter().all(|s| s.valid), "seed {seed}: invalid");
        for (k, &i) in fingers.iter().enumerate() {
            let mid = r.min_mid_sdf(i);
            let end = r.final_sdf(i);
            let target = r.regrasp_target_distance[k];
            eprintln!(
                "{} seed {seed} finger {i}: min sdf mid-mode {mid:.4}, final sdf {end:.4}, \
                 target distance {target:.4}",
                mode.name()
            );
            // Contact is really broken, by at least δ = 1.5 cm in the world, at every step
            // before the last (the plan keeps δ + 1 mm to the object's poses at both ends of
            // each step, with the held screwdriver pinned; docs/csvto.md §4).
            assert!(mid >= REGRASP_CLEARANCE, "seed {seed}: mid sdf {mid}");
            // And remade at the end.
            assert!(end.abs() <= 3e-3, "seed {seed}: final sdf {end}");
            // Close to the regrasp target (the default fingertip position on the object).
            assert!(target <= 0.015, "seed {seed}: target distance {target}");
        }
    }
}

#[test]
fn index_regrasp_breaks_and_remakes_contact_at_the_target() {
    check_regrasp(Mode::IndexRegrasp, &[0]);
}

#[test]
fn thumb_middle_regrasp_breaks_and_remakes_contact_at_the_target() {
    check_regrasp(Mode::ThumbMiddleRegrasp, &[1, 2]);
}

fn card_dy(r: &ModeRun) -> f64 {
    let n = r.end_state.len();
    r.end_state[n - 2] - r.start_state[n - 2]
}

#[test]
fn single_finger_card_pushes_move_it_at_least_a_centimetre() {
    for seed in 0..seeds() {
        for mode in [Mode::CardIndex, Mode::CardMiddle] {
            let runs = run(SceneKind::Card, &[mode], seed);
            let dy = card_dy(&runs[0]);
            let warm = &runs[0].steps[0];
            let violation = warm.max_eq_violation.max(warm.max_ineq_violation);
            eprintln!(
                "{} seed {seed}: Δy {dy:.4} (warm-up {} iterations, violation {violation:.1e})",
                mode.name(),
                warm.iters
            );

            assert!(runs[0].steps.iter().all(|s| s.valid));
            assert!(dy <= -0.01, "{} seed {seed}: Δy {dy}", mode.name());
        }
    }
}

#[test]
fn three_both_modes_slide_the_card_four_centimetres() {
    for seed in 0..seeds() {
        let runs = run(SceneKind::Card, &[Mode::CardBoth; 3], seed);
        let n = runs[0].start_state.len();
        let dy = runs[2].end_state[n - 2] - runs[0].start_state[n - 2];
        eprintln!("both×3 seed {seed}: Δy {dy:.4}");
        assert!(dy <= -0.04, "seed {seed}: Δy {dy}");
    }
}

#[test]
fn csvto_sampled_screwdriver_episodes_turn_a_radian() {
    let n = seeds().max(10);
    let settings = ExecSettings::for_task(SceneKind::Screwdriver);
    let mut good = 0;
    for seed in 0..n {
        let mut rng = KernelRng::seed_from_u64(seed ^ 0x5eed_c0de);
        let modes = sample_prior_sequence(SceneKind::Screwdriver, &mut rng);
        let r = run_episode(
            SceneKind::Screwdriver,
            "csvto-sampled",
            seed,
            &modes,
            &settings,
            &mut |_| {},
        )
        .expect("world step failed");
        let y = r.final_yaw.unwrap_or(0.0);
        eprintln!("episode seed {seed}: final yaw {y:.3}, valid {}", r.valid);
        if r.valid && y <= -1.0 {
            good += 1;
        }
    }
    assert!(
        good * 10 >= 8 * n,
        "{good} of {n} episodes turned ≥ 1 rad and stayed valid"
    );
}

#[test]
fn prior_sequences_follow_the_task_priors() {
    let mut rng = KernelRng::seed_from_u64(1);
    for _ in 0..20 {
        let s = sample_prior_sequence(SceneKind::Screwdriver, &mut rng);
        assert_eq!(s.len(), 7);
        assert_eq!(s[0], Mode::Turn);
        assert_eq!(s[3], Mode::Turn);
        assert_eq!(s[6], Mode::Turn);
        for pair in [[s[1], s[2]], [s[4], s[5]]] {
            assert!(pair.contains(&Mode::IndexRegrasp) && pair.contains(&Mode::ThumbMiddleRegrasp));
        }
        let c = sample_prior_sequence(SceneKind::Card, &mut rng);
        assert_eq!(c.len(), 5);
        assert!(c.iter().all(|m| m.task() == SceneKind::Card));
    }
}

#[test]
fn given_initial_particles_of_the_wrong_size_are_a_typed_error() {
    use dips_exec::ExecError;
    let hand = HandModel::allegro_v4();
    let mut world = World::new(SceneKind::Screwdriver);
    let settings = ExecSettings::for_task(SceneKind::Screwdriver);
    let mut rng = KernelRng::seed_from_u64(0);
    let bad = vec![vec![0.0; 12 * 36], vec![0.0; 5]];
    let err = run_mode(
        &mut world,
        &hand,
        Mode::Turn,
        &settings,
        Some(bad),
        &mut rng,
        &mut |_| {},
    )
    .expect_err("wrong particle size must be rejected");
    assert!(
        matches!(
            err,
            ExecError::InitialParticles {
                index: 1,
                got: 5,
                expected: 432,
                ..
            }
        ),
        "{err}"
    );
    assert!(matches!(
        run_mode(
            &mut world,
            &hand,
            Mode::Turn,
            &settings,
            Some(vec![]),
            &mut rng,
            &mut |_| {}
        ),
        Err(ExecError::NoParticles)
    ));
}
