//! [`Controller`]: the joint PD loop on its own thread, at the rate the hand streams its
//! poses. Each complete set of four pose frames is one tick: decode, filter, check the
//! limits, PD towards the reference, clamp, send the four SET_TORQUE frames. The reference
//! moves linearly from the last goal to the new one over each action ([`Controller::move_to`]).
//!
//! The loop owns the bus inside a guard (`ShutdownGuard`): whatever ends the loop (a [`Stop`], a
//! request, Ctrl-C, a panic in the loop, the [`Controller`] dropped during a panic elsewhere)
//! the guard sends zero torques, `SYSTEM_OFF` and `SET_PERIOD {0, 0, 0}` before the thread
//! ends.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use dips_allegro_protocol::message::Request;
use dips_allegro_protocol::scale::counts_to_radians;
use dips_allegro_protocol::{CanFrame, DeviceId, HandInfo, HandReply, HostCommand, Periods};
use dips_world::kinematics::{Finger, HandJoints, HandModel};
use nalgebra::Isometry3;

use crate::bus::CanBus;
use crate::filter::JointFilter;
use crate::gains::PdGains;
use crate::gravity::gravity_pwm;
use crate::safety::{RunningLoop, SafetyLimits, Stop, interrupt_requested};
use crate::stats::{Intervals, LoopStats};

/// How the controller runs.
#[derive(Debug, Clone)]
pub struct ControllerConfig {
    /// The hand's device id.
    pub device: DeviceId,
    /// Gains and clamps.
    pub gains: PdGains,
    /// Limits.
    pub limits: SafetyLimits,
    /// The pose stream's period (ms); the vendor's drivers ask for 3.
    pub period_ms: u16,
    /// The hand's kinematic model: joint limits, gravity compensation.
    pub hand: HandModel,
    /// The hand base's pose in the world (gravity's direction in the hand).
    pub base: Isometry3<f64>,
    /// What a fault does once the torques are zero.
    pub on_fault: OnFault,
}

/// What a fault stop (anything but a requested stop) does after the shutdown frames.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum OnFault {
    /// Record it: the next call on the controller returns it (libraries, tests).
    #[default]
    Report,
    /// Also print it and end the process with [`EXIT_HAND_FAULT`], at once, whatever the
    /// program's other threads are doing (a planning call can take seconds): what the `dips`
    /// command line does, so that a hand fault ends the run within the watchdog's time.
    ExitProcess,
}

/// The exit code of a process ended by a hand fault ([`OnFault::ExitProcess`]).
pub const EXIT_HAND_FAULT: i32 = 3;

/// What the hand said at start-up.
#[derive(Debug, Clone, PartialEq)]
pub struct BringUp {
    /// `HAND_INFO`.
    pub info: HandInfo,
    /// The serial number, when it answered.
    pub serial: Option<[u8; 8]>,
}

/// A move of the reference: linear from `start` to `goal` over `duration` from `t0`.
#[derive(Debug, Clone, Copy)]
struct Segment {
    start: HandJoints,
    goal: HandJoints,
    t0: Instant,
    duration: Duration,
}

impl Segment {
    fn hold(q: HandJoints) -> Segment {
        Segment {
            start: q,
            goal: q,
            t0: Instant::now(),
            duration: Duration::ZERO,
        }
    }

    fn at(&self, now: Instant) -> HandJoints {
        let s = if self.duration.is_zero() {
            1.0
        } else {
            (now.saturating_duration_since(self.t0).as_secs_f64() / self.duration.as_secs_f64())
                .clamp(0.0, 1.0)
        };
        std::array::from_fn(|f| {
            std::array::from_fn(|j| self.start[f][j] + s * (self.goal[f][j] - self.start[f][j]))
        })
    }
}

#[derive(Debug)]
enum Phase {
    Starting,
    Running,
    Stopped(Stop),
}

#[derive(Debug)]
struct State {
    phase: Phase,
    bring_up: Option<BringUp>,
    measured: HandJoints,
    filtered: HandJoints,
    reference: Segment,
    last_pwm: [[i16; 4]; 4],
    temperatures: [[Option<u8>; 4]; 4],
    stats: LoopStats,
    intervals: Intervals,
}

