//! Both model engines plug into the search (issue 5 item 4): the exported fixture models, run
//! by tract and by the kernel interpreter, drive a real planning call through
//! `DiffusionSegmentSampler` and `DiscriminatorScorer`, directly and through the wire path.
//!
//! The fixtures have random weights, so the plans mean nothing; what is checked is that the
//! pipeline runs end to end, that it is deterministic, and that the two engines give the same
//! plan.

use std::path::PathBuf;

use dips_kernel::adapters::{
    DiffusionSegmentSampler, DimField, DimsMismatch, DiscriminatorScorer, SamplerAdapterLayout,
    ScorerAdapterLayout,
};
use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::engine::DenoiserEngine;
use dips_kernel::mode::Task;
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::{ApproximateReason, Planner, SearchConfig, SearchReport, SearchStatus};
use dips_kernel::session::{PlanSpec, plan_with_adapters};
use dips_kernel::wire_convert::{PlanInputs, plan_request};
use dips_onnx::{AnyEngine, EngineKind, Expectation, Role};
use dips_planning::{Models, Session};
use dips_wire::{PlanReply, PlanRequest, PlanStatus, SearchSettings};

/// Small capacities: k ≤ 4, any task's segment.
type SmallPlanner = Planner<4, 64, 32, 481>;
/// A planning session with those capacities.
type SmallSession = Session<4, 64, 32, 481>;

fn fixture(task: Task, file: &str) -> PathBuf {
    let dir = match task {
        Task::Screwdriver => "torch-screwdriver-legacy",
        Task::Card => "torch-card-dynamo",
    };
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../onnx/tests/fixtures")
        .join(dir)
        .join(file)
}

fn load(kind: EngineKind, task: Task, role: Role) -> AnyEngine {
    let file = match role {
        Role::Denoiser => "denoiser.onnx",
        Role::Discriminator => "discriminator.onnx",
    };
    AnyEngine::load(
        kind,
        &fixture(task, file),
        &Expectation::new(role, task.name()),
    )
    .unwrap_or_else(|e| panic!("{task:?} {role:?} with {kind:?}: {e}"))
}

fn start(task: Task) -> Vec<f32> {
    let mut s = vec![0.1f32; task.dims().state_dim];
    let sd = s.len();
    s[sd - 4] = 0.0;
    s[sd - 3] = 0.0;
    s[sd - 2] = 1.0;
    s[sd - 1] = 0.0;
    s
}

fn config() -> SearchConfig {
    SearchConfig {
        k: 4,
        node_budget: 3,
        seed: 5,
        ..SearchConfig::default()
    }
}

/// One planning call with models of `model_task` on a problem of `task`, through the host's
/// planning session (engines → adapters → planner).
fn plan(kind: EngineKind, model_task: Task, task: Task) -> SearchReport {
    let models = Models {
        denoiser: load(kind, model_task, Role::Denoiser),
        discriminator: load(kind, model_task, Role::Discriminator),
        prior: None,
        dir: std::path::PathBuf::new(),
        policy: None,
        psi_negatives: None,
        card_goals: None,
    };
    let prior = MarkovPrior::uniform(task.mode_count()).unwrap();
    let goal = match task {
        Task::Screwdriver => -1.0,
        Task::Card => -0.06,
    };
    let mut spec = PlanSpec::with_settings(task, &start(task), goal, config(), prior).unwrap();
    spec.sampler = SamplerConfig::ddim(8);
    let mut session = SmallSession::new(models);
    session.plan(&spec, &mut NoClock).unwrap()
}

