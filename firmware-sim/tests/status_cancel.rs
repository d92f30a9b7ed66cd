//! `Status` reports the loaded models, memory, the last plan and frame counts; `Cancel` stops a
//! running plan at its next expansion with the best node so far.

mod common;

use std::io::Read;
use std::time::Duration;

use common::frame_bytes;
use dips_firmware_sim::{FirmwareMemory, serve};
use dips_kernel::search::PaperPlanner;
use dips_onnx::{Expectation, Role, lower_file};
use dips_wire::*;

fn fixture(file: &str, role: Role) -> Vec<u8> {
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../onnx/tests/fixtures/torch-screwdriver-legacy")
        .join(file);
    lower_file(&path, &Expectation::new(role, "screwdriver"))
        .unwrap()
        .blob
}

/// An input that hands out its parts one read at a time, sleeping before each as told: a
/// host that sends a `Cancel` while the firmware plans.
struct Paced {
    parts: Vec<(Duration, Vec<u8>)>,
    next: usize,
    offset: usize,
}

impl Read for Paced {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let Some((delay, bytes)) = self.parts.get(self.next) else {
            return Ok(0);
        };
        if self.offset == 0 {
            std::thread::sleep(*delay);
        }
        let n = buf.len().min(bytes.len() - self.offset);
        buf[..n].copy_from_slice(&bytes[self.offset..self.offset + n]);
        self.offset += n;
        if self.offset == bytes.len() {
            self.next += 1;
            self.offset = 0;
        }
        Ok(n)
    }
}

fn replies(bytes: &[u8]) -> Vec<Frame<FromKernel>> {
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut out = Vec::new();
    let mut window = bytes;
    while let Feed::Frame { payload, remaining } = acc.feed(window) {
        out.push(decode_frame::<FromKernel>(payload).unwrap());
        window = remaining;
    }
    out
}

fn frames(first_id: u32, bodies: impl IntoIterator<Item = ToKernel>) -> Vec<u8> {
    let mut out = Vec::new();
    for (i, body) in bodies.into_iter().enumerate() {
        out.extend(frame_bytes(first_id + i as u32, body));
    }
    out
}

/// A screwdriver request whose goal cannot be reached, so only a budget or a cancel ends it.
fn endless_request() -> ToKernel {
    let mut start = [0.1f32; 16];
    start[14] = 1.0;
    start[15] = 0.0;
    ToKernel::PlanRequest(PlanRequest {
        task: Task::Screwdriver,
        start_state: heapless::Vec::from_slice(&start).unwrap(),
        goal: -3.0,
        settings: SearchSettings {
            k: 4,
            node_budget: 0,
            time_budget_ms: 120_000,
            seed: 1,
            ..SearchSettings::default()
        },
        previous_mode: None,
        card_goals: Default::default(),
        first_modes: 0b111,
    })
}

fn status_of(frame: &Frame<FromKernel>) -> KernelStatus {
    match &frame.body {
        FromKernel::Status(s) => *s,
        other => panic!("expected a status, got {other:?}"),
    }
}

