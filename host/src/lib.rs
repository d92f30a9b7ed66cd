//! `dips-host`: the std side of DIPS.

pub mod cli;
pub mod csvto;
