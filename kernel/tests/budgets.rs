//! Budgets, approximate results, capacity overflow and bad input are statuses, never panics;
//! plus a planning run on the real screwdriver objective with a noisy analytic sampler.

mod common;

use common::{
    NoisyScrewdriver, SmoothScorer, TickClock, paper_prior, screwdriver_problem, screwdriver_start,
};
use dips_kernel::budget::{Clock, NoClock};
use dips_kernel::mode::{ContactMode, ModeId, SegmentDims, Task};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::rng::KernelRng;
use dips_kernel::search::config::ConfigError;
use dips_kernel::search::{
    ApproximateReason, Capacity, Planner, Problem, SearchConfig, SearchReport, SearchStatus,
    SegmentSampler,
};
use dips_kernel::task::ScrewdriverObjective;

fn plan_with<const K: usize, const N: usize, const O: usize, const S: usize>(
    planner: &mut Planner<K, N, O, S>,
    config: &SearchConfig,
    start: &[f32],
    goal_yaw: f32,
    clock: &mut impl Clock,
) -> SearchReport {
    let prior = paper_prior();
    let problem = Problem {
        task: Task::Screwdriver,
        dims: Task::Screwdriver.dims(),
        start,
        executed: None,
        prior: &prior,
        first_modes: dips_kernel::mode::ModeSet::all(Task::Screwdriver),
    };
    let objective = ScrewdriverObjective {
        reference_yaw: 0.0,
        goal_yaw,
    };
    planner.plan(
        config,
        &problem,
        &mut NoisyScrewdriver { noise: 0.2 },
        &mut SmoothScorer,
        &objective,
        clock,
    )
}

fn paper(config: &SearchConfig, goal_yaw: f32) -> SearchReport {
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();
    plan_with(
        &mut *planner,
        config,
        &screwdriver_start(0.0),
        goal_yaw,
        &mut NoClock,
    )
}

#[test]
fn paper_settings_find_a_turning_plan() {
    let goal = -core::f32::consts::FRAC_PI_3;
    let r = paper(&SearchConfig::default(), goal);
    assert_eq!(r.status, SearchStatus::Found);
    assert!(r.expected_progress <= goal);
    let turns = r.modes.iter().filter(|m| **m == ModeId(0)).count();
    assert!(turns >= 2, "{:?}", r.modes);
    assert_eq!(r.terminal_state.len(), 16);
    assert!(r.stats.nodes_expanded >= 2);
    // One sampler and one scorer call per expansion: 3 modes × 16 particles each.
    assert_eq!(r.stats.sampler_calls, r.stats.nodes_expanded);
    assert_eq!(r.stats.segments_sampled, 48 * r.stats.nodes_expanded);
}

#[test]
fn node_budget_returns_the_closest_examined_node() {
    let config = SearchConfig {
        node_budget: 3,
        ..SearchConfig::default()
    };
    let r = paper(&config, -100.0);
    assert_eq!(
        r.status,
        SearchStatus::Approximate(ApproximateReason::NodeBudget)
    );
    assert_eq!(r.stats.nodes_expanded, 3);
    assert!(!r.modes.is_empty());
    // φ = yaw − goal: the closest node has turned.
    assert!(r.expected_progress < -0.3, "{}", r.expected_progress);
}

#[test]
fn time_budget_uses_the_injected_clock() {
    let config = SearchConfig {
        time_budget_ms: 10,
        ..SearchConfig::default()
    };
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();
    let mut clock = TickClock {
        now: 0,
        step_us: 1000,
    };
    let r = plan_with(
        &mut *planner,
        &config,
        &screwdriver_start(0.0),
        -100.0,
        &mut clock,
    );
    assert_eq!(
        r.status,
        SearchStatus::Approximate(ApproximateReason::TimeBudget)
    );
    assert!(r.stats.elapsed_ms >= 10);
    assert!(r.stats.nodes_expanded >= 1 && r.stats.nodes_expanded < 12);
}

#[test]
fn exhausting_the_tree_is_reported() {
    let config = SearchConfig {
        max_depth: 1,
        ..SearchConfig::default()
    };
    let r = paper(&config, -100.0);
    assert_eq!(
        r.status,
        SearchStatus::Approximate(ApproximateReason::Exhausted)
    );
    assert_eq!((r.stats.nodes_expanded, r.stats.nodes_popped), (1, 4));
    assert_eq!(r.modes.as_slice(), &[ModeId(0)]);
}

#[test]
fn run_time_capacity_overflow_is_a_status() {
    let start = screwdriver_start(0.0);
    let config = SearchConfig::default();
    let mut few_nodes = common::boxed_planner::<16, 8, 64, 481>();
    let r = plan_with(&mut *few_nodes, &config, &start, -100.0, &mut NoClock);
    assert_eq!(
        r.status,
        SearchStatus::Approximate(ApproximateReason::Capacity(Capacity::Nodes))
    );
    assert!(r.status.has_plan() && !r.modes.is_empty());
    let mut short_open = common::boxed_planner::<16, 1024, 4, 481>();
    let r = plan_with(&mut *short_open, &config, &start, -100.0, &mut NoClock);
    assert_eq!(
        r.status,
        SearchStatus::Approximate(ApproximateReason::Capacity(Capacity::OpenList))
    );
}

