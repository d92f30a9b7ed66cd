//! One particle's constraint linearisation: `C`, a sparse `∇C`, and the block-tridiagonal
//! factor of `∇C∇Cᵀ + λI`, with the two operations CSVTO needs from them: the tangent-space
//! projection `P = I − ∇Cᵀ(∇C∇Cᵀ)⁻¹∇C` and the Gauss–Newton step `∇Cᵀ(∇C∇Cᵀ)⁻¹C`.
//!
//! Variables are augmented with one squared slack per inequality (`h + ½z² = 0`). The
//! augmented vector is `[x (H·n) ; z (all slacks, step by step)]`.

// Row/column index loops mirror the block structure of the matrices.
#![allow(clippy::needless_range_loop)]

use super::blocktri::BlockTriFactor;
use super::problem::{Problem, StepConstraints};

/// Diagonal regularisation added to `∇C∇Cᵀ` (spec §1.2 step 3).
pub const GRAM_REGULARISATION: f64 = 1e-6;

/// A particle's linearised constraints.
#[derive(Debug, Clone)]
pub struct Linearization {
    /// Dimension of the trajectory part `H·n`.
    dim_x: usize,
    /// Total augmented dimension (trajectory plus slacks).
    dim: usize,
    /// Combined constraint values `C = [g ; h + ½z²]`, step by step.
    values: Vec<f64>,
    /// Raw inequality values `h`, step by step (for slack initialisation).
    raw_ineq: Vec<f64>,
    /// CSR row pointers into `cols`/`vals`.
    ptr: Vec<usize>,
    /// Global column of each non-zero (trajectory part only).
    cols: Vec<u32>,
    /// Non-zero values.
    vals: Vec<f64>,
    /// Per constraint row: the slack's global column and `z`, or `None` for equalities.
    slack: Vec<Option<(usize, f64)>>,
    /// The factor of `∇C∇Cᵀ + λI`.
    factor: BlockTriFactor,
}

/// Per-step counts used to lay out constraints and slacks.
#[derive(Debug, Clone)]
pub struct Layout {
    /// Equalities per step.
    pub n_eq: Vec<usize>,
    /// Inequalities per step.
    pub n_ineq: Vec<usize>,
    /// Offset of each step's slacks in the slack vector.
    pub slack_offset: Vec<usize>,
    /// Total number of slacks.
    pub n_slack: usize,
}

impl Layout {
    /// The layout of `problem`.
    pub fn of(problem: &dyn Problem) -> Self {
        let h = problem.horizon();
        let n_eq: Vec<usize> = (0..h).map(|t| problem.n_eq(t)).collect();
        let n_ineq: Vec<usize> = (0..h).map(|t| problem.n_ineq(t)).collect();
        let mut slack_offset = Vec::with_capacity(h);
        let mut acc = 0;
        for &m in &n_ineq {
            slack_offset.push(acc);
            acc += m;
        }
        Self {
            n_eq,
            n_ineq,
            slack_offset,
            n_slack: acc,
        }
    }
}

/// Evaluate every step's constraints of `problem` at `x`, calling `f(t, constraints)`.
pub fn for_each_step(
    problem: &dyn Problem,
    layout: &Layout,
    x: &[f64],
    scratch: &mut StepConstraints,
    mut f: impl FnMut(usize, &StepConstraints),
) {
    let (n, ds) = (problem.row_dim(), problem.state_dim());
    for t in 0..problem.horizon() {
        let prev = if t == 0 {
            problem.start_state()
        } else {
            &x[(t - 1) * n..(t - 1) * n + ds]
        };
        scratch.reset(layout.n_eq[t], layout.n_ineq[t], ds + n);
        problem.step_constraints(t, prev, &x[t * n..(t + 1) * n], scratch);
        f(t, scratch);
    }
}

/// Initial slacks for `x`: `z = sqrt(−2h)` where `h < 0`, else 0 (spec §1.1).
pub fn initial_slack(problem: &dyn Problem, layout: &Layout, x: &[f64]) -> Vec<f64> {
    let mut z = vec![0.0; layout.n_slack];
    let mut sc = StepConstraints::default();
    for_each_step(problem, layout, x, &mut sc, |t, c| {
        for (i, &h) in c.ineq.iter().enumerate() {
            z[layout.slack_offset[t] + i] = if h < 0.0 { (-2.0 * h).sqrt() } else { 0.0 };
        }
    });
    z
}

