//! The reverse diffusion loops: DDPM (ancestral, over every or over strided training steps)
//! and DDIM, with classifier-free guidance in one engine call per step and inpainting of the
//! start state.

use crate::diffusion::config::{SamplerConfig, SamplingMethod};
use crate::diffusion::error::{SampleError, SamplerError};
use crate::diffusion::normalize::{denormalize_in_place, is_valid};
use crate::diffusion::schedule::{cosine_beta, fill_alpha_bar};
use crate::diffusion::scratch::SamplerScratch;
use crate::engine::{DenoiserEngine, ModelDims, ObjectFrame};
use crate::rng::KernelRng;

/// Lower clip of the posterior variance before its logarithm is taken.
const MIN_POSTERIOR_VARIANCE: f32 = 1e-20;

/// What to sample: one contact mode (and optionally one start state) per trajectory.
#[derive(Debug, Clone, Copy)]
pub struct SampleRequest<'r> {
    /// `[n, F]` contact modes (±1), one row per trajectory.
    pub context: &'r [f32],
    /// `[n, state_dim]` raw start states to inpaint into row 0, or `None` for free samples.
    pub start_states: Option<&'r [f32]>,
}

/// Per-step coefficients of one reverse update `x ← a·x̂0 + b·x + c·ε̂ + σ·z`, with
/// `x̂0 = r·x − r1·ε̂`.
#[derive(Debug, Clone, Copy)]
struct StepCoefficients {
    /// Engine input `t`.
    t: f32,
    /// `√(1/ᾱ_t)`.
    r: f32,
    /// `√(1/ᾱ_t − 1)`.
    r1: f32,
    /// Weight of `x̂0`.
    a: f32,
    /// Weight of `x_t`.
    b: f32,
    /// Weight of `ε̂`.
    c: f32,
    /// Noise standard deviation (0: no noise is drawn).
    sigma: f32,
}

impl StepCoefficients {
    fn ddpm(t: usize, steps: usize, alpha_bar: &[f32], noise_factor: f32) -> Self {
        let ab = alpha_bar.get(t).copied().unwrap_or(1.0);
        let ab_prev = match t.checked_sub(1) {
            Some(p) => alpha_bar.get(p).copied().unwrap_or(1.0),
            None => 1.0,
        };
        let beta = cosine_beta(t, steps);
        let one_minus_ab = 1.0 - ab;
        let variance = beta * (1.0 - ab_prev) / one_minus_ab;
        let log_variance = libm::logf(variance.max(MIN_POSTERIOR_VARIANCE));
        // No noise on the last step (t = 0), as in the reference sampler.
        let sigma = if t == 0 {
            0.0
        } else {
            noise_factor * libm::expf(0.5 * log_variance)
        };
        Self {
            t: t as f32,
            r: libm::sqrtf(1.0 / ab),
            r1: libm::sqrtf(1.0 / ab - 1.0),
            a: beta * libm::sqrtf(ab_prev) / one_minus_ab,
            b: (1.0 - ab_prev) * libm::sqrtf(1.0 - beta) / one_minus_ab,
            c: 0.0,
            sigma,
        }
    }

    /// The DDPM posterior of the jump from step `t` to `t_next` (`None`: to the clean
    /// sample), its standard deviation scaled by `noise_factor`.
    fn ddpm_strided(t: usize, t_next: Option<usize>, alpha_bar: &[f32], noise_factor: f32) -> Self {
        let ab = alpha_bar.get(t).copied().unwrap_or(1.0);
        let ab_next = t_next
            .and_then(|n| alpha_bar.get(n).copied())
            .unwrap_or(1.0);
        // β of the jump: 1 − ᾱ_t / ᾱ_t'.
        let beta = 1.0 - ab / ab_next;
        let one_minus_ab = 1.0 - ab;
        let variance = beta * (1.0 - ab_next) / one_minus_ab;
        // No noise on the last step, as in the full sampler.
        let sigma = match t_next {
            Some(_) => noise_factor * libm::sqrtf(variance.max(MIN_POSTERIOR_VARIANCE)),
            None => 0.0,
        };
        Self {
            t: t as f32,
            r: libm::sqrtf(1.0 / ab),
            r1: libm::sqrtf(1.0 / ab - 1.0),
            a: beta * libm::sqrtf(ab_next) / one_minus_ab,
            b: (1.0 - ab_next) * libm::sqrtf(1.0 - beta) / one_minus_ab,
            c: 0.0,
            sigma,
        }
    }

