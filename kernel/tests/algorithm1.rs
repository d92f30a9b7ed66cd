//! Algorithm 1 (`propagate_variability`) inside the A*, checked step by step against numbers
//! computed by hand: accumulated scores with the discount γ^depth(parent), resampling with
//! probability S'/ΣS', the score-weighted cost-to-come g, and the heuristic h.
//!
//! The hand case (k = 2, γ = 0.5, α = 1, screwdriver modes, state (x, depth)):
//! - root expansion (d = 0, discount 1): mode 0 (`turn`) moves x by −1 with Ψ = [0, 0.1] and
//!   J = [5, 7], so its child holds two copies of particle 1 with scores [0.1, 0.1] and g = 7;
//!   modes 1 and 2 move x by +1 (Ψ = 0.5, J = 1).
//! - expansion of that child (d = 1, discount 0.5): mode 0 has Ψ = [0.2, 1.0] and J = [2, 4],
//!   so S' = 0.5·Ψ + 0.1 = [0.2, 0.6]: particle 0 is drawn with probability 0.25. The child's
//!   g is 7 + 2 (both draws 0, p = 1/16), 7 + 4 (both 1, p = 9/16) or, for mixed draws
//!   (p = 6/16), 7 + (0.2·2 + 0.6·4)/0.8 = 10.5.
//! - the goal x ≤ −100 is never met, so after the whole depth-2 tree the result is the
//!   examined node with the least φ: x = −2 via (turn, turn), h = α·φ = 1·(−2 + 100) = 98.

mod common;

use common::{LineObjective, StepSampler, StepScorer, step_dims};
use dips_kernel::budget::NoClock;
use dips_kernel::mode::{ModeId, ModeSet, Task};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::rng::KernelRng;
use dips_kernel::search::particles::resample;
use dips_kernel::search::{
    ApproximateReason, CostToCome, Problem, SearchConfig, SearchReport, SearchStatus, SearchVariant,
};

fn step(x: f32, z: f32, m: usize, j: usize) -> (f32, f32) {
    let _ = x;
    if m == 0 {
        let a = if z == 0.0 {
            [5.0, 7.0][j]
        } else {
            [2.0, 4.0][j]
        };
        (-1.0, a)
    } else {
        (1.0, 1.0)
    }
}

fn psi(z: f32, m: usize, j: usize) -> f32 {
    match (m, z == 0.0) {
        (0, true) => [0.0, 0.1][j],
        (0, false) => [0.2, 1.0][j],
        _ => 0.5,
    }
}

fn config(seed: u64) -> SearchConfig {
    SearchConfig {
        k: 2,
        max_depth: 2,
        gamma: 0.5,
        alpha: 1.0,
        beta: 0.0,
        p_min: 0.1,
        node_budget: 0,
        time_budget_ms: 0,
        seed,
        ..SearchConfig::default()
    }
}

fn run(
    config: &SearchConfig,
    goal: f32,
    prior: &MarkovPrior,
    executed: Option<ModeId>,
) -> SearchReport {
    run_from(
        config,
        goal,
        prior,
        executed,
        ModeSet::all(Task::Screwdriver),
    )
}

fn run_from(
    config: &SearchConfig,
    goal: f32,
    prior: &MarkovPrior,
    executed: Option<ModeId>,
    first_modes: ModeSet,
) -> SearchReport {
    let task = Task::Screwdriver;
    let k = usize::from(config.k);
    let mut planner = common::boxed_planner::<2, 64, 64, 6>();
    let mut sampler = StepSampler {
        task,
        k,
        step,
        calls: 0,
    };
    let mut scorer = StepScorer { task, k, psi };
    let problem = Problem {
        task,
        dims: step_dims(task),
        start: &[0.0, 0.0],
        executed,
        prior,
        first_modes,
    };
    let objective = LineObjective { goal, slope: 1.0 };
    planner.plan(
        config,
        &problem,
        &mut sampler,
        &mut scorer,
        &objective,
        &mut NoClock,
    )
}

fn uniform() -> MarkovPrior {
    MarkovPrior::uniform(3).unwrap()
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() < 1e-5
}

