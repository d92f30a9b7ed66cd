//! The firmware plans with uploaded models: the host lowers the exported fixture models,
//! uploads them over the wire into firmware-sim, sends a plan request, and gets the same plan,
//! bit for bit, as the kernel computes in-process with the same blobs, prior and sampler.
//! Models the firmware cannot run are refused with typed errors, and models of another task
//! get the search's `InvalidProblem` status.
//!
//! The fixtures have random weights: the plans mean nothing, but every stage of the firmware's
//! path runs on real lowered models.

use std::io::Cursor;
use std::path::PathBuf;

use dips_firmware_sim::{FirmwareMemory, serve};
use dips_kernel::adapters::{
    DiffusionSegmentSampler, DiscriminatorScorer, SamplerAdapterLayout, ScorerAdapterLayout,
};
use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::engine::DenoiserEngine;
use dips_kernel::mode::Task;
use dips_kernel::nn::engine::KernelEngine;
use dips_kernel::nn::model::parse;
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::PaperPlanner;
use dips_kernel::wire_convert::plan_request;
use dips_onnx::{Expectation, Role, lower_file};
use dips_wire::error::RequestField;
use dips_wire::{
    Feed, Frame, FrameAccumulator, FromKernel, Hello, MAX_ENCODED_FRAME_LEN, ModelFault, ModelRole,
    PROTOCOL_VERSION, PlanReply, PlanRequest, PlanStatus, PriorTable, SCHEMA_KEY, SamplerMethod,
    SamplerSettings, SearchSettings, ToKernel, WireError, decode_frame, encode_frame,
    upload_messages,
};

const MODEL_CAPACITY: usize = 4 << 20;
const WORK_FLOATS: usize = 8 << 20;

fn lowered(task: Task, role: Role) -> Vec<u8> {
    let (dir, file) = match (task, role) {
        (Task::Screwdriver, Role::Denoiser) => ("torch-screwdriver-legacy", "denoiser.onnx"),
        (Task::Screwdriver, Role::Discriminator) => {
            ("torch-screwdriver-legacy", "discriminator.onnx")
        }
        (Task::Card, Role::Denoiser) => ("torch-card-dynamo", "denoiser.onnx"),
        (Task::Card, Role::Discriminator) => ("torch-card-dynamo", "discriminator.onnx"),
    };
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../onnx/tests/fixtures")
        .join(dir)
        .join(file);
    lower_file(&path, &Expectation::new(role, task.name()))
        .unwrap_or_else(|e| panic!("lowering {}: {e}", path.display()))
        .blob
}

fn request(seed: u64) -> PlanRequest {
    let mut start = vec![0.1f32; Task::Screwdriver.dims().state_dim];
    let sd = start.len();
    start[sd - 2] = 1.0; // cos yaw
    start[sd - 1] = 0.0; // sin yaw
    PlanRequest {
        task: dips_wire::Task::Screwdriver,
        start_state: start.iter().copied().collect(),
        goal: -1.0,
        settings: SearchSettings {
            k: 4,
            max_depth: 3,
            node_budget: 3,
            seed,
            ..SearchSettings::default()
        },
        previous_mode: None,
        card_goals: Default::default(),
        first_modes: 0b111,
    }
}

fn frames(messages: impl IntoIterator<Item = ToKernel>) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut buf = [0u8; MAX_ENCODED_FRAME_LEN];
    for (i, body) in messages.into_iter().enumerate() {
        let frame = Frame {
            request_id: i as u32 + 1,
            body,
        };
        bytes.extend_from_slice(encode_frame(&frame, &mut buf).unwrap());
    }
    bytes
}

fn replies(bytes: &[u8]) -> Vec<FromKernel> {
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut out = Vec::new();
    let mut window = bytes;
    loop {
        match acc.feed(window) {
            Feed::Consumed => return out,
            Feed::Frame { payload, remaining } => {
                out.push(decode_frame::<FromKernel>(payload).unwrap().body);
                window = remaining;
            }
            Feed::Error { error, .. } => panic!("bad reply frame: {error}"),
        }
    }
}

