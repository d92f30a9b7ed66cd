//! The search's sampler and scorer adapters over engine doubles: the real diffusion sampler
//! and the real planner, end to end.

mod common;
mod engines;

use common::{paper_prior, screwdriver_problem, screwdriver_start};
use dips_kernel::adapters::*;
use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::{
    SampleRequest, SamplerConfig, SamplerError, SamplerScratch, SamplingMethod, ScratchBuffer,
    ScratchLayout, sample,
};
use dips_kernel::engine::{DenoiserEngine, DiscriminatorEngine};
use dips_kernel::mode::{ContactMode, ModeId, SegmentDims, Task};
use dips_kernel::rng::KernelRng;
use dips_kernel::search::TaskObjective;
use dips_kernel::search::{
    ApproximateReason, Problem, SearchConfig, SearchReport, SearchStatus, SegmentSampler,
    SegmentScorer,
};
use dips_kernel::task::ScrewdriverObjective;
use engines::{GaussianDenoiser, LogisticDiscriminator, TURN};

const STEPS: usize = 16;

fn mode(task: Task, name: &str) -> ContactMode {
    task.contact_mode(task.mode_by_name(name).unwrap()).unwrap()
}

fn yaw_of(row: &[f32]) -> f32 {
    row[15].atan2(row[14])
}

/// Buffers for both adapters, sized for `max_segments` per sampler call.
struct Buffers {
    sampler: Vec<f32>,
    sampler_layout: SamplerAdapterLayout,
    scorer: Vec<f32>,
    scorer_layout: ScorerAdapterLayout,
}

fn buffers(denoiser: &GaussianDenoiser, max_segments: usize, chunk: usize) -> Buffers {
    let sampler_layout = SamplerAdapterLayout::new(denoiser.dims, max_segments, chunk);
    let scorer_layout = ScorerAdapterLayout::new(denoiser.dims, chunk);
    Buffers {
        sampler: vec![0.0; sampler_layout.total()],
        sampler_layout,
        scorer: vec![0.0; scorer_layout.total()],
        scorer_layout,
    }
}

impl Buffers {
    /// The sampler over `denoiser` and the scorer over `disc`, carved out of these buffers.
    fn adapters<D: DenoiserEngine, S: DiscriminatorEngine>(
        &mut self,
        denoiser: D,
        disc: S,
        config: SamplerConfig,
    ) -> (DiffusionSegmentSampler<'_, D>, DiscriminatorScorer<'_, S>) {
        let sampler =
            DiffusionSegmentSampler::new(denoiser, config, &mut self.sampler, &self.sampler_layout)
                .unwrap();
        let scorer = DiscriminatorScorer::new(disc, &mut self.scorer, &self.scorer_layout).unwrap();
        (sampler, scorer)
    }
}

fn plan_screwdriver(
    config: &SearchConfig,
    sampler_config: SamplerConfig,
    chunk: usize,
) -> (SearchReport, GaussianDenoiser, LogisticDiscriminator) {
    let mut denoiser = GaussianDenoiser::new(Task::Screwdriver, STEPS);
    let mut disc = LogisticDiscriminator::new(Task::Screwdriver);
    let mut b = buffers(&denoiser, 48, chunk);
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();
    let prior = paper_prior();
    let start = screwdriver_start(0.3);
    let objective = ScrewdriverObjective::from_state(&start).unwrap();
    let problem = screwdriver_problem(&start, None, &prior);
    let report = {
        let (mut sampler, mut scorer) = b.adapters(&mut denoiser, &mut disc, sampler_config);
        planner.plan(
            config,
            &problem,
            &mut sampler,
            &mut scorer,
            &objective,
            &mut NoClock,
        )
    };
    (report, denoiser, disc)
}

