//! A `#![no_std]` `#![no_main]` x86_64 binary that links `dips-kernel` and `dips-wire` and runs
//! them for real.
//!
//! If any dependency of those crates pulls in `std`, this fails to build with a duplicate
//! `panic_impl` lang item. Its self-test goes through the whole kernel path the controller
//! runs: a `PlanRequest` is framed (postcard + COBS), fed byte-chunk-wise through the frame
//! accumulator and decoded; it is planned by the real A* search with the real diffusion
//! sampler and discriminator adapters over two small analytic models defined below (an exact
//! Gaussian ε-predictor and a logistic discriminator: a self-test harness, not models); the
//! `PlanReply` is framed, decoded back and checked. A second identical request must give a
//! bit-identical reply. The plan is printed; any failed check exits with status 1.
//!
//! Everything lives on the main thread's stack (under 200 KiB, the planner about 115 KiB): no
//! heap, no `static mut`. The goal is two card moves away (−4 cm) to keep the search small.
#![no_std]
#![no_main]
#![allow(unsafe_code)] // the C entry point and libc calls are the whole point of this binary

use core::fmt::{self, Write};

use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::diffusion::schedule::fill_alpha_bar;
use dips_kernel::engine::{DenoiserEngine, DiscriminatorEngine, ModelDims, Normalization};
use dips_kernel::mode::{ModeId, Task};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::{Planner, SearchConfig};
use dips_kernel::session::{SessionLayout, plan_with_engines};
use dips_kernel::wire_convert::PlanInputs;
use dips_wire::{
    Feed, Frame, FrameAccumulator, FromKernel, MAX_ENCODED_FRAME_LEN, Message, PlanReply,
    PlanRequest, PlanStatus, SearchSettings, ToKernel, decode_frame, encode_frame,
};

unsafe extern "C" {
    fn write(fd: i32, buf: *const u8, len: usize) -> isize;
    fn _exit(code: i32) -> !;
}

