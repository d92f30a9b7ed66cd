//! Analytic engine doubles for the model adapters: an exact Gaussian ε-predictor and a
//! logistic discriminator, in the real screwdriver layout (or any task's sizes).
#![allow(dead_code, unreachable_pub, missing_docs)]

use dips_kernel::engine::{DenoiserEngine, DiscriminatorEngine, ModelDims, Normalization};
use dips_kernel::mode::{SegmentDims, Task};

/// The cosine schedule's ᾱ in f64, computed independently of the kernel.
pub fn alpha_bars(steps: usize) -> Vec<f64> {
    let s = 0.008;
    let f = |k: f64| {
        (((k / steps as f64 + s) / (1.0 + s)) * std::f64::consts::FRAC_PI_2)
            .cos()
            .powi(2)
    };
    let mut acc = 1.0;
    (0..steps)
        .map(|i| {
            let beta = (1.0 - f(i as f64 + 1.0) / f(i as f64)).clamp(0.0, 0.999);
            acc *= 1.0 - beta;
            acc
        })
        .collect()
}

pub fn model_dims(dims: SegmentDims, diffusion_steps: usize) -> ModelDims {
    ModelDims {
        horizon: dims.horizon,
        state_dim: dims.state_dim,
        action_dim: dims.action_dim,
        fingers: dims.fingers,
        diffusion_steps,
    }
}

/// The yaw turned by a segment whose fingers are all in contact.
pub const TURN: f32 = -std::f32::consts::FRAC_PI_6;

/// Data, in normalized units and given the (clean, inpainted) normalized start row `y0`:
/// every column of rows `r ≥ 1` and the actions of row 0 are independent Gaussians. Joints
/// and the two plain object columns stay at `y0` (σ 0.05), the `(cos, sin)` pair is `y0`'s
/// rotated by `r/(T−1)·TURN` when conditioned on a mode with every finger in contact (held
/// otherwise, and when unconditioned; σ 0.02), actions are `N(0, 0.3²)`. The prediction is
/// the exact posterior mean `E[ε | x_t] = √(1−ᾱ)(x_t − √ᾱ a)/(ᾱ b² + 1 − ᾱ)`.
#[derive(Debug, Clone)]
pub struct GaussianDenoiser {
    pub dims: ModelDims,
    pub mean: Vec<f32>,
    pub std: Vec<f32>,
    pub alpha_bar: Vec<f64>,
    pub max_batch: usize,
    /// Engine calls made.
    pub calls: usize,
    /// Samples evaluated.
    pub samples: usize,
    /// Fail every call after this many (never when `None`).
    pub fail_after: Option<usize>,
}

impl GaussianDenoiser {
    pub fn new(task: Task, diffusion_steps: usize) -> Self {
        let dims = model_dims(task.dims(), diffusion_steps);
        let (sd, d) = (dims.state_dim, dims.dim());
        let mut mean = vec![0.0f32; d];
        let mut std = vec![1.0f32; d];
        mean[..sd - 4].fill(0.5);
        std[..sd - 4].fill(0.3);
        std[sd - 4..sd - 2].fill(0.05);
        std[sd..].fill(0.1);
        Self {
            dims,
            mean,
            std,
            alpha_bar: alpha_bars(diffusion_steps),
            max_batch: usize::MAX,
            calls: 0,
            samples: 0,
            fail_after: None,
        }
    }

    /// The data's mean `a` and standard deviation `b` of row `r`, column `j`.
    fn moments(&self, y0: &[f32], turn: bool, r: usize, j: usize) -> (f64, f64) {
        let sd = self.dims.state_dim;
        let last = (self.dims.horizon - 1) as f32;
        if j >= sd {
            return (0.0, 0.3);
        }
        if r == 0 {
            return (f64::from(y0[j]), 0.0);
        }
        if j < sd - 2 {
            return (f64::from(y0[j]), 0.05);
        }
        let angle = if turn { TURN * r as f32 / last } else { 0.0 };
        let (s, c) = angle.sin_cos();
        let (c0, s0) = (y0[sd - 2], y0[sd - 1]);
        let a = if j == sd - 2 {
            c * c0 - s * s0
        } else {
            s * c0 + c * s0
        };
        (f64::from(a), 0.02)
    }
}

impl DenoiserEngine for GaussianDenoiser {
    type Error = &'static str;

