//! Finite-difference checks of the problem's Jacobians and cost gradient, and small
//! open-loop solves.

use dips_kernel::rng::KernelRng;

use super::allegro::{AllegroProblem, ProblemSpec};
use super::init::default_particles;
use super::mode::Mode;
use dips_csvto::{CsvtoSettings, Problem, StepConstraints, solve};
use dips_world::kinematics::HandModel;
use dips_world::scenes::SceneKind;

fn start_state(task: SceneKind) -> Vec<f64> {
    let q = task.default_joints();
    let mut s = Vec::new();
    for f in task.task_fingers() {
        s.extend_from_slice(&q[f.index()]);
    }
    s.extend_from_slice(&[0.0, 0.0, 0.0]);
    s
}

fn spec(mode: Mode, horizon: usize) -> ProblemSpec {
    let task = SceneKind::from(mode.task());
    ProblemSpec {
        task,
        mode,
        horizon,
        start: start_state(task),
        goal: [0.0, 0.0, -0.5],
    }
}

fn perturbed(problem: &AllegroProblem, mode: Mode, seed: u64) -> Vec<f64> {
    let mut rng = KernelRng::seed_from_u64(seed);
    let mut x = default_particles(problem, mode, 1, &mut rng).remove(0);
    // Move the object off its start a little so every term has a derivative.
    let n = problem.row_dim();
    let nq = 4 * problem.fingers();
    for t in 0..problem.horizon() {
        x[t * n + nq] += 0.01 * (t as f64 + 1.0);
        x[t * n + nq + 1] -= 0.007 * (t as f64 + 1.0);
        x[t * n + nq + 2] -= 0.02 * (t as f64 + 1.0);
    }
    x
}

#[test]
fn constraint_jacobians_match_finite_differences() {
    let hand = HandModel::allegro_v4();
    for (m, &mode) in [
        Mode::Turn,
        Mode::IndexRegrasp,
        Mode::ThumbMiddleRegrasp,
        Mode::CardIndex,
        Mode::CardBoth,
        Mode::CardRegrasp,
    ]
    .iter()
    .enumerate()
    {
        let p = AllegroProblem::new(&hand, &spec(mode, 3)).expect("valid spec");
        let x = perturbed(&p, mode, 7 + m as u64);
        let (n, ds) = (p.row_dim(), p.state_dim());
        let width = ds + n;
        for t in 1..3 {
            let mut local: Vec<f64> = x[(t - 1) * n..(t - 1) * n + ds].to_vec();
            local.extend_from_slice(&x[t * n..(t + 1) * n]);
            let eval = |v: &[f64]| {
                let mut sc = StepConstraints::default();
                sc.reset(p.n_eq(t), p.n_ineq(t), width);
                p.step_constraints(t, &v[..ds], &v[ds..], &mut sc);
                sc
            };
            let base = eval(&local);
            let eps = 1e-6;
            for c in 0..width {
                let mut up = local.clone();
                up[c] += eps;
                let mut dn = local.clone();
                dn[c] -= eps;
                let (a, b) = (eval(&up), eval(&dn));
                for r in 0..base.eq.len() {
                    let fd = (a.eq[r] - b.eq[r]) / (2.0 * eps);
                    let an = base.jac_eq[r * width + c];
                    assert!(
                        (fd - an).abs() < 1e-5 * (1.0 + fd.abs()),
                        "{mode:?} t={t} eq row {r} col {c}: fd {fd} vs {an}"
                    );
                }
                for r in 0..base.ineq.len() {
                    let fd = (a.ineq[r] - b.ineq[r]) / (2.0 * eps);
                    let an = base.jac_ineq[r * width + c];
                    assert!(
                        (fd - an).abs() < 1e-5 * (1.0 + fd.abs()),
                        "{mode:?} t={t} ineq row {r} col {c}: fd {fd} vs {an}"
                    );
                }
            }
        }
    }
}

