//! The diffusion sampler against analytic denoiser doubles.
//!
//! Data whose columns are independent Gaussians `N(μ, σ²)` has an exact optimal ε-predictor:
//! with `y` the normalized data, `a = E[y]`, `b² = Var[y]` and `x_t = √ᾱ y + √(1−ᾱ) ε`,
//! `E[ε | x_t] = √(1−ᾱ) (x_t − √ᾱ a) / (ᾱ b² + 1 − ᾱ)`. A correct sampler driven by it must
//! reproduce the data's moments.

mod engines;

use dips_kernel::diffusion::*;
use dips_kernel::engine::{DenoiserEngine, ModelDims, Normalization};
use dips_kernel::rng::KernelRng;
use engines::{alpha_bars, posterior_eps};

const T: usize = 3;
const STATE: usize = 2;
const ACTION: usize = 3;
const D: usize = STATE + ACTION;
const F: usize = 2;
const STEPS: usize = 256;

#[derive(Debug, Clone)]
struct Call {
    batch: usize,
    x: Vec<f32>,
    t: Vec<f32>,
    context: Vec<f32>,
    cond_mask: Vec<f32>,
}

/// Which branch the double answers with, whatever `cond_mask` says.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Branch {
    /// Honour `cond_mask`.
    Mask,
    /// Always the conditioned prediction.
    Cond,
    /// Always the unconditioned prediction.
    Uncond,
}

/// Raw data: column j of row r is `N(mu[r][j] + delta[r][j]·context[0], sigma[r][j]²)` when
/// conditioned, `N(mu[r][j], sigma[r][j]²)` unconditioned.
#[derive(Debug, Clone)]
struct GaussianDenoiser {
    mu: [[f32; D]; T],
    delta: [[f32; D]; T],
    sigma: [[f32; D]; T],
    mean: [f32; D],
    std: [f32; D],
    alpha_bar: Vec<f64>,
    max_batch: usize,
    branch: Branch,
    /// Multiplies every prediction: 1 is the exact predictor, 0 a network that learned nothing.
    eps_scale: f32,
    record: bool,
    calls: Vec<Call>,
}

impl GaussianDenoiser {
    fn new() -> Self {
        let mut mu = [[0.0; D]; T];
        let mut delta = [[0.0; D]; T];
        let mut sigma = [[0.0; D]; T];
        for r in 0..T {
            for j in 0..D {
                mu[r][j] = 1.5 * j as f32 - 2.0 + 0.3 * r as f32;
                delta[r][j] = 0.4 + 0.1 * j as f32;
                sigma[r][j] = 0.3 + 0.15 * ((r + j) % 4) as f32;
            }
        }
        Self {
            mu,
            delta,
            sigma,
            // Deliberately not the data's moments: normalization must be undone exactly.
            mean: [0.5, -1.0, 0.0, 2.0, 1.0],
            std: [0.8, 1.5, 0.6, 1.2, 0.9],
            alpha_bar: alpha_bars(STEPS),
            max_batch: usize::MAX,
            branch: Branch::Mask,
            eps_scale: 1.0,
            record: false,
            calls: Vec::new(),
        }
    }

    fn data_mean(&self, r: usize, j: usize, ctx0: f32, conditioned: bool) -> f32 {
        self.mu[r][j]
            + if conditioned {
                self.delta[r][j] * ctx0
            } else {
                0.0
            }
    }
}

impl DenoiserEngine for GaussianDenoiser {
    type Error = &'static str;

    fn dims(&self) -> ModelDims {
        ModelDims {
            horizon: T,
            state_dim: STATE,
            action_dim: ACTION,
            fingers: F,
            diffusion_steps: STEPS,
        }
    }

