//! Which constraint rows one step has, block by block, counted in one place: CSVTO's row
//! counts (`Problem::n_eq`, `n_ineq`) are this layout's totals, and
//! the fill (`constraints.rs`) writes each block at the offset given here (checked with
//! `debug_assert`s after each block, and over every task, mode and step in the tests).

use super::{AllegroProblem, PYRAMID_FACES};
use dips_world::scenes::SceneKind;

/// Equality rows of a contact finger: `sdf = 0` (1), rolling (2), joint impedance balance (4).
pub const CONTACT_EQ_ROWS: usize = 1 + 2 + 4;
/// Equality rows of a regrasping finger's free motion `q_{t+1} = q_t + Δq_t`.
pub const FREE_MOTION_ROWS: usize = 4;
/// Equality rows of a lifting finger's first step (its two rolling rows).
pub const LIFT_OFF_ROWS: usize = 2;
/// Inequality rows of a contact finger: the friction pyramid's faces and the minimum normal
/// force.
pub const CONTACT_INEQ_ROWS: usize = PYRAMID_FACES + 1;
/// Inequality rows of a regrasping finger before the last step: clearance where the step
/// leaves the object and where it found it.
pub const CLEARANCE_ROWS: usize = 2;

/// The row layout of one step: where each block of equality and inequality rows starts, and
/// the totals.
///
/// Equality rows, in order: each contact finger's [`CONTACT_EQ_ROWS`]; the object's rows
/// (wrench balance with a finger in contact, or holding still without one; then the pinned
/// coordinates); each regrasping finger's [`FREE_MOTION_ROWS`]; at `t = 0` each lifting
/// finger's [`LIFT_OFF_ROWS`]; at the last step one `sdf = 0` row per regrasping finger.
/// Inequality rows: each contact finger's [`CONTACT_INEQ_ROWS`], then before the last step
/// each regrasping finger's [`CLEARANCE_ROWS`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepRows {
    /// First object row (after the contact fingers' rows).
    pub object: usize,
    /// Object rows: balance or hold, plus the pinned coordinates.
    pub object_len: usize,
    /// First free-motion row of the regrasping fingers.
    pub free_motion: usize,
    /// First lift-off row (`t = 0` only; none otherwise).
    pub lift_off: usize,
    /// First terminal-contact row (last step only; none otherwise).
    pub terminal: usize,
    /// Equality rows in all.
    pub eq: usize,
    /// First clearance row among the inequalities.
    pub clearance: usize,
    /// Inequality rows in all.
    pub ineq: usize,
}

/// The object's own equality rows: with a finger in contact the screwdriver's torque balance
/// about its pivot (3) or the card's force balance (3) and its table friction (1); without
/// one the pose holds still (3), and the card's table force carries its weight (3 more).
pub fn object_rows(task: SceneKind, any_contact: bool) -> usize {
    match (task, any_contact) {
        (SceneKind::Screwdriver, _) => 3,
        (SceneKind::Card, true) => 3 + 1,
        (SceneKind::Card, false) => 3 + 3,
    }
}

impl AllegroProblem {
    /// The row layout of step `t` (`0 ≤ t < H`).
    pub fn step_rows(&self, t: usize) -> StepRows {
        let regrasping = self.nf - self.nc;
        let lifting = self.lift_off.iter().filter(|&&l| l).count();
        let last = t + 1 == self.horizon;
        let object = CONTACT_EQ_ROWS * self.nc;
        let object_len = object_rows(self.task, self.nc > 0) + self.pinned;
        let free_motion = object + object_len;
        let lift_off = free_motion + FREE_MOTION_ROWS * regrasping;
        let terminal = lift_off + if t == 0 { LIFT_OFF_ROWS * lifting } else { 0 };
        let eq = terminal + if last { regrasping } else { 0 };
        let clearance = CONTACT_INEQ_ROWS * self.nc;
        let ineq = clearance + if last { 0 } else { CLEARANCE_ROWS * regrasping };
        StepRows {
            object,
            object_len,
            free_motion,
            lift_off,
            terminal,
            eq,
            clearance,
            ineq,
        }
    }
}