#[test]
fn cost_gradient_matches_finite_differences() {
    let hand = HandModel::allegro_v4();
    for (m, &mode) in [Mode::Turn, Mode::IndexRegrasp, Mode::CardMiddle]
        .iter()
        .enumerate()
    {
        let p = AllegroProblem::new(&hand, &spec(mode, 3)).expect("valid spec");
        let x = perturbed(&p, mode, 30 + m as u64);
        let mut g = vec![0.0; x.len()];
        p.cost(&x, &mut g);
        let eps = 1e-6;
        for c in 0..x.len() {
            let mut up = x.clone();
            up[c] += eps;
            let mut dn = x.clone();
            dn[c] -= eps;
            let mut s = vec![0.0; x.len()];
            let fd = (p.cost(&up, &mut s) - p.cost(&dn, &mut s)) / (2.0 * eps);
            assert!(
                (fd - g[c]).abs() < 1e-4 * (1.0 + fd.abs()),
                "{mode:?} col {c}: fd {fd} vs {}",
                g[c]
            );
        }
    }
}

#[test]
fn counts_match_the_spec_bookkeeping() {
    let hand = HandModel::allegro_v4();
    let p = AllegroProblem::new(&hand, &spec(Mode::Turn, 12)).expect("valid spec");
    // 3 contact fingers: 7 each + 3 torques; 8 friction faces + min force each.
    assert_eq!(p.n_eq(0), 24);
    assert_eq!(p.n_ineq(0), 27);
    assert_eq!(p.row_dim(), 15 + 12 + 9);
    // Index regrasp from the default grasp (every finger in contact): 2 contact fingers, 3
    // torques, 3 pinned object coordinates, 4 free-motion rows, and 2 lift-off rows in the
    // first step only; two clearance rows (end and start pose of the step) before the last
    // step, the terminal contact at the last.
    let p = AllegroProblem::new(&hand, &spec(Mode::IndexRegrasp, 12)).expect("valid spec");
    assert_eq!(p.n_eq(0), 14 + 3 + 3 + 4 + 2);
    assert_eq!(p.n_eq(1), 14 + 3 + 3 + 4);
    assert_eq!(p.n_eq(11), 14 + 3 + 3 + 4 + 1);
    assert_eq!(p.n_ineq(0), 18 + 2);
    assert_eq!(p.n_ineq(11), 18);
    // Thumb-middle regrasp: the index alone, the yaw pinned, two regrasping fingers, lift-off
    // rows for those of them touching the handle at the start.
    let s = spec(Mode::ThumbMiddleRegrasp, 12);
    let p = AllegroProblem::new(&hand, &s).expect("valid spec");
    let touching = [1, 2]
        .into_iter()
        .filter(|&i| {
            let q = [
                s.start[4 * i],
                s.start[4 * i + 1],
                s.start[4 * i + 2],
                s.start[4 * i + 3],
            ];
            p.finger_sdf(i, &q, &[0.0; 3]) < super::allegro::LIFT_OFF_CONTACT
        })
        .count();
    assert!(touching >= 1);
    assert_eq!(p.n_eq(0), 7 + 3 + 1 + 8 + 2 * touching);
    assert_eq!(p.n_eq(11), 7 + 3 + 1 + 8 + 2);
    assert_eq!(p.n_ineq(0), 9 + 4);
    // A regrasping finger that starts clear of the object has no lift-off rows.
    let mut lifted = spec(Mode::IndexRegrasp, 12);
    lifted.start[2] -= 0.4;
    let p = AllegroProblem::new(&hand, &lifted).expect("valid spec");
    assert_eq!(p.n_eq(0), 14 + 3 + 3 + 4);
    // Card pushes pin nothing; the middle finger regrasps (no lift-off rows for the card)
    // while the index pushes.
    let p = AllegroProblem::new(&hand, &spec(Mode::CardIndex, 8)).expect("valid spec");
    assert_eq!(p.n_eq(0), 7 + 4 + 4);
    assert_eq!(p.n_ineq(0), 9 + 2);
}