    fn normalization(&self) -> Normalization<'_> {
        Normalization {
            mean: &self.mean,
            std: &self.std,
        }
    }

    fn max_batch(&self) -> usize {
        self.max_batch
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
        if batch > self.max_batch {
            return Err("batch above max_batch");
        }
        assert_eq!(x.len(), batch * T * D);
        assert_eq!(eps.len(), batch * T * D);
        assert_eq!(t.len(), batch);
        assert_eq!(context.len(), batch * F);
        assert_eq!(cond_mask.len(), batch);
        if self.record {
            self.calls.push(Call {
                batch,
                x: x.to_vec(),
                t: t.to_vec(),
                context: context.to_vec(),
                cond_mask: cond_mask.to_vec(),
            });
        }
        for b in 0..batch {
            let ab = self.alpha_bar[t[b] as usize];
            let conditioned = match self.branch {
                Branch::Mask => cond_mask[b] == 1.0,
                Branch::Cond => true,
                Branch::Uncond => false,
            };
            for r in 0..T {
                for j in 0..D {
                    let i = (b * T + r) * D + j;
                    let a = f64::from(
                        (self.data_mean(r, j, context[b * F], conditioned) - self.mean[j])
                            / self.std[j],
                    );
                    let bs = f64::from(self.sigma[r][j] / self.std[j]);
                    eps[i] = self.eps_scale * posterior_eps(ab, f64::from(x[i]), a, bs) as f32;
                }
            }
        }
        Ok(())
    }
}

fn contexts(n: usize) -> Vec<f32> {
    (0..n)
        .flat_map(|i| if i % 2 == 0 { [1.0, -1.0] } else { [-1.0, 1.0] })
        .collect()
}

fn starts(n: usize) -> Vec<f32> {
    (0..n * STATE).map(|i| 0.25 * i as f32 - 1.0).collect()
}

/// Sample with a scratch of `chunk` trajectories per call.
fn run(
    engine: &mut GaussianDenoiser,
    config: &SamplerConfig,
    ctx: &[f32],
    start: Option<&[f32]>,
    seed: u64,
    chunk: usize,
) -> Result<Vec<f32>, SampleError<&'static str>> {
    let n = ctx.len() / F;
    let layout = ScratchLayout::new(engine.dims(), chunk);
    let mut buf = vec![0.0f32; layout.total()];
    let mut scratch = SamplerScratch::split(&mut buf, &layout).unwrap();
    let mut out = vec![0.0f32; n * T * D];
    let mut rng = KernelRng::seed_from_u64(seed);
    let request = SampleRequest {
        context: ctx,
        start_states: start,
    };
    let got = sample(engine, config, &request, &mut rng, &mut scratch, &mut out)?;
    assert_eq!(got, n);
    Ok(out)
}

/// Mean and std of entry (r, j) over the trajectories whose context[0] is `ctx0`.
fn moments(out: &[f32], ctx: &[f32], ctx0: f32, r: usize, j: usize) -> (f64, f64, usize) {
    let vals: Vec<f64> = out
        .chunks(T * D)
        .zip(ctx.chunks(F))
        .filter(|(_, c)| c[0] == ctx0)
        .map(|(traj, _)| f64::from(traj[r * D + j]))
        .collect();
    let n = vals.len() as f64;
    let mean = vals.iter().sum::<f64>() / n;
    let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt(), vals.len())
}

/// Check every entry's moments against the data (conditional mean shifted by `w·δ·ctx0`).
fn assert_moments(engine: &GaussianDenoiser, out: &[f32], ctx: &[f32], w: f32, std_tol: f64) {
    assert_moments_with(engine, out, ctx, w, std_tol, |r, j| {
        f64::from(engine.sigma[r][j])
    });
}

/// What DDIM (η = 0, `steps` steps, "leading" spacing) must produce for entry (r, j): the
/// standard deviation and the pull of the mean toward the normalisation mean.
///
/// With the exact ε-predictor of Gaussian data (normalised mean `a`, std `b`), each DDIM step
/// is the linear map `x − √ᾱ'a ← k·(x − √ᾱa)` with
/// `k = (√(ᾱ'ᾱ)·b² + √((1−ᾱ')(1−ᾱ))) / (ᾱb² + 1 − ᾱ)`. The loop starts from `N(0, 1)` at
/// `t_s = ⌊(S−1)N/S⌋`, not from the true `x_{t_s}`: the sample's std is `K = Πk` (normalised)
/// and its mean `a·(1 − K√ᾱ_{t_s})`, which the sampler must match exactly.
fn ddim_moments(engine: &GaussianDenoiser, r: usize, j: usize, steps: usize) -> (f64, f64) {
    let ab = &engine.alpha_bar;
    let b = f64::from(engine.sigma[r][j] / engine.std[j]);
    let mut s = 1.0;
    for k in (0..steps).rev() {
        let t = k * STEPS / steps;
        let an = k.checked_sub(1).map_or(1.0, |n| ab[n * STEPS / steps]);
        let a = ab[t];
        s *= ((an * a).sqrt() * b * b + ((1.0 - an) * (1.0 - a)).sqrt()) / (a * b * b + 1.0 - a);
    }
    let start = ab[(steps - 1) * STEPS / steps];
    (s * f64::from(engine.std[j]), s * start.sqrt())
}