impl Linearization {
    /// Linearise `problem`'s constraints at trajectory `x` with slacks `z`.
    pub fn build(problem: &dyn Problem, layout: &Layout, x: &[f64], z: &[f64]) -> Self {
        let (h, n, ds) = (problem.horizon(), problem.row_dim(), problem.state_dim());
        let width = ds + n;
        let dim_x = h * n;
        let total_rows: usize = layout.n_eq.iter().sum::<usize>() + layout.n_slack;
        let mut values = Vec::with_capacity(total_rows);
        let mut raw_ineq = Vec::with_capacity(layout.n_slack);
        let mut ptr = Vec::with_capacity(total_rows + 1);
        ptr.push(0);
        let mut cols: Vec<u32> = Vec::with_capacity(total_rows * 16);
        let mut vals = Vec::with_capacity(total_rows * 16);
        let mut slack = Vec::with_capacity(total_rows);
        let mut sizes = Vec::with_capacity(h);
        let mut diag = Vec::with_capacity(h);
        let mut sub = Vec::with_capacity(h);
        // This step's and the previous step's constraint blocks (the previous one is kept to
        // form the coupling block); swapped after each step instead of copied.
        let mut cur = StepConstraints::default();
        let mut prev = StepConstraints::default();
        // Local non-zeros of each row of the current step: (local col, value).
        let mut local: Vec<Vec<(usize, f64)>> = Vec::new();
        fn jrow(c: &StepConstraints, r: usize, width: usize) -> &[f64] {
            let me = c.eq.len();
            if r < me {
                &c.jac_eq[r * width..(r + 1) * width]
            } else {
                &c.jac_ineq[(r - me) * width..(r - me + 1) * width]
            }
        }
        for t in 0..h {
            let prev_state = if t == 0 {
                problem.start_state()
            } else {
                &x[(t - 1) * n..(t - 1) * n + ds]
            };
            cur.reset(layout.n_eq[t], layout.n_ineq[t], width);
            problem.step_constraints(t, prev_state, &x[t * n..(t + 1) * n], &mut cur);
            let c = &cur;
            let me = c.eq.len();
            let mi = c.ineq.len();
            let m = me + mi;
            // The start state is fixed: no derivative with respect to it at t = 0.
            let first_col = if t == 0 { ds } else { 0 };
            local.resize_with(m, Vec::new);
            for r in 0..m {
                let lr = &mut local[r];
                lr.clear();
                let row = jrow(c, r, width);
                for (lc, &v) in row.iter().enumerate().skip(first_col) {
                    if v != 0.0 {
                        lr.push((lc, v));
                        let gc = if lc < ds {
                            (t - 1) * n + lc
                        } else {
                            t * n + (lc - ds)
                        };
                        cols.push(gc as u32);
                        vals.push(v);
                    }
                }
                ptr.push(cols.len());
                if r < me {
                    values.push(c.eq[r]);
                    slack.push(None);
                } else {
                    let i = r - me;
                    let zi = z[layout.slack_offset[t] + i];
                    values.push(c.ineq[i] + 0.5 * zi * zi);
                    raw_ineq.push(c.ineq[i]);
                    slack.push(Some((dim_x + layout.slack_offset[t] + i, zi)));
                }
            }
            // Diagonal block A_tt = J Jᵀ + diag(z²) + λI.
            let mut d = vec![0.0; m * m];
            for r in 0..m {
                for s in 0..=r {
                    let rs = jrow(c, s, width);
                    let mut acc = 0.0;
                    for &(lc, v) in &local[r] {
                        acc += v * rs[lc];
                    }
                    d[r * m + s] = acc;
                    d[s * m + r] = acc;
                }
                let zr = if r >= me {
                    z[layout.slack_offset[t] + r - me]
                } else {
                    0.0
                };
                d[r * m + r] += zr * zr + GRAM_REGULARISATION;
            }
            // Coupling block A_{t,t−1}: this step's prev-state columns against the previous
            // step's row columns (its first `ds` entries are the state it produced).
            let mut b = Vec::new();
            if t > 0 {
                let prev_m = prev.eq.len() + prev.ineq.len();
                b = vec![0.0; m * prev_m];
                for r in 0..m {
                    if local[r].first().is_none_or(|&(lc, _)| lc >= ds) {
                        continue;
                    }
                    for s in 0..prev_m {
                        let ps = &jrow(&prev, s, width)[ds..ds + ds];
                        let mut acc = 0.0;
                        for &(lc, v) in &local[r] {
                            if lc < ds {
                                acc += v * ps[lc];
                            } else {
                                break;
                            }
                        }
                        b[r * prev_m + s] = acc;
                    }
                }
            }
            sizes.push(m);
            diag.push(d);
            sub.push(b);
            std::mem::swap(&mut prev, &mut cur);
        }
        let factor = BlockTriFactor::factor(sizes, diag, sub);
        Self {
            dim_x,
            dim: dim_x + layout.n_slack,
            values,
            raw_ineq,
            ptr,
            cols,
            vals,
            slack,
            factor,
        }
    }

