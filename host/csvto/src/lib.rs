//! Constrained Stein variational trajectory optimisation (CSVTO), generic over a
//! [`Problem`] (spec `algorithms.md` §1).
//!
//! - [`problem`]: the problem trait (per-step constraints with Jacobians, cost, bounds);
//! - [`blocktri`]: block-tridiagonal Cholesky of `∇C∇Cᵀ`, linear in the horizon;
//! - [`linearization`]: squared slack, the tangent-space projector and Gauss–Newton step;
//! - [`kernel`]: the RBF kernel with the median bandwidth;
//! - [`solver`]: the iteration (γ annealing, clipping, bounds, final sort by penalty);
//! - [`resample`]: penalty-weighted resampling with tangent-space noise.

pub mod blocktri;
pub mod kernel;
pub mod linearization;
pub mod problem;
pub mod resample;
pub mod solver;

pub use problem::{Problem, StepConstraints};
pub use solver::{CsvtoError, CsvtoSettings, SolveReport, solve};

#[cfg(test)]
mod tests;