fn ddim_std(engine: &GaussianDenoiser, r: usize, j: usize, steps: usize) -> f64 {
    ddim_moments(engine, r, j, steps).0
}

fn assert_moments_with(
    engine: &GaussianDenoiser,
    out: &[f32],
    ctx: &[f32],
    w: f32,
    std_tol: f64,
    want_std: impl Fn(usize, usize) -> f64,
) {
    assert_moments_pulled(engine, out, ctx, w, std_tol, want_std, |_, _| 0.0);
}

/// [`assert_moments_with`] where the mean is pulled toward the normalisation mean by the
/// fraction `pull(r, j)`.
fn assert_moments_pulled(
    engine: &GaussianDenoiser,
    out: &[f32],
    ctx: &[f32],
    w: f32,
    std_tol: f64,
    want_std: impl Fn(usize, usize) -> f64,
    pull: impl Fn(usize, usize) -> f64,
) {
    for ctx0 in [1.0f32, -1.0] {
        for r in 0..T {
            for j in 0..D {
                let (mean, sd, count) = moments(out, ctx, ctx0, r, j);
                if r == T - 1 && j >= STATE {
                    // The layout's last row `(s_H, 0)`: the sampler writes no action there.
                    assert_eq!((mean, sd), (0.0, 0.0), "last-row action ({r},{j})");
                    continue;
                }
                let sigma = want_std(r, j);
                let data = f64::from(engine.mu[r][j] + w * engine.delta[r][j] * ctx0);
                let m = f64::from(engine.mean[j]);
                let want = data - pull(r, j) * (data - m);
                let se = sigma / (count as f64).sqrt();
                assert!(
                    (mean - want).abs() < 5.0 * se + 0.01 * sigma,
                    "mean of ({r},{j}) ctx {ctx0}: {mean} vs {want} (se {se})"
                );
                assert!(
                    (sd / sigma - 1.0).abs() < std_tol,
                    "std of ({r},{j}) ctx {ctx0}: {sd} vs {sigma}"
                );
            }
        }
    }
}

#[test]
fn ddpm_with_noise_factor_one_reproduces_the_data_distribution() {
    let mut engine = GaussianDenoiser::new();
    let ctx = contexts(4000);
    let config = SamplerConfig {
        method: SamplingMethod::Ddpm { noise_factor: 1.0 },
        guidance_weight: 1.0,
        ..SamplerConfig::default()
    };
    let out = run(&mut engine, &config, &ctx, None, 11, 4000).unwrap();
    assert_moments(&engine, &out, &ctx, 1.0, 0.06);
}

#[test]
fn ddpm_low_temperature_shrinks_the_spread() {
    let mut engine = GaussianDenoiser::new();
    let ctx = contexts(1000);
    let out = run(&mut engine, &SamplerConfig::default(), &ctx, None, 12, 1000).unwrap();
    for r in 0..T {
        for j in 0..D {
            let (_, sd, _) = moments(&out, &ctx, 1.0, r, j);
            assert!(
                sd < 0.9 * f64::from(engine.sigma[r][j]),
                "({r},{j}) std {sd}"
            );
        }
    }
}

#[test]
fn ddim_is_deterministic_and_lands_on_the_data_mean() {
    let mut engine = GaussianDenoiser::new();
    let ctx = contexts(2000);
    let config = SamplerConfig {
        method: SamplingMethod::Ddim {
            steps: 50,
            eta: 0.0,
        },
        guidance_weight: 1.0,
        ..SamplerConfig::default()
    };
    let a = run(&mut engine, &config, &ctx, None, 5, 2000).unwrap();
    let b = run(&mut engine, &config, &ctx, None, 5, 2000).unwrap();
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    assert_moments_pulled(
        &engine,
        &a,
        &ctx,
        1.0,
        0.06,
        |r, j| ddim_std(&engine, r, j, 50),
        |r, j| ddim_moments(&engine, r, j, 50).1,
    );
    // The coarse steps shrink the spread, but by little.
    assert!((ddim_std(&engine, 1, 0, 50) / 0.45 - 1.0).abs() < 0.15);
    // η = 0 draws only x_T: the map from x_T to the sample is deterministic, so a different
    // seed gives a different sample.
    let c = run(&mut engine, &config, &ctx, None, 6, 2000).unwrap();
    assert_ne!(a, c);
}