    /// DDIM from step `t` to `t_next` (`None`: to the clean sample).
    fn ddim(t: usize, t_next: Option<usize>, alpha_bar: &[f32], eta: f32) -> Self {
        let ab = alpha_bar.get(t).copied().unwrap_or(1.0);
        let ab_next = t_next
            .and_then(|n| alpha_bar.get(n).copied())
            .unwrap_or(1.0);
        let sigma = eta
            * libm::sqrtf(((1.0 - ab_next) / (1.0 - ab)).max(0.0))
            * libm::sqrtf((1.0 - ab / ab_next).max(0.0));
        Self {
            t: t as f32,
            r: libm::sqrtf(1.0 / ab),
            r1: libm::sqrtf(1.0 / ab - 1.0),
            a: libm::sqrtf(ab_next),
            b: 0.0,
            c: libm::sqrtf((1.0 - ab_next - sigma * sigma).max(0.0)),
            sigma,
        }
    }
}

/// Sample `n = out.len() / (T·D)` trajectories into `out` (`[n, T, D]`, raw units).
///
/// Starts from `x_T ~ N(0, I)` (normalized), runs the reverse process of `config`, and
/// de-normalizes; the last row's action columns are zero, as the layout defines them
/// (`(s_H, 0)`). Every step evaluates the conditioned and the unconditioned copy of each
/// trajectory in one engine call (`cond_mask` 1 then 0), in chunks of at most
/// `max_batch() / 2` trajectories (and what the scratch holds); chunking does not change the
/// result. With start states, row 0's state columns are set to the normalized start state
/// before the loop and after every step, and to the raw start state exactly in the output.
/// A model that measures the object from the segment's start ([`ObjectFrame::SegmentStart`])
/// is inpainted with those columns at zero, and the start's values are added to them in every
/// row of the output, so the output is in the world's frame whatever the model's. Free
/// samples (no start states) are returned in the model's frame.
///
/// Random draws are trajectory-major (`x_T`, then each step's noise), so the same `rng` state
/// gives the same bits whatever the chunking.
pub fn sample<E: DenoiserEngine>(
    engine: &mut E,
    config: &SamplerConfig,
    request: &SampleRequest<'_>,
    rng: &mut KernelRng,
    scratch: &mut SamplerScratch<'_>,
    out: &mut [f32],
) -> Result<usize, SampleError<E::Error>> {
    let dims = engine.dims();
    let n = validate(engine, config, request, out.len())?;
    let chunk = scratch
        .chunk_capacity(dims)?
        .min(engine.max_batch() / 2)
        .min(n);
    let steps = dims.diffusion_steps;
    if !fill_alpha_bar(steps, scratch.alpha_bar) {
        return Err(SamplerError::BadDims.into());
    }

    rng.fill_normal(out);
    inpaint_all(engine, request, dims, out);

    match config.method {
        SamplingMethod::Ddpm { noise_factor } => {
            for t in (0..steps).rev() {
                let k = StepCoefficients::ddpm(t, steps, scratch.alpha_bar, noise_factor);
                step(engine, config, request, rng, scratch, out, chunk, &k)?;
            }
        }
        SamplingMethod::DdpmStrided {
            steps: s,
            noise_factor,
        } => {
            for (t, t_next) in strided_steps(usize::from(s), steps) {
                let k = StepCoefficients::ddpm_strided(t, t_next, scratch.alpha_bar, noise_factor);
                step(engine, config, request, rng, scratch, out, chunk, &k)?;
            }
        }
        SamplingMethod::Ddim { steps: s, eta } => {
            for (t, t_next) in strided_steps(usize::from(s), steps) {
                let c = StepCoefficients::ddim(t, t_next, scratch.alpha_bar, eta);
                step(engine, config, request, rng, scratch, out, chunk, &c)?;
            }
        }
    }

    let norm = engine.normalization();
    denormalize_in_place(&norm, out);
    // The layout's last row is `(s_H, 0)`: no action follows the last state.
    let td = dims.floats_per_trajectory();
    if dims.horizon > 0 {
        let last = (dims.horizon - 1) * (dims.state_dim + dims.action_dim) + dims.state_dim;
        for traj in out.chunks_mut(td) {
            if let Some(action) = traj.get_mut(last..) {
                action.fill(0.0);
            }
        }
    }
    if let Some(starts) = request.start_states
        && dims.state_dim > 0
    {
        to_world_frame(engine.object_frame(), dims, out, starts);
        let td = dims.floats_per_trajectory();
        for (traj, s0) in out.chunks_mut(td).zip(starts.chunks(dims.state_dim)) {
            if let Some(row0) = traj.get_mut(..dims.state_dim) {
                row0.copy_from_slice(s0);
            }
        }
    }
    Ok(n)
}

