//! Platform services the planner needs from outside: a monotonic clock for its time budget.
//!
//! The kernel has no clock of its own. The host passes one built on `std::time::Instant`, the
//! controller one built on its timer; a planner without a time budget can use [`NoClock`].

/// A monotonic clock.
pub trait Clock {
    /// Microseconds since an arbitrary fixed origin; never decreases.
    fn now_us(&mut self) -> u64;
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
}
