//! `dips sim` and `dips bench sim` through the binary.

use std::path::{Path, PathBuf};
use std::process::Command;

fn dips() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dips"))
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dips-sim-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run_sim(scene: &str, cmds: &str, dir: &Path) -> (std::process::Output, PathBuf) {
    let c = dir.join("cmds.json");
    std::fs::write(&c, cmds).unwrap();
    let out = dir.join("out.json");
    let o = dips()
        .args(["sim", "run", "--scene", scene, "--commands"])
        .arg(&c)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    (o, out)
}

#[test]
fn run_writes_trajectory_in_contract_shape() {
    let dir = tmpdir("run");
    for (scene, n, state) in [("screwdriver", 12, 15), ("card", 8, 11)] {
        let mut row = vec![0.0; n];
        row[1] = 0.05;
        let cmds = serde_json::json!({ "dq": [row.clone(), row, vec![0.0; n]] }).to_string();
        let (o, out) = run_sim(scene, &cmds, &dir);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let states = v["states"].as_array().unwrap();
        assert_eq!(states.len(), 4);
        assert!(states.iter().all(|s| s.as_array().unwrap().len() == state));
        assert_eq!(v["valid"].as_array().unwrap().len(), 4);
        let contacts = v["contacts"].as_array().unwrap();
        assert_eq!(contacts.len(), 4);
        let any = contacts
            .iter()
            .flat_map(|c| c.as_array().unwrap())
            .next()
            .expect("some contact");
        for key in ["finger", "part", "point", "normal", "force"] {
            assert!(any.get(key).is_some(), "{key} missing in {any}");
        }
        // Pressing the index's second joint moved something.
        assert_ne!(states[0], states[3]);
        // Render the last state to both formats.
        for ext in ["svg", "png"] {
            let img = dir.join(format!("{scene}.{ext}"));
            let r = dips()
                .args(["sim", "render", "--scene", scene, "--trajectory"])
                .arg(&out)
                .arg("--out")
                .arg(&img)
                .output()
                .unwrap();
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
            let bytes = std::fs::read(&img).unwrap();
            match ext {
                "svg" => assert!(String::from_utf8(bytes).unwrap().contains("<circle")),
                _ => assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n"),
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_commands_get_clear_errors() {
    let dir = tmpdir("bad");
    let cases = [
        (
            "screwdriver",
            r#"{"dq": [[0,0,0]]}"#,
            "dq row 0 has 3 numbers, the screwdriver task needs 12",
        ),
        ("card", r#"{"dq": [[0,0,0,0,0,0,0,NaN]]}"#, "not valid JSON"),
        (
            "card",
            r#"{"dq": [[0,0,0,0,0,0,0,1e999]]}"#,
            "not valid JSON",
        ),
        ("card", "this is not json", "not valid JSON"),
        ("card", r#"{"actions": []}"#, "not valid JSON"),
        ("plate", r#"{"dq": []}"#, "unknown scene"),
    ];
    for (scene, text, expect) in cases {
        let (o, _) = run_sim(scene, text, &dir);
        assert!(!o.status.success(), "{text} succeeded");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(expect), "{text}: {err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bench_sim_prints_json_figures() {
    let o = dips()
        .args(["bench", "sim", "--json", "--actions", "2"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let sc = v["scenarios"].as_array().unwrap();
    assert_eq!(sc.len(), 4);
    assert!(sc.iter().all(|s| s["mean_ms"].as_f64().unwrap() > 0.0));
    // Without --json the same figures come as readable lines, not JSON.
    let o = dips()
        .args(["bench", "sim", "--actions", "2"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        serde_json::from_str::<serde_json::Value>(&text).is_err(),
        "{text}"
    );
    assert!(
        text.starts_with("bench: sim\n") && text.contains("mean_ms: "),
        "{text}"
    );
}

#[test]
fn run_with_log_is_replayable() {
    let dir = tmpdir("log");
    let c = dir.join("cmds.json");
    let mut row = vec![0.0; 8];
    row[1] = 0.08;
    row[5] = 0.08;
    std::fs::write(
        &c,
        serde_json::json!({ "dq": [row.clone(), row] }).to_string(),
    )
    .unwrap();
    let out = dir.join("out.json");
    let log = dir.join("log.jsonl");
    let o = dips()
        .args(["sim", "run", "--scene", "card", "--commands"])
        .arg(&c)
        .arg("--out")
        .arg(&out)
        .arg("--log")
        .arg(&log)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rep = dips_world::hand::replay(&log).unwrap();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let states: Vec<Vec<f64>> = serde_json::from_value(v["states"].clone()).unwrap();
    assert_eq!(rep.states.len(), states.len());
    for (a, b) in rep.states.iter().zip(&states) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() < 1e-9);
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn hand_file_is_loaded_at_run_time() {
    let dir = tmpdir("hand");
    let c = dir.join("cmds.json");
    std::fs::write(&c, r#"{"dq": [[0,0,0,0,0,0,0,0]]}"#).unwrap();
    let good = dir.join("hand.json");
    std::fs::write(&good, dips_world::kinematics::DEFAULT_HAND_JSON).unwrap();
    let bad = dir.join("bad_hand.json");
    std::fs::write(
        &bad,
        dips_world::kinematics::DEFAULT_HAND_JSON
            .replace("\"tip_radius\": 0.015", "\"tip_radius\": 0"),
    )
    .unwrap();
    for (hand, ok) in [(&good, true), (&bad, false)] {
        let o = dips()
            .args(["sim", "run", "--scene", "card", "--commands"])
            .arg(&c)
            .arg("--out")
            .arg(dir.join("out.json"))
            .arg("--hand-model")
            .arg(hand)
            .output()
            .unwrap();
        assert_eq!(
            o.status.success(),
            ok,
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        if !ok {
            assert!(String::from_utf8_lossy(&o.stderr).contains("tip_radius must be positive"));
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `dips sim render --scene card [EXTRA..] --trajectory TRAJ --out OUT`.
fn render_card(extra: &[&str], traj: &Path, out: &Path) -> std::process::Output {
    dips()
        .args(["sim", "render", "--scene", "card"])
        .args(extra)
        .arg("--trajectory")
        .arg(traj)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn an_empty_trajectory_is_named_as_empty_and_a_bad_step_names_the_range() {
    let dir = tmpdir("empty");
    std::fs::create_dir_all(&dir).unwrap();
    let empty = dir.join("empty.json");
    std::fs::write(
        &empty,
        r#"{"scene":"card","states":[],"valid":[],"contacts":[],"max_penetration":[],"flags":[]}"#,
    )
    .unwrap();
    let r = render_card(&[], &empty, &dir.join("x.svg"));
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("holds no states"), "{err}");
    assert!(!err.contains("--step"), "no --step was given: {err}");

    let (o, traj) = run_sim("card", r#"{"dq": [[0,0,0,0,0,0,0,0]]}"#, &dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = render_card(&["--step", "5"], &traj, &dir.join("y.svg"));
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("--step 5 is out of range (0 ≤ step < 2)"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