#[test]
fn ddim_over_all_steps_with_eta_one_matches_ddpm_moments() {
    let mut engine = GaussianDenoiser::new();
    let ctx = contexts(2000);
    let config = SamplerConfig {
        method: SamplingMethod::Ddim {
            steps: STEPS as u16,
            eta: 1.0,
        },
        guidance_weight: 1.0,
        ..SamplerConfig::default()
    };
    let out = run(&mut engine, &config, &ctx, None, 8, 2000).unwrap();
    assert_moments(&engine, &out, &ctx, 1.0, 0.08);
}

#[test]
fn strided_ddpm_over_every_step_with_noise_factor_one_reproduces_the_data_distribution() {
    // Over every step it is the textbook sampler. (With fewer steps each jump's posterior
    // around x̂0 leaves out x0's own uncertainty, so the spread shrinks: 16 steps give about
    // 0.8 of the data's standard deviation here.)
    let mut engine = GaussianDenoiser::new();
    let ctx = contexts(4000);
    let config = SamplerConfig {
        method: SamplingMethod::DdpmStrided {
            steps: STEPS as u16,
            noise_factor: 1.0,
        },
        guidance_weight: 1.0,
        ..SamplerConfig::default()
    };
    let out = run(&mut engine, &config, &ctx, None, 11, 4000).unwrap();
    assert_moments(&engine, &out, &ctx, 1.0, 0.06);
}

#[test]
fn strided_ddpm_over_every_step_is_ddpm_and_visits_the_ddim_steps() {
    // Over every training step the jumps are DDPM's steps: the same draws, and the same
    // samples up to the rounding of the jump's β (1 − ᾱ_t/ᾱ_{t−1} against the schedule's).
    let mut engine = GaussianDenoiser::new();
    let ctx = contexts(200);
    let full = run(&mut engine, &SamplerConfig::default(), &ctx, None, 21, 200).unwrap();
    let strided_config = SamplerConfig {
        method: SamplingMethod::DdpmStrided {
            steps: STEPS as u16,
            noise_factor: DEFAULT_NOISE_FACTOR,
        },
        ..SamplerConfig::default()
    };
    let strided = run(&mut engine, &strided_config, &ctx, None, 21, 200).unwrap();
    let worst = full
        .iter()
        .zip(&strided)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-3, "largest difference {worst}");
    // With fewer steps it visits the same training steps as DDIM.
    engine.record = true;
    engine.calls.clear();
    let ten = SamplerConfig {
        method: SamplingMethod::DdpmStrided {
            steps: 10,
            noise_factor: DEFAULT_NOISE_FACTOR,
        },
        ..SamplerConfig::default()
    };
    run(&mut engine, &ten, &ctx, None, 1, 200).unwrap();
    let ts: Vec<f32> = engine.calls.iter().map(|c| c.t[0]).collect();
    assert_eq!(
        ts,
        vec![
            230.0, 204.0, 179.0, 153.0, 128.0, 102.0, 76.0, 51.0, 25.0, 0.0
        ]
    );
}

#[test]
fn guidance_weight_scales_the_conditional_shift() {
    // ε is linear in the data mean, so guidance w moves the mean to μ + w·δ·c exactly (up to
    // DDIM's known pull of the start, `ddim_moments`).
    let mut engine = GaussianDenoiser::new();
    let ctx = contexts(2000);
    let config = SamplerConfig {
        method: SamplingMethod::Ddim {
            steps: 64,
            eta: 0.0,
        },
        guidance_weight: 2.0,
        ..SamplerConfig::default()
    };
    let out = run(&mut engine, &config, &ctx, None, 9, 2000).unwrap();
    assert_moments_pulled(
        &engine,
        &out,
        &ctx,
        2.0,
        0.06,
        |r, j| ddim_std(&engine, r, j, 64),
        |r, j| ddim_moments(&engine, r, j, 64).1,
    );
}

