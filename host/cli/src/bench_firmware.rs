//! `dips bench firmware`: what the firmware needs on a controller, measured with the shipped
//! models at the paper's search settings.
//!
//! - **Static memory**: the planner (`PaperPlanner`), the two model buffers and the upload
//!   staging buffer (each at least the larger lowered model), and the planning work area one
//!   call uses (the firmware's `Status` after a real call).
//! - **Peak stack** of a planning call: the call runs on a fresh thread with a 64 MiB stack,
//!   and the pages of that stack the call has touched are read from `/proc/self/smaps` (the
//!   resident size of the mapping that holds the thread's locals): pages once touched stay
//!   resident, so it is the high-water mark, to the page. The heap-free kernel keeps its big
//!   state in the planner and the work area, so the stack holds frames and small arrays.
//! - **The wire per planning call**: the frames' encoded bytes (request, reply, and the
//!   `Status` a host reads after it), the CPU time to encode and decode them, and the round
//!   trip of one request to a spawned `dips-firmware-sim` over pipes.

use std::time::Instant;

use anyhow::{Context, anyhow, bail};
use clap::Args;
use dips_exec::problems::contract::contract_state;
use dips_firmware_sim::{Firmware, FirmwareMemory};
use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::Task;
use dips_kernel::search::{PaperPlanner, SearchOverrides};
use dips_kernel::session::PlanSpec;
use dips_kernel::wire_convert::settings_from_sampler;
use dips_onnx::{Expectation, Role, lower_file};
use dips_planning::{model_file, models_dir};
use dips_wire::{
    Frame, FromKernel, Hello, MAX_ENCODED_FRAME_LEN, ModelRole, PlanRequest, ToKernel,
    decode_frame, encode_frame, upload_messages,
};
use dips_world::scenes::SceneKind;
use dips_world::world::World;
use serde_json::json;

/// `dips bench firmware`.
#[derive(Debug, Args)]
pub struct FirmwareBenchArgs {
    /// Task: `screwdriver` or `card`.
    #[arg(long, default_value = "screwdriver", value_parser = crate::search_args::named::<SceneKind>())]
    pub task: SceneKind,
    /// Models directory (default: the shipped models).
    #[arg(long)]
    pub models: Option<std::path::PathBuf>,
    /// Diffusion sampler of the measured call (the stack and memory do not depend on it).
    #[arg(long, default_value = crate::search_args::DEFAULT_SAMPLER)]
    pub sampler: SamplerConfig,
    /// Expansions of the measured call (the stack and memory do not depend on it).
    #[arg(long, default_value_t = 2)]
    pub expansions: u32,
    /// Round trips timed over the spawned firmware.
    #[arg(long, default_value_t = 2000)]
    pub round_trips: usize,
    /// Print JSON instead of readable `key: value` lines.
    #[arg(long)]
    pub json: bool,
}

/// The lowered models and a paper-settings plan request of the task's start state.
struct Setup {
    denoiser: Vec<u8>,
    discriminator: Vec<u8>,
    request: PlanRequest,
    sampler: ToKernel,
}

fn setup(args: &FirmwareBenchArgs, task: Task) -> anyhow::Result<Setup> {
    let scene = SceneKind::from(task);
    let dir = models_dir(args.models.as_deref(), task)?;
    let lower = |role| {
        let file = dir.join(model_file(role));
        lower_file(&file, &Expectation::new(role, task.name()))
            .map(|l| l.blob)
            .with_context(|| format!("lowering {}", file.display()))
    };
    let start: Vec<f32> = contract_state(&World::new(scene).state())
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let goal = PlanSpec::paper_goal(task, &start).ok_or_else(|| anyhow!("short state"))?;
    let config = SearchOverrides {
        node_budget: Some(args.expansions),
        ..SearchOverrides::default()
    }
    .resolve(task, 0, 0);
    let sampler = settings_from_sampler(&args.sampler)
        .ok_or_else(|| anyhow!("--sampler: not expressible on the wire"))?;
    Ok(Setup {
        denoiser: lower(Role::Denoiser)?,
        discriminator: lower(Role::Discriminator)?,
        request: PlanRequest {
            task: task.into(),
            start_state: heapless::Vec::from_slice(&start)
                .map_err(|_| anyhow!("state too long"))?,
            goal,
            settings: config.into(),
            previous_mode: None,
            card_goals: Default::default(),
            first_modes: dips_kernel::mode::ModeSet::all(task).0,
        },
        sampler: ToKernel::SetSampler(sampler),
    })
}

