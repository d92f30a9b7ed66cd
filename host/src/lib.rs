//! `dips-host`: the std side of DIPS.

pub mod atomic_write;
pub mod cli;
pub mod geometry;
pub mod hand;
pub mod kinematics;
pub mod render;
pub mod scenes;
pub mod world;