#[test]
fn guidance_one_is_the_conditioned_prediction_and_zero_the_unconditioned() {
    let ctx = contexts(16);
    for (w, branch) in [(1.0, Branch::Cond), (0.0, Branch::Uncond)] {
        let config = SamplerConfig {
            method: SamplingMethod::Ddpm { noise_factor: 0.5 },
            guidance_weight: w,
            ..SamplerConfig::default()
        };
        let guided = run(&mut GaussianDenoiser::new(), &config, &ctx, None, 3, 16).unwrap();
        let mut single = GaussianDenoiser::new();
        single.branch = branch;
        let plain = run(&mut single, &config, &ctx, None, 3, 16).unwrap();
        for (g, p) in guided.iter().zip(&plain) {
            assert!((g - p).abs() <= 1e-4 * (1.0 + p.abs()), "w {w}: {g} vs {p}");
        }
    }
}

#[test]
fn every_call_stacks_conditioned_then_unconditioned_copies() {
    let n = 5;
    let ctx = contexts(n);
    let start = starts(n);
    let mut engine = GaussianDenoiser::new();
    engine.record = true;
    engine.max_batch = 4; // two trajectories per call: chunks of 2, 2, 1
    run(
        &mut engine,
        &SamplerConfig::default(),
        &ctx,
        Some(&start),
        1,
        8,
    )
    .unwrap();
    assert_eq!(engine.calls.len(), STEPS * 3);
    let mut expected_t = STEPS;
    for (k, call) in engine.calls.iter().enumerate() {
        let first = (k % 3) * 2;
        let m = call.batch / 2;
        assert_eq!(call.batch, if k % 3 == 2 { 2 } else { 4 });
        if k % 3 == 0 {
            expected_t -= 1;
        }
        assert!(call.t.iter().all(|&t| t == expected_t as f32));
        assert!(call.cond_mask[..m].iter().all(|&v| v == 1.0));
        assert!(call.cond_mask[m..].iter().all(|&v| v == 0.0));
        assert_eq!(call.x[..m * T * D], call.x[m * T * D..]);
        assert_eq!(call.context[..m * F], call.context[m * F..]);
        assert_eq!(call.context[..m * F], ctx[first * F..(first + m) * F]);
        // Row 0's state columns hold the normalized start state at every step.
        for b in 0..call.batch {
            let traj = first + b % m;
            for j in 0..STATE {
                let want = (start[traj * STATE + j] - engine.mean[j]) / engine.std[j];
                assert!((call.x[b * T * D + j] - want).abs() < 1e-6);
            }
        }
    }
    assert_eq!(expected_t, 0);
}

#[test]
fn ddim_visits_evenly_spaced_steps() {
    let ctx = contexts(2);
    let mut engine = GaussianDenoiser::new();
    engine.record = true;
    run(&mut engine, &SamplerConfig::ddim(10), &ctx, None, 1, 2).unwrap();
    let ts: Vec<f32> = engine.calls.iter().map(|c| c.t[0]).collect();
    // floor(k·256/10) for k = 9..0 ("leading" spacing).
    assert_eq!(
        ts,
        vec![
            230.0, 204.0, 179.0, 153.0, 128.0, 102.0, 76.0, 51.0, 25.0, 0.0
        ]
    );
}

#[test]
fn inpainting_holds_row_zero_state_and_frees_its_actions() {
    let n = 64;
    let ctx = contexts(n);
    let start = starts(n);
    let mut engine = GaussianDenoiser::new();
    let out = run(
        &mut engine,
        &SamplerConfig::default(),
        &ctx,
        Some(&start),
        4,
        64,
    )
    .unwrap();
    for (i, traj) in out.chunks(T * D).enumerate() {
        assert_eq!(&traj[..STATE], &start[i * STATE..(i + 1) * STATE]);
    }
    // Row 0's action columns are sampled: they vary across trajectories of the same context.
    for j in STATE..D {
        let (_, sd, _) = moments(&out, &ctx, 1.0, 0, j);
        assert!(sd > 0.05, "action column {j} of row 0 has std {sd}");
    }
}

#[test]
fn chunking_gives_identical_bits() {
    let n = 7;
    let ctx = contexts(n);
    let start = starts(n);
    for config in [
        SamplerConfig::default(),
        SamplerConfig {
            method: SamplingMethod::Ddim {
                steps: 20,
                eta: 0.7,
            },
            guidance_weight: 1.2,
            ..SamplerConfig::default()
        },
    ] {
        let whole = run(
            &mut GaussianDenoiser::new(),
            &config,
            &ctx,
            Some(&start),
            21,
            n,
        )
        .unwrap();
        // Limited by the engine's max batch (6 → 3 trajectories per call) ...
        let mut limited = GaussianDenoiser::new();
        limited.max_batch = 6;
        let by_engine = run(&mut limited, &config, &ctx, Some(&start), 21, n).unwrap();
        // ... or by the scratch (2 trajectories per call).
        let by_scratch = run(
            &mut GaussianDenoiser::new(),
            &config,
            &ctx,
            Some(&start),
            21,
            2,
        )
        .unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&whole), bits(&by_engine));
        assert_eq!(bits(&whole), bits(&by_scratch));
    }
}