/// A firmware over heap buffers sized for the setup, its models uploaded and sampler set.
fn with_firmware<T>(
    s: &Setup,
    work_floats: usize,
    run: impl FnOnce(&mut Firmware<'_>) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    let cap = s.denoiser.len().max(s.discriminator.len());
    let mut memory = FirmwareMemory::planning(cap, work_floats);
    let mut fw = memory.firmware();
    let mut clock = NoClock;
    let mut messages = vec![ToKernel::Hello(Hello::current()), s.sampler.clone()];
    messages.extend(
        upload_messages(ModelRole::Denoiser, &s.denoiser).ok_or_else(|| anyhow!("upload"))?,
    );
    messages.extend(
        upload_messages(ModelRole::Discriminator, &s.discriminator)
            .ok_or_else(|| anyhow!("upload"))?,
    );
    for m in &messages {
        if let FromKernel::Error(e) = fw.handle(1, m, &mut clock) {
            bail!("setting up the firmware: {e}");
        }
    }
    run(&mut fw)
}

/// Encode `body` as a frame, then deframe and decode it as the other side does (the CPU work
/// of one message on the wire).
fn codec_round<B: dips_wire::Message + Clone>(body: &B) {
    let mut buf = [0u8; MAX_ENCODED_FRAME_LEN];
    let frame = Frame {
        request_id: 2,
        body: body.clone(),
    };
    if let Ok(bytes) = encode_frame(&frame, &mut buf) {
        let mut acc = dips_wire::FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
        if let dips_wire::Feed::Frame { payload, .. } = acc.feed(bytes) {
            let _ = decode_frame::<B>(payload);
        }
    }
}

/// Frame `body` and return its encoded length.
fn encoded_len<B: serde::Serialize>(id: u32, body: B) -> anyhow::Result<usize> {
    let mut buf = [0u8; MAX_ENCODED_FRAME_LEN];
    Ok(encode_frame(
        &Frame {
            request_id: id,
            body,
        },
        &mut buf,
    )
    .map_err(|e| anyhow!("{e}"))?
    .len())
}

/// Resident KiB of the memory mapping that holds this thread's stack (`/proc/self/smaps`).
fn stack_resident_kib() -> anyhow::Result<u64> {
    let marker = 0u8;
    let addr = std::hint::black_box(&marker) as *const u8 as usize;
    let smaps = std::fs::read_to_string("/proc/self/smaps")
        .context("reading /proc/self/smaps (the stack probe needs Linux)")?;
    let mut inside = false;
    for line in smaps.lines() {
        let head = line.split_whitespace().next().unwrap_or("");
        if let Some((a, b)) = head.split_once('-')
            && let (Ok(a), Ok(b)) = (usize::from_str_radix(a, 16), usize::from_str_radix(b, 16))
        {
            inside = (a..b).contains(&addr);
            continue;
        }
        if inside && let Some(v) = line.strip_prefix("Rss:") {
            return v
                .trim()
                .trim_end_matches("kB")
                .trim()
                .parse()
                .context("the Rss line of /proc/self/smaps");
        }
    }
    bail!("no mapping in /proc/self/smaps holds this thread's stack")
}

/// Median of `f()`'s wall time over `n` runs, in microseconds.
fn median_us(n: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..n.max(1))
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

const WORK_FLOATS: usize = 16 << 20;

/// Run the benchmark.
pub fn run(args: &FirmwareBenchArgs) -> anyhow::Result<()> {
    let task = args.task.task();
    let s = setup(args, task)?;

    // Memory and the wire's bytes, from one real call.
    let t0 = Instant::now();
    let (status, reply) = with_firmware(&s, WORK_FLOATS, |fw| {
        let reply = fw.handle(2, &ToKernel::PlanRequest(s.request.clone()), &mut NoClock);
        match fw.handle(3, &ToKernel::Status, &mut NoClock) {
            FromKernel::Status(st) => Ok((st, reply)),
            other => bail!("{other:?}"),
        }
    })?;
    let plan_s = t0.elapsed().as_secs_f64();
    let FromKernel::PlanReply(plan) = &reply else {
        bail!("the plan failed: {reply:?}");
    };
    // The least work area: a tiny one is refused naming what one segment per engine call
    // needs (the firmware splits a batch down to that, with the same plan).
    let min_work_floats = with_firmware(&s, 1, |fw| {
        match fw.handle(2, &ToKernel::PlanRequest(s.request.clone()), &mut NoClock) {
            FromKernel::Error(dips_wire::WireError::ModelRejected {
                fault: dips_wire::ModelFault::TooLarge { needed_floats, .. },
                ..
            }) => Ok(needed_floats),
            other => bail!("expected the work area to be refused, got {other:?}"),
        }
    })?;
    let planner_bytes = std::mem::size_of::<PaperPlanner>();
    let model_buffer = s.denoiser.len().max(s.discriminator.len());
    let work_bytes = status.memory.work_floats_used as usize * 4;
    let static_bytes = planner_bytes + 3 * model_buffer + work_bytes;

    // Peak stack: the resident pages of a fresh thread's stack after a call on it.
    let (stack_before, stack_after) = with_firmware(&s, WORK_FLOATS, |fw| {
        let body = ToKernel::PlanRequest(s.request.clone());
        std::thread::scope(|scope| {
            std::thread::Builder::new()
                .stack_size(64 << 20)
                .spawn_scoped(scope, || -> anyhow::Result<(u64, u64)> {
                    let before = stack_resident_kib()?;
                    let reply = fw.handle(2, &body, &mut NoClock);
                    let after = stack_resident_kib()?;
                    match reply {
                        FromKernel::PlanReply(_) => Ok((before, after)),
                        other => bail!("{other:?}"),
                    }
                })?
                .join()
                .map_err(|_| anyhow!("the planning thread panicked"))?
        })
    })?;

    // The wire: bytes and CPU time per planning call, and the link's round trip.
    let req = ToKernel::PlanRequest(s.request.clone());
    let req_bytes = encoded_len(2, req.clone())?;
    let reply_bytes = encoded_len(2, reply.clone())?;
    let status_bytes =
        encoded_len(3, ToKernel::Status)? + encoded_len(3, FromKernel::Status(status))?;
    let codec_us = median_us(20_000, || {
        codec_round(&req);
        codec_round(&reply);
    });
    let upload_bytes: usize = [
        (ModelRole::Denoiser, &s.denoiser),
        (ModelRole::Discriminator, &s.discriminator),
    ]
    .iter()
    .flat_map(|(r, b)| upload_messages(*r, b).into_iter().flatten())
    .map(|m| encoded_len(1, m).unwrap_or(0))
    .sum();
    let round_trip_us = match dips_link::find_firmware() {
        Ok(fw) => {
            let mut link = dips_link::Link::spawn(&fw, &[]).map_err(|e| anyhow!("{e}"))?;
            let timeout = link.timeouts().reply;
            link.request(&ToKernel::Hello(Hello::current()), timeout)?;
            Some(median_us(args.round_trips, || {
                let _ = link.request(&ToKernel::Status, timeout);
            }))
        }
        Err(e) => {
            crate::note!("no round trip measured: {e}");
            None
        }
    };
    let mib = |b: usize| b as f64 / (1 << 20) as f64;
    let out = json!({
        "bench": "firmware",
        "task": task.name(),
        "settings": {
            "k": s.request.settings.k,
            "max_depth": s.request.settings.max_depth,
            "sampler": args.sampler.method.to_string(),
            "expansions": plan.stats.nodes_expanded,
        },
        "static_memory": {
            "planner_bytes": planner_bytes,
            "denoiser_bytes": s.denoiser.len(),
            "discriminator_bytes": s.discriminator.len(),
            "model_buffers_bytes": 3 * model_buffer,
            "work_floats": status.memory.work_floats_used,
            "work_bytes": work_bytes,
            "work_floats_one_segment_per_call": min_work_floats,
            "total_bytes": static_bytes,
            "total_mib": mib(static_bytes),
        },
        "stack": {
            "thread_start_kib": stack_before,
            "peak_kib": stack_after,
        },
        "wire": {
            "plan_request_bytes": req_bytes,
            "plan_reply_bytes": reply_bytes,
            "status_round_trip_bytes": status_bytes,
            "encode_decode_us": codec_us,
            "round_trip_us": round_trip_us,
            "upload_bytes": upload_bytes,
        },
        "plan_s": plan_s,
    });
    crate::output::figures(args.json, &out)?;
    Ok(())
}
