//! Solver tests on small problems with known solutions.

use super::linearization::{Layout, Linearization, initial_slack};
use super::problem::{Problem, StepConstraints};
use super::solver::{CsvtoSettings, solve};

/// `min Σ_t ‖x_t − a‖²` s.t. `x_t,0 + x_t,1 = 1` and (optionally) `x_t,0 − x_{t−1},0 ≤ 0.1`,
/// from the start `(0, 1)`. Without the inequality the optimum is `(0.5, 0.5)` at every
/// step; with it, `x_t,0 = 0.1(t+1)`.
struct ToyQp {
    h: usize,
    with_ineq: bool,
    start: [f64; 2],
}

impl Problem for ToyQp {
    fn horizon(&self) -> usize {
        self.h
    }
    fn row_dim(&self) -> usize {
        2
    }
    fn state_dim(&self) -> usize {
        2
    }
    fn start_state(&self) -> &[f64] {
        &self.start
    }
    fn n_eq(&self, _t: usize) -> usize {
        1
    }
    fn n_ineq(&self, _t: usize) -> usize {
        usize::from(self.with_ineq)
    }
    fn step_constraints(&self, _t: usize, prev: &[f64], row: &[f64], out: &mut StepConstraints) {
        // Columns: prev (2), row (2).
        out.eq[0] = row[0] + row[1] - 1.0;
        out.jac_eq[2] = 1.0;
        out.jac_eq[3] = 1.0;
        if self.with_ineq {
            out.ineq[0] = row[0] - prev[0] - 0.1;
            out.jac_ineq[0] = -1.0;
            out.jac_ineq[2] = 1.0;
        }
    }
    fn cost(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        let mut j = 0.0;
        for (v, g) in x.iter().zip(grad.iter_mut()) {
            j += (v - 1.0) * (v - 1.0);
            *g = 2.0 * (v - 1.0);
        }
        j
    }
    fn clamp(&self, x: &mut [f64]) {
        for v in x.iter_mut() {
            *v = v.clamp(-5.0, 5.0);
        }
    }
}

fn settings() -> CsvtoSettings {
    CsvtoSettings {
        alpha_j: 1.0,
        alpha_c: 1.0,
        step_size: 0.1,
        ..CsvtoSettings::default()
    }
}

#[test]
fn equality_qp_converges_to_constrained_optimum() {
    let p = ToyQp {
        h: 4,
        with_ineq: false,
        start: [0.0, 1.0],
    };
    let mut parts = vec![vec![0.3, -0.2, 0.9, 0.0, -0.4, 0.7, 0.1, 0.1]];
    let rep = solve(&p, &mut parts, 300, &settings()).unwrap();
    for t in 0..4 {
        assert!((parts[0][2 * t] - 0.5).abs() < 1e-3, "{:?}", parts[0]);
        assert!((parts[0][2 * t + 1] - 0.5).abs() < 1e-3, "{:?}", parts[0]);
    }
    assert!(rep.max_eq_violation[0] < 1e-6);
}

#[test]
fn inequalities_are_respected_at_the_optimum() {
    let p = ToyQp {
        h: 3,
        with_ineq: true,
        start: [0.0, 1.0],
    };
    let mut parts = vec![vec![0.0, 1.0, 0.0, 1.0, 0.0, 1.0]];
    let rep = solve(&p, &mut parts, 400, &settings()).unwrap();
    for t in 0..3 {
        let want = 0.1 * (t as f64 + 1.0);
        assert!(
            (parts[0][2 * t] - want).abs() < 5e-3,
            "t={t}: {:?}",
            parts[0]
        );
    }
    assert!(rep.max_ineq_violation[0] < 1e-3, "{rep:?}");
    assert!(rep.max_eq_violation[0] < 1e-5, "{rep:?}");
}

#[test]
fn particles_stay_feasible_and_spread_and_sort_by_penalty() {
    let p = ToyQp {
        h: 3,
        with_ineq: false,
        start: [0.0, 1.0],
    };
    let mut parts: Vec<Vec<f64>> = (0..6)
        .map(|i| {
            (0..6)
                .map(|c| ((i * 7 + c * 3) % 5) as f64 * 0.3 - 0.5)
                .collect()
        })
        .collect();
    let rep = solve(&p, &mut parts, 200, &settings()).unwrap();
    for x in &parts {
        for t in 0..3 {
            assert!((x[2 * t] + x[2 * t + 1] - 1.0).abs() < 1e-6);
        }
    }
    // The particles approximate exp(−J) on the constraint: mean 0.5 along x_t,0 (the
    // repulsion spreads them with a standard deviation of about 0.5).
    for t in 0..3 {
        let mean = parts.iter().map(|x| x[2 * t]).sum::<f64>() / parts.len() as f64;
        assert!((mean - 0.5).abs() < 0.25, "t={t}: mean {mean}, {parts:?}");
    }
    assert!(rep.penalties.windows(2).all(|w| w[0] <= w[1]));
    let spread = parts
        .iter()
        .map(|x| (x[0] - parts[0][0]).abs())
        .fold(0.0, f64::max);
    assert!(spread > 1e-4, "repulsion should keep particles apart");
}

#[test]
fn projector_removes_constraint_normal_component() {
    let p = ToyQp {
        h: 3,
        with_ineq: true,
        start: [0.0, 1.0],
    };
    let x = vec![0.05, 0.95, 0.1, 0.9, 0.12, 0.88];
    let layout = Layout::of(&p);
    let z = initial_slack(&p, &layout, &x);
    let lin = Linearization::build(&p, &layout, &x, &z);
    let mut v: Vec<f64> = (0..lin.dim()).map(|i| (i as f64 * 0.7).sin()).collect();
    let mut scratch = Vec::new();
    lin.project(&mut v, 1, &mut scratch);
    // Projected direction is tangent: the equality rows are orthogonal to it.
    for t in 0..3 {
        assert!((v[2 * t] + v[2 * t + 1]).abs() < 1e-5, "{v:?}");
    }
    // Projection is idempotent.
    let mut w = v.clone();
    lin.project(&mut w, 1, &mut scratch);
    for (a, b) in v.iter().zip(&w) {
        assert!((a - b).abs() < 1e-5, "{v:?} vs {w:?}");
    }
}
