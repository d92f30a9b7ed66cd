//! `dips-host`: the std side of DIPS.

pub mod execute;
pub mod online;
pub mod planning;
pub mod policy;
pub mod problems;
pub mod quality;

// The world and the generic solver are crates of their own (`dips-world`, `dips-csvto`); their
// modules are re-exported here so that `dips_host::world::World` and the like stay the paths.
pub use dips_csvto as csvto;
pub use dips_world::{geometry, hand, kinematics, render, scenes, world};