/// A session: hello, the two uploads, then `requests`; returns the replies to `requests`.
fn session(
    denoiser: &[u8],
    discriminator: &[u8],
    work_floats: usize,
    requests: &[PlanRequest],
) -> Vec<FromKernel> {
    configured_session(denoiser, discriminator, work_floats, &[], requests)
}

/// [`session`] with `config` messages after the uploads; returns the replies to `config`
/// and `requests`.
fn configured_session(
    denoiser: &[u8],
    discriminator: &[u8],
    work_floats: usize,
    config: &[ToKernel],
    requests: &[PlanRequest],
) -> Vec<FromKernel> {
    let mut memory = FirmwareMemory::planning(MODEL_CAPACITY, work_floats);
    let mut firmware = memory.firmware();
    let mut messages = vec![ToKernel::Hello(Hello {
        protocol_version: PROTOCOL_VERSION,
        schema_key: SCHEMA_KEY,
    })];
    messages.extend(upload_messages(ModelRole::Denoiser, denoiser).unwrap());
    messages.extend(upload_messages(ModelRole::Discriminator, discriminator).unwrap());
    let setup = messages.len();
    messages.extend(config.iter().cloned());
    messages.extend(requests.iter().cloned().map(ToKernel::PlanRequest));
    let mut out = Vec::new();
    serve(&mut firmware, Cursor::new(frames(messages)), &mut out).unwrap();
    let all = replies(&out);
    assert_eq!(all.len(), setup + config.len() + requests.len());
    for reply in &all[..setup] {
        assert!(!matches!(reply, FromKernel::Error(_)), "setup: {reply:?}");
    }
    all[setup..].to_vec()
}

/// Hello, the two uploads, then `then`; every reply, the uploads' included.
fn raw_session(
    denoiser: &[u8],
    discriminator: &[u8],
    work_floats: usize,
    then: &[ToKernel],
) -> Vec<FromKernel> {
    let mut memory = FirmwareMemory::planning(MODEL_CAPACITY, work_floats);
    let mut firmware = memory.firmware();
    let mut messages = vec![ToKernel::Hello(Hello::current())];
    messages.extend(upload_messages(ModelRole::Denoiser, denoiser).unwrap());
    messages.extend(upload_messages(ModelRole::Discriminator, discriminator).unwrap());
    messages.extend(then.iter().cloned());
    let mut out = Vec::new();
    serve(&mut firmware, Cursor::new(frames(messages)), &mut out).unwrap();
    replies(&out)
}

/// The same request planned in-process with the kernel engines over the same blobs, the
/// paper's prior and sampler.
fn in_process(denoiser: &[u8], discriminator: &[u8], request: &PlanRequest) -> PlanReply {
    let prior = MarkovPrior::paper(Task::Screwdriver, request.settings.p_min).unwrap();
    in_process_with(
        denoiser,
        discriminator,
        request,
        &prior,
        SamplerConfig::default(),
    )
}

/// [`in_process`] with the given prior (already floored) and sampler.
fn in_process_with(
    denoiser: &[u8],
    discriminator: &[u8],
    request: &PlanRequest,
    prior: &MarkovPrior,
    sampler_config: SamplerConfig,
) -> PlanReply {
    let den_info = parse(denoiser).unwrap();
    let disc_info = parse(discriminator).unwrap();
    let segments = 3 * usize::from(request.settings.k);
    let mut den_mem = vec![0.0f32; den_info.memory_len(2 * segments).unwrap()];
    let mut disc_mem = vec![0.0f32; disc_info.memory_len(segments).unwrap()];
    let den = KernelEngine::new(denoiser, &mut den_mem).unwrap();
    let disc = KernelEngine::new(discriminator, &mut disc_mem).unwrap();
    let sl = SamplerAdapterLayout::new(DenoiserEngine::dims(&den), segments, segments);
    let cl = ScorerAdapterLayout::new(disc_info.dims, segments);
    let (mut sb, mut cb) = (vec![0.0f32; sl.total()], vec![0.0f32; cl.total()]);
    let mut sampler =
        DiffusionSegmentSampler::new(den, sampler_config, &mut sb, &sl).expect("sampler adapter");
    // The task's start anchor, as every planning session applies it.
    sampler.set_start_anchor(dips_kernel::session::start_anchor(Task::from(request.task)));
    let mut scorer = DiscriminatorScorer::new(disc, &mut cb, &cl).expect("scorer adapter");
    let mut planner = Box::new(PaperPlanner::new());
    plan_request(
        &mut planner,
        request,
        prior,
        &mut sampler,
        &mut scorer,
        &mut NoClock,
    )
    .unwrap()
}

