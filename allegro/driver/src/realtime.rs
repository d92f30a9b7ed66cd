//! Real-time scheduling of the driver's threads: the control loop asks for `SCHED_FIFO` at
//! [`LOOP_PRIORITY`] (the emulated hand's firmware one below), as a real-time driver should:
//! a tick late by more than the watchdog's 30 ms is a stop, and under load (CSVTO and the
//! planner on every core) a normal thread can wait that long. It needs root or
//! `CAP_SYS_NICE` (`setcap cap_sys_nice+ep target/release/dips`, or an rtprio limit in
//! `/etc/security/limits.conf`); without them the thread stays normal and the loop's
//! statistics say so.

use thread_priority::{
    RealtimeThreadSchedulePolicy, ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
    set_thread_priority_and_policy, thread_native_id,
};

/// The control loop's `SCHED_FIFO` priority (1–99).
pub const LOOP_PRIORITY: u8 = 80;
/// The emulated hand's firmware thread's.
pub const EMULATOR_PRIORITY: u8 = 79;

/// Ask for `SCHED_FIFO` at `priority` for the calling thread: how it is scheduled, as the
/// loop's statistics record it (`fifo:80`, or `normal (why)`).
pub fn make_realtime(priority: u8) -> String {
    let value = match ThreadPriorityValue::try_from(priority.clamp(1, 99)) {
        Ok(v) => v,
        Err(e) => return format!("normal ({e})"),
    };
    match set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    ) {
        Ok(()) => format!("fifo:{priority}"),
        Err(e) => format!("normal ({e:?})"),
    }
}