#[test]
fn both_engines_drive_the_search_and_agree() {
    for task in Task::ALL {
        let tract = plan(EngineKind::Tract, task, task);
        let kernel = plan(EngineKind::Kernel, task, task);
        for r in [&tract, &kernel] {
            // Random weights: the goal may or may not be met within the 3 expansions.
            assert!(
                matches!(
                    r.status,
                    SearchStatus::Found | SearchStatus::Approximate(ApproximateReason::NodeBudget)
                ),
                "{task:?}: {:?}",
                r.status
            );
            let n = r.stats.nodes_expanded;
            assert!((1..=3).contains(&n), "{task:?}: {n} expansions");
            assert_eq!((r.stats.sampler_calls, r.stats.scorer_calls), (n, n));
            assert_eq!(
                r.stats.segments_sampled as usize,
                n as usize * task.mode_count() * 4
            );
            assert!(r.expected_progress.is_finite());
            assert!(r.terminal_state.iter().all(|v| v.is_finite()));
        }
        // The engines agree to about 1e-5; the search makes the same discrete choices.
        assert_eq!(tract.status, kernel.status, "{task:?}");
        assert_eq!(tract.modes, kernel.modes, "{task:?}");
        assert_eq!(tract.stats.nodes_expanded, kernel.stats.nodes_expanded);
        let (a, b) = (tract.expected_progress, kernel.expected_progress);
        assert!(
            (a - b).abs() <= 1e-3 * a.abs().max(1e-2),
            "{task:?}: {a} vs {b}"
        );
        // Same engine, same seed: the same bits.
        let again = plan(EngineKind::Kernel, task, task);
        assert_eq!(again, kernel, "{task:?}");
    }
}

#[test]
fn models_of_another_task_are_refused_before_sampling() {
    let report = plan(EngineKind::Kernel, Task::Card, Task::Screwdriver);
    assert_eq!(report.status, SearchStatus::InvalidProblem);
    assert_eq!(report.stats.sampler_calls, 0);
    let mut card = load(EngineKind::Tract, Task::Card, Role::Denoiser);
    let layout = SamplerAdapterLayout::new(DenoiserEngine::dims(&card), 4, 4);
    let mut buf = vec![0.0f32; layout.total()];
    let sampler =
        DiffusionSegmentSampler::new(&mut card, SamplerConfig::default(), &mut buf, &layout)
            .unwrap();
    assert_eq!(
        sampler.check_dims(&Task::Screwdriver.dims()),
        Err(DimsMismatch {
            field: DimField::Horizon,
            model: 9,
            problem: 13
        })
    );
}

#[test]
fn a_wire_request_is_planned_with_the_kernel_engine() {
    let task = Task::Screwdriver;
    let mut denoiser = load(EngineKind::Kernel, task, Role::Denoiser);
    let mut discriminator = load(EngineKind::Kernel, task, Role::Discriminator);
    let dims = DenoiserEngine::dims(&denoiser);
    let sl = SamplerAdapterLayout::new(dims, 12, 6);
    let cl = ScorerAdapterLayout::new(dims, 6);
    let (mut sb, mut cb) = (vec![0.0f32; sl.total()], vec![0.0f32; cl.total()]);
    let mut sampler =
        DiffusionSegmentSampler::new(&mut denoiser, SamplerConfig::ddim(8), &mut sb, &sl).unwrap();
    let mut scorer = DiscriminatorScorer::new(&mut discriminator, &mut cb, &cl).unwrap();
    let prior = MarkovPrior::uniform(3).unwrap();
    let mut request = PlanRequest {
        task: dips_wire::Task::Screwdriver,
        start_state: Default::default(),
        goal: -1.0,
        settings: SearchSettings::from(config()),
        previous_mode: Some(1),
        card_goals: Default::default(),
        first_modes: 0b111,
    };
    for v in start(task) {
        request.start_state.push(v).unwrap();
    }
    let mut planner = Box::new(SmallPlanner::new());
    let reply = plan_request(
        &mut planner,
        &request,
        &prior,
        &mut sampler,
        &mut scorer,
        &mut NoClock,
    )
    .unwrap();
    assert!(
        matches!(
            reply.status,
            PlanStatus::Found
                | PlanStatus::Approximate {
                    reason: dips_wire::ApproximateReason::NodeBudget
                }
        ),
        "{:?}",
        reply.status
    );
    assert!((1..=3).contains(&reply.stats.nodes_expanded));
    // The same call made directly gives the same reply.
    let spec = PlanInputs::from_request(&request)
        .unwrap()
        .into_spec(prior, SamplerConfig::ddim(8));
    let report = plan_with_adapters(&mut planner, &spec, &mut sampler, &mut scorer, &mut NoClock);
    assert_eq!(reply, PlanReply::from(&report));
}