#[test]
fn setup_capacity_and_bad_input_are_statuses() {
    let start = screwdriver_start(0.0);
    let ok = SearchConfig::default();
    let mut p = common::boxed_planner::<16, 512, 256, 481>();
    let mut status = |config: &SearchConfig, start: &[f32], goal: f32| {
        plan_with(&mut *p, config, start, goal, &mut NoClock).status
    };
    assert_eq!(
        status(&SearchConfig { k: 17, ..ok }, &start, -1.0),
        SearchStatus::CapacityExceeded(Capacity::Particles)
    );
    assert_eq!(
        status(&SearchConfig { gamma: 0.0, ..ok }, &start, -1.0),
        SearchStatus::InvalidConfig(ConfigError::Gamma)
    );
    assert_eq!(status(&ok, &start[..15], -1.0), SearchStatus::InvalidStart);
    let mut nan = start;
    nan[3] = f32::NAN;
    assert_eq!(status(&ok, &nan, -1.0), SearchStatus::InvalidStart);
    assert_eq!(status(&ok, &start, f32::NAN), SearchStatus::InvalidGoal);

    let mut small = common::boxed_planner::<16, 64, 64, 100>();
    let r = plan_with(&mut *small, &ok, &start, -1.0, &mut NoClock);
    assert_eq!(
        r.status,
        SearchStatus::CapacityExceeded(Capacity::SegmentFloats)
    );
    assert!(r.modes.is_empty() && r.terminal_state.is_empty());

    // Prior of the wrong size, unknown executed mode, dims the objective cannot read.
    let objective = ScrewdriverObjective {
        reference_yaw: 0.0,
        goal_yaw: -1.0,
    };
    let card_prior = MarkovPrior::uniform(4).unwrap();
    let prior = paper_prior();
    let cases: [(&MarkovPrior, Option<ModeId>, SegmentDims); 3] = [
        (&card_prior, None, Task::Screwdriver.dims()),
        (&prior, Some(ModeId(3)), Task::Screwdriver.dims()),
        (
            &prior,
            None,
            SegmentDims {
                action_dim: 17,
                ..Task::Screwdriver.dims()
            },
        ),
    ];
    let mut p = common::boxed_planner::<16, 512, 256, 481>();
    for (i, (prior, executed, dims)) in cases.into_iter().enumerate() {
        let problem = Problem {
            task: Task::Screwdriver,
            dims,
            start: &start,
            executed,
            prior,
            first_modes: dips_kernel::mode::ModeSet::all(Task::Screwdriver),
        };
        let r = p.plan(
            &ok,
            &problem,
            &mut NoisyScrewdriver { noise: 0.2 },
            &mut SmoothScorer,
            &objective,
            &mut NoClock,
        );
        assert_eq!(r.status, SearchStatus::InvalidProblem, "case {i}");
    }
}

struct Failing;

impl SegmentSampler for Failing {
    type Error = &'static str;
    fn max_batch(&self) -> usize {
        usize::MAX
    }
    fn sample(
        &mut self,
        _: &SegmentDims,
        _: &[f32],
        _: &[ContactMode],
        _: &mut KernelRng,
        _: &mut [f32],
    ) -> Result<(), &'static str> {
        Err("engine down")
    }
}

#[test]
fn sampler_failure_returns_the_root() {
    let prior = paper_prior();
    let start = screwdriver_start(0.0);
    let problem = screwdriver_problem(&start, None, &prior);
    let objective = ScrewdriverObjective {
        reference_yaw: 0.0,
        goal_yaw: -1.0,
    };
    let mut p = common::boxed_planner::<16, 512, 256, 481>();
    let r = p.plan(
        &SearchConfig::default(),
        &problem,
        &mut Failing,
        &mut SmoothScorer,
        &objective,
        &mut NoClock,
    );
    assert_eq!(
        r.status,
        SearchStatus::Approximate(ApproximateReason::SamplerFailed)
    );
    assert!(r.modes.is_empty());
    assert_eq!(r.expected_progress, 0.0);
}

/// The same noisy sampler limited to small batches.
struct Chunked(NoisyScrewdriver, usize);

impl SegmentSampler for Chunked {
    type Error = ();
    fn max_batch(&self) -> usize {
        self.1
    }
    fn sample(
        &mut self,
        dims: &SegmentDims,
        starts: &[f32],
        modes: &[ContactMode],
        rng: &mut KernelRng,
        out: &mut [f32],
    ) -> Result<(), ()> {
        assert!(modes.len() <= self.1);
        self.0.sample(dims, starts, modes, rng, out)
    }
}

#[test]
fn small_sampler_batches_are_split_without_changing_the_plan() {
    let prior = paper_prior();
    let start = screwdriver_start(0.0);
    let problem = screwdriver_problem(&start, None, &prior);
    let objective = ScrewdriverObjective {
        reference_yaw: 0.0,
        goal_yaw: -1.0,
    };
    let config = SearchConfig::default();
    let mut p = common::boxed_planner::<16, 512, 256, 481>();
    let whole = p.plan(
        &config,
        &problem,
        &mut NoisyScrewdriver { noise: 0.2 },
        &mut SmoothScorer,
        &objective,
        &mut NoClock,
    );
    let split = p.plan(
        &config,
        &problem,
        &mut Chunked(NoisyScrewdriver { noise: 0.2 }, 5),
        &mut SmoothScorer,
        &objective,
        &mut NoClock,
    );
    assert_eq!(split.stats.sampler_calls, 10 * split.stats.nodes_expanded);
    assert_eq!(whole.modes, split.modes);
    assert_eq!(whole.terminal_state, split.terminal_state);
    assert_eq!(whole.cost_to_come.to_bits(), split.cost_to_come.to_bits());
}
