//! `--hand world|mujoco` (issue 37 item 4): an unknown value is one error line naming the
//! allowed ones; the `dips` binary runs `--hand mujoco` in a `dips-mujoco` next to it or on
//! PATH, with the same arguments and exit code, and says in one line when there is none. No
//! MuJoCo is needed: the tests use a stand-in script.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};

/// Spawning a binary this test process has just written can fail with "text file busy"
/// (ETXTBSY) while another test thread's fork still holds the file's write descriptor
/// between fork and exec; retry for up to a few seconds.
trait BusySafe {
    fn spawn_busy_safe(&mut self) -> Child;
    fn output_busy_safe(&mut self) -> Output;
}

impl BusySafe for Command {
    fn spawn_busy_safe(&mut self) -> Child {
        for _ in 0..200 {
            match self.spawn() {
                Err(e) if e.kind() == std::io::ErrorKind::ExecutableFileBusy => {
                    std::thread::sleep(std::time::Duration::from_millis(20))
                }
                r => return r.unwrap(),
            }
        }
        self.spawn().unwrap()
    }

    fn output_busy_safe(&mut self) -> Output {
        for _ in 0..200 {
            match self.output() {
                Err(e) if e.kind() == std::io::ErrorKind::ExecutableFileBusy => {
                    std::thread::sleep(std::time::Duration::from_millis(20))
                }
                r => return r.unwrap(),
            }
        }
        self.output().unwrap()
    }
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dips-hand-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The error lines of stderr (clap adds a blank line and a `--help` hint).
fn error_lines(stderr: &[u8]) -> Vec<String> {
    String::from_utf8_lossy(stderr)
        .lines()
        .filter(|l| l.starts_with("error"))
        .map(str::to_string)
        .collect()
}

#[test]
fn an_unknown_hand_lists_the_allowed_ones() {
    for args in [
        &[
            "episode", "--task", "card", "--method", "dips", "--out", "x",
        ][..],
        &["eval", "--task", "card", "--out", "x"][..],
        &["bench", "sim", "--json"][..],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_dips"))
            .args(args)
            .args(["--hand", "isaac"])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2));
        let lines = error_lines(&out.stderr);
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert!(
            lines[0].contains("unknown hand `isaac` (allowed: world, mujoco, allegro:IFACE)"),
            "{lines:?}"
        );
    }
    // `dips sim run --hand FILE` was the hand description: the error says its new flag.
    let out = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(["sim", "run", "--scene", "card", "--commands", "c.json"])
        .args(["--out", "o.json", "--hand", "host/data/allegro_v4.json"])
        .output()
        .unwrap();
    let lines = error_lines(&out.stderr);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains("--hand-model FILE"), "{lines:?}");
}

/// A copy of `dips` alone in a fresh folder, and that folder.
fn lone_dips(name: &str) -> (PathBuf, PathBuf) {
    let dir = scratch(name);
    let exe = dir.join("dips");
    std::fs::copy(env!("CARGO_BIN_EXE_dips"), &exe).unwrap();
    (dir, exe)
}

fn episode_args(out: &Path) -> Vec<String> {
    [
        "episode",
        "--task",
        "card",
        "--method",
        "csvto-sampled",
        "--modes",
        "both",
        "--hand",
        "mujoco",
        "--out",
    ]
    .iter()
    .map(|s| s.to_string())
    .chain([out.display().to_string()])
    .collect()
}

