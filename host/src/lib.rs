//! `dips-host`: the std side of DIPS.

pub mod atomic_write;
pub mod csvto;
pub mod execute;
pub mod geometry;
pub mod hand;
pub mod kinematics;
pub mod online;
pub mod planning;
pub mod policy;
pub mod problems;
pub mod quality;
pub mod render;
pub mod scenes;
pub mod world;
