//! Constrained Stein variational trajectory optimisation (spec `algorithms.md` §1.2).

use rayon::prelude::*;

use super::kernel::RbfKernel;
use super::linearization::{Layout, Linearization, initial_slack};
use super::problem::Problem;

/// CSVTO settings (spec §1.6).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CsvtoSettings {
    /// Weight `α_J` of the Stein (cost and repulsion) direction.
    pub alpha_j: f64,
    /// Weight `α_C` of the Gauss–Newton constraint step.
    pub alpha_c: f64,
    /// Step size `ε`.
    pub step_size: f64,
    /// Penalty weight `ρ` on `Σ|C|` used to rank particles.
    pub penalty: f64,
    /// Largest allowed norm of one particle's step `Δ` before `ε` (spec: 1).
    pub max_step_norm: f64,
    /// Bound on the slack variables (±).
    pub slack_bound: f64,
    /// Iteration counts above this anneal `γ` linearly from 0 (spec: 50).
    pub anneal_above: usize,
    /// Clip the Stein part `α_J φ` and the constraint part `α_C ξ` to
    /// [`Self::max_step_norm`] separately instead of clipping their sum (spec: the sum).
    /// With very large cost gradients (the card's 1.5e5 goal weight) the summed clip scales
    /// the constraint correction down with the cost step and feasibility is lost.
    pub clip_separately: bool,
}

impl Default for CsvtoSettings {
    fn default() -> Self {
        Self {
            alpha_j: 5e-3,
            alpha_c: 1.0,
            step_size: 0.1,
            penalty: 1e6,
            max_step_norm: 1.0,
            slack_bound: 1e3,
            anneal_above: 50,
            clip_separately: false,
        }
    }
}

/// A CSVTO setting or call that cannot be run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CsvtoError {
    /// A setting is out of range (named).
    #[error(
        "CSVTO setting `{0}` is out of range (must be finite and positive, or ≥ 0 for weights)"
    )]
    Setting(&'static str),
    /// A count is zero.
    #[error("CSVTO count `{0}` must be at least 1")]
    ZeroCount(&'static str),
    /// No particles were given.
    #[error("no particles to optimise")]
    NoParticles,
    /// A particle's length does not match the problem.
    #[error("particle {index} has {got} values; the problem needs {expected}")]
    ParticleLength {
        /// Which particle.
        index: usize,
        /// Its length.
        got: usize,
        /// `H · row_dim`.
        expected: usize,
    },
}

impl CsvtoSettings {
    /// Check every setting: weights finite and `≥ 0`, step size, step-norm and slack bounds
    /// finite and `> 0`. The first bad one is named.
    pub fn validate(&self) -> Result<(), CsvtoError> {
        let non_negative = [
            ("alpha_j", self.alpha_j),
            ("alpha_c", self.alpha_c),
            ("penalty", self.penalty),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CsvtoError::Setting(name));
            }
        }
        let positive = [
            ("step_size", self.step_size),
            ("max_step_norm", self.max_step_norm),
            ("slack_bound", self.slack_bound),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(CsvtoError::Setting(name));
            }
        }
        Ok(())
    }
}

/// What a solve returns besides the updated particles.
#[derive(Debug, Clone, PartialEq)]
pub struct SolveReport {
    /// Cost `J` of each particle, in the sorted order.
    pub costs: Vec<f64>,
    /// Constraint violation `Σ|g| + Σ max(h, 0)` of each particle, sorted order.
    pub violations: Vec<f64>,
    /// Largest violated inequality `max(h, 0)` of each particle, sorted order.
    pub max_ineq_violation: Vec<f64>,
    /// Largest `|g|` over the equalities of each particle, sorted order.
    pub max_eq_violation: Vec<f64>,
    /// The ranking penalty `J + ρ·violation`, ascending.
    pub penalties: Vec<f64>,
}

/// The value of `γ` at iteration `k` of `iters` (spec §1.2 step 6).
pub fn gamma(k: usize, iters: usize, anneal_above: usize) -> f64 {
    if iters > anneal_above {
        k as f64 / iters as f64
    } else {
        1.0
    }
}

/// Evaluated particle: linearisation, cost and gradient.
struct Evaluated {
    lin: Linearization,
    grad: Vec<f64>,
    cost: f64,
}

fn evaluate(problem: &dyn Problem, layout: &Layout, x: &[f64], z: &[f64]) -> Evaluated {
    let lin = Linearization::build(problem, layout, x, z);
    let mut grad = vec![0.0; x.len()];
    let cost = problem.cost(x, &mut grad);
    Evaluated { lin, grad, cost }
}

