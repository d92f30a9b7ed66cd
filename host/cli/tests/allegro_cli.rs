//! `--hand allegro:…` and `dips hand` on the command line (issue 53): a card episode through
//! the driver and the emulated hand (the joint model with our world moving the card), a
//! silent hand that ends the run within a second through the watchdog, the dry run's frames,
//! and bring-up. The episodes run in real time (1 s per action), so they are short.

use std::process::Command;
use std::time::{Duration, Instant};

fn dips() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dips"))
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("dips-allegro-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn a_card_episode_runs_through_the_driver_and_the_emulated_hand() {
    let dir = temp_dir("card");
    let out = dips()
        .args([
            "episode", "--task", "card", "--method", "dips", "--seed", "2",
        ])
        .args(["--max-modes", "1", "--hand", "allegro:emulated", "--out"])
        .arg(&dir)
        .output()
        .expect("run dips");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("result.json")).unwrap()).unwrap();
    assert_eq!(v["hand"], "allegro");
    let r = &v["hand_report"];
    assert_eq!(r["hand"], "allegro:emulated");
    assert_eq!(r["plant"], "joint-model");
    assert_eq!(r["gains"], "vendor");
    assert_eq!(r["bring_up"]["hardware_version"], "0x0402");
    let lp = &r["loop"];
    let sets = lp["pose_sets"].as_u64().unwrap();
    let steps = v["mode_runs"][0]["steps"].as_array().unwrap().len() as u64;
    // About 333 pose sets per action, and four torque frames for each.
    assert!(sets > 150 * steps, "{sets} pose sets for {steps} actions");
    assert!(lp["torque_frames"].as_u64().unwrap() >= 4 * sets);
    assert_eq!(lp["bad_frames"], 0);
    let p50 = lp["period"]["p50_ms"].as_f64().unwrap();
    assert!((2.0..5.0).contains(&p50), "{p50}");
    assert!(v["final_distance_m"].as_f64().unwrap().is_finite());
    assert_eq!(r["tracking"]["actions"].as_u64().unwrap(), steps);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_silent_hand_ends_the_episode_through_the_watchdog() {
    let dir = temp_dir("silence");
    let t0 = Instant::now();
    let out = dips()
        .args([
            "episode", "--task", "card", "--method", "dips", "--seed", "2",
        ])
        .args(["--hand", "allegro:emulated,fault=silence@2", "--out"])
        .arg(&dir)
        .output()
        .expect("run dips");
    let took = t0.elapsed();
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("error: allegro hand: watchdog:"), "{err}");
    assert!(err.contains("torques zeroed, servo off"), "{err}");
    // Start-up and the move home take about a second; the silence starts 2 s after servo on
    // and the watchdog fires 30 ms later, whatever the episode is doing then.
    assert!(took < Duration::from_secs(6), "{took:?}");
    assert!(!dir.join("result.json").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_dry_run_prints_the_frames_and_opens_no_bus() {
    let out = dips()
        .args([
            "hand",
            "home",
            "--hand",
            "allegro:can0",
            "--dry-run",
            "--task",
            "card",
        ])
        .output()
        .expect("run dips");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    for id in ["180", "184", "188", "18C"] {
        assert!(
            text.contains(&format!(" can0 {id} [8] ")),
            "no SET_TORQUE {id}"
        );
    }
    assert!(text.contains("largest error after 1 s hold"), "{text}");
}

#[test]
fn bring_up_reports_the_hand_and_a_missing_interface_is_one_clear_error() {
    let out = dips()
        .args(["hand", "info", "--hand", "allegro:emulated"])
        .output()
        .expect("run dips");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("hardware version: 0x0402"), "{text}");
    assert!(text.contains("serial:           SAH040X1"), "{text}");
    let out = dips()
        .args(["hand", "info", "--hand", "allegro:nosuchcan7"])
        .output()
        .expect("run dips");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("CAN interface nosuchcan7"), "{err}");
    let out = dips()
        .args([
            "episode", "--task", "card", "--method", "dips", "--out", "x",
        ])
        .args(["--hand", "allegro:emulated,fault=boom"])
        .output()
        .expect("run dips");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("fault `boom`: expected silence@SECONDS, garbage or hot@SECONDS"),
        "{err}"
    );
}