#[test]
fn sampler_adapter_is_the_diffusion_sampler_with_modes_as_context() {
    let task = Task::Screwdriver;
    let dims = task.dims();
    let modes = [
        mode(task, "turn"),
        mode(task, "index-regrasp"),
        mode(task, "thumb-middle-regrasp"),
        mode(task, "turn"),
    ];
    let mut starts = Vec::new();
    for (i, _) in modes.iter().enumerate() {
        starts.extend_from_slice(&screwdriver_start(0.5 * i as f32 - 1.0));
    }
    let n = modes.len();

    // Through the adapter, with a chunk of 3 trajectories per engine call.
    let mut denoiser = GaussianDenoiser::new(task, STEPS);
    let mut b = buffers(&denoiser, n, 3);
    let mut via_adapter = vec![0.0f32; n * dims.floats()];
    let mut sampler = DiffusionSegmentSampler::new(
        &mut denoiser,
        SamplerConfig::default(),
        &mut b.sampler,
        &b.sampler_layout,
    )
    .unwrap();
    assert_eq!(SegmentSampler::max_batch(&sampler), n);
    assert!(sampler.accepts(&dims));
    sampler
        .sample(
            &dims,
            &starts,
            &modes,
            &mut KernelRng::seed_from_u64(9),
            &mut via_adapter,
        )
        .unwrap();

    // Directly, with the contract's ±1 context rows written by hand.
    let mut direct_engine = GaussianDenoiser::new(task, STEPS);
    let context: Vec<f32> = modes
        .iter()
        .flat_map(|m| (0..3).map(move |i| f32::from(m.sign(i))))
        .collect();
    let layout = ScratchLayout::new(direct_engine.dims(), n);
    let mut buf = vec![0.0f32; layout.total()];
    let mut scratch = SamplerScratch::split(&mut buf, &layout).unwrap();
    let mut direct = vec![0.0f32; n * dims.floats()];
    sample(
        &mut direct_engine,
        &SamplerConfig::default(),
        &SampleRequest {
            context: &context,
            start_states: Some(&starts),
        },
        &mut KernelRng::seed_from_u64(9),
        &mut scratch,
        &mut direct,
    )
    .unwrap();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&via_adapter), bits(&direct));

    // Row 0 is the start state exactly; turns turn, regrasps hold.
    let (td, d) = (dims.floats(), dims.dim());
    for i in 0..n {
        let seg = &via_adapter[i * td..(i + 1) * td];
        assert_eq!(&seg[..16], &starts[i * 16..(i + 1) * 16]);
        let turned = yaw_of(&seg[12 * d..]) - yaw_of(seg);
        if i == 0 || i == 3 {
            // Guidance 1.2 overshoots the conditioned turn a little.
            assert!(
                turned < 0.9 * TURN && turned > 1.5 * TURN,
                "turn {i}: {turned}"
            );
        } else {
            assert!(turned.abs() < 0.1, "regrasp {i}: {turned}");
        }
    }
}

#[test]
fn scorer_adapter_normalizes_with_the_models_normalization_and_chunks() {
    let task = Task::Screwdriver;
    let dims = task.dims();
    let n = 7;
    let mut rng = KernelRng::seed_from_u64(4);
    let mut segments = vec![0.0f32; n * dims.floats()];
    rng.fill_normal(&mut segments);
    let names = ["turn", "index-regrasp", "thumb-middle-regrasp"];
    let modes: Vec<ContactMode> = (0..n).map(|i| mode(task, names[i % 3])).collect();

    let mut disc = LogisticDiscriminator::new(task);
    disc.max_batch = 2;
    disc.record = true;
    // Room for 3 segments per call; the engine takes 2.
    let layout = ScorerAdapterLayout::new(disc.dims, 3);
    let mut buf = vec![0.0f32; layout.total()];
    let mut scores = vec![0.0f32; n];
    {
        let mut scorer = DiscriminatorScorer::new(&mut disc, &mut buf, &layout).unwrap();
        assert_eq!(SegmentScorer::max_batch(&scorer), usize::MAX);
        scorer.score(&dims, &segments, &modes, &mut scores).unwrap();
    }
    assert_eq!(disc.calls, 4);
    let d = dims.dim();
    for i in 0..n {
        let raw = &segments[i * dims.floats()..(i + 1) * dims.floats()];
        let norm: Vec<f32> = raw
            .iter()
            .enumerate()
            .map(|(k, v)| (v - disc.mean[k % d]) / disc.std[k % d])
            .collect();
        let ctx: Vec<f32> = (0..3).map(|f| f32::from(modes[i].sign(f))).collect();
        assert_eq!(
            &disc.seen_x[i * dims.floats()..(i + 1) * dims.floats()],
            &norm[..]
        );
        assert_eq!(&disc.seen_context[i * 3..(i + 1) * 3], &ctx[..]);
        let expect = LogisticDiscriminator::logistic(disc.dims, &disc.mean, &norm, &ctx);
        assert_eq!(scores[i].to_bits(), expect.to_bits(), "segment {i}");
        assert!(scores[i] > 0.0 && scores[i] < 1.0);
    }
}