#[test]
fn hand_case_scores_discount_resampling_g_and_h() {
    let mut counts = [0u32; 3];
    let seeds = 800;
    for seed in 0..seeds {
        let r = run(&config(seed), -100.0, &uniform(), None);
        assert_eq!(
            r.status,
            SearchStatus::Approximate(ApproximateReason::Exhausted)
        );
        assert_eq!(r.modes.as_slice(), &[ModeId(0), ModeId(0)]);
        assert_eq!(r.expected_progress, -2.0);
        assert_eq!(r.terminal_state.as_slice(), &[-2.0, 2.0]);
        assert!(close(r.heuristic, 98.0), "{}", r.heuristic);
        assert!(close(r.terminal_cost, 98.0));
        let g = r.cost_to_come;
        let which = [9.0, 10.5, 11.0].iter().position(|&v| close(g, v));
        counts[which.unwrap_or_else(|| panic!("g = {g} is none of 9, 10.5, 11"))] += 1;
        // Whole depth-2 tree: root + 3 depth-1 nodes expanded, 1 + 3 + 9 nodes.
        assert_eq!(r.stats.nodes_expanded, 4);
        assert_eq!(r.stats.sampler_calls, 4);
        assert_eq!(r.stats.scorer_calls, 4);
        assert_eq!(r.stats.segments_sampled, 4 * 3 * 2);
        assert_eq!(r.stats.nodes_generated, 13);
        assert_eq!(r.stats.nodes_popped, 13);
        assert_eq!(r.stats.dead_children, 0);
    }
    // P = 1/16, 6/16, 9/16 of 800: 50, 300, 450 (4σ ≈ 27, 55, 56).
    let expected = [50.0, 300.0, 450.0];
    for (c, e) in counts.iter().zip(expected) {
        assert!((f64::from(*c) - e).abs() < 60.0, "{counts:?}");
    }
}

#[test]
fn last_segment_cost_to_come_is_the_authors_switch() {
    let c = SearchConfig {
        cost_to_come: CostToCome::LastSegment,
        ..config(3)
    };
    for seed in 0..50 {
        let r = run(&SearchConfig { seed, ..c }, -100.0, &uniform(), None);
        let g = r.cost_to_come;
        assert!([2.0, 3.5, 4.0].iter().any(|&v| close(g, v)), "{g}");
    }
}

#[test]
fn max_likelihood_keeps_the_best_scored_segment() {
    let c = SearchConfig {
        variant: SearchVariant::MaxLikelihood,
        ..config(0)
    };
    for seed in 0..20 {
        let r = run(&SearchConfig { seed, ..c }, -100.0, &uniform(), None);
        assert_eq!(r.modes.as_slice(), &[ModeId(0), ModeId(0)]);
        // Root: Ψ [0, 0.1] keeps segment 1 (J 7); then S' = [0.2, 0.6] keeps segment 1 (J 4).
        assert!(close(r.cost_to_come, 11.0), "{}", r.cost_to_come);
        // Each expansion still diffuses k segments per mode from the one stored trajectory.
        assert_eq!(r.stats.segments_sampled, 4 * 3 * 2);
    }
}

#[test]
fn prior_term_of_the_heuristic_and_replanning_root() {
    let prior = MarkovPrior::from_rows(
        &[0.5, 0.25, 0.25],
        &[&[0.2, 0.4, 0.4], &[0.3, 0.3, 0.4], &[0.6, 0.2, 0.2]],
    )
    .unwrap();
    let c = SearchConfig {
        beta: 2.0,
        ..config(1)
    };
    let r = run(&c, -100.0, &prior, None);
    assert_eq!(r.modes.as_slice(), &[ModeId(0), ModeId(0)]);
    let want = 98.0 - 2.0 * (libm::logf(0.5) + libm::logf(0.2));
    assert!(close(r.heuristic, want), "{} vs {want}", r.heuristic);

    // Replanning after mode 1: the sequence continues from it, no start term.
    let r = run(&c, -100.0, &prior, Some(ModeId(1)));
    assert_eq!(r.executed, Some(ModeId(1)));
    assert_eq!(r.modes.as_slice(), &[ModeId(0), ModeId(0)]);
    let want = 98.0 - 2.0 * (libm::logf(0.3) + libm::logf(0.2));
    assert!(close(r.heuristic, want), "{} vs {want}", r.heuristic);
    // The prior is floored at p_min before use: a 0 transition becomes 0.1.
    let sparse = MarkovPrior::from_rows(
        &[1.0, 0.0, 0.0],
        &[&[0.0, 0.5, 0.5], &[1.0, 0.0, 0.0], &[1.0, 0.0, 0.0]],
    )
    .unwrap();
    let r = run(&c, -100.0, &sparse, None);
    let want = 98.0 - 2.0 * (libm::logf(0.8) + libm::logf(0.1));
    assert!(
        (r.heuristic - want).abs() < 1e-4,
        "{} vs {want}",
        r.heuristic
    );
}

#[test]
fn goal_test_on_pop_includes_the_root_and_uses_the_expectation() {
    let r = run(&config(0), 1.0, &uniform(), None);
    assert_eq!(r.status, SearchStatus::Found);
    assert!(r.modes.is_empty());
    assert_eq!(r.stats.nodes_expanded, 0);
    assert_eq!(r.stats.nodes_popped, 1);

    let r = run(&config(0), -1.5, &uniform(), None);
    assert_eq!(r.status, SearchStatus::Found);
    assert_eq!(r.modes.as_slice(), &[ModeId(0), ModeId(0)]);
}

#[test]
fn single_particle_with_zero_score_is_a_dead_child() {
    let c = SearchConfig { k: 1, ..config(0) };
    let r = run(&c, -100.0, &uniform(), None);
    // Root's mode 0 has Ψ = 0 for its only particle: no child. Nothing beats the root's x = 0.
    assert!(r.stats.dead_children >= 1);
    assert_eq!(
        r.status,
        SearchStatus::Approximate(ApproximateReason::Exhausted)
    );
    assert!(r.modes.is_empty());
    assert_eq!(r.expected_progress, 0.0);
}

