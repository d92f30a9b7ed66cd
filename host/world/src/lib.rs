//! `dips-world`: the quasi-static test world and everything it stands on.
//!
//! The Allegro hand's kinematics (`kinematics`, data in `host/data/`), collision geometry
//! (`geometry`), the two scenes (`scenes`), the Clarabel quasi-static world (`world`), the
//! `Hand` trait a planner drives (world or robot, with logs and replay: `hand`), what a world
//! state looks like (`render`). Nothing here knows about planning, CSVTO or training;
//! `dips-host` re-exports every module, so `dips_host::world::World` and
//! `dips_world::world::World` are the same type.

pub mod geometry;
pub mod hand;
pub mod kinematics;
pub mod render;
pub mod scenes;
pub mod world;
