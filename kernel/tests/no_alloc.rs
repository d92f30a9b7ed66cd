//! A whole planning call makes zero heap allocations: a counting global allocator counts
//! the allocations of the planning thread while `plan` runs.
#![allow(unsafe_code)]

mod common;

use common::{NoisyScrewdriver, SmoothScorer, screwdriver_start};
use dips_kernel::budget::NoClock;
use dips_kernel::mode::{ModeId, Task};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::{Problem, SearchConfig, SearchStatus, SearchVariant};
use dips_kernel::task::ScrewdriverObjective;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

fn note() {
    let armed = ARMED.try_with(Cell::get).unwrap_or(false);
    if armed {
        let _ = COUNT.try_with(|c| c.set(c.get() + 1));
    }
}

// SAFETY: forwards every call to the system allocator unchanged; the counters are
// const-initialised thread-locals without destructors, so touching them never allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn planning_calls_do_not_allocate() {
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();
    let prior = MarkovPrior::from_rows(
        &[0.8, 0.1, 0.1],
        &[&[0.1, 0.45, 0.45], &[0.45, 0.1, 0.45], &[0.45, 0.45, 0.1]],
    )
    .unwrap();
    let start = screwdriver_start(0.0);
    let objective = ScrewdriverObjective::from_state(&start).unwrap();
    let mut sampler = NoisyScrewdriver { noise: 0.2 };
    let mut scorer = SmoothScorer;

    // The counter works: a Vec allocation is seen.
    ARMED.with(|a| a.set(true));
    let v = vec![1u8; 16];
    ARMED.with(|a| a.set(false));
    drop(v);
    assert_eq!(COUNT.with(Cell::get), 1);
    COUNT.with(|c| c.set(0));

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
        let problem = Problem {
            task: Task::Screwdriver,
            dims: Task::Screwdriver.dims(),
            start: &start,
            executed,
            prior: &prior,
        };
        ARMED.with(|a| a.set(true));
        let report = planner.plan(
            &config,
            &problem,
            &mut sampler,
            &mut scorer,
            &objective,
            &mut NoClock,
        );
        ARMED.with(|a| a.set(false));
        assert!(report.status.has_plan(), "{:?}", report.status);
        assert_ne!(report.status, SearchStatus::InvalidProblem);
        expanded += report.stats.nodes_expanded;
    }
    assert!(expanded >= 3);
    assert_eq!(COUNT.with(Cell::get), 0, "heap allocations during planning");
}