#[test]
fn mismatched_models_and_calls_get_typed_errors() {
    let screwdriver = Task::Screwdriver.dims();
    let mut card_denoiser = GaussianDenoiser::new(Task::Card, STEPS);
    let mut card_disc = LogisticDiscriminator::new(Task::Card);
    let mut b = buffers(&card_denoiser, 64, 4);
    let (mut sampler, mut scorer) =
        b.adapters(&mut card_denoiser, &mut card_disc, SamplerConfig::default());
    let horizon = DimsMismatch {
        field: DimField::Horizon,
        model: 9,
        problem: 13,
    };
    assert_eq!(sampler.check_dims(&screwdriver), Err(horizon));
    assert_eq!(scorer.check_dims(&screwdriver), Err(horizon));
    assert_eq!(
        horizon.to_string(),
        "model horizon is 9 but the problem's is 13"
    );
    let wider = SegmentDims {
        action_dim: 18,
        ..Task::Card.dims()
    };
    assert_eq!(
        sampler.check_dims(&wider),
        Err(DimsMismatch {
            field: DimField::ActionDim,
            model: 17,
            problem: 18
        })
    );
    assert!(!sampler.accepts(&screwdriver) && !scorer.accepts(&screwdriver));

    // A call with the wrong sizes is refused before the model runs.
    let turn = mode(Task::Screwdriver, "turn");
    let mut out = vec![0.0f32; screwdriver.floats()];
    let err = sampler
        .sample(
            &screwdriver,
            &screwdriver_start(0.0),
            &[turn],
            &mut KernelRng::seed_from_u64(0),
            &mut out,
        )
        .unwrap_err();
    assert_eq!(err, SegmentModelError::Adapter(AdapterError::Dims(horizon)));
    let mut p = [0.0f32];
    let err = scorer
        .score(&screwdriver, &out, &[turn], &mut p)
        .unwrap_err();
    assert_eq!(err, SegmentModelError::Adapter(AdapterError::Dims(horizon)));

    // A mode of the other task, too many segments, short buffers.
    let card = Task::Card.dims();
    let start = [0.0f32; 12];
    let mut out = vec![0.0f32; card.floats()];
    let err = sampler
        .sample(
            &card,
            &start,
            &[turn],
            &mut KernelRng::seed_from_u64(0),
            &mut out,
        )
        .unwrap_err();
    assert_eq!(
        err,
        SegmentModelError::Adapter(AdapterError::ModeFingers {
            expected: 2,
            got: 3
        })
    );
    let both = mode(Task::Card, "both");
    let many = vec![both; 65];
    let starts = vec![0.0f32; 65 * 12];
    let mut out = vec![0.0f32; 65 * card.floats()];
    let err = sampler
        .sample(
            &card,
            &starts,
            &many,
            &mut KernelRng::seed_from_u64(0),
            &mut out,
        )
        .unwrap_err();
    assert_eq!(
        err,
        SegmentModelError::Adapter(AdapterError::TooManySegments {
            got: 65,
            capacity: 64
        })
    );
    let err = sampler
        .sample(
            &card,
            &starts[..11],
            &[both],
            &mut KernelRng::seed_from_u64(0),
            &mut out[..card.floats()],
        )
        .unwrap_err();
    assert_eq!(
        err,
        SegmentModelError::Adapter(AdapterError::StartsLength {
            expected: 12,
            got: 11
        })
    );
    let mut tiny = [0.0f32; 10];
    let layout = SamplerAdapterLayout::new(GaussianDenoiser::new(Task::Card, STEPS).dims, 4, 1);
    let err = DiffusionSegmentSampler::new(
        GaussianDenoiser::new(Task::Card, STEPS),
        SamplerConfig::default(),
        &mut tiny,
        &layout,
    )
    .unwrap_err();
    assert!(matches!(
        err,
        AdapterError::ScratchTooSmall {
            buffer: AdapterBuffer::Sampler,
            got: 10,
            ..
        }
    ));
    // A diffusion scratch whose `x` cannot hold one guided pair is the sampler's own error.
    let (mut ab, mut x, mut eps) = (vec![0.0f32; STEPS], vec![0.0f32; 10], vec![0.0f32; 522]);
    let (mut t, mut c, mut m, mut ctx) = ([0.0f32; 2], [0.0f32; 4], [0.0f32; 2], [0.0f32; 8]);
    let scratch = SamplerScratch {
        alpha_bar: &mut ab,
        x: &mut x,
        eps: &mut eps,
        t: &mut t,
        context: &mut c,
        cond_mask: &mut m,
    };
    let err = DiffusionSegmentSampler::from_parts(
        GaussianDenoiser::new(Task::Card, STEPS),
        SamplerConfig::default(),
        scratch,
        &mut ctx,
    )
    .unwrap_err();
    assert_eq!(
        err,
        AdapterError::Sampler(SamplerError::ScratchTooSmall {
            buffer: ScratchBuffer::X,
            needed: 2 * 9 * 29,
            got: 10
        })
    );
    let mut bad_norm = LogisticDiscriminator::new(Task::Card);
    bad_norm.std[3] = 0.0;
    let layout = ScorerAdapterLayout::new(bad_norm.dims, 1);
    let mut buf = vec![0.0f32; layout.total()];
    assert_eq!(
        DiscriminatorScorer::new(bad_norm, &mut buf, &layout).unwrap_err(),
        AdapterError::BadNormalization
    );
}

