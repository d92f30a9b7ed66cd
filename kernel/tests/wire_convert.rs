//! Kernel ↔ wire conversions: settings, statuses, tasks and mode ids round-trip; requests are
//! checked field by field; a report survives the trip to bytes and back as a reply.

mod common;
mod engines;

use common::{paper_prior, screwdriver_start};
use dips_kernel::adapters::{
    DiffusionSegmentSampler, DiscriminatorScorer, SamplerAdapterLayout, ScorerAdapterLayout,
};
use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::{ModeId, Task};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::config::ConfigError;
use dips_kernel::search::{
    ApproximateReason, Capacity, CostToCome, SearchConfig, SearchStatus, SearchVariant,
    TaskObjective,
};
use dips_kernel::task::{CardGoals, CardObjective, Objective};
use dips_kernel::wire_convert::*;
use dips_wire::{
    Feed, Frame, FrameAccumulator, FromKernel, MAX_ENCODED_FRAME_LEN, PlanCapacity, PlanReply,
    PlanRequest, PlanStatus, RequestField, SearchSettings, SettingsField, ToKernel, WireError,
    decode_frame, encode_frame,
};
use engines::{GaussianDenoiser, LogisticDiscriminator};
use proptest::prelude::*;

fn every_status() -> Vec<SearchStatus> {
    let capacities = [
        Capacity::Particles,
        Capacity::Nodes,
        Capacity::OpenList,
        Capacity::StateDim,
        Capacity::SegmentFloats,
        Capacity::Modes,
    ];
    let configs = [
        ConfigError::K,
        ConfigError::MaxDepth,
        ConfigError::Gamma,
        ConfigError::Alpha,
        ConfigError::Beta,
        ConfigError::PMin,
    ];
    let mut all = vec![
        SearchStatus::Found,
        SearchStatus::InvalidProblem,
        SearchStatus::InvalidStart,
        SearchStatus::InvalidGoal,
    ];
    for r in [
        ApproximateReason::NodeBudget,
        ApproximateReason::TimeBudget,
        ApproximateReason::Exhausted,
        ApproximateReason::SamplerFailed,
        ApproximateReason::ScorerFailed,
    ] {
        all.push(SearchStatus::Approximate(r));
    }
    for c in capacities {
        all.push(SearchStatus::Approximate(ApproximateReason::Capacity(c)));
        all.push(SearchStatus::CapacityExceeded(c));
    }
    all.extend(configs.map(SearchStatus::InvalidConfig));
    all
}

#[test]
fn every_search_status_round_trips_through_the_wire() {
    let all = every_status();
    assert_eq!(all.len(), 27);
    let mut seen = Vec::new();
    for s in all {
        let wire = PlanStatus::from(s);
        assert!(!seen.contains(&wire), "{s:?} maps onto a taken status");
        seen.push(wire);
        assert_eq!(SearchStatus::try_from(wire), Ok(s));
    }
    for only_wire in [PlanStatus::NoPlan, PlanStatus::Cancelled] {
        assert_eq!(
            SearchStatus::try_from(only_wire),
            Err(NoSearchStatus(only_wire))
        );
    }
    // Spot checks of the mapping itself.
    assert_eq!(
        PlanStatus::from(SearchStatus::Approximate(ApproximateReason::Capacity(
            Capacity::OpenList
        ))),
        PlanStatus::Approximate {
            reason: dips_wire::ApproximateReason::Capacity {
                capacity: PlanCapacity::OpenList
            }
        }
    );
    assert_eq!(
        PlanStatus::from(SearchStatus::InvalidConfig(ConfigError::PMin)),
        PlanStatus::InvalidSettings {
            field: SettingsField::PMin
        }
    );
}

#[test]
fn tasks_and_mode_ids_round_trip() {
    for task in Task::ALL {
        assert_eq!(Task::from(dips_wire::Task::from(task)), task);
        for id in task.candidate_modes() {
            let w = mode_to_wire(id);
            assert_eq!(usize::from(w), id.index());
            assert_eq!(mode_from_wire(task, w), Some(id));
        }
        assert_eq!(mode_from_wire(task, task.mode_count() as u8), None);
        assert_eq!(mode_from_wire(task, u8::MAX), None);
    }
    assert_eq!(
        Task::Screwdriver.mode_name(mode_from_wire(Task::Screwdriver, 2).unwrap()),
        Some("thumb-middle-regrasp")
    );
}

fn finite() -> impl Strategy<Value = f32> {
    prop_oneof![
        -1.0e6f32..1.0e6,
        Just(0.0f32),
        Just(f32::NAN),
        Just(f32::INFINITY)
    ]
}

