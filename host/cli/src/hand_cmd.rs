//! `dips hand info|monitor|home`: what a lab runs before any experiment with the Allegro
//! hand, on a real bus (`--hand allegro:can0`) or the emulated hand (`allegro:emulated`, the
//! default): the hand's information and serial, temperatures, live joint angles and the loop's
//! timing, and a slow move to a task's start pose. `--dry-run` prints every frame the driver
//! sends instead of opening the bus (the emulated hand answers). `dips hand emulate` runs the
//! emulated hand as a process of its own on a SocketCAN interface (`vcan0`), for a driver in
//! another process (or another program) to drive.

use std::time::{Duration, Instant};

use anyhow::Context;
use clap::{Args, Subcommand};
use dips_allegro::emu::{Emulator, EmulatorConfig};
use dips_allegro::hand::Connection;
use dips_world::hand::{
    AllegroBus, AllegroOptions, EmulatedPlant, EmulatorFault, GainsChoice, HandKind,
};
use dips_world::kinematics::{Finger, HandJoints, max_joint_difference};
use dips_world::scenes::SceneKind;
use dips_world::world::World;

use crate::hands::CliHands;

/// `dips hand`.
#[derive(Debug, Clone, Args)]
pub struct HandArgs {
    /// What to do.
    #[command(subcommand)]
    pub action: HandAction,
}

/// The bus flags every `dips hand` command takes.
#[derive(Debug, Clone, Args)]
pub struct BusArgs {
    /// The hand: `allegro:IFACE[,gains=vendor|paper|FILE]` (e.g. allegro:can0) or
    /// `allegro:emulated[,fault=…]`.
    #[arg(
        long,
        value_name = "allegro:IFACE[,…]",
        default_value = "allegro:emulated"
    )]
    pub hand: String,
    /// Print the frames the driver sends (candump's form) instead of opening the bus; the
    /// emulated hand answers.
    #[arg(long)]
    pub dry_run: bool,
}

/// The bring-up commands.
#[derive(Debug, Clone, Subcommand)]
pub enum HandAction {
    /// Hand information, serial number and temperatures, then servo off.
    Info(BusArgs),
    /// Live joint angles (degrees), temperatures and the loop's period, holding the joints
    /// where they are.
    Monitor {
        /// The bus.
        #[command(flatten)]
        bus: BusArgs,
        /// How long to watch (s).
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// Lines per second.
        #[arg(long, default_value_t = 4.0)]
        rate_hz: f64,
    },
    /// Move slowly to a task's start pose (at most 0.5 rad/s) and hold it for a second.
    Home {
        /// The bus.
        #[command(flatten)]
        bus: BusArgs,
        /// Whose start pose: `card` or `screwdriver`.
        #[arg(long, default_value = "card")]
        task: SceneKind,
    },
    /// Run the emulated hand on a SocketCAN interface until Ctrl-C (or `--seconds`): it
    /// answers the V4 protocol there as a hand would.
    Emulate {
        /// The interface (`vcan0`: `ip link add vcan0 type vcan; ip link set vcan0 up`).
        #[arg(long)]
        iface: String,
        /// The task scene the hand starts in.
        #[arg(long, default_value = "card")]
        task: SceneKind,
        /// What moves its joints: `joint-model` or `mujoco` (dips-mujoco).
        #[arg(long, default_value = "joint-model")]
        plant: EmulatedPlant,
        /// Faults to inject (`silence@T`, `garbage`, `hot@T`; repeatable).
        #[arg(long)]
        fault: Vec<EmulatorFault>,
        /// Stop after this long (s); default: until Ctrl-C.
        #[arg(long)]
        seconds: Option<f64>,
    },
}

impl HandArgs {
    /// The hand's options, `--dry-run` included (`emulate`: the emulated hand it runs).
    pub fn options(&self) -> anyhow::Result<AllegroOptions> {
        let bus = match &self.action {
            HandAction::Info(b) => b,
            HandAction::Monitor { bus, .. } | HandAction::Home { bus, .. } => bus,
            HandAction::Emulate { plant, fault, .. } => {
                return Ok(AllegroOptions {
                    bus: AllegroBus::Emulated,
                    gains: GainsChoice::Vendor,
                    pose: None,
                    faults: fault.clone(),
                    plant: *plant,
                    dry_run: false,
                });
            }
        };
        let kind: HandKind = bus
            .hand
            .parse()
            .map_err(|e| anyhow::anyhow!("--hand {}: {e}", bus.hand))?;
        let HandKind::Allegro(o) = kind else {
            anyhow::bail!(
                "--hand {}: dips hand brings up the Allegro hand (allegro:IFACE or \
                 allegro:emulated)",
                bus.hand
            );
        };
        let mut o = *o;
        o.dry_run |= bus.dry_run;
        Ok(o)
    }
}

fn degrees(q: &HandJoints) -> String {
    Finger::ALL
        .iter()
        .map(|f| {
            let v = q[f.index()].map(|x| format!("{:7.2}", x.to_degrees()));
            format!("{:>6} {}", f.name(), v.join(" "))
        })
        .collect::<Vec<_>>()
        .join(" |")
}