#[test]
fn same_seed_same_bits_different_seed_different_samples() {
    let ctx = contexts(4);
    let with_seed = |seed| {
        let config = SamplerConfig::default();
        run(&mut GaussianDenoiser::new(), &config, &ctx, None, seed, 4).unwrap()
    };
    let (a, b, c) = (with_seed(99), with_seed(99), with_seed(98));
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    assert_ne!(a, c);
}

#[test]
fn bad_calls_get_typed_errors() {
    let mut engine = GaussianDenoiser::new();
    let dims = engine.dims();
    let layout = ScratchLayout::new(dims, 2);
    let mut buf = vec![0.0f32; layout.total()];
    let ctx = contexts(2);
    let start = starts(2);
    let mut rng = KernelRng::seed_from_u64(0);
    let config = SamplerConfig::default();
    let mut call = |engine: &mut GaussianDenoiser,
                    config: &SamplerConfig,
                    ctx: &[f32],
                    start: Option<&[f32]>,
                    out_len: usize,
                    buf: &mut [f32]| {
        let mut scratch = SamplerScratch {
            alpha_bar: &mut [],
            x: &mut [],
            eps: &mut [],
            t: &mut [],
            context: &mut [],
            cond_mask: &mut [],
        };
        if !buf.is_empty() {
            scratch = SamplerScratch::split(buf, &layout).unwrap();
        }
        let mut out = vec![0.0; out_len];
        let request = SampleRequest {
            context: ctx,
            start_states: start,
        };
        sample(engine, config, &request, &mut rng, &mut scratch, &mut out)
    };
    let td = T * D;
    let err = |e| Err(SampleError::Sampler(e));
    assert_eq!(
        call(&mut engine, &config, &ctx, None, td + 1, &mut buf),
        err(SamplerError::OutputLength {
            floats_per_trajectory: td,
            got: td + 1
        })
    );
    assert_eq!(
        call(&mut engine, &config, &ctx, None, 0, &mut buf),
        err(SamplerError::OutputLength {
            floats_per_trajectory: td,
            got: 0
        })
    );
    assert_eq!(
        call(&mut engine, &config, &ctx[..3], None, 2 * td, &mut buf),
        err(SamplerError::ContextLength {
            expected: 4,
            got: 3
        })
    );
    assert_eq!(
        call(
            &mut engine,
            &config,
            &ctx,
            Some(&start[..1]),
            2 * td,
            &mut buf
        ),
        err(SamplerError::StartStateLength {
            expected: 4,
            got: 1
        })
    );
    assert_eq!(
        call(
            &mut engine,
            &config,
            &ctx,
            Some(&[f32::NAN, 0.0, 0.0, 0.0]),
            2 * td,
            &mut buf
        ),
        err(SamplerError::NonFiniteStartState)
    );
    assert_eq!(
        call(&mut engine, &config, &ctx, None, 2 * td, &mut []),
        err(SamplerError::ScratchTooSmall {
            buffer: ScratchBuffer::AlphaBar,
            needed: STEPS,
            got: 0
        })
    );
    assert_eq!(
        call(
            &mut engine,
            &SamplerConfig::ddim(0),
            &ctx,
            None,
            2 * td,
            &mut buf
        ),
        err(SamplerError::StridedSteps {
            steps: 0,
            diffusion_steps: STEPS
        })
    );
    assert_eq!(
        call(
            &mut engine,
            &SamplerConfig::ddim(257),
            &ctx,
            None,
            2 * td,
            &mut buf
        ),
        err(SamplerError::StridedSteps {
            steps: 257,
            diffusion_steps: STEPS
        })
    );
    let nan_w = SamplerConfig {
        guidance_weight: f32::NAN,
        ..config
    };
    assert_eq!(
        call(&mut engine, &nan_w, &ctx, None, 2 * td, &mut buf),
        err(SamplerError::BadConfig)
    );
    let mut one = GaussianDenoiser::new();
    one.max_batch = 1;
    assert_eq!(
        call(&mut one, &config, &ctx, None, 2 * td, &mut buf),
        err(SamplerError::MaxBatchTooSmall { max_batch: 1 })
    );
    let mut bad_norm = GaussianDenoiser::new();
    bad_norm.std[3] = 0.0;
    assert_eq!(
        call(&mut bad_norm, &config, &ctx, None, 2 * td, &mut buf),
        err(SamplerError::BadNormalization)
    );
    assert_eq!(
        SamplerScratch::split(&mut [0.0; 3], &layout).unwrap_err(),
        SamplerError::ScratchTooSmall {
            buffer: ScratchBuffer::Whole,
            needed: layout.total(),
            got: 3
        }
    );
    // Errors explain themselves.
    let text = SamplerError::ContextLength {
        expected: 4,
        got: 3,
    }
    .to_string();
    assert!(text.contains('4') && text.contains('3'), "{text}");
}