fn plan_reply(reply: &FromKernel) -> PlanReply {
    match reply {
        FromKernel::PlanReply(r) => r.clone(),
        other => panic!("expected a plan reply, got {other:?}"),
    }
}

/// Everything but the wall-clock time (the firmware reads a real clock, the in-process
/// reference none).
fn without_time(mut reply: PlanReply) -> PlanReply {
    reply.stats.elapsed_ms = 0;
    reply
}

#[test]
fn the_firmware_plans_with_uploaded_models_as_the_kernel_does_in_process() {
    let den = lowered(Task::Screwdriver, Role::Denoiser);
    let disc = lowered(Task::Screwdriver, Role::Discriminator);
    let requests = [request(5), request(6), request(5)];
    let got = session(&den, &disc, WORK_FLOATS, &requests);
    let first = plan_reply(&got[0]);
    assert!(
        matches!(
            first.status,
            PlanStatus::Found | PlanStatus::Approximate { .. }
        ),
        "{first:?}"
    );
    assert!(!first.modes.is_empty());
    assert!((1..=3).contains(&first.stats.nodes_expanded));
    assert_eq!(
        without_time(first.clone()),
        without_time(in_process(&den, &disc, &requests[0]))
    );
    // Same seed, same plan, also later in the same session; another seed plans anew.
    assert_eq!(
        without_time(plan_reply(&got[2])),
        without_time(first.clone())
    );
    assert_eq!(
        without_time(plan_reply(&got[1])),
        without_time(in_process(&den, &disc, &requests[1]))
    );

    // A work area too small for the models' full batch splits it into smaller engine calls:
    // the same plan.
    let den_info = parse(&den).unwrap();
    let disc_info = parse(&disc).unwrap();
    let tight = den_info.memory_len(6).unwrap() + disc_info.memory_len(3).unwrap() + (1 << 16);
    let small = session(&den, &disc, tight, &requests[..1]);
    assert_eq!(without_time(plan_reply(&small[0])), without_time(first));
}

/// The kernel's op kernels have AVX2 copies chosen at run time (`nn::ops::cpu`); with them
/// or without, the same plan, bit for bit (expected terminal states, costs and weights
/// included), so a plan does not depend on the CPU that made it.
#[test]
fn the_plan_is_the_same_with_or_without_the_wide_op_kernels() {
    let den = lowered(Task::Screwdriver, Role::Denoiser);
    let disc = lowered(Task::Screwdriver, Role::Discriminator);
    let request = request(7);
    dips_kernel::nn::ops::cpu::allow_wide(false);
    let narrow = without_time(in_process(&den, &disc, &request));
    dips_kernel::nn::ops::cpu::allow_wide(true);
    let wide = without_time(in_process(&den, &disc, &request));
    assert!(!wide.modes.is_empty());
    assert_eq!(wide, narrow);
}