/// The `(t, t_next)` jumps of a sampler over `s` of the `n` training steps ("leading"
/// spacing): `t_k = ⌊k·n/s⌋` for `k = s−1, …, 0`, the jump from `t_0 = 0` going to the clean
/// sample (`None`). With `s = n` these are DDPM's steps. Starting at `n − 1` instead (where
/// ᾱ ≈ 4e-8 under the cosine schedule) makes the first `x̂₀ = (x − √(1−ᾱ) ε̂)/√ᾱ` hopelessly
/// ill-conditioned for a few-step sampler (`docs/training.md`).
fn strided_steps(s: usize, n: usize) -> impl Iterator<Item = (usize, Option<usize>)> {
    (0..s)
        .rev()
        .map(move |k| (k * n / s, k.checked_sub(1).map(|j| j * n / s)))
}

/// Check the call; returns the number of trajectories.
fn validate<E: DenoiserEngine>(
    engine: &E,
    config: &SamplerConfig,
    request: &SampleRequest<'_>,
    out_len: usize,
) -> Result<usize, SamplerError> {
    let dims = engine.dims();
    let td = dims.floats_per_trajectory();
    if dims.diffusion_steps == 0 || td == 0 || dims.state_dim > dims.dim() {
        return Err(SamplerError::BadDims);
    }
    if out_len == 0 || !out_len.is_multiple_of(td) {
        return Err(SamplerError::OutputLength {
            floats_per_trajectory: td,
            got: out_len,
        });
    }
    let n = out_len / td;
    if request.context.len() != n * dims.fingers {
        return Err(SamplerError::ContextLength {
            expected: n * dims.fingers,
            got: request.context.len(),
        });
    }
    if let Some(starts) = request.start_states {
        if starts.len() != n * dims.state_dim {
            return Err(SamplerError::StartStateLength {
                expected: n * dims.state_dim,
                got: starts.len(),
            });
        }
        if starts.iter().any(|v| !v.is_finite()) {
            return Err(SamplerError::NonFiniteStartState);
        }
    }
    if !is_valid(&engine.normalization(), dims.dim()) {
        return Err(SamplerError::BadNormalization);
    }
    if engine.max_batch() < 2 {
        return Err(SamplerError::MaxBatchTooSmall {
            max_batch: engine.max_batch(),
        });
    }
    let finite_non_negative = |v: f32| v.is_finite() && v >= 0.0;
    if !config.guidance_weight.is_finite()
        || config.clip_denoised.is_nan()
        || config.clip_denoised <= 0.0
    {
        return Err(SamplerError::BadConfig);
    }
    match config.method {
        SamplingMethod::Ddpm { noise_factor }
        | SamplingMethod::DdpmStrided { noise_factor, .. }
            if !finite_non_negative(noise_factor) =>
        {
            Err(SamplerError::BadConfig)
        }
        SamplingMethod::Ddim { eta, .. } if !finite_non_negative(eta) => {
            Err(SamplerError::BadConfig)
        }
        SamplingMethod::Ddim { steps, .. } | SamplingMethod::DdpmStrided { steps, .. }
            if steps == 0 || usize::from(steps) > dims.diffusion_steps =>
        {
            Err(SamplerError::StridedSteps {
                steps,
                diffusion_steps: dims.diffusion_steps,
            })
        }
        _ => Ok(n),
    }
}

