//! A whole planning call makes zero heap allocations: a counting global allocator counts
//! the allocations of the planning thread while `plan` runs.
#![allow(unsafe_code)]

mod alloc_count;
mod common;

use common::{NoisyScrewdriver, SmoothScorer, paper_prior, screwdriver_problem, screwdriver_start};
use dips_kernel::budget::NoClock;
use dips_kernel::mode::ModeId;
use dips_kernel::search::{SearchConfig, SearchStatus, SearchVariant};
use dips_kernel::task::ScrewdriverObjective;
#[global_allocator]
static GLOBAL: alloc_count::Counting = alloc_count::Counting;

#[test]
fn planning_calls_do_not_allocate() {
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();
    let prior = paper_prior();
    let start = screwdriver_start(0.0);
    let objective = ScrewdriverObjective::from_state(&start).unwrap();
    let mut sampler = NoisyScrewdriver { noise: 0.2 };
    let mut scorer = SmoothScorer;

    // The counter works: a Vec allocation is seen.
    let v = alloc_count::armed(|| vec![1u8; 16]);
    drop(v);
    assert_eq!(alloc_count::count(), 1);
    alloc_count::reset();

    let mut expanded = 0;
    for (variant, executed, budget) in [
        (SearchVariant::Particles, None, 0),
        (SearchVariant::MaxLikelihood, Some(ModeId(1)), 0),
        (SearchVariant::Particles, Some(ModeId(0)), 4),
    ] {
        let config = SearchConfig {
            variant,
            node_budget: budget,
            ..SearchConfig::default()
        };
        let problem = screwdriver_problem(&start, executed, &prior);
        let report = alloc_count::armed(|| {
            planner.plan(
                &config,
                &problem,
                &mut sampler,
                &mut scorer,
                &objective,
                &mut NoClock,
            )
        });
        assert!(report.status.has_plan(), "{:?}", report.status);
        assert_ne!(report.status, SearchStatus::InvalidProblem);
        expanded += report.stats.nodes_expanded;
    }
    assert!(expanded >= 3);
    assert_eq!(alloc_count::count(), 0, "heap allocations during planning");
}