proptest! {
    #[test]
    fn settings_and_config_round_trip_bit_for_bit(
        k in any::<u16>(), max_depth in any::<u8>(),
        floats in proptest::array::uniform4(finite()),
        node_budget in any::<u32>(), time_budget_ms in any::<u32>(), seed in any::<u64>(),
        last in any::<bool>(), ml in any::<bool>(),
    ) {
        let settings = SearchSettings {
            k, max_depth, gamma: floats[0], alpha: floats[1], beta: floats[2], p_min: floats[3],
            node_budget, time_budget_ms, seed,
            cost_to_come: if last {
                dips_wire::CostToCome::LastSegment
            } else {
                dips_wire::CostToCome::Cumulative
            },
            variant: if ml {
                dips_wire::SearchVariant::MaxLikelihood
            } else {
                dips_wire::SearchVariant::Particles
            },
        };
        let config = SearchConfig::from(settings);
        prop_assert_eq!((config.k, config.max_depth, config.seed), (k, max_depth, seed));
        prop_assert_eq!((config.node_budget, config.time_budget_ms), (node_budget, time_budget_ms));
        prop_assert_eq!(config.cost_to_come == CostToCome::LastSegment, last);
        prop_assert_eq!(config.variant == SearchVariant::MaxLikelihood, ml);
        let back = SearchSettings::from(config);
        let bits = |s: &SearchSettings| [s.gamma, s.alpha, s.beta, s.p_min].map(f32::to_bits);
        prop_assert_eq!(bits(&back), bits(&settings));
        prop_assert_eq!(
            (back.k, back.max_depth, back.node_budget, back.time_budget_ms, back.seed),
            (k, max_depth, node_budget, time_budget_ms, seed)
        );
        prop_assert_eq!((back.cost_to_come, back.variant), (settings.cost_to_come, settings.variant));
    }
}

#[test]
fn default_configs_map_onto_each_other() {
    let from_wire = SearchConfig::from(SearchSettings::default());
    assert_eq!(from_wire, SearchConfig::default());
    assert_eq!(
        SearchSettings::from(SearchConfig::default()),
        SearchSettings::default()
    );
    // 0 is "unlimited" on both sides and survives the trip.
    assert_eq!(SearchSettings::from(SearchConfig::default()).node_budget, 0);
    assert_eq!(
        SearchSettings::from(SearchConfig::default()).time_budget_ms,
        300_000
    );
}

fn request(task: dips_wire::Task, start: &[f32], goal: f32) -> PlanRequest {
    PlanRequest {
        task,
        start_state: heapless::Vec::from_slice(start).unwrap(),
        goal,
        settings: SearchSettings::default(),
        previous_mode: None,
        card_goals: Default::default(),
        first_modes: dips_kernel::mode::ModeSet::all(dips_kernel::mode::Task::from(task)).0,
    }
}

#[test]
fn requests_are_checked_field_by_field() {
    let start = screwdriver_start(0.4);
    let ok = request(dips_wire::Task::Screwdriver, &start, -0.6);
    let inputs = PlanInputs::from_request(&ok).unwrap();
    assert_eq!(inputs.task, Task::Screwdriver);
    assert_eq!(inputs.dims, Task::Screwdriver.dims());
    assert_eq!(&inputs.start[..], &start[..]);
    assert_eq!(inputs.executed, None);
    assert_eq!(inputs.config, SearchConfig::from(SearchSettings::default()));

    let mut short = ok.clone();
    short.start_state.truncate(12);
    let mut nan = ok.clone();
    nan.start_state[3] = f32::NAN;
    let card_len = request(dips_wire::Task::Card, &start, -0.06);
    let goal = request(dips_wire::Task::Screwdriver, &start, f32::INFINITY);
    let mut settings = ok.clone();
    settings.settings.gamma = 0.0;
    let mut previous = ok.clone();
    previous.previous_mode = Some(3);
    let mut card_previous = request(dips_wire::Task::Card, &start[..12], -0.06);
    card_previous.previous_mode = Some(3);
    assert_eq!(
        PlanInputs::from_request(&short),
        Err(RequestField::StartState)
    );
    assert_eq!(
        PlanInputs::from_request(&nan),
        Err(RequestField::StartState)
    );
    assert_eq!(
        PlanInputs::from_request(&card_len),
        Err(RequestField::StartState)
    );
    assert_eq!(PlanInputs::from_request(&goal), Err(RequestField::Goal));
    assert_eq!(
        PlanInputs::from_request(&settings),
        Err(RequestField::Settings)
    );
    assert_eq!(
        PlanInputs::from_request(&previous),
        Err(RequestField::PreviousMode)
    );
    // The card has a fourth mode.
    let card = PlanInputs::from_request(&card_previous).unwrap();
    assert_eq!(card.executed, Some(ModeId(3)));
    assert!(matches!(card.objective, Objective::Card(o) if o.goal_y == -0.06));
    assert!(matches!(card.objective, Objective::Card(o) if o.goals == CardGoals::Capped));
}