    /// Augmented dimension (trajectory plus slacks).
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Dimension of the trajectory part.
    pub fn dim_x(&self) -> usize {
        self.dim_x
    }

    /// The combined constraint values.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The raw inequality values `h` (feasible when `≤ 0`).
    pub fn raw_inequalities(&self) -> &[f64] {
        &self.raw_ineq
    }

    /// `Σ|C|`, the constraint violation used in the penalty.
    pub fn violation(&self) -> f64 {
        self.values.iter().map(|v| v.abs()).sum()
    }

    /// How many pivots of the factorisation had to be raised (near-singular `∇C∇Cᵀ`).
    pub fn raised_pivots(&self) -> usize {
        self.factor.raised_pivots
    }

    /// `Y = ∇C V` for `k` vectors stored coordinate-major (`dim×k` in, rows×k out).
    fn jac_times(&self, v: &[f64], k: usize, y: &mut [f64]) {
        for r in 0..self.values.len() {
            let yr = &mut y[r * k..(r + 1) * k];
            yr.fill(0.0);
            for q in self.ptr[r]..self.ptr[r + 1] {
                let (c, a) = (self.cols[q] as usize, self.vals[q]);
                let vc = &v[c * k..(c + 1) * k];
                for j in 0..k {
                    yr[j] += a * vc[j];
                }
            }
            if let Some((c, zr)) = self.slack[r] {
                let vc = &v[c * k..(c + 1) * k];
                for j in 0..k {
                    yr[j] += zr * vc[j];
                }
            }
        }
    }

    /// `V ← V + s·∇Cᵀ Y`.
    fn add_jac_transpose_times(&self, y: &[f64], k: usize, s: f64, v: &mut [f64]) {
        for r in 0..self.values.len() {
            let yr = &y[r * k..(r + 1) * k];
            for q in self.ptr[r]..self.ptr[r + 1] {
                let (c, a) = (self.cols[q] as usize, s * self.vals[q]);
                let vc = &mut v[c * k..(c + 1) * k];
                for j in 0..k {
                    vc[j] += a * yr[j];
                }
            }
            if let Some((c, zr)) = self.slack[r] {
                let vc = &mut v[c * k..(c + 1) * k];
                let a = s * zr;
                for j in 0..k {
                    vc[j] += a * yr[j];
                }
            }
        }
    }

    /// Project `k` vectors (coordinate-major, `dim×k`) onto the tangent space of the
    /// constraints: `V ← (I − ∇Cᵀ(∇C∇Cᵀ)⁻¹∇C) V`. `scratch` is resized as needed.
    pub fn project(&self, v: &mut [f64], k: usize, scratch: &mut Vec<f64>) {
        scratch.resize(self.values.len() * k, 0.0);
        self.jac_times(v, k, scratch);
        self.factor.solve_in_place(scratch, k);
        self.add_jac_transpose_times(scratch, k, -1.0, v);
    }

    /// The Gauss–Newton (minimum-norm) constraint step `∇Cᵀ(∇C∇Cᵀ)⁻¹C` (`dim` entries).
    pub fn constraint_step(&self) -> Vec<f64> {
        let mut y = self.values.clone();
        self.factor.solve_in_place(&mut y, 1);
        let mut out = vec![0.0; self.dim];
        self.add_jac_transpose_times(&y, 1, 1.0, &mut out);
        out
    }
}