#[test]
fn models_the_firmware_cannot_run_are_refused_with_typed_errors() {
    let den = lowered(Task::Screwdriver, Role::Denoiser);
    let disc = lowered(Task::Screwdriver, Role::Discriminator);
    let req = [request(1)];
    let error = |replies: Vec<FromKernel>| match &replies[0] {
        FromKernel::Error(e) => *e,
        other => panic!("expected an error, got {other:?}"),
    };
    // Bytes with a correct CRC that are not a lowered model, and the two models uploaded in
    // each other's place: refused at the upload's end, so no denoiser is loaded.
    let junk = vec![7u8; 1000];
    for (d, c, fault) in [
        (&junk, &disc, ModelFault::Invalid),
        (&disc, &den, ModelFault::WrongShape),
    ] {
        let all = raw_session(d, c, WORK_FLOATS, &[ToKernel::PlanRequest(request(1))]);
        let end_replies: Vec<&FromKernel> = all
            .iter()
            .filter(|r| {
                matches!(
                    r,
                    FromKernel::ModelLoaded(_) | FromKernel::Error(WireError::ModelRejected { .. })
                )
            })
            .collect();
        assert_eq!(
            end_replies[0],
            &FromKernel::Error(WireError::ModelRejected {
                role: ModelRole::Denoiser,
                fault
            })
        );
        assert_eq!(
            all.last().unwrap(),
            &FromKernel::Error(WireError::ModelNotLoaded {
                role: ModelRole::Denoiser
            })
        );
    }
    // A denoiser and a discriminator of different tasks.
    let card_disc = lowered(Task::Card, Role::Discriminator);
    assert_eq!(
        error(session(&den, &card_disc, WORK_FLOATS, &req)),
        WireError::ModelRejected {
            role: ModelRole::Discriminator,
            fault: ModelFault::WrongShape
        }
    );
    // Too little memory for even one sample.
    match error(session(&den, &disc, 1000, &req)) {
        WireError::ModelRejected {
            fault:
                ModelFault::TooLarge {
                    needed_floats,
                    capacity_floats,
                },
            ..
        } => assert!(needed_floats > capacity_floats && capacity_floats == 1000),
        other => panic!("{other:?}"),
    }
}

/// An upload that is refused, broken off, restarted or interleaved with plan requests never
/// touches the model in use: every plan in between is the plan of the good models.
#[test]
fn a_refused_or_broken_upload_leaves_the_models_in_use() {
    let den = lowered(Task::Screwdriver, Role::Denoiser);
    let disc = lowered(Task::Screwdriver, Role::Discriminator);
    let card_den = lowered(Task::Card, Role::Denoiser);
    let plan = ToKernel::PlanRequest(request(2));
    let good = plan_reply(&session(&den, &disc, WORK_FLOATS, &[request(2)])[0]);
    let upload =
        |role, bytes: &[u8]| -> Vec<ToKernel> { upload_messages(role, bytes).unwrap().collect() };
    let junk_den = upload(ModelRole::Denoiser, &[9u8; 3000]);
    let card = upload(ModelRole::Denoiser, &card_den);
    let mut then = Vec::new();
    // A junk model, refused at its end.
    then.extend(junk_den.iter().cloned());
    then.push(plan.clone());
    // A denoiser upload broken off after two chunks, a plan request in the middle of it.
    then.extend(card[..3].iter().cloned());
    then.push(plan.clone());
    // Restarted with a bad CRC: refused at its end.
    let mut bad_crc = card.clone();
    if let ToKernel::ModelBegin(b) = &mut bad_crc[0] {
        b.crc32 ^= 1;
    }
    then.extend(bad_crc);
    then.push(plan.clone());
    // A chunk out of order, then an end: refused, nothing changes.
    then.push(card[0].clone());
    then.push(card[2].clone());
    then.push(ToKernel::ModelEnd);
    then.push(plan.clone());
    let all = raw_session(&den, &disc, WORK_FLOATS, &then);
    let plans: Vec<PlanReply> = all
        .iter()
        .filter_map(|r| match r {
            FromKernel::PlanReply(p) => Some(without_time(p.clone())),
            _ => None,
        })
        .collect();
    assert_eq!(plans.len(), 4, "{all:?}");
    for p in plans {
        assert_eq!(p, without_time(good.clone()));
    }
    let errors: Vec<WireError> = all
        .iter()
        .filter_map(|r| match r {
            FromKernel::Error(e) => Some(*e),
            _ => None,
        })
        .collect();
    assert!(errors.contains(&WireError::ModelRejected {
        role: ModelRole::Denoiser,
        fault: ModelFault::Invalid
    }));
    assert!(errors.iter().any(|e| matches!(
        e,
        WireError::Upload(dips_wire::UploadError::CrcMismatch { .. })
    )));
    assert!(errors.iter().any(|e| matches!(
        e,
        WireError::Upload(dips_wire::UploadError::BadOffset { .. })
    )));
    assert!(errors.iter().any(|e| matches!(
        e,
        WireError::Upload(dips_wire::UploadError::Incomplete { .. })
    )));
}

