//! Output the way users pipe it: a closed pipe is a quiet exit, a full disk a clear error,
//! and user errors never print a backtrace, whatever `RUST_BACKTRACE` says.

use std::process::{Command, Stdio};

fn fixture() -> String {
    format!(
        "{}/../../onnx/tests/fixtures/torch-card-dynamo/denoiser.onnx",
        env!("CARGO_MANIFEST_DIR")
    )
}

#[test]
fn a_closed_pipe_is_a_quiet_exit() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(["model", "check", &fixture()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The reader goes away before the first byte, as `| head -0` would.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {err}", out.status);
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn a_full_disk_is_an_error_not_a_panic() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        return; // no /dev/full on this system
    };
    let out = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(["model", "check", &fixture()])
        .stdout(full)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("cannot write to stdout"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn user_errors_print_no_backtrace() {
    let out = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(["episode", "--task", "pen", "--method", "dips", "--out", "x"])
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    // A bad flag value is a usage error, refused by the flag's parser (exit status 2).
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: unknown task `pen`"), "{err}");
    assert!(!err.to_lowercase().contains("backtrace"), "{err}");
}

#[test]
fn file_errors_name_the_file_and_what_was_done() {
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_dips"))
            .args(args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1));
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let model = fixture();
    let err = run(&[
        "model",
        "run",
        &model,
        "--input",
        "/nonexistent/in.json",
        "--output",
        "/tmp/x.json",
    ]);
    assert!(
        err.contains("cannot read tensor file /nonexistent/in.json"),
        "{err}"
    );
    let err = run(&["model", "lower", &model, "--out", "/nonexistent/x.dipsm"]);
    assert!(
        err.contains("cannot write kernel blob /nonexistent/x.dipsm"),
        "{err}"
    );
}