#[test]
fn a_planner_refuses_models_of_another_task() {
    let mut denoiser = GaussianDenoiser::new(Task::Card, STEPS);
    let mut disc = LogisticDiscriminator::new(Task::Screwdriver);
    let mut b = buffers(&denoiser, 48, 8);
    let (mut sampler, mut scorer) = b.adapters(&mut denoiser, &mut disc, SamplerConfig::default());
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();
    let prior = paper_prior();
    let start = screwdriver_start(0.0);
    let report = planner.plan(
        &SearchConfig::default(),
        &screwdriver_problem(&start, None, &prior),
        &mut sampler,
        &mut scorer,
        &ScrewdriverObjective::from_state(&start).unwrap(),
        &mut NoClock,
    );
    assert_eq!(report.status, SearchStatus::InvalidProblem);
    assert_eq!(report.stats.sampler_calls, 0);
    assert_eq!(sampler.engine().calls, 0);
}

#[test]
fn full_planning_call_through_both_adapters_finds_two_turns() {
    let config = SearchConfig {
        seed: 11,
        ..SearchConfig::default()
    };
    let (report, denoiser, disc) = plan_screwdriver(&config, SamplerConfig::default(), 16);
    assert_eq!(report.status, SearchStatus::Found, "{report:?}");
    let turn = ModeId(0);
    assert_eq!(
        report.modes.iter().filter(|&&m| m == turn).count(),
        2,
        "{:?}",
        report.modes
    );
    let start = screwdriver_start(0.3);
    let objective = ScrewdriverObjective::from_state(&start).unwrap();
    assert!(objective.goal_reached(report.expected_progress));
    assert!(report.expected_progress > 0.3 + 3.0 * TURN);
    // One sampler call (3 modes × 16 particles) and one scorer call per expansion.
    let s = report.stats;
    assert!(s.nodes_expanded >= 2);
    assert_eq!(
        (s.sampler_calls, s.scorer_calls),
        (s.nodes_expanded, s.nodes_expanded)
    );
    assert_eq!(s.segments_sampled, 48 * s.nodes_expanded);
    // DDPM visits every step; 48 trajectories in chunks of 16 are 3 engine calls per step,
    // each of a conditioned and an unconditioned copy.
    let expansions = s.nodes_expanded as usize;
    assert_eq!(denoiser.calls, expansions * STEPS * 3);
    assert_eq!(denoiser.samples, expansions * STEPS * 96);
    // The scorer's buffer holds 16 segments: 3 calls per expansion.
    assert_eq!(disc.calls, expansions * 3);
}

