//! `dips-host`: the std side of DIPS.

pub mod cli;
pub mod csvto;
pub mod execute;
pub mod geometry;
pub mod kinematics;
pub mod problems;
pub mod scenes;
pub mod world;
