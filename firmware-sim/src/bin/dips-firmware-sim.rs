//! `dips-firmware-sim`: serve the DIPS wire protocol on stdin/stdout or over TCP.
//!
//! Usage: `dips-firmware-sim [--listen ADDR] [--model-capacity-bytes N] [--work-floats N]`.
//! The two model buffers and the upload staging buffer (`MODEL_CAPACITY_BYTES` each), the planner and the planning work
//! area (`WORK_FLOATS` floats) are static, zero-initialised memory that costs nothing until
//! written; `--model-capacity-bytes` and `--work-floats` use only a prefix of them.
//! Nothing is allocated while serving. With `--listen`, connections are served one after
//! another (each is a new session; loaded models persist) and the bound address is printed
//! to stderr as `listening on ADDR`. Statistics go to stderr.

use std::net::TcpListener;
use std::process::ExitCode;
use std::sync::Mutex;

use dips_firmware_sim::planning::PlanMemory;
use dips_firmware_sim::{Firmware, MODEL_CAPACITY_BYTES, ServeStats, WORK_FLOATS, serve};
use dips_kernel::search::PaperPlanner;

static DENOISER: Mutex<[u8; MODEL_CAPACITY_BYTES]> = Mutex::new([0; MODEL_CAPACITY_BYTES]);
static DISCRIMINATOR: Mutex<[u8; MODEL_CAPACITY_BYTES]> = Mutex::new([0; MODEL_CAPACITY_BYTES]);
static STAGING: Mutex<[u8; MODEL_CAPACITY_BYTES]> = Mutex::new([0; MODEL_CAPACITY_BYTES]);
static PLANNER: Mutex<PaperPlanner> = Mutex::new(PaperPlanner::new());
static WORK: Mutex<[f32; WORK_FLOATS]> = Mutex::new([0.0; WORK_FLOATS]);

const USAGE: &str =
    "usage: dips-firmware-sim [--listen ADDR] [--model-capacity-bytes N] [--work-floats N]";

/// `--help`: what the program does and every option, on stdout.
fn help() -> String {
    format!(
        "dips-firmware-sim: the DIPS planning kernel served as the hand's controller would, over \
         the postcard wire protocol (docs/wire.md), with static memory only.\n\n\
         {USAGE}\n\n\
         Without --listen it serves one session on stdin/stdout (frames in, frames out;\n\
         statistics on stderr).\n\n\
         Options:\n  \
           --listen ADDR                serve TCP connections on ADDR (e.g. 127.0.0.1:0), one\n                               \
           after another; prints `listening on ADDR` to stderr\n  \
           --model-capacity-bytes N     use N bytes of each static model buffer (at most\n                               \
           {MODEL_CAPACITY_BYTES})\n  \
           --work-floats N              use N floats of the static planning work area (at most\n                               \
           {WORK_FLOATS})\n  \
           -h, --help                   print this help\n"
    )
}

struct Args {
    listen: Option<String>,
    capacity: usize,
    work: usize,
}

/// Parse a size flag's value, at most `max`.
fn size(name: &str, v: &str, max: usize) -> Result<usize, String> {
    let n: usize = v.parse().map_err(|e| format!("{name} {v:?}: {e}"))?;
    if n > max {
        return Err(format!("{name} {v} exceeds the static {max}"));
    }
    Ok(n)
}

/// The arguments, or `None` when `--help` was asked for.
fn parse_args() -> Result<Option<Args>, String> {
    let mut parsed = Args {
        listen: None,
        capacity: MODEL_CAPACITY_BYTES,
        work: WORK_FLOATS,
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        match arg.as_str() {
            "--listen" => parsed.listen = Some(value("--listen")?),
            "--model-capacity-bytes" => {
                let v = value("--model-capacity-bytes")?;
                parsed.capacity = size("--model-capacity-bytes", &v, MODEL_CAPACITY_BYTES)?;
            }
            "--work-floats" => {
                let v = value("--work-floats")?;
                parsed.work = size("--work-floats", &v, WORK_FLOATS)?;
            }
            "-h" | "--help" => return Ok(None),
            other => return Err(format!("unknown argument {other:?}; {USAGE}")),
        }
    }
    Ok(Some(parsed))
}

fn report(stats: &ServeStats) {
    eprintln!(
        "dips-firmware-sim: {} requests, {} bad frames, {} replies",
        stats.requests, stats.bad_frames, stats.replies
    );
}

fn run(args: &Args) -> Result<(), String> {
    let mut denoiser = DENOISER.lock().map_err(|_| "model buffer poisoned")?;
    let mut discriminator = DISCRIMINATOR.lock().map_err(|_| "model buffer poisoned")?;
    let mut planner = PLANNER.lock().map_err(|_| "planner poisoned")?;
    let mut work = WORK.lock().map_err(|_| "work area poisoned")?;
    let mut staging = STAGING.lock().map_err(|_| "model buffer poisoned")?;
    let mut firmware = Firmware::with_planning(
        &mut denoiser[..args.capacity],
        &mut discriminator[..args.capacity],
        &mut staging[..args.capacity],
        PlanMemory {
            planner: &mut planner,
            work: &mut work[..args.work],
        },
    );
    let Some(addr) = &args.listen else {
        let stats = serve(&mut firmware, std::io::stdin(), std::io::stdout().lock())
            .map_err(|e| format!("stdio: {e}"))?;
        report(&stats);
        return Ok(());
    };
    let listener = TcpListener::bind(addr).map_err(|e| format!("bind {addr}: {e}"))?;
    let local = listener.local_addr().map_err(|e| format!("{addr}: {e}"))?;
    eprintln!("listening on {local}");
    for stream in listener.incoming() {
        let stream = match stream {
            Ok(s) => s,
            Err(e) => {
                eprintln!("dips-firmware-sim: accept: {e}");
                continue;
            }
        };
        let reader = stream.try_clone().map_err(|e| format!("socket: {e}"))?;
        firmware.reset_session();
        match serve(&mut firmware, reader, stream) {
            Ok(stats) => report(&stats),
            Err(e) => eprintln!("dips-firmware-sim: connection: {e}"),
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(Some(a)) => a,
        Ok(None) => {
            print!("{}", help());
            return ExitCode::SUCCESS;
        }
        Err(msg) => {
            eprintln!("{msg}");
            return ExitCode::from(2);
        }
    };
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("dips-firmware-sim: {msg}");
            ExitCode::FAILURE
        }
    }
}