#[test]
fn clipping_the_denoised_estimate_keeps_an_imperfect_denoiser_bounded() {
    // A denoiser that predicts no noise (an untrained one, roughly) makes every DDPM step
    // `x ← x/√α_t`: unclipped the samples grow by 1/√ᾱ_T ≈ 5000; clipped they stay within the
    // bound (in normalised units).
    let ctx = contexts(64);
    let worst = |clip: f32| {
        let mut engine = GaussianDenoiser::new();
        engine.eps_scale = 0.0;
        let config = SamplerConfig {
            clip_denoised: clip,
            ..SamplerConfig::default()
        };
        let out = run(&mut engine, &config, &ctx, None, 4, 64).unwrap();
        out.chunks(D)
            .flat_map(|row| {
                row.iter()
                    .enumerate()
                    .map(|(j, v)| ((v - engine.mean[j]) / engine.std[j]).abs())
                    .collect::<Vec<_>>()
            })
            .fold(0.0f32, f32::max)
    };
    let unclipped = worst(f32::INFINITY);
    let clipped = worst(DEFAULT_DENOISED_CLIP);
    assert!(unclipped > 100.0, "unclipped worst |z| {unclipped}");
    assert!(
        clipped <= DEFAULT_DENOISED_CLIP + 1e-3,
        "clipped worst |z| {clipped}"
    );
    // The exact predictor is untouched by the default bound: same bits with and without.
    let config = SamplerConfig::default();
    let off = SamplerConfig {
        clip_denoised: f32::INFINITY,
        ..config
    };
    let a = run(&mut GaussianDenoiser::new(), &config, &ctx, None, 4, 64).unwrap();
    let b = run(&mut GaussianDenoiser::new(), &off, &ctx, None, 4, 64).unwrap();
    assert_eq!(a, b);
    for bad in [0.0, -1.0, f32::NAN] {
        let c = SamplerConfig {
            clip_denoised: bad,
            ..config
        };
        assert_eq!(
            run(&mut GaussianDenoiser::new(), &c, &ctx, None, 4, 64).unwrap_err(),
            SampleError::Sampler(SamplerError::BadConfig)
        );
    }
}

#[test]
fn engine_errors_are_passed_through() {
    struct Failing(GaussianDenoiser);
    impl DenoiserEngine for Failing {
        type Error = &'static str;
        fn dims(&self) -> ModelDims {
            self.0.dims()
        }
        fn normalization(&self) -> Normalization<'_> {
            self.0.normalization()
        }
        fn max_batch(&self) -> usize {
            8
        }
        fn predict_eps(
            &mut self,
            _: usize,
            _: &[f32],
            _: &[f32],
            _: &[f32],
            _: &[f32],
            _: &mut [f32],
        ) -> Result<(), &'static str> {
            Err("boom")
        }
    }
    let mut engine = Failing(GaussianDenoiser::new());
    let layout = ScratchLayout::new(engine.dims(), 1);
    let mut buf = vec![0.0f32; layout.total()];
    let mut scratch = SamplerScratch::split(&mut buf, &layout).unwrap();
    let mut out = vec![0.0; T * D];
    let request = SampleRequest {
        context: &[1.0, 1.0],
        start_states: None,
    };
    let mut rng = KernelRng::seed_from_u64(0);
    assert_eq!(
        sample(
            &mut engine,
            &SamplerConfig::default(),
            &request,
            &mut rng,
            &mut scratch,
            &mut out
        ),
        Err(SampleError::Engine("boom"))
    );
}
