//! Bad input is refused with one message that names the file or flag and what is allowed
//! (issue 36).

use std::process::Command;

/// Run `dips ARGS`; the exit code and stderr.
fn dips(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn temp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("dips-bad-{name}-{}", std::process::id()))
}

fn commands(name: &str, text: &str) -> String {
    let p = temp(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

#[test]
fn commands_beyond_a_joints_range_or_not_finite_are_refused() {
    let out = temp("traj.json").display().to_string();
    let huge = commands("huge.json", r#"{"dq": [[1e300, 0, 0, 0, 0, 0, 0, 0]]}"#);
    let (code, err) = dips(&[
        "sim",
        "run",
        "--scene",
        "card",
        "--commands",
        &huge,
        "--out",
        &out,
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains(&huge) && err.contains("1e300"), "{err}");
    assert!(
        err.contains("within ±0.940 rad") && err.contains("index joint 0"),
        "{err}"
    );
    assert!(
        !std::path::Path::new(&out).exists(),
        "no trajectory of a refused file"
    );

    let nan = commands("nan.json", r#"{"dq": [[NaN, 0, 0, 0, 0, 0, 0, 0]]}"#);
    let (code, err) = dips(&[
        "sim",
        "run",
        "--scene",
        "card",
        "--commands",
        &nan,
        "--out",
        &out,
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("JSON has no NaN or Infinity"), "{err}");
    // Within the limits still runs.
    let ok = commands("ok.json", r#"{"dq": [[0.01, 0, 0, 0, 0, 0, 0, 0]]}"#);
    let (code, err) = dips(&[
        "sim",
        "run",
        "--scene",
        "card",
        "--commands",
        &ok,
        "--out",
        &out,
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.is_empty(), "{err}");
}

#[test]
fn flags_say_what_is_allowed() {
    let out = temp("episode").display().to_string();
    let base = [
        "episode", "--task", "card", "--method", "dips", "--out", &out,
    ];
    let with = |extra: &[&str]| {
        let mut a = base.to_vec();
        a.extend_from_slice(extra);
        dips(&a)
    };
    let (code, err) = with(&["--seed", "-1"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("seeds are non-negative integers"), "{err}");
    for args in [
        vec![
            "eval",
            "--task",
            "card",
            "--first-seed",
            "-1",
            "--out",
            &out,
        ],
        vec![
            "datagen",
            "--task",
            "card",
            "--first-seed",
            "-1",
            "--out",
            &out,
        ],
    ] {
        let (code, err) = dips(&args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(
            err.contains("seeds are non-negative integers"),
            "{args:?}: {err}"
        );
    }
    let (code, err) = with(&["--time-budget-s", "-1"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--time-budget-s") && err.contains("≥ 0"),
        "{err}"
    );
    let (code, err) = with(&["--node-budget", "-3"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--node-budget") && err.contains("from 0"),
        "{err}"
    );
    let (code, err) = with(&["--max-modes", "0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--max-modes") && err.contains("≥ 1"), "{err}");
    let (code, err) = with(&["--exec-profile", "lab"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("lab") && err.contains("simulation") && err.contains("hardware"),
        "{err}"
    );
    let (code, err) = with(&["--press", "hard"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("hard") && err.contains("light") && err.contains("firm"),
        "{err}"
    );
    let (code, err) = with(&["--first-mode", "sometimes"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("sometimes") && err.contains("any") && err.contains("touching"),
        "{err}"
    );
    let (code, err) = with(&["--regrasp-guard", "always"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("always") && err.contains("off") && err.contains("clearance"),
        "{err}"
    );
    // The paper's hardware settings exist for the screwdriver only.
    let (code, err) = with(&["--exec-profile", "hardware"]);
    assert_ne!(code, Some(0), "{err}");
    assert!(
        err.contains("hardware") && err.contains("card") && err.contains("simulation"),
        "{err}"
    );
    let (code, err) = dips(&[
        "eval",
        "--task",
        "card",
        "--exec-profile",
        "hardware",
        "--first-seed",
        "0",
        "--out",
        &out,
    ]);
    assert_ne!(code, Some(0), "{err}");
    assert!(
        err.contains("--exec-profile hardware") && err.contains("card"),
        "{err}"
    );
    assert!(
        std::fs::read_dir(&out).map_or(true, |d| d.count() == 0),
        "nothing written"
    );
}

#[test]
fn file_errors_are_one_message_naming_the_path() {
    let (code, err) = dips(&[
        "render",
        "--input",
        "/nonexistent/r.json",
        "--out",
        "/tmp/x.png",
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("/nonexistent/r.json"), "{err}");
    assert_eq!(err.matches("os error 2").count(), 1, "said once: {err}");

    let file = temp("a-file");
    std::fs::write(&file, "x").unwrap();
    let out = file.join("x.png").display().to_string();
    let (code, err) = dips(&["sim", "render", "--scene", "card", "--out", &out]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("is a file, not a directory"), "{err}");

    let corrupt = temp("corrupt.onnx");
    std::fs::write(&corrupt, b"\x0a\xff\xff not a model").unwrap();
    let c = corrupt.display().to_string();
    let io = format!(
        "{}/../../onnx/tests/fixtures/torch-card-dynamo/denoiser.io.json",
        env!("CARGO_MANIFEST_DIR")
    );
    for args in [
        vec![
            "model",
            "run",
            &c,
            "--input",
            &io,
            "--output",
            "/tmp/eps.json",
        ],
        vec!["model", "lower", &c, "--out", "/tmp/x.dipsm"],
        vec!["bench", "inference", &c, "--batch", "2", "--json"],
    ] {
        let (code, err) = dips(&args);
        assert_eq!(code, Some(1), "{args:?}: {err}");
        assert!(err.contains(&c), "{args:?} names the file: {err}");
    }
}

#[test]
fn commands_that_write_a_file_say_so() {
    let out = temp("scene").with_extension("png");
    let (code, err) = dips(&[
        "sim",
        "render",
        "--scene",
        "card",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(err.trim(), format!("wrote {}", out.display()));
}

#[test]
fn help_lists_the_allowed_values() {
    let help = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_dips"))
            .args(args)
            .arg("--help")
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout).replace('\n', " ")
    };
    let episode = help(&["episode"]);
    for v in [
        "screwdriver",
        "card",
        "dips-max-likelihood",
        "diffusion-policy",
        "index-regrasp",
        "thumb-middle-regrasp",
        "regrasp",
        "ddim:STEPS",
    ] {
        assert!(episode.contains(v), "episode --help lacks {v}: {episode}");
    }
    let eval = help(&["eval"]);
    for v in [
        "dips-k1",
        "dips-no-replan",
        "csvto-sampled",
        "diffusion-policy",
    ] {
        assert!(eval.contains(v), "eval --help lacks {v}: {eval}");
    }
}
