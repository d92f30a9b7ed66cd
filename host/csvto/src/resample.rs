//! Particle resampling (spec `algorithms.md` §1.3): draw particles in proportion to
//! `softmax(−penalty/τ)` of the min-max-normalised penalty and perturb them with noise
//! projected onto each drawn particle's constraint tangent space.

use dips_kernel::rng::KernelRng;

use super::linearization::{Layout, Linearization, initial_slack};
use super::problem::Problem;

/// Resampling settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResampleSettings {
    /// Softmax temperature `τ` on the normalised penalty (spec: 0.1).
    pub temperature: f64,
    /// Standard deviation `σ` of the tangent-space noise (spec: 0.01).
    pub sigma: f64,
}

impl Default for ResampleSettings {
    fn default() -> Self {
        Self {
            temperature: 0.1,
            sigma: 0.01,
        }
    }
}

/// Softmax weights of `−normalised(penalty)/τ`.
pub fn resample_weights(penalties: &[f64], temperature: f64) -> Vec<f64> {
    let lo = penalties.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = penalties.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = if hi > lo { hi - lo } else { 1.0 };
    let logits: Vec<f64> = penalties
        .iter()
        .map(|p| -((p - lo) / span) / temperature)
        .collect();
    let mx = logits.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = logits.iter().map(|l| (l - mx).exp()).collect();
    let s: f64 = e.iter().sum();
    e.iter().map(|v| v / s).collect()
}

/// Resample `particles` (with their `penalties`) in place.
pub fn resample(
    problem: &dyn Problem,
    particles: &mut [Vec<f64>],
    penalties: &[f64],
    settings: &ResampleSettings,
    rng: &mut KernelRng,
) {
    let w = resample_weights(penalties, settings.temperature);
    let layout = Layout::of(problem);
    let old: Vec<Vec<f64>> = particles.to_vec();
    let mut cdf = Vec::with_capacity(w.len());
    let mut acc = 0.0;
    for v in &w {
        acc += v;
        cdf.push(acc);
    }
    for p in particles.iter_mut() {
        let u = rng.uniform_f64() * acc;
        let idx = cdf.iter().position(|&c| u < c).unwrap_or(w.len() - 1);
        let x = &old[idx];
        let z = initial_slack(problem, &layout, x);
        let lin = Linearization::build(problem, &layout, x, &z);
        let mut noise: Vec<f64> = (0..lin.dim())
            .map(|_| settings.sigma * f64::from(rng.normal_f32()))
            .collect();
        let mut scratch = Vec::new();
        lin.project(&mut noise, 1, &mut scratch);
        *p = x.iter().zip(&noise).map(|(a, b)| a + b).collect();
        problem.clamp(p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_favour_low_penalty() {
        let w = resample_weights(&[0.0, 1.0, 0.5], 0.1);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(w[0] > w[2] && w[2] > w[1]);
        assert!((w[0] / w[1] - 10f64.exp()).abs() < 1e-6 * 10f64.exp());
    }
}