#[test]
fn status_names_the_models_memory_and_frames_and_cancel_stops_a_running_plan() {
    let den = fixture("denoiser.onnx", Role::Denoiser);
    let disc = fixture("discriminator.onnx", Role::Discriminator);
    let mut setup = vec![ToKernel::Hello(Hello::current()), ToKernel::Status];
    setup.extend(upload_messages(ModelRole::Denoiser, &den).unwrap());
    setup.push(ToKernel::Status);
    setup.extend(upload_messages(ModelRole::Discriminator, &disc).unwrap());
    let setup_len = setup.len() as u32;
    let mut first = frames(1, setup);
    // A garbage frame counts as a bad frame.
    first.extend([0x05, 0xff, 0xff, 0xff, 0xff, 0x00]);
    let plan_id = 1 + setup_len;
    first.extend(frame_bytes(plan_id, endless_request()));
    let later = frames(plan_id + 1, [ToKernel::Cancel, ToKernel::Status]);
    let input = Paced {
        parts: vec![(Duration::ZERO, first), (Duration::from_millis(300), later)],
        next: 0,
        offset: 0,
    };
    let mut memory = FirmwareMemory::planning(4 << 20, 4_000_000);
    let mut firmware = memory.firmware();
    let mut out = Vec::new();
    let stats = serve(&mut firmware, input, &mut out).unwrap();
    let got = replies(&out);
    assert_eq!(stats.bad_frames, 1);

    // Before any upload: no models, the fixed capacities.
    let before = status_of(&got[1]);
    assert_eq!((before.denoiser, before.discriminator), (None, None));
    assert_eq!(before.memory.model_capacity_bytes, 4 << 20);
    assert_eq!(before.memory.work_floats, 4_000_000);
    assert_eq!(
        before.memory.planner_bytes as usize,
        std::mem::size_of::<PaperPlanner>()
    );
    assert_eq!(before.frames.requests, 2);
    assert_eq!(before.frames.replies, 1);
    assert_eq!(before.last_plan, None);
    // After the denoiser: its identity and shapes.
    let status_at = got
        .iter()
        .filter(|f| matches!(f.body, FromKernel::Status(_)))
        .nth(1)
        .unwrap();
    let mid = status_of(status_at);
    let id = mid.denoiser.expect("the denoiser is loaded");
    assert_eq!((id.len_bytes, id.crc32), (den.len() as u32, crc32(&den)));
    assert_eq!(id.task, Some(Task::Screwdriver));
    assert_eq!((id.state_dim, id.action_dim, id.fingers), (16, 21, 3));
    assert!(id.diffusion_steps > 0 && id.horizon > 1);
    assert_eq!(mid.discriminator, None);
    assert_eq!(mid.memory.models_bytes, den.len() as u32);

    // The plan was stopped by the cancel: the best node so far, after few expansions.
    let plan = got
        .iter()
        .find(|f| f.request_id == plan_id)
        .expect("the plan is answered");
    let FromKernel::PlanReply(reply) = &plan.body else {
        panic!("expected a plan reply, got {:?}", plan.body);
    };
    assert_eq!(
        reply.status,
        PlanStatus::Approximate {
            reason: ApproximateReason::Cancelled
        }
    );
    assert!(!reply.modes.is_empty(), "the best node so far: {reply:?}");
    assert!(reply.stats.nodes_expanded >= 1 && reply.stats.nodes_expanded <= 10);
    // Then the cancel's own answer and the status, in order.
    let n = got.len();
    assert_eq!(got[n - 2].request_id, plan_id + 1);
    assert_eq!(got[n - 2].body, FromKernel::Applied);
    let after = status_of(&got[n - 1]);
    assert_eq!(after.frames.cancelled_plans, 1);
    assert_eq!(after.frames.bad_frames, 1);
    let last = after.last_plan.expect("a plan ran");
    assert_eq!(last.request_id, plan_id);
    assert_eq!(last.status, reply.status);
    assert_eq!(last.nodes_expanded, reply.stats.nodes_expanded);
    assert!(last.segments_sampled >= 12 && last.particles >= 1);
    assert!(after.memory.work_floats_used > 0);
    assert_eq!(after.discriminator.map(|d| d.crc32), Some(crc32(&disc)));
}

#[test]
fn a_cancel_with_no_plan_running_is_applied_and_changes_nothing() {
    let mut memory = FirmwareMemory::models(1024);
    let mut firmware = memory.firmware();
    let input = frames(
        1,
        [
            ToKernel::Hello(Hello::current()),
            ToKernel::Cancel,
            ToKernel::Status,
        ],
    );
    let mut out = Vec::new();
    serve(&mut firmware, &input[..], &mut out).unwrap();
    let got = replies(&out);
    assert_eq!(got[1].body, FromKernel::Applied);
    let status = status_of(&got[2]);
    assert_eq!(status.frames.cancelled_plans, 0);
    assert_eq!(status.last_plan, None);
    assert_eq!(status.memory.work_floats, 0);
}