fn temperatures(c: &Connection) -> String {
    c.controller
        .temperatures()
        .iter()
        .zip(Finger::ALL)
        .map(|(t, f)| {
            let v: Vec<String> = t
                .iter()
                .map(|x| x.map_or("?".into(), |c| c.to_string()))
                .collect();
            format!("{} {}", f.name(), v.join("/"))
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Run `dips hand`.
pub fn run(args: HandArgs, hands: &dyn CliHands) -> anyhow::Result<()> {
    let options = args.options()?;
    if let HandAction::Emulate {
        iface,
        task,
        seconds,
        ..
    } = &args.action
    {
        return emulate(iface, *task, *seconds, &options, hands);
    }
    let scene = match &args.action {
        HandAction::Home { task, .. } => *task,
        _ => SceneKind::Card,
    };
    let conn = Connection::open(
        &options,
        scene,
        hands.allegro_plant(options.plant),
        dips_allegro::controller::OnFault::Report,
    )
    .with_context(|| format!("--hand allegro:{options}"))?;
    let outcome = act(&args.action, &conn, scene);
    let stats = conn.controller.stats();
    let stop = conn.close();
    eprintln!(
        "loop: {} pose sets, period p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms; {} frames sent \
         ({} SET_TORQUE), {} received, {} bad; stopped: {stop}",
        stats.pose_sets,
        stats.period.p50_ms,
        stats.period.p99_ms,
        stats.period.max_ms,
        stats.frames_sent,
        stats.torque_frames,
        stats.frames_received,
        stats.bad_frames,
    );
    outcome
}

fn act(action: &HandAction, conn: &Connection, scene: SceneKind) -> anyhow::Result<()> {
    let c = &conn.controller;
    match action {
        HandAction::Info(_) => {
            let b = c.bring_up().context("the hand gave no information")?;
            println!("bus:              {}", conn.bus_name);
            println!("hardware version: {:#06x}", b.info.hardware_version);
            println!("firmware version: {:#06x}", b.info.firmware_version);
            println!("hand:             {:?}", b.info.hand_type);
            println!(
                "serial:           {}",
                b.serial
                    .map(|s| String::from_utf8_lossy(&s).into_owned())
                    .unwrap_or_else(|| "(no answer)".into())
            );
            println!("temperature:      {} °C", b.info.temperature_c);
            println!(
                "status:           {:#04x} (servo {}, high temperature {}, internal comms fault {})",
                b.info.status.0,
                b.info.status.servo_on(),
                b.info.status.high_temperature(),
                b.info.status.internal_communication_fault()
            );
            // One temperature poll comes right after start-up.
            c.wait_until(Instant::now() + Duration::from_millis(100))?;
            println!("joints (°C):      {}", temperatures(conn));
            println!("joints (deg):     {}", degrees(&c.joints()));
        }
        HandAction::Monitor {
            seconds, rate_hz, ..
        } => {
            let every = Duration::from_secs_f64(1.0 / rate_hz.clamp(0.1, 100.0));
            let end = Instant::now() + Duration::from_secs_f64(seconds.max(0.0));
            while Instant::now() < end {
                c.wait_until(Instant::now() + every)?;
                let s = c.stats();
                println!(
                    "{} | p99 {:.2} ms | {}",
                    degrees(&c.joints()),
                    s.period.p99_ms,
                    temperatures(conn)
                );
            }
        }
        // `run` runs the emulator before any connection is opened.
        HandAction::Emulate { .. } => {}
        HandAction::Home { .. } => {
            let start = World::new(scene).joints();
            eprintln!(
                "moving to the {} start pose at most 0.5 rad/s",
                scene.name()
            );
            conn.home(&start)?;
            c.wait_until(Instant::now() + Duration::from_secs(1))?;
            let q = c.joints();
            let err = max_joint_difference(&q, &start);
            println!("home: {}", degrees(&q));
            println!("largest error after 1 s hold: {:.4} rad", err);
        }
    }
    Ok(())
}

/// `dips hand emulate`: the emulated hand on a SocketCAN interface.
fn emulate(
    iface: &str,
    scene: SceneKind,
    seconds: Option<f64>,
    options: &AllegroOptions,
    hands: &dyn CliHands,
) -> anyhow::Result<()> {
    #[cfg(target_os = "linux")]
    {
        let bus = dips_allegro::bus::socketcan::SocketCanBus::open(iface)?;
        let plant = (hands.allegro_plant(options.plant))(scene, World::new(scene).joints())?;
        let config = EmulatorConfig {
            faults: options.faults.clone(),
            ..EmulatorConfig::default()
        };
        let emu = Emulator::new(Box::new(bus), plant, config).spawn()?;
        eprintln!(
            "emulated Allegro hand ({}, {}) on {iface}; Ctrl-C stops it",
            options.plant,
            scene.name()
        );
        let end = seconds.map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
        while emu.is_running() && end.is_none_or(|e| Instant::now() < e) {
            std::thread::sleep(Duration::from_millis(50));
        }
        let report = emu.shutdown()?;
        eprintln!(
            "emulator: {} frames received ({} bad), {} pose sets sent",
            report.stats.frames_received, report.stats.bad_frames, report.stats.pose_sets_sent
        );
        Ok(())
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = (scene, seconds, options, hands);
        anyhow::bail!("dips hand emulate --iface {iface}: SocketCAN needs Linux")
    }
}