fn print(msg: &str) {
    // SAFETY: `msg` is a valid buffer of `msg.len()` bytes for the duration of the call.
    unsafe {
        write(1, msg.as_ptr(), msg.len());
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    print("dips-nostd-check: panic\n");
    // SAFETY: `_exit` never returns and takes any status code.
    unsafe { _exit(101) }
}

/// core is precompiled with unwinding tables that name this symbol; nothing calls it.
#[unsafe(no_mangle)]
pub extern "C" fn rust_eh_personality() {}

/// A line of text formatted on the stack (truncated when too long).
struct Line {
    buf: [u8; 512],
    len: usize,
}

impl Line {
    const fn new() -> Self {
        Self {
            buf: [0; 512],
            len: 0,
        }
    }

    fn print(&self) {
        print(core::str::from_utf8(&self.buf[..self.len]).unwrap_or("<bad utf-8>\n"));
    }
}

impl Write for Line {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let room = self.buf.len() - self.len;
        let n = s.len().min(room);
        self.buf[self.len..self.len + n].copy_from_slice(&s.as_bytes()[..n]);
        self.len += n;
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------
// The card task's sizes (docs/contracts.md §2) and two analytic models of them.

const STEPS: usize = 32;
const DIMS: ModelDims = ModelDims {
    horizon: 9,
    state_dim: 12,
    action_dim: 17,
    fingers: 2,
    diffusion_steps: STEPS,
};
const D: usize = 29;
const Y: usize = 9;

/// Normalization: joints around 0.3 rad, card x/y in centimetres, cos/sin as they are,
/// actions around 0 with std 0.5.
const MEAN: [f32; D] = {
    let mut m = [0.0; D];
    let mut j = 0;
    while j < 8 {
        m[j] = 0.3;
        j += 1;
    }
    m
};
const STD: [f32; D] = {
    let mut s = [0.5; D];
    let mut j = 0;
    while j < 8 {
        s[j] = 0.2;
        j += 1;
    }
    s[8] = 0.01;
    s[9] = 0.01;
    s[10] = 1.0;
    s[11] = 1.0;
    s
};

/// Data given the clean normalized start row `y0`: every entry is Gaussian, the state holds
/// `y0` (σ 0.05) except the card's `y`, which moves by `r/(T−1)·Δ` with Δ = −2 cm for `both`
/// fingers and −1.5 cm for one (conditioned only; held unconditioned and on regrasp);
/// actions are `N(0, 0.05²)`. The prediction is the exact posterior mean of ε.
struct GaussianCardDenoiser {
    alpha_bar: [f32; STEPS],
}

impl GaussianCardDenoiser {
    fn moments(y0: &[f32], ctx: &[f32], conditioned: bool, r: usize, j: usize) -> (f32, f32) {
        if j >= DIMS.state_dim {
            return (0.0, 0.05);
        }
        if r == 0 {
            return (y0[j], 0.0);
        }
        if j != Y {
            return (y0[j], 0.05);
        }
        let pushing = ctx.iter().filter(|&&c| c > 0.0).count();
        let delta_m = match (conditioned, pushing) {
            (false, _) | (true, 0) => 0.0,
            (true, 1) => -0.015,
            (true, _) => -0.02,
        };
        let frac = r as f32 / (DIMS.horizon - 1) as f32;
        (y0[j] + frac * delta_m / STD[Y], 0.05)
    }
}

impl DenoiserEngine for GaussianCardDenoiser {
    type Error = &'static str;

    fn dims(&self) -> ModelDims {
        DIMS
    }

    fn normalization(&self) -> Normalization<'_> {
        Normalization {
            mean: &MEAN,
            std: &STD,
        }
    }

    fn max_batch(&self) -> usize {
        usize::MAX
    }

    fn predict_eps(
        &mut self,
        batch: usize,
        x: &[f32],
        t: &[f32],
        context: &[f32],
        cond_mask: &[f32],
        eps: &mut [f32],
    ) -> Result<(), Self::Error> {
        let td = DIMS.floats_per_trajectory();
        let f = DIMS.fingers;
        if x.len() != batch * td || eps.len() != batch * td || context.len() != batch * f {
            return Err("denoiser: bad input sizes");
        }
        for b in 0..batch {
            let step = t.get(b).copied().unwrap_or(-1.0);
            if !(0.0..STEPS as f32).contains(&step) {
                return Err("denoiser: step out of range");
            }
            let ab = self.alpha_bar[step as usize];
            let conditioned = cond_mask.get(b).is_some_and(|&m| m > 0.5);
            let ctx = &context[b * f..(b + 1) * f];
            let xb = &x[b * td..(b + 1) * td];
            let y0 = &xb[..DIMS.state_dim];
            for r in 0..DIMS.horizon {
                for j in 0..D {
                    let (a, s) = Self::moments(y0, ctx, conditioned, r, j);
                    let xv = xb[r * D + j];
                    eps[b * td + r * D + j] = libm::sqrtf(1.0 - ab) * (xv - libm::sqrtf(ab) * a)
                        / (ab * s * s + 1.0 - ab);
                }
            }
        }
        Ok(())
    }
}

/// `p_real = sigmoid(2 − mean(u²) + 0.5·mean(c))` over the normalized actions `u` and the
/// context `c`: realistic segments have small actions, and both fingers pushing is likelier.
struct LogisticCardDiscriminator;

impl DiscriminatorEngine for LogisticCardDiscriminator {
    type Error = &'static str;

    fn dims(&self) -> ModelDims {
        ModelDims {
            diffusion_steps: 0,
            ..DIMS
        }
    }

    fn normalization(&self) -> Normalization<'_> {
        Normalization {
            mean: &MEAN,
            std: &STD,
        }
    }

    fn max_batch(&self) -> usize {
        16
    }

    fn p_real(
        &mut self,
        batch: usize,
        x: &[f32],
        context: &[f32],
        p_real: &mut [f32],
    ) -> Result<(), Self::Error> {
        let td = DIMS.floats_per_trajectory();
        let f = DIMS.fingers;
        if batch > 16 || x.len() != batch * td || p_real.len() != batch {
            return Err("discriminator: bad input sizes");
        }
        for (b, p) in p_real.iter_mut().enumerate() {
            let mut act = 0.0;
            for row in x[b * td..(b + 1) * td].chunks(D) {
                act += row[DIMS.state_dim..].iter().map(|u| u * u).sum::<f32>();
            }
            act /= (DIMS.horizon * DIMS.action_dim) as f32;
            let c = context[b * f..(b + 1) * f].iter().sum::<f32>() / f as f32;
            *p = 1.0 / (1.0 + libm::expf(-(2.0 - act + 0.5 * c)));
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------
// The self-test.

/// Particles per node, node arena, open list, floats per card segment (9 × 29).
type CheckPlanner = Planner<8, 256, 128, 261>;
const K: u16 = 8;
const SESSION_LAYOUT: SessionLayout = SessionLayout::new(DIMS, 4 * K as usize, 8);
const GOAL_Y_M: f32 = -0.04;

fn fail(what: &'static str) -> Result<(), Failure> {
    Err(Failure(what))
}

fn check(ok: bool, what: &'static str) -> Result<(), Failure> {
    if ok { Ok(()) } else { fail(what) }
}

/// A failed self-test check.
#[derive(Debug)]
struct Failure(&'static str);

/// Frame `body`, feed the bytes through an accumulator in 7-byte pieces and decode them.
fn through_the_wire<M: Message + Clone>(id: u32, body: &M) -> Result<Frame<M>, Failure> {
    let mut tx = [0u8; MAX_ENCODED_FRAME_LEN];
    let bytes = encode_frame(
        &Frame {
            request_id: id,
            body: body.clone(),
        },
        &mut tx,
    )
    .map_err(|_| Failure("frame does not fit"))?;
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut decoded = None;
    for piece in bytes.chunks(7) {
        let mut window = piece;
        loop {
            match acc.feed(window) {
                Feed::Consumed => break,
                Feed::Frame { payload, remaining } => {
                    let frame =
                        decode_frame::<M>(payload).map_err(|_| Failure("frame does not decode"))?;
                    if decoded.replace(frame).is_some() {
                        return Err(Failure("more than one frame"));
                    }
                    window = remaining;
                }
                Feed::Error { .. } => return Err(Failure("accumulator dropped the frame")),
            }
        }
    }
    decoded.ok_or(Failure("no frame came out"))
}

fn request() -> PlanRequest {
    let mut request = PlanRequest {
        task: dips_wire::Task::Card,
        start_state: Default::default(),
        goal: GOAL_Y_M,
        settings: SearchSettings::from(SearchConfig {
            k: K,
            seed: 7,
            node_budget: 64,
            time_budget_ms: 0,
            ..SearchConfig::card()
        }),
        previous_mode: None,
        card_goals: Default::default(),
        first_modes: 0b1111,
    };
    // Index and middle joints, the card at the origin with θ = 0.
    for v in [
        0.3f32, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.0, 0.0, 1.0, 0.0,
    ] {
        if request.start_state.push(v).is_err() {
            break;
        }
    }
    request
}

fn plan_once(
    planner: &mut CheckPlanner,
    request: &PlanRequest,
    prior: &MarkovPrior,
) -> Result<PlanReply, Failure> {
    let mut alpha_bar = [0.0f32; STEPS];
    check(fill_alpha_bar(STEPS, &mut alpha_bar), "schedule")?;
    let denoiser = GaussianCardDenoiser { alpha_bar };
    let discriminator = LogisticCardDiscriminator;
    let mut work = [0.0f32; SESSION_LAYOUT.total()];
    // The firmware's path: the request checked, then one planning session (engines →
    // adapters → planner).
    let spec = PlanInputs::from_request(request)
        .map_err(|_| Failure("the request was refused"))?
        .into_spec(*prior, SamplerConfig::default());
    let report = plan_with_engines(
        planner,
        &spec,
        denoiser,
        discriminator,
        &SESSION_LAYOUT,
        &mut work,
        &mut NoClock,
    )
    .map_err(|_| Failure("the adapters refused their engines or buffers"))?;
    Ok(PlanReply::from(&report))
}

/// The Allegro protocol without std: a real session's SET_TORQUE frame and pose reply, both
/// ways.
fn allegro_frames() -> Result<(), Failure> {
    use dips_allegro_protocol::{CanFrame, DeviceId, HandReply, HostCommand};
    use embedded_can::{Frame as _, StandardId};
    let d0 = DeviceId::DEFAULT;
    let cmd = HostCommand::SetTorque {
        finger: 0,
        pwm: [2, 203, 66, 37],
    };
    let f: CanFrame = cmd.to_frame(d0).ok_or(Failure("allegro: no torque frame"))?;
    check(f.raw_id() == 0x180, "allegro: torque id")?;
    check(
        f.data() == [0x02, 0x00, 0xCB, 0x00, 0x42, 0x00, 0x25, 0x00],
        "allegro: torque bytes",
    )?;
    let id = StandardId::new(0x08C).ok_or(Failure("allegro: id"))?;
    let pose = CanFrame::new(id, &[0x34, 0x0A, 0xEF, 0xFF, 0xAF, 0x00, 0xFC, 0xFF])
        .ok_or(Failure("allegro: pose frame"))?;
    let reply = HandReply::from_frame(&pose).map_err(|_| Failure("allegro: pose decode"))?;
    check(
        reply.0
            == HandReply::FingerPose {
                finger: 3,
                counts: [2612, -17, 175, -4],
            },
        "allegro: pose counts",
    )
}

fn self_test(line: &mut Line) -> Result<(), Failure> {
    allegro_frames()?;
    let request = request();
    check(request.start_state.len() == 12, "start state")?;
    let received = through_the_wire(1, &ToKernel::PlanRequest(request.clone()))?;
    check(received.request_id == 1, "request id")?;
    let ToKernel::PlanRequest(received) = received.body else {
        return fail("not a plan request");
    };
    check(received == request, "request changed on the wire")?;

    let prior =
        MarkovPrior::uniform(Task::Card.mode_count()).map_err(|_| Failure("uniform prior"))?;
    let mut planner = CheckPlanner::new();
    let reply = plan_once(&mut planner, &received, &prior)?;
    check(
        reply.status == PlanStatus::Found,
        "the plan did not reach the goal",
    )?;
    check(!reply.modes.is_empty(), "empty plan")?;
    let regrasp = Task::Card
        .mode_by_name("regrasp")
        .map_err(|_| Failure("mode table"))?;
    check(
        reply.modes.iter().all(|&m| m != regrasp.0),
        "a regrasp does not move the card",
    )?;
    let y = reply.terminal_state.get(Y).copied().unwrap_or(f32::NAN);
    check(y <= GOAL_Y_M, "terminal y above the goal")?;
    check(
        reply.stats.nodes_expanded >= 3 && reply.stats.sampler_calls == reply.stats.nodes_expanded,
        "counters",
    )?;

    let again = plan_once(&mut planner, &received, &prior)?;
    let bits = |r: &PlanReply| {
        let mut h = 0u64;
        for v in &r.terminal_state {
            h = h.rotate_left(5) ^ u64::from(v.to_bits());
        }
        h
    };
    check(
        again == reply && bits(&again) == bits(&reply),
        "same seed, different plan",
    )?;

    let back = through_the_wire(1, &FromKernel::PlanReply(reply.clone()))?;
    check(
        back.request_id == 1 && back.body == FromKernel::PlanReply(reply.clone()),
        "reply changed on the wire",
    )?;

    firmware_session()?;

    let _ = write!(
        line,
        "dips-nostd-check: kernel, firmware core and Allegro protocol linked without std; firmware session \
         answered; plan found:"
    );
    for &m in &reply.modes {
        let name = Task::Card.mode_name(ModeId(m)).unwrap_or("?");
        let _ = write!(line, " {name}");
    }
    let _ = writeln!(
        line,
        " (card y {:.4} m, goal {GOAL_Y_M} m; {} expansions, {} nodes, {} sampler and {} \
         discriminator calls)",
        y,
        reply.stats.nodes_expanded,
        reply.stats.nodes_generated,
        reply.stats.sampler_calls,
        reply.stats.discriminator_calls,
    );
    Ok(())
}

/// The firmware core's request handler without std: greeting, an upload that is refused at
/// its end (not a model), a plan request without models, the status.
fn firmware_session() -> Result<(), Failure> {
    use dips_firmware_core::Firmware;
    use dips_wire::{Hello, ModelRole, WireError, upload_messages};
    let (mut den, mut disc, mut stage) = ([0u8; 2048], [0u8; 2048], [0u8; 2048]);
    let mut fw = Firmware::new(&mut den, &mut disc, &mut stage);
    let mut clock = NoClock;
    let hello = fw.handle(1, &ToKernel::Hello(Hello::current()), &mut clock);
    check(matches!(hello, FromKernel::HelloAck(_)), "firmware: no HelloAck")?;
    let junk = [7u8; 1500];
    let mut last = FromKernel::Applied;
    for m in upload_messages(ModelRole::Denoiser, &junk).ok_or(Failure("upload"))? {
        last = fw.handle(2, &m, &mut clock);
    }
    check(
        matches!(last, FromKernel::Error(WireError::ModelRejected { .. })),
        "firmware: a junk model was not refused",
    )?;
    let status = fw.handle(3, &ToKernel::Status, &mut clock);
    let FromKernel::Status(s) = status else {
        return Err(Failure("firmware: no status"));
    };
    check(s.denoiser.is_none(), "firmware: junk became the model")?;
    Ok(())
}

/// Entry point called by libc's `_start`.
#[unsafe(no_mangle)]
pub extern "C" fn main(_argc: i32, _argv: *const *const u8) -> i32 {
    let mut line = Line::new();
    match self_test(&mut line) {
        Ok(()) => {
            line.print();
            0
        }
        Err(Failure(what)) => {
            let mut line = Line::new();
            let _ = writeln!(line, "dips-nostd-check: FAILED: {what}");
            line.print();
            1
        }
    }
}
