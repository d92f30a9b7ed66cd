//! The interface between CSVTO and a trajectory-optimisation problem.
//!
//! A trajectory has `H` rows of width `n` (`row_dim`). Row `t` is `[s_{t+1}, u_t]`: the state
//! reached after step `t` followed by the control applied at `s_t`; the start state `s_0` is
//! fixed and not a variable (spec `algorithms.md` §1.1). The first `ds` entries of a row are
//! its state. Constraints of step `t` may depend on the state `s_t` (the previous row's first
//! `ds` entries, or the start state at `t = 0`) and on row `t`: that is what makes the
//! constraint Jacobian block-bidiagonal in time and lets the solver factor `∇C∇Cᵀ` in time
//! linear in `H`.

/// Values and Jacobians of one step's constraints, filled by [`Problem::step_constraints`].
///
/// Jacobians are row-major with `ds + n` columns: the first `ds` columns are derivatives with
/// respect to the previous state `s_t`, the other `n` with respect to row `t`.
#[derive(Debug, Clone, Default)]
pub struct StepConstraints {
    /// Equality values `g` (to be driven to 0).
    pub eq: Vec<f64>,
    /// Inequality values `h` (feasible when `≤ 0`).
    pub ineq: Vec<f64>,
    /// `∂g/∂(s_t, row_t)`, `eq.len() × (ds + n)`.
    pub jac_eq: Vec<f64>,
    /// `∂h/∂(s_t, row_t)`, `ineq.len() × (ds + n)`.
    pub jac_ineq: Vec<f64>,
}

impl StepConstraints {
    /// Resize for `n_eq` equalities and `n_ineq` inequalities over `width` columns, zeroed.
    pub fn reset(&mut self, n_eq: usize, n_ineq: usize, width: usize) {
        self.eq.clear();
        self.eq.resize(n_eq, 0.0);
        self.ineq.clear();
        self.ineq.resize(n_ineq, 0.0);
        self.jac_eq.clear();
        self.jac_eq.resize(n_eq * width, 0.0);
        self.jac_ineq.clear();
        self.jac_ineq.resize(n_ineq * width, 0.0);
    }
}

/// A trajectory-optimisation problem for CSVTO.
pub trait Problem: Sync {
    /// Number of rows `H`.
    fn horizon(&self) -> usize;
    /// Width `n` of one row.
    fn row_dim(&self) -> usize;
    /// Width `ds` of the state at the start of each row.
    fn state_dim(&self) -> usize;
    /// The fixed start state `s_0` (`ds` entries).
    fn start_state(&self) -> &[f64];
    /// Number of equality constraints of step `t`.
    fn n_eq(&self, t: usize) -> usize;
    /// Number of inequality constraints of step `t`.
    fn n_ineq(&self, t: usize) -> usize;
    /// Evaluate step `t`'s constraints at previous state `prev` and row `row`. `out` has
    /// already been reset to the right sizes and zeroed.
    fn step_constraints(&self, t: usize, prev: &[f64], row: &[f64], out: &mut StepConstraints);
    /// Cost of the whole trajectory `x` (`H·n`, row-major); writes `∂J/∂x` into `grad`
    /// (same length, zeroed by the caller).
    fn cost(&self, x: &[f64], grad: &mut [f64]) -> f64;
    /// Project `x` onto the problem's bounds (box bounds and any bounds that depend on other
    /// variables, e.g. `q + Δq` inside the joint limits).
    fn clamp(&self, x: &mut [f64]);
}