/// Run `iters` CSVTO iterations on `particles` (each a flat `H·n` trajectory) for `problem`,
/// then sort them by penalty, best first. Slacks are initialised from the inequalities at
/// the start of the solve. Bad settings, no particles or a particle of the wrong length are
/// errors, checked before anything runs.
pub fn solve(
    problem: &dyn Problem,
    particles: &mut Vec<Vec<f64>>,
    iters: usize,
    settings: &CsvtoSettings,
) -> Result<SolveReport, CsvtoError> {
    settings.validate()?;
    let layout = Layout::of(problem);
    let np = particles.len();
    if np == 0 {
        return Err(CsvtoError::NoParticles);
    }
    let dim_x = problem.horizon() * problem.row_dim();
    if let Some((index, p)) = particles.iter().enumerate().find(|(_, p)| p.len() != dim_x) {
        return Err(CsvtoError::ParticleLength {
            index,
            got: p.len(),
            expected: dim_x,
        });
    }
    for p in particles.iter_mut() {
        problem.clamp(p);
    }
    let mut slacks: Vec<Vec<f64>> = particles
        .par_iter()
        .map(|x| initial_slack(problem, &layout, x))
        .collect();
    let dim = dim_x + layout.n_slack;
    let mut blocks = vec![vec![0.0; dim * np]; np];
    let mut scratches: Vec<Vec<f64>> = vec![Vec::new(); np];
    let mut sum = vec![0.0; dim * np];
    for k in 0..iters {
        let g = gamma(k, iters, settings.anneal_above);
        let evals: Vec<Evaluated> = particles
            .par_iter()
            .zip(slacks.par_iter())
            .map(|(x, z)| evaluate(problem, &layout, x, z))
            .collect();
        let kern = RbfKernel::new(particles);
        let two_over_h = 2.0 / kern.bandwidth;
        // S[:, m] = Σ_n P_n k_nm [γ(−∇J_n) − (2/h)(x_n − x_m)], coordinate-major (dim×N).
        // Each particle's projected block in parallel, then summed in a fixed order so that
        // the result does not depend on thread scheduling. Buffers are reused across
        // iterations (fresh ones cost page faults and zeroing).
        blocks
            .par_iter_mut()
            .zip(scratches.par_iter_mut())
            .enumerate()
            .for_each(|(n, (v, scratch))| {
                let xn = &particles[n];
                let gn = &evals[n].grad;
                v.fill(0.0);
                for m in 0..np {
                    let knm = kern.at(n, m);
                    let xm = &particles[m];
                    for c in 0..dim_x {
                        v[c * np + m] = knm * (-g * gn[c] - two_over_h * (xn[c] - xm[c]));
                    }
                }
                evals[n].lin.project(v, np, scratch);
            });
        sum.fill(0.0);
        for b in &blocks {
            for (a, x) in sum.iter_mut().zip(b) {
                *a += x;
            }
        }
        let inv_n = 1.0 / np as f64;
        particles
            .par_iter_mut()
            .zip(slacks.par_iter_mut())
            .enumerate()
            .for_each(|(m, (x, z))| {
                let lin = &evals[m].lin;
                let mut phi: Vec<f64> = (0..dim).map(|c| sum[c * np + m] * inv_n).collect();
                let mut scratch = Vec::new();
                lin.project(&mut phi, 1, &mut scratch);
                let xi = lin.constraint_step();
                // Δ = α_J(−φ) + α_C ξ, clipped, then x ← x − εΔ.
                let clip = |v: &mut [f64]| {
                    let norm = v.iter().map(|d| d * d).sum::<f64>().sqrt();
                    if norm > settings.max_step_norm {
                        let s = settings.max_step_norm / norm;
                        v.iter_mut().for_each(|d| *d *= s);
                    }
                };
                let mut stein: Vec<f64> = phi.iter().map(|p| -settings.alpha_j * p).collect();
                let mut correction: Vec<f64> = xi.iter().map(|c| settings.alpha_c * c).collect();
                if settings.clip_separately {
                    clip(&mut stein);
                    clip(&mut correction);
                }
                let mut delta: Vec<f64> =
                    stein.iter().zip(&correction).map(|(a, b)| a + b).collect();
                clip(&mut delta);
                for c in 0..dim_x {
                    x[c] -= settings.step_size * delta[c];
                }
                for (i, zi) in z.iter_mut().enumerate() {
                    *zi = (*zi - settings.step_size * delta[dim_x + i])
                        .clamp(-settings.slack_bound, settings.slack_bound);
                }
                problem.clamp(x);
            });
    }
    Ok(finish(problem, &layout, particles, &slacks, settings))
}

/// Score every particle and sort them by penalty, best first.
fn finish(
    problem: &dyn Problem,
    layout: &Layout,
    particles: &mut Vec<Vec<f64>>,
    slacks: &[Vec<f64>],
    settings: &CsvtoSettings,
) -> SolveReport {
    let scored: Vec<(f64, f64, f64, f64)> = particles
        .par_iter()
        .zip(slacks.par_iter())
        .map(|(x, z)| {
            let e = evaluate(problem, layout, x, z);
            let max_ineq = e
                .lin
                .raw_inequalities()
                .iter()
                .fold(0.0f64, |a, &h| a.max(h));
            let ineq_sum: f64 = e.lin.raw_inequalities().iter().map(|h| h.max(0.0)).sum();
            // Equalities come first within each step.
            let (mut max_eq, mut eq_sum) = (0.0f64, 0.0);
            let mut off = 0;
            for t in 0..layout.n_eq.len() {
                for &g in &e.lin.values()[off..off + layout.n_eq[t]] {
                    max_eq = max_eq.max(g.abs());
                    eq_sum += g.abs();
                }
                off += layout.n_eq[t] + layout.n_ineq[t];
            }
            (e.cost, eq_sum + ineq_sum, max_ineq, max_eq)
        })
        .collect();
    let mut order: Vec<usize> = (0..particles.len()).collect();
    let pen = |i: usize| scored[i].0 + settings.penalty * scored[i].1;
    order.sort_by(|&a, &b| pen(a).total_cmp(&pen(b)));
    let sorted: Vec<Vec<f64>> = order.iter().map(|&i| particles[i].clone()).collect();
    *particles = sorted;
    SolveReport {
        costs: order.iter().map(|&i| scored[i].0).collect(),
        violations: order.iter().map(|&i| scored[i].1).collect(),
        max_ineq_violation: order.iter().map(|&i| scored[i].2).collect(),
        max_eq_violation: order.iter().map(|&i| scored[i].3).collect(),
        penalties: order.iter().map(|&i| pen(i)).collect(),
    }
}
