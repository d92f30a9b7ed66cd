//! `dips episode` on the command line.

use std::process::Command;

fn dips() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dips"))
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("dips-episode-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn search_methods_are_rejected_with_a_clear_error() {
    let out = dips()
        .args([
            "episode",
            "--task",
            "screwdriver",
            "--method",
            "dips",
            "--out",
        ])
        .arg(temp_dir("reject"))
        .output()
        .expect("run dips");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("csvto-sampled") && err.contains("`dips`"),
        "{err}"
    );
}

#[test]
fn unknown_mode_names_list_the_valid_ones() {
    let out = dips()
        .args(["episode", "--task", "card", "--method", "csvto-sampled"])
        .args(["--modes", "both,turn", "--out"])
        .arg(temp_dir("mode"))
        .output()
        .expect("run dips");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("turn") && err.contains("regrasp"), "{err}");
}

#[test]
fn a_given_mode_sequence_writes_result_json() {
    let dir = temp_dir("turn");
    let out = dips()
        .args([
            "episode",
            "--task",
            "screwdriver",
            "--method",
            "csvto-sampled",
        ])
        .args(["--seed", "4", "--modes", "turn", "--out"])
        .arg(&dir)
        .output()
        .expect("run dips");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.join("result.json")).expect("result.json");
    let v: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    assert_eq!(v["task"], "screwdriver");
    assert_eq!(v["method"], "csvto-sampled");
    assert_eq!(v["seed"], 4);
    assert_eq!(v["modes"], serde_json::json!(["turn"]));
    assert!(v["final_yaw"].as_f64().expect("final_yaw") < -0.2);
    assert!(v["valid"].is_boolean());
    assert_eq!(v["csvto_step_s"].as_array().map(Vec::len), Some(12));
    assert_eq!(v["planning_s"].as_array().map(Vec::len), Some(1));
    // Progress went to stderr.
    assert!(String::from_utf8_lossy(&out.stderr).contains("turn step 12/12"));
    let _ = std::fs::remove_dir_all(&dir);
}
