//! A planning call through the real model adapters (diffusion sampler over a denoiser engine,
//! discriminator scorer) and the wire path (`plan_request`) makes zero heap allocations: a
//! counting global allocator counts the planning thread's allocations while they run.
#![allow(unsafe_code)]

mod alloc_count;
mod common;
mod engines;

use alloc_count::armed;
use common::{paper_prior, screwdriver_problem, screwdriver_start};
use dips_kernel::adapters::{
    DiffusionSegmentSampler, DiscriminatorScorer, SamplerAdapterLayout, ScorerAdapterLayout,
};
use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::Task;
use dips_kernel::search::{SearchConfig, SearchStatus};
use dips_kernel::task::ScrewdriverObjective;
use dips_kernel::wire_convert::plan_request;
use dips_wire::{PlanRequest, PlanStatus, SearchSettings};
use engines::{GaussianDenoiser, LogisticDiscriminator};
#[global_allocator]
static GLOBAL: alloc_count::Counting = alloc_count::Counting;

#[test]
fn planning_through_the_model_adapters_does_not_allocate() {
    // The counter works.
    let v = armed(|| vec![1u8; 8]);
    drop(v);
    assert_eq!(alloc_count::count(), 1);
    alloc_count::reset();

    let mut denoiser = GaussianDenoiser::new(Task::Screwdriver, 16);
    let mut disc = LogisticDiscriminator::new(Task::Screwdriver);
    let sampler_layout = SamplerAdapterLayout::new(denoiser.dims, 48, 16);
    let scorer_layout = ScorerAdapterLayout::new(disc.dims, 16);
    let mut sampler_buf = vec![0.0f32; sampler_layout.total()];
    let mut scorer_buf = vec![0.0f32; scorer_layout.total()];
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();
    let prior = paper_prior();
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
        card_goals: Default::default(),
        first_modes: 0b111,
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
            &screwdriver_problem(&start, None, &prior),
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
    assert_eq!(alloc_count::count(), 0, "heap allocations while planning");
}