#[test]
fn resampling_frequencies_follow_normalised_scores() {
    let scores = [0.2f32, 0.6, 0.0, 0.2];
    let mut rng = KernelRng::seed_from_u64(11);
    let mut idx = [0u16; 4000];
    assert!(resample(&scores, &mut rng, &mut idx));
    let mut counts = [0u32; 4];
    for &i in &idx {
        counts[usize::from(i)] += 1;
    }
    assert_eq!(counts[2], 0);
    for (c, p) in counts.iter().zip([0.2, 0.6, 0.0, 0.2]) {
        assert!((f64::from(*c) / 4000.0 - p).abs() < 0.03, "{counts:?}");
    }
}

/// The report's particle diagnostics over the hand case's whole tree (4 expansions × 3 modes ×
/// k = 2): Ψ's histogram and moments over all 24 segments, and the effective number of Ψ alone
/// per child (mode 0 at the root: Ψ [0, 0.1] keeps 1; deeper: [0.2, 1.0] keeps 1.44/1.04;
/// the other modes' equal Ψ keep both).
#[test]
fn particle_diagnostics_count_the_whole_tree() {
    let r = run(&config(5), -100.0, &uniform(), None);
    let d = r.particle_diagnostics;
    assert_eq!(d.children, 12);
    assert_eq!(d.mode_children[..3], [4, 4, 4]);
    assert_eq!(d.psi_histogram, [1, 1, 3, 0, 0, 16, 0, 0, 0, 3]);
    let psi_sum = 0.1 + 16.0 * 0.5 + 3.0 * 0.2 + 3.0;
    assert!(close(d.psi_sum, psi_sum), "{}", d.psi_sum);
    assert!(close(d.ess_psi_min, 1.0));
    let deep = 1.2f32 * 1.2 / (0.04 + 1.0);
    assert!(
        close(d.ess_psi_sum, 1.0 + 4.0 + 3.0 * (deep + 4.0)),
        "{}",
        d.ess_psi_sum
    );
    // Both samples of a mode end at the same x: no spread, and the weights move nothing.
    assert_eq!(d.progress_spread_sum[..3], [0.0; 3]);
    assert_eq!(d.weight_shift_sum, 0.0);
    // k = 2 draws keep one or two distinct samples per child.
    assert!((12..=24).contains(&d.distinct_sum), "{}", d.distinct_sum);
    assert!(d.ess_scores_min >= 1.0 - 1e-6 && d.ess_scores_sum <= 24.0 + 1e-4);
}

#[test]
fn the_root_expands_only_into_the_first_modes() {
    // Without `turn` first, the best depth-3 end is one step up and two down: x = −1, via
    // (index-regrasp | thumb-middle-regrasp, turn, turn). `turn` is still allowed after the
    // root.
    let first = ModeSet::EMPTY.with(ModeId(1)).with(ModeId(2));
    let deep = |seed| SearchConfig {
        max_depth: 3,
        ..config(seed)
    };
    for seed in 0..50 {
        let r = run_from(&deep(seed), -100.0, &uniform(), None, first);
        assert_eq!(
            r.status,
            SearchStatus::Approximate(ApproximateReason::Exhausted)
        );
        assert_eq!(r.modes.len(), 3, "{r:?}");
        assert!(first.contains(r.modes[0]), "{:?}", r.modes);
        assert_eq!(&r.modes[1..], &[ModeId(0), ModeId(0)]);
        assert_eq!(r.expected_progress, -1.0);
        // Root + 2 depth-1 + 6 depth-2 nodes expanded: 1 + 2 + 6 + 18 nodes.
        assert_eq!(r.stats.nodes_expanded, 9);
        assert_eq!(r.stats.nodes_generated, 27);
        // Every mode is the protocol-2 search, bit for bit.
        let all = ModeSet::all(Task::Screwdriver);
        assert_eq!(
            run_from(&deep(seed), -100.0, &uniform(), None, all),
            run(&deep(seed), -100.0, &uniform(), None)
        );
        assert_eq!(
            run(&deep(seed), -100.0, &uniform(), None).modes[0],
            ModeId(0)
        );
    }
    // When replanning, the executed mode does not count: the set is of the plan's first mode.
    let r = run_from(&deep(3), -100.0, &uniform(), Some(ModeId(0)), first);
    assert!(!r.modes.is_empty() && first.contains(r.modes[0]), "{r:?}");
}

#[test]
fn first_modes_outside_the_task_are_an_invalid_problem() {
    for bad in [ModeSet::EMPTY, ModeSet(0b1000), ModeSet(0b1001)] {
        let r = run_from(&config(1), -100.0, &uniform(), None, bad);
        assert_eq!(r.status, SearchStatus::InvalidProblem, "{bad:?}");
    }
}