#[test]
fn open_loop_turn_solve_is_feasible_and_turns() {
    let hand = HandModel::allegro_v4();
    let mut s = spec(Mode::Turn, 12);
    s.goal = [0.0, 0.0, -std::f64::consts::PI / 6.0];
    let p = AllegroProblem::new(&hand, &s).expect("valid spec");
    let mut rng = KernelRng::seed_from_u64(3);
    let mut parts = default_particles(&p, Mode::Turn, 8, &mut rng);
    let rep = solve(&p, &mut parts, 100, &CsvtoSettings::default()).unwrap();
    let n = p.row_dim();
    let yaw_end = parts[0][11 * n + 14];
    assert!(rep.max_eq_violation[0] < 5e-3, "{rep:?}");
    assert!(yaw_end < -0.2, "planned yaw {yaw_end}");
}

#[test]
fn bad_specs_are_typed_errors() {
    use super::allegro::ProblemError;
    let hand = HandModel::allegro_v4();
    let mut s = spec(Mode::Turn, 12);
    s.task = SceneKind::Card;
    assert!(matches!(
        AllegroProblem::new(&hand, &s),
        Err(ProblemError::ModeTask { .. })
    ));
    let mut s = spec(Mode::Turn, 12);
    s.start.pop();
    assert_eq!(
        AllegroProblem::new(&hand, &s).err(),
        Some(ProblemError::StartLength {
            task: "screwdriver",
            expected: 15,
            got: 14
        })
    );
    let s = spec(Mode::Turn, 0);
    assert_eq!(
        AllegroProblem::new(&hand, &s).err(),
        Some(ProblemError::ZeroHorizon)
    );
    let mut s = spec(Mode::Turn, 12);
    s.goal[2] = f64::NAN;
    assert!(matches!(
        AllegroProblem::new(&hand, &s),
        Err(ProblemError::NotFinite {
            what: "goal",
            index: 2
        })
    ));
}

/// The planner's geometry takes object coordinates in problem units (the card's heading in
/// units of `CARD_THETA_UNIT`) and must place the object where the world does: the fingertip
/// distances of both agree with the world's parry geometry at turned, shifted object poses.
#[test]
fn planner_geometry_matches_the_world_at_moved_object_poses() {
    use dips_world::world::World;
    let hand = HandModel::allegro_v4();
    let cases: [(Mode, [f64; 3]); 4] = [
        (Mode::Turn, [0.04, -0.03, 0.7]),
        (Mode::Turn, [-0.02, 0.05, -1.9]),
        (Mode::CardBoth, [0.01, -0.02, 0.25]),
        (Mode::CardBoth, [-0.03, -0.05, -0.6]),
    ];
    let mut rng = KernelRng::seed_from_u64(11);
    for (mode, o) in cases {
        let p = AllegroProblem::new(&hand, &spec(mode, 2)).expect("valid spec");
        let task = SceneKind::from(mode.task());
        let mut world = World::new(task);
        for trial in 0..5 {
            let mut state = start_state(task);
            for v in state.iter_mut().take(4 * p.fingers()) {
                *v += 0.2 * f64::from(rng.normal_f32());
            }
            let nq = 4 * p.fingers();
            state[nq..].copy_from_slice(&o);
            world.set_state(&state).expect("state fits the world");
            // The world clamps joints to their limits; read back what it holds.
            let state = world.state();
            let measured = world.tip_distances();
            for (i, &w) in measured.iter().enumerate() {
                let q = [
                    state[4 * i],
                    state[4 * i + 1],
                    state[4 * i + 2],
                    state[4 * i + 3],
                ];
                let planned = p.finger_sdf(i, &q, &o);
                // Inside the handle the planner measures depth to the cap's top (it merges
                // handle and cap into one cylinder), 1 mm above the handle's own top.
                let tolerance = if w < 0.0 { 1.01e-3 } else { 1e-6 };
                assert!(
                    (planned - w).abs() < tolerance,
                    "{} trial {trial} finger {i} at {o:?}: planner {planned}, world {w}",
                    task.name()
                );
            }
        }
    }
}