#[test]
fn planning_through_the_adapters_is_deterministic_for_a_seed() {
    let config = SearchConfig {
        seed: 5,
        ..SearchConfig::default()
    };
    let (a, ..) = plan_screwdriver(&config, SamplerConfig::default(), 16);
    // Another chunking of the same batch gives the same bits.
    let (b, ..) = plan_screwdriver(&config, SamplerConfig::default(), 5);
    let bits = |r: &SearchReport| {
        (
            r.terminal_state
                .iter()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>(),
            r.expected_progress.to_bits(),
            r.cost_to_come.to_bits(),
            r.heuristic.to_bits(),
        )
    };
    assert_eq!(a, b);
    assert_eq!(bits(&a), bits(&b));
    let (c, ..) = plan_screwdriver(
        &SearchConfig { seed: 6, ..config },
        SamplerConfig::default(),
        16,
    );
    assert_ne!(bits(&a), bits(&c));
}

#[test]
fn ddim_and_sampler_settings_are_selectable() {
    let config = SearchConfig {
        seed: 3,
        ..SearchConfig::default()
    };
    let ddim = SamplerConfig {
        method: SamplingMethod::Ddim { steps: 4, eta: 0.0 },
        guidance_weight: 1.0,
        ..SamplerConfig::default()
    };
    let (report, denoiser, _) = plan_screwdriver(&config, ddim, 48);
    assert_eq!(report.status, SearchStatus::Found, "{report:?}");
    assert_eq!(
        denoiser.calls,
        report.stats.nodes_expanded as usize * 4,
        "4 DDIM steps, one engine call each"
    );
    // A bad setting is the sampler's typed error, and the search stops on it.
    let bad = SamplerConfig {
        method: SamplingMethod::Ddpm {
            noise_factor: f32::NAN,
        },
        guidance_weight: 1.2,
        ..SamplerConfig::default()
    };
    let (report, denoiser, _) = plan_screwdriver(&config, bad, 8);
    assert_eq!(
        report.status,
        SearchStatus::Approximate(ApproximateReason::SamplerFailed)
    );
    assert_eq!(denoiser.calls, 0);
    assert!(report.modes.is_empty());
}

#[test]
fn an_engine_failure_stops_the_search_with_a_status() {
    let mut denoiser = GaussianDenoiser::new(Task::Screwdriver, STEPS);
    denoiser.fail_after = Some(STEPS * 6 + 2);
    let mut disc = LogisticDiscriminator::new(Task::Screwdriver);
    let mut b = buffers(&denoiser, 48, 8);
    let mut sampler = DiffusionSegmentSampler::new(
        &mut denoiser,
        SamplerConfig::default(),
        &mut b.sampler,
        &b.sampler_layout,
    )
    .unwrap();
    let mut out = vec![0.0f32; 48 * 481];
    let starts: Vec<f32> = (0..48).flat_map(|_| screwdriver_start(0.0)).collect();
    let modes = vec![mode(Task::Screwdriver, "turn"); 48];
    let dims = Task::Screwdriver.dims();
    sampler
        .sample(
            &dims,
            &starts,
            &modes,
            &mut KernelRng::seed_from_u64(1),
            &mut out,
        )
        .unwrap();
    let err = sampler
        .sample(
            &dims,
            &starts,
            &modes,
            &mut KernelRng::seed_from_u64(1),
            &mut out,
        )
        .unwrap_err();
    assert_eq!(
        err,
        SegmentModelError::Sample(dips_kernel::diffusion::SampleError::Engine(
            "denoiser double: failing as asked"
        ))
    );
    let mut scorer = DiscriminatorScorer::new(&mut disc, &mut b.scorer, &b.scorer_layout).unwrap();
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();
    let prior = paper_prior();
    let start = screwdriver_start(0.0);
    let report = planner.plan(
        &SearchConfig::default(),
        &Problem {
            task: Task::Screwdriver,
            dims,
            start: &start,
            executed: None,
            prior: &prior,
            first_modes: dips_kernel::mode::ModeSet::all(Task::Screwdriver),
        },
        &mut sampler,
        &mut scorer,
        &ScrewdriverObjective::from_state(&start).unwrap(),
        &mut NoClock,
    );
    assert_eq!(
        report.status,
        SearchStatus::Approximate(ApproximateReason::SamplerFailed)
    );
}