/// One reverse step over all trajectories, chunk by chunk.
#[allow(clippy::too_many_arguments)]
fn step<E: DenoiserEngine>(
    engine: &mut E,
    config: &SamplerConfig,
    request: &SampleRequest<'_>,
    rng: &mut KernelRng,
    scratch: &mut SamplerScratch<'_>,
    out: &mut [f32],
    chunk: usize,
    k: &StepCoefficients,
) -> Result<(), SampleError<E::Error>> {
    let dims = engine.dims();
    let td = dims.floats_per_trajectory();
    let f = dims.fingers;
    let w = config.guidance_weight;
    let clip = config.clip_denoised;
    for (c, x_chunk) in out.chunks_mut(chunk * td).enumerate() {
        let m = x_chunk.len() / td;
        let first = c * chunk;
        let ctx_rows = request
            .context
            .get(first * f..(first + m) * f)
            .unwrap_or(&[]);
        let batch = 2 * m;
        let half = m * td;
        let (Some(x_in), Some(eps), Some(t_in), Some(ctx_in), Some(mask)) = (
            scratch.x.get_mut(..batch * td),
            scratch.eps.get_mut(..batch * td),
            scratch.t.get_mut(..batch),
            scratch.context.get_mut(..batch * f),
            scratch.cond_mask.get_mut(..batch),
        ) else {
            // chunk_capacity() sized `chunk` to the scratch, so this cannot happen.
            return Err(SamplerError::BadDims.into());
        };
        let (x_cond, x_uncond) = x_in.split_at_mut(half);
        x_cond.copy_from_slice(x_chunk);
        x_uncond.copy_from_slice(x_chunk);
        t_in.fill(k.t);
        let (ctx_cond, ctx_uncond) = ctx_in.split_at_mut(m * f);
        ctx_cond.copy_from_slice(ctx_rows);
        ctx_uncond.copy_from_slice(ctx_rows);
        let (mask_cond, mask_uncond) = mask.split_at_mut(m);
        mask_cond.fill(1.0);
        mask_uncond.fill(0.0);

        engine
            .predict_eps(batch, x_in, t_in, ctx_in, mask, eps)
            .map_err(SampleError::Engine)?;

        let (eps_cond, eps_uncond) = eps.split_at(half);
        for ((x, ec), eu) in x_chunk.iter_mut().zip(eps_cond).zip(eps_uncond) {
            let mut e = eu + w * (ec - eu);
            let raw = k.r * *x - k.r1 * e;
            let x0 = raw.clamp(-clip, clip);
            if x0 != raw && k.r1 > 0.0 {
                // The noise estimate that agrees with the clipped x̂₀ (used by DDIM's `c`).
                e = (k.r * *x - x0) / k.r1;
            }
            let mut next = k.a * x0 + k.b * *x + k.c * e;
            if k.sigma > 0.0 {
                next += k.sigma * rng.normal_f32();
            }
            *x = next;
        }
        if let Some(starts) = request.start_states {
            let rows = starts.get(first * dims.state_dim..(first + m) * dims.state_dim);
            inpaint(engine, dims, x_chunk, rows.unwrap_or(&[]));
        }
    }
    Ok(())
}

/// Inpaint every trajectory of `out` (before the loop).
fn inpaint_all<E: DenoiserEngine>(
    engine: &E,
    request: &SampleRequest<'_>,
    dims: ModelDims,
    out: &mut [f32],
) {
    if let Some(starts) = request.start_states {
        inpaint(engine, dims, out, starts);
    }
}

/// Write the normalized start states into row 0's state columns of each trajectory, in the
/// model's object frame (the columns it measures from the start hold zero there).
fn inpaint<E: DenoiserEngine>(engine: &E, dims: ModelDims, trajs: &mut [f32], starts: &[f32]) {
    let norm = engine.normalization();
    let td = dims.floats_per_trajectory();
    if dims.state_dim == 0 {
        return;
    }
    let relative = engine
        .object_frame()
        .start_columns(dims.fingers, dims.state_dim);
    for (traj, s0) in trajs.chunks_mut(td).zip(starts.chunks(dims.state_dim)) {
        for (col, (((v, raw), m), s)) in traj
            .iter_mut()
            .zip(s0)
            .zip(norm.mean)
            .zip(norm.std)
            .enumerate()
        {
            let raw = if relative.contains(&col) { 0.0 } else { *raw };
            *v = (raw - m) / s;
        }
    }
}

/// Move the sampled trajectories of `out` (raw rows) from the model's object frame into the
/// world's: the start's value of every column the frame measures from row 0 is added to that
/// column of every row.
fn to_world_frame(frame: ObjectFrame, dims: ModelDims, out: &mut [f32], starts: &[f32]) {
    let relative = frame.start_columns(dims.fingers, dims.state_dim);
    let d = dims.dim();
    if relative.is_empty() || d == 0 {
        return;
    }
    let td = dims.floats_per_trajectory();
    for (traj, s0) in out.chunks_mut(td).zip(starts.chunks(dims.state_dim)) {
        for row in traj.chunks_exact_mut(d) {
            for col in relative.clone() {
                row[col] += s0[col];
            }
        }
    }
}