#[test]
fn the_card_goals_travel_both_ways() {
    let start = screwdriver_start(0.4);
    let spec = dips_kernel::session::PlanSpec::new(Task::Card, &start[..12], -0.06)
        .unwrap()
        .with_card_goals(CardGoals::Paper);
    let request = spec.to_request();
    assert_eq!(request.card_goals, dips_wire::CardGoals::Paper);
    let inputs = PlanInputs::from_request(&request).unwrap();
    let Objective::Card(o) = inputs.objective else {
        panic!("a card objective");
    };
    assert_eq!(o.goals, CardGoals::Paper);
    // The paper's test is exact: half a millimetre short of the goal is not there; ours is.
    assert!(!o.goal_reached(-0.0595));
    assert!(CardObjective::new(-0.06).goal_reached(-0.0595));
    // The screwdriver ignores them.
    let screwdriver = dips_kernel::session::PlanSpec::new(Task::Screwdriver, &start, -0.6)
        .unwrap()
        .with_card_goals(CardGoals::Paper);
    assert_eq!(screwdriver.card_goals(), CardGoals::Capped);
}

#[test]
fn the_screwdriver_start_yaw_is_taken_on_the_goals_branch() {
    // The host tracks the unwrapped yaw: −3.5 rad now, goal π/3 further clockwise. The state
    // only has cos/sin, whose atan2 is −3.5 + 2π.
    let yaw = -3.5f32;
    let goal = yaw - std::f32::consts::FRAC_PI_3;
    let start = screwdriver_start(yaw);
    let inputs =
        PlanInputs::from_request(&request(dips_wire::Task::Screwdriver, &start, goal)).unwrap();
    let Objective::Screwdriver(o) = inputs.objective else {
        panic!("screwdriver objective expected");
    };
    assert!((o.reference_yaw - yaw).abs() < 1e-5, "{}", o.reference_yaw);
    assert_eq!(o.goal_yaw, goal);
    assert!((inputs.objective.progress(&start) - yaw).abs() < 1e-5);
    assert!(
        (inputs
            .objective
            .terminal_cost(inputs.objective.progress(&start))
            - 1.047)
            .abs()
            < 1e-3
    );
    assert!(
        !inputs
            .objective
            .goal_reached(inputs.objective.progress(&start))
    );
    // One turn further is the goal.
    assert!(
        inputs
            .objective
            .goal_reached(inputs.objective.progress(&screwdriver_start(goal - 0.01)))
    );
}

fn frame_bytes<B: dips_wire::Message>(id: u32, body: B) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED_FRAME_LEN];
    encode_frame(
        &Frame {
            request_id: id,
            body,
        },
        &mut buf,
    )
    .unwrap()
    .to_vec()
}

fn deframe<M: dips_wire::Message>(bytes: &[u8]) -> Frame<M> {
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    match acc.feed(bytes) {
        Feed::Frame { payload, remaining } => {
            assert!(remaining.is_empty());
            decode_frame::<M>(payload).unwrap()
        }
        other => panic!("no frame: {other:?}"),
    }
}

