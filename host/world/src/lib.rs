//! `dips-world`: the quasi-static test world and everything it stands on.
//!
//! The Allegro hand's kinematics (`kinematics`, data in `host/data/`), collision geometry
//! (`geometry`), the two scenes (`scenes`), the Clarabel quasi-static world (`world`), the
//! `Hand` trait a planner drives (world or robot, with logs and replay: `hand`). Nothing here
//! knows about planning, CSVTO, training or pictures (what a world state looks like is
//! `dips_report::render`).

pub mod geometry;
pub mod hand;
pub mod kinematics;
pub mod scenes;
pub mod world;
