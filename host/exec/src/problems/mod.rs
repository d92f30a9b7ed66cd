//! The Allegro contact trajectory-optimisation problems for CSVTO (spec `algorithms.md` §2).
//!
//! - [`mode`]: tasks' contact modes and their names (`docs/contracts.md` §2);
//! - [`dual`]: forward-mode dual numbers and generic 3-vectors for exact Jacobians;
//! - [`fk`]: finger kinematics over a generic scalar, built from the world's hand model;
//! - [`sdf`]: analytic sphere-to-object signed distances with normals;
//! - [`allegro`]: the per-mode problem (constraints, costs, bounds);
//! - [`init`]: the default particle initialisation;
//! - [`contract`]: conversion to and from the `docs/contracts.md` §2 trajectory layout.

pub mod allegro;
pub mod contract;
pub mod dual;
pub mod fk;
pub mod init;
pub mod mode;
pub mod sdf;

pub use allegro::{AllegroProblem, ProblemError, ProblemSpec};
pub use mode::Mode;

#[cfg(test)]
mod tests;