#[test]
fn a_framed_request_is_planned_and_its_reply_matches_the_report() {
    let mut denoiser = GaussianDenoiser::new(Task::Screwdriver, 16);
    let mut disc = LogisticDiscriminator::new(Task::Screwdriver);
    let sl = SamplerAdapterLayout::new(denoiser.dims, 48, 48);
    let cl = ScorerAdapterLayout::new(disc.dims, 48);
    let mut sb = vec![0.0f32; sl.total()];
    let mut cb = vec![0.0f32; cl.total()];
    let mut sampler =
        DiffusionSegmentSampler::new(&mut denoiser, SamplerConfig::default(), &mut sb, &sl)
            .unwrap();
    let mut scorer = DiscriminatorScorer::new(&mut disc, &mut cb, &cl).unwrap();
    let prior = paper_prior();
    let mut planner = common::boxed_planner::<16, 512, 256, 481>();

    let start = screwdriver_start(1.0);
    let mut req = request(dips_wire::Task::Screwdriver, &start, 1.0 - 1.2);
    req.settings.seed = 21;
    req.previous_mode = Some(0);
    let bytes = frame_bytes(42, ToKernel::PlanRequest(req.clone()));
    let frame = deframe::<ToKernel>(&bytes);
    assert_eq!(frame.request_id, 42);
    let ToKernel::PlanRequest(decoded) = frame.body else {
        panic!("plan request expected");
    };
    assert_eq!(decoded, req);
    let reply = plan_request(
        &mut planner,
        &decoded,
        &prior,
        &mut sampler,
        &mut scorer,
        &mut NoClock,
    )
    .unwrap();

    // The same call straight on the planner.
    let inputs = PlanInputs::from_request(&req).unwrap();
    let report = planner.plan(
        &inputs.config,
        &inputs.problem(&prior),
        &mut sampler,
        &mut scorer,
        &inputs.objective,
        &mut NoClock,
    );
    assert_eq!(report.status, SearchStatus::Found);
    assert_eq!(report.executed, Some(ModeId(0)));
    assert_eq!(reply, PlanReply::from(&report));
    assert_eq!(reply.status, PlanStatus::Found);
    let modes: Vec<u8> = report.modes.iter().map(|&m| m.0).collect();
    assert_eq!(&reply.modes[..], &modes[..]);
    assert_eq!(&reply.terminal_state[..], &report.terminal_state[..]);
    assert_eq!(reply.stats.nodes_expanded, report.stats.nodes_expanded);
    assert_eq!(reply.stats.discriminator_calls, report.stats.scorer_calls);
    assert_eq!(reply.stats.sampler_calls, report.stats.sampler_calls);
    assert_eq!(reply.stats.nodes_generated, report.stats.nodes_generated);
    // Two turns reach a goal 1.2 rad away; the yaw of the terminal state shows it.
    assert_eq!(reply.modes.iter().filter(|&&m| m == 0).count(), 2);
    let yaw = reply.terminal_state[15].atan2(reply.terminal_state[14]);
    assert!(yaw <= -0.2, "{yaw}");

    let back = deframe::<FromKernel>(&frame_bytes(42, FromKernel::PlanReply(reply.clone())));
    assert_eq!(back.request_id, 42);
    assert_eq!(back.body, FromKernel::PlanReply(reply));

    // A bad request is a typed wire error, and nothing is searched.
    let mut bad = req.clone();
    bad.previous_mode = Some(7);
    assert_eq!(
        plan_request(
            &mut planner,
            &bad,
            &prior,
            &mut sampler,
            &mut scorer,
            &mut NoClock
        ),
        Err(WireError::InvalidRequest {
            field: RequestField::PreviousMode
        })
    );
    // First modes that name none of the screwdriver's three modes, or a fourth.
    for first_modes in [0, 0b1000, 0b1010] {
        let mut bad = req.clone();
        bad.first_modes = first_modes;
        assert_eq!(
            plan_request(
                &mut planner,
                &bad,
                &prior,
                &mut sampler,
                &mut scorer,
                &mut NoClock
            ),
            Err(WireError::InvalidRequest {
                field: RequestField::FirstModes
            }),
            "{first_modes:#b}"
        );
    }
    // The set travels: a request without `turn` first plans a regrasp first.
    let mut no_turn = req.clone();
    no_turn.first_modes = 0b110;
    let reply = plan_request(
        &mut planner,
        &no_turn,
        &prior,
        &mut sampler,
        &mut scorer,
        &mut NoClock,
    )
    .unwrap();
    assert!(matches!(reply.modes.first(), Some(1 | 2)), "{reply:?}");
    // Search-level failures are statuses: a prior of the wrong size.
    let card_prior = MarkovPrior::uniform(4).unwrap();
    let reply = plan_request(
        &mut planner,
        &req,
        &card_prior,
        &mut sampler,
        &mut scorer,
        &mut NoClock,
    )
    .unwrap();
    assert_eq!(reply.status, PlanStatus::InvalidProblem);
    assert!(reply.modes.is_empty() && reply.terminal_state.is_empty());
}

#[test]
fn the_strided_ddpm_round_trips_on_the_wire_and_bad_settings_are_named() {
    use dips_kernel::diffusion::SamplingMethod;
    let strided = SamplerConfig {
        method: SamplingMethod::DdpmStrided {
            steps: 16,
            noise_factor: 0.5,
        },
        ..SamplerConfig::default()
    };
    let settings = settings_from_sampler(&strided).unwrap();
    assert_eq!(sampler_from_settings(&settings), Ok(strided));
    for (steps, noise_factor) in [(0, 0.5), (16, 1.5), (16, f32::NAN)] {
        let bad = dips_wire::SamplerSettings {
            method: dips_wire::SamplerMethod::DdpmStrided {
                steps,
                noise_factor,
            },
            ..settings
        };
        assert_eq!(
            sampler_from_settings(&bad),
            Err(RequestField::Sampler),
            "{steps} {noise_factor}"
        );
    }
}