#[test]
fn without_dips_mujoco_the_error_is_one_line() {
    let (dir, exe) = lone_dips("none");
    let out = Command::new(&exe)
        .args(episode_args(&dir.join("ep")))
        .env("PATH", "")
        .output_busy_safe();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        stderr.trim_end(),
        format!(
            "error: --hand mujoco needs the dips-mujoco binary (build it: scripts/mujoco-test.sh), \
             not found next to {} or on PATH",
            exe.display()
        )
    );
    assert!(!dir.join("ep").exists(), "nothing ran");
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn dips_mujoco_runs_with_the_same_arguments_and_exit_code() {
    use std::os::unix::fs::PermissionsExt;
    let (dir, exe) = lone_dips("stand-in");
    let args_file = dir.join("args.txt");
    // A stand-in for dips-mujoco: records its arguments and stdin, answers on both streams
    // (shell builtins only: PATH may be empty).
    let script = format!(
        "#!/bin/sh\nprintf '%s\\n' \"$@\" > '{}'\nread -r l\nprintf '%s\\n' \"$l\" >> '{}'\necho out\necho err >&2\nexit 3\n",
        args_file.display(),
        args_file.display()
    );
    for (folder, on_path) in [(dir.clone(), false), (dir.join("bin"), true)] {
        std::fs::create_dir_all(&folder).unwrap();
        let _ = std::fs::remove_file(dir.join("dips-mujoco"));
        let stand_in = folder.join("dips-mujoco");
        std::fs::write(&stand_in, &script).unwrap();
        std::fs::set_permissions(&stand_in, std::fs::Permissions::from_mode(0o755)).unwrap();
        let mut child = Command::new(&exe)
            .args(episode_args(&dir.join("ep")))
            .env(
                "PATH",
                if on_path {
                    folder.display().to_string()
                } else {
                    String::new()
                },
            )
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn_busy_safe();
        {
            use std::io::Write;
            child
                .stdin
                .take()
                .unwrap()
                .write_all(b"stdin-line\n")
                .unwrap();
        }
        let out = child.wait_with_output().unwrap();
        assert_eq!(out.status.code(), Some(3), "on PATH: {on_path}");
        assert_eq!(String::from_utf8_lossy(&out.stdout), "out\n");
        assert_eq!(String::from_utf8_lossy(&out.stderr), "err\n");
        let mut want = episode_args(&dir.join("ep")).join("\n");
        want.push_str("\nstdin-line\n");
        assert_eq!(std::fs::read_to_string(&args_file).unwrap(), want);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A `dips-mujoco` stand-in in `dir` that exits 3 after writing its arguments to
/// `dir/args.txt`.
#[cfg(unix)]
fn stand_in(dir: &Path) {
    use std::os::unix::fs::PermissionsExt;
    let script = format!(
        "#!/bin/sh\nprintf '%s\\n' \"$@\" > '{}'\nexit 3\n",
        dir.join("args.txt").display()
    );
    let path = dir.join("dips-mujoco");
    std::fs::write(&path, script).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
}

#[cfg(unix)]
#[test]
fn a_protocol_of_the_mujoco_hand_runs_in_dips_mujoco() {
    let (dir, exe) = lone_dips("protocol");
    let file = dir.join("p.json");
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/../../onnx/models/card");
    let out = Command::new(&exe)
        .args([
            "eval",
            "--task",
            "card",
            "--methods",
            "csvto-sampled",
            "--first-seed",
        ])
        .args([
            "500",
            "--trials",
            "1",
            "--models",
            models,
            "--write-protocol",
        ])
        .arg(&file)
        .output_busy_safe();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut p: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    assert!(
        p["eval"]["episode"].get("hand").is_none(),
        "our world: absent"
    );
    p["eval"]["episode"]["hand"] = "mujoco".into();
    std::fs::write(&file, serde_json::to_string_pretty(&p).unwrap()).unwrap();
    stand_in(&dir);
    let args = ["eval", "--protocol", "p.json", "--out", "x"];
    let out = Command::new(&exe)
        .current_dir(&dir)
        .args(args)
        .env("PATH", "")
        .output_busy_safe();
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let passed = std::fs::read_to_string(dir.join("args.txt")).unwrap();
    assert_eq!(passed, args.join("\n") + "\n");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn tracker_noise_on_our_world_is_refused() {
    let dir = scratch("noise");
    let out = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(["episode", "--task", "card", "--method", "csvto-sampled"])
        .args(["--modes", "both", "--noise-position", "0.001", "--out"])
        .arg(dir.join("ep"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("tracker noise") && stderr.contains("--hand mujoco"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