#[test]
fn models_of_another_task_give_an_invalid_problem_reply() {
    let den = lowered(Task::Card, Role::Denoiser);
    let disc = lowered(Task::Card, Role::Discriminator);
    let reply = plan_reply(&session(&den, &disc, WORK_FLOATS, &[request(1)])[0]);
    assert_eq!(reply.status, PlanStatus::InvalidProblem);
    assert_eq!(reply.stats.sampler_calls, 0);
}

#[test]
fn the_host_sets_the_prior_and_the_sampler() {
    let den = lowered(Task::Screwdriver, Role::Denoiser);
    let disc = lowered(Task::Screwdriver, Role::Discriminator);
    // Start with a thumb-middle regrasp, then alternate strictly (before the p_min floor).
    let table = |task, probabilities: &[f32]| {
        ToKernel::SetPrior(PriorTable {
            task,
            probabilities: probabilities.iter().copied().collect(),
        })
    };
    let screwdriver = [
        0.0, 0.0, 1.0, // p(c0): turn, index-regrasp, thumb-middle-regrasp
        0.0, 0.3, 0.7, // after a turn
        1.0, 0.0, 0.0, // after an index regrasp
        0.5, 0.5, 0.0, // after a thumb-middle regrasp
    ];
    let ddim = ToKernel::SetSampler(SamplerSettings {
        method: SamplerMethod::Ddim { steps: 8 },
        guidance_weight: 1.5,
    });
    // A card prior must not touch screwdriver plans.
    let card = table(dips_wire::Task::Card, &[1.0; 20]);
    let config = [
        table(dips_wire::Task::Screwdriver, &screwdriver),
        ddim,
        card,
    ];
    let req = request(9);
    let got = configured_session(
        &den,
        &disc,
        WORK_FLOATS,
        &config,
        std::slice::from_ref(&req),
    );
    assert!(
        got[..3].iter().all(|r| *r == FromKernel::Applied),
        "{got:?}"
    );
    let rows: Vec<&[f32]> = screwdriver[3..].chunks(3).collect();
    let prior = MarkovPrior::from_rows(&screwdriver[..3], &rows)
        .unwrap()
        .with_floor(req.settings.p_min)
        .unwrap();
    let mut sampler = SamplerConfig::ddim(8);
    sampler.guidance_weight = 1.5;
    let want = in_process_with(&den, &disc, &req, &prior, sampler);
    assert_eq!(
        without_time(plan_reply(&got[3])),
        without_time(want.clone())
    );
    // The settings changed the plan (the paper's prior and DDPM give another one).
    assert_ne!(
        without_time(want),
        without_time(in_process(&den, &disc, &req))
    );

    // Bad tables and settings are refused and change nothing.
    let bad = [
        table(dips_wire::Task::Card, &screwdriver),
        table(dips_wire::Task::Screwdriver, &[-1.0; 12]),
        table(dips_wire::Task::Screwdriver, &[0.0; 12]),
        table(dips_wire::Task::Screwdriver, &[f32::NAN; 12]),
        ToKernel::SetSampler(SamplerSettings {
            method: SamplerMethod::Ddim { steps: 0 },
            guidance_weight: 1.2,
        }),
        ToKernel::SetSampler(SamplerSettings {
            method: SamplerMethod::Ddpm { noise_factor: 1.5 },
            guidance_weight: 1.2,
        }),
        ToKernel::SetSampler(SamplerSettings {
            method: SamplerMethod::Ddpm { noise_factor: 0.5 },
            guidance_weight: f32::INFINITY,
        }),
    ];
    let got = configured_session(&den, &disc, WORK_FLOATS, &bad, std::slice::from_ref(&req));
    let fields: Vec<_> = got[..bad.len()]
        .iter()
        .map(|r| match r {
            FromKernel::Error(WireError::InvalidRequest { field }) => *field,
            other => panic!("expected a refusal, got {other:?}"),
        })
        .collect();
    use RequestField::{Prior, Sampler};
    assert_eq!(
        fields,
        [Prior, Prior, Prior, Prior, Sampler, Sampler, Sampler]
    );
    assert_eq!(
        without_time(plan_reply(&got[bad.len()])),
        without_time(in_process(&den, &disc, &req))
    );
}
