//! Platform services the planner needs from outside: a monotonic clock for its time budget,
//! and a way to be told to stop.
//!
//! The kernel has no clock of its own. The host passes one built on `std::time::Instant`, the
//! controller one built on its timer; a planner without a time budget can use [`NoClock`].
//! The planner asks the same object, before every expansion, whether it has been cancelled:
//! a firmware answers from its link (a `Cancel` frame), a host from a flag.

/// A monotonic clock, and the planner's cancellation point.
pub trait Clock {
    /// Microseconds since an arbitrary fixed origin; never decreases.
    fn now_us(&mut self) -> u64;

    /// Whether the running plan should stop now (asked before every expansion, right after
    /// [`Self::now_us`]); the plan then ends with the best node so far. Never, by default.
    fn cancelled(&mut self) -> bool {
        false
    }
}

/// A clock that never advances: time budgets never expire and elapsed times read zero.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoClock;

impl Clock for NoClock {
    fn now_us(&mut self) -> u64 {
        0
    }
}

impl<C: Clock + ?Sized> Clock for &mut C {
    fn now_us(&mut self) -> u64 {
        (**self).now_us()
    }

    fn cancelled(&mut self) -> bool {
        (**self).cancelled()
    }
}