#[derive(Debug)]
struct Shared {
    state: Mutex<State>,
    changed: Condvar,
    stop: AtomicBool,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic while holding the lock poisons it; the state is still what was last
        // written, which is all a stop needs.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// The running controller. Dropping it stops the loop and zeroes the torques.
#[derive(Debug)]
pub struct Controller {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl Controller {
    /// Start the loop on `bus`: flush, `SYSTEM_OFF`, `HAND_INFO` and `SERIAL` requests,
    /// `SET_PERIOD {period, 0, 0}`, `SYSTEM_ON`, then hold the joints where the first pose
    /// set finds them. Returns once the loop runs, or the [`Stop`] that ended start-up.
    pub fn start(bus: Box<dyn CanBus>, config: ControllerConfig) -> Result<Controller, Stop> {
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                phase: Phase::Starting,
                bring_up: None,
                measured: [[0.0; 4]; 4],
                filtered: [[0.0; 4]; 4],
                reference: Segment::hold([[0.0; 4]; 4]),
                last_pwm: [[0; 4]; 4],
                temperatures: [[None; 4]; 4],
                stats: LoopStats::default(),
                intervals: Intervals::default(),
            }),
            changed: Condvar::new(),
            stop: AtomicBool::new(false),
        });
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("allegro-pd".into())
            .spawn(move || run(bus, config, s))
            .map_err(|e| Stop::Bus(format!("cannot start the control thread: {e}")))?;
        let controller = Controller {
            shared,
            thread: Some(thread),
        };
        let mut st = controller.shared.lock();
        while matches!(st.phase, Phase::Starting) {
            st = controller
                .shared
                .changed
                .wait(st)
                .unwrap_or_else(|p| p.into_inner());
        }
        if let Phase::Stopped(stop) = &st.phase {
            let stop = stop.clone();
            drop(st);
            return Err(stop);
        }
        drop(st);
        Ok(controller)
    }

    /// What the hand said at start-up.
    pub fn bring_up(&self) -> Option<BringUp> {
        self.shared.lock().bring_up.clone()
    }

    /// The last measured joint positions (encoder, unfiltered).
    pub fn joints(&self) -> HandJoints {
        self.shared.lock().measured
    }

    /// The last filtered joint positions.
    pub fn filtered_joints(&self) -> HandJoints {
        self.shared.lock().filtered
    }

    /// The reference now.
    pub fn reference(&self) -> HandJoints {
        self.shared.lock().reference.at(Instant::now())
    }

    /// The goal of the current move (the last target).
    pub fn goal(&self) -> HandJoints {
        self.shared.lock().reference.goal
    }

    /// The last PWM sent per joint.
    pub fn last_pwm(&self) -> [[i16; 4]; 4] {
        self.shared.lock().last_pwm
    }

    /// The last temperatures read per joint (°C).
    pub fn temperatures(&self) -> [[Option<u8>; 4]; 4] {
        self.shared.lock().temperatures
    }

    /// Frame counts and period statistics so far.
    pub fn stats(&self) -> LoopStats {
        let st = self.shared.lock();
        let mut s = st.stats.clone();
        s.period = st.intervals.stats(s.pose_sets);
        s
    }

    /// Why the loop stopped, once it has.
    pub fn stopped(&self) -> Option<Stop> {
        match &self.shared.lock().phase {
            Phase::Stopped(s) => Some(s.clone()),
            _ => None,
        }
    }

    /// Move the reference from the last goal to `goal` (clamped to the joint limits) over
    /// `duration`, starting now. Returns at once; [`Controller::wait_until`] waits.
    pub fn move_to(&self, goal: &HandJoints, hand: &HandModel, duration: Duration) {
        let goal = Finger::ALL.map(|f| hand.clamp_to_limits(f, &goal[f.index()]));
        let mut st = self.shared.lock();
        let start = st.reference.goal;
        st.reference = Segment {
            start,
            goal,
            t0: Instant::now(),
            duration,
        };
    }

    /// Wait until `deadline`, or until the loop stops (its [`Stop`] is the error).
    pub fn wait_until(&self, deadline: Instant) -> Result<(), Stop> {
        let mut st = self.shared.lock();
        loop {
            if let Phase::Stopped(s) = &st.phase {
                return Err(s.clone());
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(());
            }
            st = self
                .shared
                .changed
                .wait_timeout(st, deadline - now)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    /// Stop the loop (zero torques, servo off, streaming stopped) and wait for it. Returns
    /// why it stopped ([`Stop::Requested`] unless something stopped it before).
    pub fn stop(mut self) -> Stop {
        self.stop_and_join(false)
    }

    fn stop_and_join(&mut self, panicking: bool) -> Stop {
        self.shared.stop.store(true, Ordering::SeqCst);
        if panicking {
            let mut st = self.shared.lock();
            if !matches!(st.phase, Phase::Stopped(_)) {
                st.phase = Phase::Stopped(Stop::ProgramError("a thread panicked".into()));
            }
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.stopped().unwrap_or(Stop::Requested)
    }
}

impl Drop for Controller {
    fn drop(&mut self) {
        self.stop_and_join(std::thread::panicking());
    }
}

/// Owns the bus; on drop (every way out of the loop) sends the shutdown frames.
struct ShutdownGuard {
    bus: Box<dyn CanBus>,
    device: DeviceId,
    done: bool,
    sent: u64,
    torque_frames: u64,
}

impl ShutdownGuard {
    fn send(&mut self, cmd: HostCommand) -> Result<(), Stop> {
        let frame: CanFrame = cmd
            .to_frame(self.device)
            .ok_or_else(|| Stop::Bus("a frame could not be built".into()))?;
        self.bus
            .send(&frame)
            .map_err(|e| Stop::Bus(e.to_string()))?;
        self.sent += 1;
        if matches!(cmd, HostCommand::SetTorque { .. }) {
            self.torque_frames += 1;
        }
        Ok(())
    }

    /// Zero torques, servo off, streaming stopped; every frame tried even if one fails.
    fn shutdown(&mut self) {
        if self.done {
            return;
        }
        self.done = true;
        for finger in 0..4 {
            let _ = self.send(HostCommand::SetTorque {
                finger,
                pwm: [0; 4],
            });
        }
        let _ = self.send(HostCommand::SystemOff);
        let _ = self.send(HostCommand::SetPeriod(Periods::STOPPED));
    }
}

impl Drop for ShutdownGuard {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn run(bus: Box<dyn CanBus>, config: ControllerConfig, shared: Arc<Shared>) {
    let _running = RunningLoop::enter();
    shared.lock().stats.scheduling = crate::realtime::make_realtime(crate::realtime::LOOP_PRIORITY);
    let mut guard = ShutdownGuard {
        bus,
        device: config.device,
        done: false,
        sent: 0,
        torque_frames: 0,
    };
    let outcome = catch_unwind(AssertUnwindSafe(|| {
        Loop::new(&config, &shared).run(&mut guard)
    }));
    let stop = match outcome {
        Ok(stop) => stop,
        Err(panic) => Stop::Panicked(
            panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into()),
        ),
    };
    guard.shutdown();
    let fault = !matches!(stop, Stop::Requested | Stop::ProgramError(_));
    if fault && config.on_fault == OnFault::ExitProcess {
        eprintln!("error: allegro hand: {stop}");
        std::process::exit(EXIT_HAND_FAULT);
    }
    let mut st = shared.lock();
    st.stats.frames_sent = guard.sent;
    st.stats.torque_frames = guard.torque_frames;
    if !matches!(st.phase, Phase::Stopped(_)) {
        st.phase = Phase::Stopped(stop);
    }
    drop(st);
    shared.changed.notify_all();
}

/// The loop's own state, on its thread.
struct Loop<'a> {
    config: &'a ControllerConfig,
    shared: &'a Shared,
    counts: [[i16; 4]; 4],
    mask: u8,
    filter: Option<JointFilter>,
    last_tick: Option<Instant>,
    next_poll: Instant,
}

impl<'a> Loop<'a> {
    fn new(config: &'a ControllerConfig, shared: &'a Shared) -> Loop<'a> {
        Loop {
            config,
            shared,
            counts: [[0; 4]; 4],
            mask: 0,
            filter: None,
            last_tick: None,
            next_poll: Instant::now(),
        }
    }

    fn period(&self) -> Duration {
        Duration::from_millis(u64::from(self.config.period_ms.max(1)))
    }

    fn run(&mut self, guard: &mut ShutdownGuard) -> Stop {
        match self.start_up(guard) {
            Ok(()) => {}
            Err(stop) => return stop,
        }
        loop {
            if let Err(stop) = self.step(guard) {
                return stop;
            }
        }
    }

    fn no_hand(&self, guard: &ShutdownGuard, what: &'static str) -> Stop {
        Stop::NoHand {
            bus: guard.bus.name().to_string(),
            what,
            waited_ms: self.config.limits.startup_timeout.as_millis() as u64,
            device: self.config.device.get(),
        }
    }

    fn start_up(&mut self, guard: &mut ShutdownGuard) -> Result<(), Stop> {
        guard.bus.flush().map_err(|e| Stop::Bus(e.to_string()))?;
        guard.send(HostCommand::SystemOff)?;
        guard.send(HostCommand::Request(Request::HandInfo))?;
        guard.send(HostCommand::Request(Request::Serial))?;
        let deadline = Instant::now() + self.config.limits.startup_timeout;
        let mut info = None;
        let mut serial = None;
        while info.is_none() || (serial.is_none() && Instant::now() < deadline) {
            let Some(reply) = self.receive_until(guard, deadline)? else {
                if info.is_none() {
                    return Err(self.no_hand(guard, "HAND_INFO reply"));
                }
                break;
            };
            match reply {
                HandReply::HandInfo(i) => info = Some(i),
                HandReply::Serial(s) => serial = Some(s),
                _ => {}
            }
            if info.is_some() && serial.is_some() {
                break;
            }
        }
        let Some(info) = info else {
            return Err(self.no_hand(guard, "HAND_INFO reply"));
        };
        self.check_hand_status(&info)?;
        self.shared.lock().bring_up = Some(BringUp { info, serial });
        guard.send(HostCommand::SetPeriod(Periods {
            position_ms: self.config.period_ms,
            ..Periods::STOPPED
        }))?;
        guard.send(HostCommand::SystemOn)?;
        let deadline = Instant::now() + self.config.limits.startup_timeout;
        while self.mask != 0xF {
            if self.receive_until(guard, deadline)?.is_none() {
                return Err(self.no_hand(guard, "first pose set"));
            }
        }
        let q = self.joints_of_counts();
        {
            let mut st = self.shared.lock();
            st.measured = q;
            st.filtered = q;
            st.reference = Segment::hold(q);
            st.phase = Phase::Running;
        }
        self.shared.changed.notify_all();
        self.tick(guard, Instant::now())
    }

    /// Receive frames until one decodes as a reply of our device, or the deadline passes.
    fn receive_until(
        &mut self,
        guard: &mut ShutdownGuard,
        deadline: Instant,
    ) -> Result<Option<HandReply>, Stop> {
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            if let Some(r) = self.receive(guard, deadline - now)? {
                return Ok(Some(r));
            }
        }
    }

    /// One frame (or none within `timeout`), counted; pose frames fill the set.
    fn receive(
        &mut self,
        guard: &mut ShutdownGuard,
        timeout: Duration,
    ) -> Result<Option<HandReply>, Stop> {
        let Some(frame) = guard
            .bus
            .recv(timeout)
            .map_err(|e| Stop::Bus(e.to_string()))?
        else {
            return Ok(None);
        };
        let mut st = self.shared.lock();
        st.stats.frames_received += 1;
        match HandReply::from_frame(&frame) {
            Ok((reply, device)) if device == self.config.device => {
                drop(st);
                match reply {
                    HandReply::FingerPose { finger, counts } => {
                        let f = usize::from(finger & 3);
                        self.counts[f] = counts;
                        self.mask |= 1 << f;
                    }
                    HandReply::Temperature { finger, celsius } => {
                        self.check_temperatures(usize::from(finger & 3), celsius)?;
                    }
                    HandReply::HandInfo(info) => self.check_hand_status(&info)?,
                    _ => {}
                }
                Ok(Some(reply))
            }
            Ok(_) => {
                st.stats.ignored_frames += 1;
                Ok(None)
            }
            Err(_) => {
                st.stats.bad_frames += 1;
                Ok(None)
            }
        }
    }

    fn check_hand_status(&self, info: &HandInfo) -> Result<(), Stop> {
        if info.status.high_temperature() {
            return Err(Stop::Temperature {
                what: "hand status (high-temperature bit)".into(),
                celsius: info.temperature_c,
                limit: self.config.limits.max_temperature_c,
            });
        }
        Ok(())
    }

    fn check_temperatures(&self, finger: usize, celsius: [u8; 4]) -> Result<(), Stop> {
        let limit = self.config.limits.max_temperature_c;
        self.shared.lock().temperatures[finger] = celsius.map(Some);
        for (j, c) in celsius.iter().enumerate() {
            if *c >= limit {
                return Err(Stop::Temperature {
                    what: format!("{} joint {j}", Finger::ALL[finger].name()),
                    celsius: *c,
                    limit,
                });
            }
        }
        Ok(())
    }

    fn joints_of_counts(&self) -> HandJoints {
        self.counts.map(|f| f.map(counts_to_radians))
    }

    /// One pass: stop requests, a frame, a tick when the set is complete, the watchdog, the
    /// temperature poll.
    fn step(&mut self, guard: &mut ShutdownGuard) -> Result<(), Stop> {
        if self.shared.stop.load(Ordering::SeqCst) {
            return Err(Stop::Requested);
        }
        if interrupt_requested() {
            return Err(Stop::Interrupted);
        }
        let limit = self.period() * self.config.limits.watchdog_periods.max(1);
        let last = self.last_tick.unwrap_or_else(Instant::now);
        let now = Instant::now();
        let watchdog_at = last + limit;
        let wait = watchdog_at
            .min(self.next_poll)
            .saturating_duration_since(now)
            .min(self.period());
        self.receive(guard, wait)?;
        let now = Instant::now();
        if self.mask == 0xF {
            self.tick(guard, now)?;
        } else if now > watchdog_at {
            return Err(Stop::Watchdog {
                silent_ms: now.duration_since(last).as_secs_f64() * 1e3,
                periods: self.config.limits.watchdog_periods,
                period_ms: self.config.period_ms,
            });
        }
        if now >= self.next_poll {
            for f in 0..4 {
                guard.send(HostCommand::Request(Request::Temperature(f)))?;
            }
            guard.send(HostCommand::Request(Request::HandInfo))?;
            self.next_poll = now + self.config.limits.temperature_poll;
        }
        Ok(())
    }

    /// A complete pose set: filter, limits, PD, four SET_TORQUE frames.
    fn tick(&mut self, guard: &mut ShutdownGuard, now: Instant) -> Result<(), Stop> {
        self.mask = 0;
        let q = self.joints_of_counts();
        let dt = self
            .last_tick
            .map(|t| now.duration_since(t).as_secs_f64())
            .unwrap_or(f64::from(self.config.period_ms) * 1e-3);
        let filter = self.filter.get_or_insert_with(|| JointFilter::new(q));
        filter.update(&q, dt);
        let (qf, vf) = (*filter.position(), *filter.velocity());
        self.check_joint_limits(&q)?;
        let reference = self.shared.lock().reference.at(now);
        let gravity = if self.config.gains.gravity_compensation {
            gravity_pwm(&self.config.hand, &self.config.base, &qf)
        } else {
            [[0.0; 4]; 4]
        };
        let gains = &self.config.gains;
        let mut pwm = [[0i16; 4]; 4];
        let mut saturated = false;
        for f in 0..4 {
            for j in 0..4 {
                let raw = gains.pd(f, j, reference[f][j] - qf[f][j], vf[f][j]) + gravity[f][j];
                let clamped = gains.clamp(f, j, raw);
                saturated |= clamped != raw;
                pwm[f][j] = clamped.round() as i16;
            }
        }
        for (f, p) in pwm.iter().enumerate() {
            guard.send(HostCommand::SetTorque {
                finger: f as u8,
                pwm: *p,
            })?;
        }
        let mut st = self.shared.lock();
        if let Some(last) = self.last_tick {
            st.intervals
                .push(now.duration_since(last).as_secs_f64() * 1e3);
        }
        st.stats.pose_sets += 1;
        st.stats.saturated_ticks += u64::from(saturated);
        st.stats.frames_sent = guard.sent;
        st.stats.torque_frames = guard.torque_frames;
        st.measured = q;
        st.filtered = qf;
        st.last_pwm = pwm;
        drop(st);
        self.last_tick = Some(now);
        Ok(())
    }

    fn check_joint_limits(&self, q: &HandJoints) -> Result<(), Stop> {
        let margin = self.config.limits.joint_margin_rad;
        for f in Finger::ALL {
            for (j, (lo, hi)) in self.config.hand.joint_limits(f).into_iter().enumerate() {
                let p = q[f.index()][j];
                if p < lo - margin || p > hi + margin {
                    return Err(Stop::JointLimit {
                        finger: f.name(),
                        joint: j,
                        position: p,
                        lo,
                        hi,
                        margin,
                    });
                }
            }
        }
        Ok(())
    }
}