/// The row layout ([`AllegroProblem::step_rows`]) is what the fill writes: for every mode, at
/// the first, a middle and the last step, with and without lift-off fingers, every counted
/// row is written (none keeps its NaN) and none past the counts (that would panic), in
/// release builds too, where the fill's `debug_assert`s are off.
#[test]
fn every_counted_row_is_written() {
    let hand = HandModel::allegro_v4();
    let modes = [
        Mode::Turn,
        Mode::IndexRegrasp,
        Mode::ThumbMiddleRegrasp,
        Mode::CardIndex,
        Mode::CardMiddle,
        Mode::CardBoth,
        Mode::CardRegrasp,
    ];
    for (m, &mode) in modes.iter().enumerate() {
        for lifted in [false, true] {
            let mut s = spec(mode, 4);
            if lifted {
                s.start[2] -= 0.4;
            }
            let p = AllegroProblem::new(&hand, &s).expect("valid spec");
            let x = perturbed(&p, mode, 50 + m as u64);
            let (n, ds) = (p.row_dim(), p.state_dim());
            for t in [0, 1, 3] {
                let rows = p.step_rows(t);
                assert_eq!((rows.eq, rows.ineq), (p.n_eq(t), p.n_ineq(t)));
                let prev: Vec<f64> = if t == 0 {
                    p.start_state().to_vec()
                } else {
                    x[(t - 1) * n..(t - 1) * n + ds].to_vec()
                };
                let mut sc = StepConstraints::default();
                sc.reset(rows.eq, rows.ineq, ds + n);
                sc.eq.fill(f64::NAN);
                sc.ineq.fill(f64::NAN);
                p.step_constraints(t, &prev, &x[t * n..(t + 1) * n], &mut sc);
                for (what, v) in [("eq", &sc.eq), ("ineq", &sc.ineq)] {
                    if let Some(r) = v.iter().position(|x| x.is_nan()) {
                        panic!(
                            "{mode:?} lifted {lifted} t={t}: {what} row {r} of {rows:?} unwritten"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn finger_sdf_gradient_matches_central_differences_in_world_units() {
    let hand = HandModel::allegro_v4();
    // The card's heading is scaled inside the problem (`CARD_THETA_UNIT`): the object
    // derivative must come back per radian.
    let cases: [(Mode, [f64; 3]); 3] = [
        (Mode::Turn, [0.04, -0.03, 0.7]),
        (Mode::CardBoth, [0.01, -0.02, 0.25]),
        (Mode::CardRegrasp, [-0.03, -0.05, -0.6]),
    ];
    let h = 1e-6;
    for (mode, o) in cases {
        let p = AllegroProblem::new(&hand, &spec(mode, 2)).expect("valid spec");
        let start = start_state(SceneKind::from(mode.task()));
        for i in 0..p.fingers() {
            let q: [f64; 4] = std::array::from_fn(|k| start[4 * i + k] + 0.05);
            let (v, dq, d_o) = p.finger_sdf_gradient(i, &q, &o);
            assert_eq!(v, p.finger_sdf(i, &q, &o));
            for k in 0..4 {
                let (mut a, mut b) = (q, q);
                a[k] += h;
                b[k] -= h;
                let fd = (p.finger_sdf(i, &a, &o) - p.finger_sdf(i, &b, &o)) / (2.0 * h);
                assert!(
                    (fd - dq[k]).abs() < 1e-6,
                    "{mode:?} finger {i} q{k}: {fd} vs {}",
                    dq[k]
                );
            }
            for k in 0..3 {
                let (mut a, mut b) = (o, o);
                a[k] += h;
                b[k] -= h;
                let fd = (p.finger_sdf(i, &q, &a) - p.finger_sdf(i, &q, &b)) / (2.0 * h);
                assert!(
                    (fd - d_o[k]).abs() < 1e-6,
                    "{mode:?} finger {i} o{k}: {fd} vs {}",
                    d_o[k]
                );
            }
        }
    }
}
