//! Every output stream is pipe-safe (issue 36): a reader that goes away early
//! (`dips episode … 2>&1 | head -2`, quitting `less`) ends the output quietly, and the work and
//! its files complete with exit code 0.

use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, Stdio};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dips-pipe-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Which of the child's streams the reader closes, and after how many bytes.
#[derive(Clone, Copy, Debug)]
enum Close {
    /// stderr, before its first byte.
    Stderr,
    /// stderr, after its first line (`2>&1 | head -1` on a progress line).
    StderrAfterLine,
    /// stdout, before its first byte.
    Stdout,
    /// Both.
    Both,
}

/// Run `dips ARGS` with the stream(s) closed as `close` says; returns the exit status and
/// whatever of stderr was read before closing it.
fn run_closing(args: &[&str], close: Close) -> std::process::ExitStatus {
    let mut child = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (out, mut err) = (child.stdout.take(), child.stderr.take());
    match close {
        Close::Stderr => drop(err.take()),
        Close::Stdout => drop(out),
        Close::Both => {
            drop(out);
            drop(err.take());
        }
        Close::StderrAfterLine => {
            let mut e = err.take().unwrap();
            let mut byte = [0u8; 1];
            while e.read(&mut byte).unwrap() == 1 && byte[0] != b'\n' {}
            drop(e);
        }
    }
    // Any stream left open is drained so the child never blocks on a full pipe.
    if let Some(mut e) = err {
        let mut sink = Vec::new();
        let _ = e.read_to_end(&mut sink);
    }
    child.wait().unwrap()
}

#[test]
fn an_episode_finishes_and_writes_its_files_whichever_stream_is_closed() {
    for close in [
        Close::Stderr,
        Close::StderrAfterLine,
        Close::Stdout,
        Close::Both,
    ] {
        let dir = temp_dir(&format!("{close:?}").to_lowercase());
        let status = run_closing(
            &[
                "episode",
                "--task",
                "card",
                "--method",
                "dips",
                "--seed",
                "0",
                "--max-modes",
                "1",
                "--out",
                dir.to_str().unwrap(),
            ],
            close,
        );
        assert!(status.success(), "{close:?}: {status:?}");
        assert!(
            dir.join("result.json").is_file(),
            "{close:?}: no result.json"
        );
        assert!(
            dir.join("report.html").is_file(),
            "{close:?}: no report.html"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn bench_plan_ends_quietly_when_its_reader_goes_away() {
    for close in [Close::Stderr, Close::StderrAfterLine, Close::Both] {
        let status = run_closing(
            &["bench", "plan", "--task", "card", "--calls", "1", "--json"],
            close,
        );
        assert!(status.success(), "{close:?}: {status:?}");
    }
}

#[test]
fn errors_on_a_closed_stderr_exit_1_without_a_panic() {
    // The error message has nowhere to go; the exit code still says it failed (not 101).
    let status = run_closing(
        &[
            "render",
            "--input",
            "/nonexistent/result.json",
            "--out",
            "/tmp/x.png",
        ],
        Close::Stderr,
    );
    assert_eq!(status.code(), Some(1), "{status:?}");
}
