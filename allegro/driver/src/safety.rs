//! What stops the hand, and why ([`Stop`]); the limits that stop it ([`SafetyLimits`]); the
//! process-wide interrupt ([`interrupt_requested`], set by Ctrl-C once
//! [`install_interrupt_handler`] ran). Whatever stops the controller, its loop sends zero
//! torques, `SYSTEM_OFF` and `SET_PERIOD {0, 0, 0}` on the way out.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

use serde::{Deserialize, Serialize};

/// The limits the controller enforces.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SafetyLimits {
    /// Stop when no complete pose set came for this many stream periods (10: 30 ms at 3 ms).
    pub watchdog_periods: u32,
    /// How long start-up waits for the hand's `HAND_INFO` reply and its first poses.
    pub startup_timeout: Duration,
    /// Stop when a measured joint is this far outside its limit (rad). Targets are clamped
    /// to the limits, so only a fault or an outside push gets there.
    pub joint_margin_rad: f64,
    /// Stop when a joint's temperature reaches this (°C), or the hand's high-temperature bit
    /// is set.
    pub max_temperature_c: u8,
    /// How often the temperatures are asked for (the vendor's ROS 2 driver: 500 ms).
    pub temperature_poll: Duration,
}

impl Default for SafetyLimits {
    fn default() -> SafetyLimits {
        SafetyLimits {
            watchdog_periods: 10,
            startup_timeout: Duration::from_secs(1),
            joint_margin_rad: 0.2,
            max_temperature_c: 70,
            temperature_poll: Duration::from_millis(500),
        }
    }
}

/// Why the controller stopped the hand. Every stop zeroes the torques first.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Stop {
    /// No complete set of four pose frames for too long.
    #[error(
        "watchdog: no complete pose set from the hand for {silent_ms:.1} ms ({periods} periods \
         of {period_ms} ms); torques zeroed, servo off"
    )]
    Watchdog {
        /// How long the hand was silent.
        silent_ms: f64,
        /// The limit in periods.
        periods: u32,
        /// The stream period.
        period_ms: u16,
    },
    /// Start-up got no answer.
    #[error(
        "no Allegro hand answered on {bus} within {waited_ms} ms ({what}); is it powered, \
         the bus at 1 Mbit/s, the device id {device}?"
    )]
    NoHand {
        /// The bus.
        bus: String,
        /// What was waited for.
        what: &'static str,
        /// How long.
        waited_ms: u64,
        /// The device id asked.
        device: u8,
    },
    /// A joint beyond its limit.
    #[error(
        "joint limit: {finger} joint {joint} at {position:.3} rad, beyond [{lo:.3}, {hi:.3}] by \
         more than {margin} rad; torques zeroed, servo off"
    )]
    JointLimit {
        /// Finger name.
        finger: &'static str,
        /// Joint 0–3.
        joint: usize,
        /// Measured position.
        position: f64,
        /// Lower limit.
        lo: f64,
        /// Upper limit.
        hi: f64,
        /// The margin allowed.
        margin: f64,
    },
    /// A joint too hot, or the hand's own high-temperature bit.
    #[error("temperature: {what} at {celsius} °C (limit {limit} °C); torques zeroed, servo off")]
    Temperature {
        /// Which joint, or `hand status`.
        what: String,
        /// The reading.
        celsius: u8,
        /// The limit.
        limit: u8,
    },
    /// The bus failed.
    #[error("CAN bus: {0}; torques zeroed where the bus still took them")]
    Bus(String),
    /// A stop was asked for (the hand was closed).
    #[error("stopped on request; torques zeroed, servo off")]
    Requested,
    /// Ctrl-C (SIGINT) or SIGTERM.
    #[error("interrupted (Ctrl-C); torques zeroed, servo off")]
    Interrupted,
    /// The control loop's thread panicked; its guard zeroed the torques while unwinding.
    #[error("the control loop panicked ({0}); torques zeroed, servo off")]
    Panicked(String),
    /// An error elsewhere in the program stopped the hand (another thread panicked, the
    /// episode failed).
    #[error("stopped by an error in the program: {0}; torques zeroed, servo off")]
    ProgramError(String),
}

static INTERRUPTED: AtomicBool = AtomicBool::new(false);
static RUNNING: AtomicUsize = AtomicUsize::new(0);
static HANDLER: OnceLock<Result<(), String>> = OnceLock::new();

/// Whether Ctrl-C was pressed since the handler was installed.
pub fn interrupt_requested() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// Count of control loops running now (what the interrupt handler waits for).
pub fn running_loops() -> usize {
    RUNNING.load(Ordering::SeqCst)
}

/// A running loop, counted while it lives.
#[derive(Debug)]
pub(crate) struct RunningLoop;

impl RunningLoop {
    pub(crate) fn enter() -> RunningLoop {
        RUNNING.fetch_add(1, Ordering::SeqCst);
        RunningLoop
    }
}

impl Drop for RunningLoop {
    fn drop(&mut self) {
        RUNNING.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Install the Ctrl-C (and SIGTERM) handler once per process: it asks every control loop to
/// stop, waits up to a second for them to zero their torques, and exits with 130. Later
/// calls return the first call's outcome.
pub fn install_interrupt_handler() -> Result<(), String> {
    HANDLER
        .get_or_init(|| {
            ctrlc::set_handler(|| {
                INTERRUPTED.store(true, Ordering::SeqCst);
                let deadline = std::time::Instant::now() + Duration::from_secs(1);
                while running_loops() > 0 && std::time::Instant::now() < deadline {
                    std::thread::sleep(Duration::from_millis(2));
                }
                eprintln!("dips: interrupted; the hand's torques are zero and its servo off");
                std::process::exit(130);
            })
            .map_err(|e| e.to_string())
        })
        .clone()
}
