//! A planning call through the real model adapters (diffusion sampler over a denoiser engine,
//! discriminator scorer) and the wire path (`plan_request`) makes zero heap allocations: a
//! counting global allocator counts the planning thread's allocations while they run.
#![allow(unsafe_code)]

mod common;
mod engines;

use common::screwdriver_start;
use dips_kernel::adapters::{
    DiffusionSegmentSampler, DiscriminatorScorer, SamplerAdapterLayout, ScorerAdapterLayout,
};
use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::Task;
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::{Problem, SearchConfig, SearchStatus};
use dips_kernel::task::ScrewdriverObjective;
use dips_kernel::wire_convert::plan_request;
use dips_wire::{PlanRequest, PlanStatus, SearchSettings};
use engines::{GaussianDenoiser, LogisticDiscriminator};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

fn note() {
    if ARMED.try_with(Cell::get).unwrap_or(false) {
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

fn armed<T>(f: impl FnOnce() -> T) -> T {
    ARMED.with(|a| a.set(true));
    let out = f();
    ARMED.with(|a| a.set(false));
    out
}

#[test]
fn planning_through_the_model_adapters_does_not_allocate() {
    // The counter works.
    let v = armed(|| vec![1u8; 8]);
    drop(v);
    assert_eq!(COUNT.with(Cell::get), 1);
    COUNT.with(|c| c.set(0));

    let mut denoiser = GaussianDenoiser::new(Task::Screwdriver, 16);
    let mut disc = LogisticDiscriminator::new(Task::Screwdriver);
    let sampler_layout = SamplerAdapterLayout::new(denoiser.dims, 48, 16);
    let scorer_layout = ScorerAdapterLayout::new(disc.dims, 16);
    let mut sampler_buf = vec![0.0f32; sampler_layout.total()];
    let mut scorer_buf = vec![0.0f32; scorer_layout.total()];
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();
    let prior = MarkovPrior::from_rows(
        &[0.8, 0.1, 0.1],
        &[&[0.1, 0.45, 0.45], &[0.45, 0.1, 0.45], &[0.45, 0.45, 0.1]],
    )
    .unwrap();
    let start = screwdriver_start(-0.2);
    let objective = ScrewdriverObjective::from_state(&start).unwrap();
    let request = PlanRequest {
        task: dips_wire::Task::Screwdriver,
        start_state: heapless::Vec::from_slice(&start).unwrap(),
        goal: objective.goal_yaw,
        settings: SearchSettings {
            seed: 8,
            node_budget: 0,
            ..SearchSettings::default()
        },
        previous_mode: Some(1),
    };

    // Building the adapters only splits the caller's buffers.
    let (mut sampler, mut scorer) = armed(|| {
        (
            DiffusionSegmentSampler::new(
                &mut denoiser,
                SamplerConfig::default(),
                &mut sampler_buf,
                &sampler_layout,
            )
            .unwrap(),
            DiscriminatorScorer::new(&mut disc, &mut scorer_buf, &scorer_layout).unwrap(),
        )
    });
    let report = armed(|| {
        planner.plan(
            &SearchConfig::default(),
            &Problem {
                task: Task::Screwdriver,
                dims: Task::Screwdriver.dims(),
                start: &start,
                executed: None,
                prior: &prior,
            },
            &mut sampler,
            &mut scorer,
            &objective,
            &mut NoClock,
        )
    });
    assert_eq!(report.status, SearchStatus::Found);
    assert!(report.stats.nodes_expanded >= 2);
    let reply = armed(|| {
        plan_request(
            &mut planner,
            &request,
            &prior,
            &mut sampler,
            &mut scorer,
            &mut NoClock,
        )
    })
    .unwrap();
    assert_eq!(reply.status, PlanStatus::Found);
    assert!(reply.stats.nodes_expanded >= 2);
    assert_eq!(COUNT.with(Cell::get), 0, "heap allocations while planning");
}
