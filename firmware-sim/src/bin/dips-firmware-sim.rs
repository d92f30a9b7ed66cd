//! `dips-firmware-sim`: serve the DIPS wire protocol on stdin/stdout.
//!
//! Usage: `dips-firmware-sim [--model-capacity-bytes N]`. Both model buffers are allocated
//! once at start; nothing is allocated while serving. Statistics go to stderr at the end.

use std::process::ExitCode;

use dips_firmware_sim::{DEFAULT_MODEL_CAPACITY_BYTES, Firmware, serve};

fn parse_args() -> Result<usize, String> {
    let mut capacity = DEFAULT_MODEL_CAPACITY_BYTES;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--model-capacity-bytes" => {
                let value = args.next().ok_or("--model-capacity-bytes needs a value")?;
                capacity = value
                    .parse()
                    .map_err(|e| format!("--model-capacity-bytes {value:?}: {e}"))?;
            }
            "-h" | "--help" => {
                return Err(
                    "usage: dips-firmware-sim [--model-capacity-bytes N] (serves stdin/stdout)"
                        .into(),
                );
            }
            other => return Err(format!("unknown argument {other:?}")),
        }
    }
    Ok(capacity)
}

fn main() -> ExitCode {
    let capacity = match parse_args() {
        Ok(c) => c,
        Err(msg) => {
            eprintln!("{msg}");
            return ExitCode::from(2);
        }
    };
    let mut denoiser = vec![0u8; capacity];
    let mut discriminator = vec![0u8; capacity];
    let mut firmware = Firmware::new(&mut denoiser, &mut discriminator);
    let stdin = std::io::stdin().lock();
    let stdout = std::io::stdout().lock();
    match serve(&mut firmware, stdin, stdout) {
        Ok(stats) => {
            eprintln!(
                "dips-firmware-sim: {} requests, {} bad frames, {} replies",
                stats.requests, stats.bad_frames, stats.replies
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("dips-firmware-sim: {e}");
            ExitCode::FAILURE
        }
    }
}