    fn dims(&self) -> ModelDims {
        self.dims
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
        if self.fail_after.is_some_and(|n| self.calls >= n) {
            return Err("denoiser double: failing as asked");
        }
        self.calls += 1;
        self.samples += batch;
        let (rows, d, f) = (self.dims.horizon, self.dims.dim(), self.dims.fingers);
        let td = rows * d;
        assert!(
            batch <= self.max_batch,
            "batch {batch} over {}",
            self.max_batch
        );
        assert_eq!((x.len(), eps.len()), (batch * td, batch * td));
        assert_eq!(
            (t.len(), cond_mask.len(), context.len()),
            (batch, batch, batch * f)
        );
        for b in 0..batch {
            let ab = self.alpha_bar[t[b] as usize];
            let ctx = &context[b * f..(b + 1) * f];
            assert!(
                ctx.iter().all(|&c| c == 1.0 || c == -1.0),
                "context {ctx:?}"
            );
            let turn = cond_mask[b] > 0.5 && ctx.iter().all(|&c| c > 0.0);
            let xb = &x[b * td..(b + 1) * td];
            let y0 = &xb[..self.dims.state_dim];
            for r in 0..rows {
                for j in 0..d {
                    let (a, s) = self.moments(y0, turn, r, j);
                    let xv = f64::from(xb[r * d + j]);
                    let e = (1.0 - ab).sqrt() * (xv - ab.sqrt() * a) / (ab * s * s + 1.0 - ab);
                    eps[b * td + r * d + j] = e as f32;
                }
            }
        }
        Ok(())
    }
}

/// `p_real = sigmoid(1 − 0.5·mean(u²) + 0.25·mean(c) − 2·mean over rows ≥ 1 of the squared
/// distance of the (cos, sin) pair from the unit circle)`, on the normalized input `u`
/// (actions) and the context `c`. Records the inputs it saw.
#[derive(Debug, Clone)]
pub struct LogisticDiscriminator {
    pub dims: ModelDims,
    pub mean: Vec<f32>,
    pub std: Vec<f32>,
    pub max_batch: usize,
    pub calls: usize,
    pub record: bool,
    pub seen_x: Vec<f32>,
    pub seen_context: Vec<f32>,
}

impl LogisticDiscriminator {
    pub fn new(task: Task) -> Self {
        let dims = model_dims(task.dims(), 0);
        let d = dims.dim();
        // Deliberately not the denoiser's normalization.
        let mean = (0..d).map(|j| 0.01 * j as f32).collect();
        let mut std: Vec<f32> = (0..d).map(|j| 0.5 + 0.05 * (j % 5) as f32).collect();
        std[dims.state_dim - 2] = 1.0;
        std[dims.state_dim - 1] = 1.0;
        Self {
            dims,
            mean,
            std,
            max_batch: usize::MAX,
            calls: 0,
            record: false,
            seen_x: Vec::new(),
            seen_context: Vec::new(),
        }
    }

    /// The score of one normalized segment and its context row.
    pub fn logistic(dims: ModelDims, mean: &[f32], x: &[f32], ctx: &[f32]) -> f32 {
        let (rows, d, sd) = (dims.horizon, dims.dim(), dims.state_dim);
        let mut act = 0.0f32;
        let mut circle = 0.0f32;
        for r in 0..rows {
            let row = &x[r * d..(r + 1) * d];
            act += row[sd..].iter().map(|u| u * u).sum::<f32>();
            if r > 0 {
                // Undo the (unit-std) normalization of the cos/sin pair.
                let c = row[sd - 2] + mean[sd - 2];
                let s = row[sd - 1] + mean[sd - 1];
                let rad = (c * c + s * s).sqrt() - 1.0;
                circle += rad * rad;
            }
        }
        act /= (rows * (d - sd)) as f32;
        circle /= (rows - 1) as f32;
        let cm = ctx.iter().sum::<f32>() / ctx.len() as f32;
        let z = 1.0 - 0.5 * act + 0.25 * cm - 2.0 * circle;
        1.0 / (1.0 + (-z).exp())
    }
}

impl DiscriminatorEngine for LogisticDiscriminator {
    type Error = &'static str;

    fn dims(&self) -> ModelDims {
        self.dims
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

    fn p_real(
        &mut self,
        batch: usize,
        x: &[f32],
        context: &[f32],
        p_real: &mut [f32],
    ) -> Result<(), Self::Error> {
        self.calls += 1;
        let (td, f) = (self.dims.floats_per_trajectory(), self.dims.fingers);
        assert!(batch <= self.max_batch);
        assert_eq!(
            (x.len(), context.len(), p_real.len()),
            (batch * td, batch * f, batch)
        );
        if self.record {
            self.seen_x.extend_from_slice(x);
            self.seen_context.extend_from_slice(context);
        }
        for b in 0..batch {
            p_real[b] = Self::logistic(
                self.dims,
                &self.mean,
                &x[b * td..(b + 1) * td],
                &context[b * f..(b + 1) * f],
            );
        }
        Ok(())
    }
}
