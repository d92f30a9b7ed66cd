//! `dips-mujoco` is the `dips` command line with the MuJoCo hand registered (release;
//! scripts/mujoco-test.sh): `dips episode --hand mujoco` runs the planner, the shipped models
//! and CSVTO of `dips episode` with the MuJoCo hand executing, and `result.json` says so in
//! its `hand` field; `dips eval --hand mujoco` records the hand in `eval.json`; `dips sim run`
//! and `dips bench sim` take `--hand mujoco`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dips-mujoco-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn dips_mujoco(args: &[&str], out: &Path) -> Output {
    let o = Command::new(env!("CARGO_BIN_EXE_dips-mujoco"))
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .expect("run dips-mujoco");
    assert!(
        o.status.success(),
        "dips-mujoco {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("read")).expect("JSON")
}

/// One card mode, a two-node search, DDIM-8, one model thread: a few seconds.
const SHORT_CARD: [&str; 12] = [
    "--task",
    "card",
    "--node-budget",
    "2",
    "--sampler",
    "ddim:8",
    "--max-modes",
    "1",
    "--time-budget-s",
    "60",
    "--hand",
    "mujoco",
];

#[test]
fn dips_card_episode_on_the_mujoco_hand_records_its_hand() {
    let dir = scratch("episode");
    let mut args = vec![
        "episode",
        "--method",
        "dips",
        "--seed",
        "500",
        "--threads",
        "1",
    ];
    args.extend(SHORT_CARD);
    dips_mujoco(&args, &dir);
    let result = json(&dir.join("result.json"));
    assert_eq!(result["hand"], "mujoco");
    assert_eq!(result["method"], "dips");
    assert_eq!(
        result["modes"].as_array().map(Vec::len),
        Some(1),
        "one mode"
    );
    assert!(
        result["final_distance_m"]
            .as_f64()
            .is_some_and(f64::is_finite)
    );
    assert!(result.get("tracker_noise").is_none());
    assert!(dir.join("report.html").is_file(), "the report is written");
    eprintln!(
        "card dips seed 500 on MuJoCo: {}, dy {:.2} cm, valid {}",
        result["modes"],
        100.0 * result["final_dy_m"].as_f64().unwrap_or(f64::NAN),
        result["valid"]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The paper's hardware CSVTO settings (`--exec-profile hardware`) on a hand the planner does
/// not model, as in its §V-D: one diffusion-initialised `turn` whose thumb and middle forces
/// are redrawn turns the screwdriver, stays valid and is recorded as such.
#[test]
fn a_turn_under_the_hardware_settings_turns_and_records_them() {
    let dir = scratch("hardware");
    let args = [
        "episode",
        "--task",
        "screwdriver",
        "--method",
        "dips-sampled",
        "--modes",
        "turn",
        "--max-modes",
        "1",
        "--sampler",
        "ddim:8",
        "--seed",
        "500",
        "--threads",
        "1",
        "--hand",
        "mujoco",
        "--exec-profile",
        "hardware",
    ];
    dips_mujoco(&args, &dir);
    let result = json(&dir.join("result.json"));
    assert_eq!(result["exec_profile"], "hardware");
    assert_eq!(result["hand"], "mujoco");
    assert_eq!(result["valid"], true);
    let yaw = result["final_yaw"].as_f64().expect("a final yaw");
    assert!(yaw < -0.1, "one hardware turn on MuJoCo: {yaw} rad");
    let iters = result["mode_runs"][0]["steps"][1]["iters"].as_u64();
    assert_eq!(iters, Some(50), "the hardware online budget");
    eprintln!("one hardware turn on MuJoCo, seed 500: {yaw:.3} rad");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn csvto_episode_with_tracker_noise_records_it() {
    let dir = scratch("noisy");
    let mut args = vec![
        "episode",
        "--method",
        "csvto-sampled",
        "--modes",
        "both",
        "--noise-position",
        "0.001",
        "--noise-rotation",
        "0.02",
    ];
    args.extend(SHORT_CARD);
    dips_mujoco(&args, &dir);
    let result = json(&dir.join("result.json"));
    assert_eq!(result["hand"], "mujoco");
    assert_eq!(result["tracker_noise"]["position"], 0.001);
    assert_eq!(result["tracker_noise"]["rotation"], 0.02);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn eval_records_the_hand_in_eval_json_and_resumes() {
    let dir = scratch("eval");
    let mut args = vec![
        "eval",
        "--methods",
        "csvto-sampled",
        "--first-seed",
        "500",
        "--trials",
        "1",
        "--jobs",
        "1",
        "--model-threads",
        "1",
        "--quiet",
        "--animate",
        "none",
    ];
    args.extend(SHORT_CARD);
    dips_mujoco(&args, &dir);
    assert_eq!(json(&dir.join("eval.json"))["episode"]["hand"], "mujoco");
    let ep = dir.join("episodes/csvto-sampled/seed-500");
    assert_eq!(json(&ep.join("result.json"))["hand"], "mujoco");
    let stamp = std::fs::metadata(ep.join("result.json"))
        .and_then(|m| m.modified())
        .expect("stamp");
    // Run again: nothing to do; on our world: another hand, refused.
    dips_mujoco(&args, &dir);
    assert_eq!(
        std::fs::metadata(ep.join("result.json"))
            .and_then(|m| m.modified())
            .expect("stamp"),
        stamp
    );
    let world: Vec<&str> = args
        .iter()
        .map(|a| if *a == "mujoco" { "world" } else { a })
        .collect();
    let o = Command::new(env!("CARGO_BIN_EXE_dips-mujoco"))
        .args(&world)
        .arg("--out")
        .arg(&dir)
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--hand"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sim_run_and_bench_sim_take_the_hand() {
    let dir = scratch("sim");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let out = dir.join("traj.json");
    let commands = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/card-commands.json"
    );
    let o = dips_mujoco(
        &[
            "sim",
            "run",
            "--scene",
            "card",
            "--commands",
            commands,
            "--hand",
            "mujoco",
        ],
        &out,
    );
    let line: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON line");
    assert_eq!(line["hand"], "mujoco");
    let traj = json(&out);
    assert_eq!(traj["hand"], "mujoco");
    assert!(traj["states"].as_array().is_some_and(|s| s.len() > 1));
    let o = Command::new(env!("CARGO_BIN_EXE_dips-mujoco"))
        .args([
            "bench",
            "sim",
            "--hand",
            "mujoco",
            "--json",
            "--actions",
            "2",
        ])
        .output()
        .expect("bench");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bench: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    let rows = bench["scenarios"].as_array().expect("scenarios");
    assert_eq!(rows.len(), 8, "2 scenes × 2 scenarios × 2 hands");
    for hand in ["mujoco", "world"] {
        assert!(
            rows.iter()
                .any(|r| r["hand"] == hand && r["p90_ms"].as_f64().is_some())
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
