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
fn an_unknown_method_lists_the_available_ones() {
    let out = dips()
        .args(["episode", "--task", "card", "--method", "pen", "--out"])
        .arg(temp_dir("reject"))
        .output()
        .expect("run dips");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unknown method")
            && err.contains("dips-max-likelihood")
            && err.contains("diffusion-policy"),
        "{err}"
    );
}

#[test]
fn bad_models_and_output_paths_fail_before_the_episode() {
    let out = dips()
        .args(["episode", "--task", "card", "--method", "dips"])
        .args(["--models", "/nonexistent-dips-models", "--out"])
        .arg(temp_dir("models"))
        .output()
        .expect("run dips");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent-dips-models"), "{err}");
    let out = dips()
        .args(["episode", "--task", "card", "--method", "csvto-sampled"])
        .args(["--out", "/dev/null/result-dir"])
        .output()
        .expect("run dips");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("cannot create the output directory"), "{err}");
    assert!(!err.contains("mode 1/"), "the episode ran first: {err}");
}

#[test]
fn a_dips_card_episode_plans_before_every_mode_with_the_shipped_models() {
    let dir = temp_dir("dips");
    let out = dips()
        .args([
            "episode", "--task", "card", "--method", "dips", "--seed", "3",
        ])
        .args(["--sampler", "ddim:4", "--node-budget", "3", "--out"])
        .arg(&dir)
        .output()
        .expect("run dips");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("result.json")).unwrap()).unwrap();
    assert_eq!(v["method"], "dips");
    let modes = v["modes"].as_array().unwrap();
    let plans = v["plans"].as_array().unwrap();
    assert!(!modes.is_empty() && modes.len() <= 5, "{v}");
    // One call before every executed mode (and one more when the last plan was empty).
    assert!(
        plans.len() == modes.len() || plans.len() == modes.len() + 1,
        "{v}"
    );
    assert_eq!(v["planning_s"].as_array().unwrap().len(), plans.len());
    for (i, p) in plans.iter().enumerate() {
        assert_eq!(p["executed"], i);
        assert!(p["nodes_expanded"].as_u64().unwrap() <= 3, "{p}");
        assert!(p["seconds"].as_f64().unwrap() > 0.0);
        if let Some(first) = p["modes"].as_array().unwrap().first() {
            assert_eq!(first, &modes[i], "plan {i} was not the executed mode");
        }
    }
    let d = v["final_distance_m"].as_f64().unwrap();
    assert!(d.is_finite());
    // success is the documented rule applied to the outcome.
    assert_eq!(
        v["success"].as_bool().unwrap(),
        v["valid"].as_bool().unwrap() && d <= 0.01
    );
    assert!(v["success_rule"].as_str().unwrap().contains("1 cm"));
    // The card's raw states are 8 joints and the card's x, y, yaw, and labelled so.
    let cols: Vec<&str> = v["state_columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert_eq!(
        cols.len(),
        v["mode_runs"][0]["start_state"].as_array().unwrap().len()
    );
    assert_eq!(cols[0], "q_index_0");
    assert_eq!(cols[9], "card_y");
    assert_eq!(
        v["plan_state_columns"].as_array().unwrap().len(),
        plans[0]["expected_terminal_state"]
            .as_array()
            .unwrap()
            .len()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_short_dips_screwdriver_episode_plans_executes_and_replans() {
    let dir = temp_dir("dips-sd");
    let out = dips()
        .args([
            "episode",
            "--task",
            "screwdriver",
            "--method",
            "dips",
            "--seed",
            "5",
        ])
        .args([
            "--sampler",
            "ddim:4",
            "--node-budget",
            "3",
            "--max-modes",
            "2",
            "--out",
        ])
        .arg(&dir)
        .output()
        .expect("run dips");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("result.json")).unwrap()).unwrap();
    let modes = v["modes"].as_array().unwrap();
    let plans = v["plans"].as_array().unwrap();
    assert!(!modes.is_empty() && modes.len() <= 2, "{v}");
    assert_eq!(
        plans.len(),
        modes.len(),
        "one planning call before each mode: {v}"
    );
    for (i, p) in plans.iter().enumerate() {
        assert_eq!(p["modes"][0], modes[i], "plan {i}");
        // The screwdriver searches the modes the episode has left (7, then 6; `--max-modes`
        // does not change it); its goal is the measured yaw − π/3.
        assert_eq!(p["depth"].as_u64(), Some(7 - i as u64), "plan {i}");
        assert!(p["goal"].as_f64().unwrap() < 0.0);
    }
    // Each mode ran 12 CSVTO steps from diffusion samples.
    assert_eq!(
        v["csvto_step_s"].as_array().unwrap().len(),
        12 * modes.len()
    );
    assert!(v["final_yaw"].as_f64().unwrap().is_finite());
    let _ = std::fs::remove_dir_all(&dir);
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
    // One turn of about −0.3 rad is short of the −π/3 the rule asks for.
    assert_eq!(v["success"], false);
    assert_eq!(v["state_columns"][14], "yaw");
    assert_eq!(v["csvto_step_s"].as_array().map(Vec::len), Some(12));
    // A fixed sequence makes no planning call.
    assert_eq!(v["planning_s"].as_array().map(Vec::len), Some(0));
    assert!(v.get("plans").is_none());
    // Progress went to stderr.
    assert!(String::from_utf8_lossy(&out.stderr).contains("turn step 12/12"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every file `page` references exists beside it, and nothing points at the network.
fn assert_assets_exist(page: &std::path::Path) -> String {
    let html = std::fs::read_to_string(page).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>"), "{}", page.display());
    let files = dips_report::html::referenced_files(&html);
    assert!(!files.is_empty());
    for f in files.iter().filter(|f| !f.starts_with('#')) {
        assert!(!f.contains("://"), "network reference {f}");
        let p = page.parent().unwrap().join(f);
        assert!(
            p.is_file(),
            "{} references missing {}",
            page.display(),
            p.display()
        );
    }
    html
}

#[test]
fn a_rendered_episode_writes_an_animation_plots_and_a_report_whose_assets_exist() {
    let dir = temp_dir("render");
    let out = dips()
        .args(["episode", "--task", "card", "--method", "csvto-sampled"])
        .args(["--modes", "index", "--seed", "5", "--render", "--out"])
        .arg(&dir)
        .output()
        .expect("run dips");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let html = assert_assets_exist(&dir.join("report.html"));
    for section in [
        "Animation",
        "Plots over time",
        "Executed modes",
        "card · csvto-sampled · seed 5",
    ] {
        assert!(html.contains(section), "report lacks {section}");
    }
    let gif = std::fs::read(dir.join("episode.gif")).unwrap();
    assert_eq!(&gif[..6], b"GIF89a");
    let svg = std::fs::read_to_string(dir.join("timeline.svg")).unwrap();
    for text in [
        "card y",
        "mode goal",
        "force (N)",
        "clearance δ",
        "CSVTO solve",
        "index",
    ] {
        assert!(svg.contains(text), "timeline lacks {text}");
    }
    // Every step logs the world's contacts, and the pushing finger pushed.
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("result.json")).unwrap()).unwrap();
    let steps = v["mode_runs"][0]["steps"].as_array().unwrap();
    assert!(steps.iter().all(|s| s["contacts"].is_array()));
    assert!(
        steps
            .iter()
            .flat_map(|s| s["contacts"].as_array().unwrap())
            .any(|c| c["finger"] == "index"),
        "the index never touched the card"
    );
    // `dips render` draws any state of it, or the whole of it; `sim render` reads it too.
    let result = dir.join("result.json");
    for (extra, name, ok) in [
        (vec![], "again.gif", true),
        (vec!["--step", "2"], "two.png", true),
        (vec![], "last.svg", true),
        (vec!["--step", "99"], "bad.png", false),
        (vec![], "bad.txt", false),
    ] {
        let o = dips()
            .args(["render", "--input"])
            .arg(&result)
            .args(&extra)
            .arg("--out")
            .arg(dir.join(name))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.success(), ok, "{name}: {err}");
        if !ok {
            assert!(
                err.contains("out of range") || err.contains(".gif (animation), .svg or .png"),
                "{err}"
            );
        }
    }
    let svg = std::fs::read_to_string(dir.join("last.svg")).unwrap();
    for text in [
        "front (x–z)",
        "top (x–y)",
        "x (cm)",
        "index",
        "task goal",
        "mode 1/1",
    ] {
        assert!(svg.contains(text), "frame lacks {text}");
    }
    let o = dips()
        .args(["sim", "render", "--scene", "card", "--trajectory"])
        .arg(&result)
        .arg("--out")
        .arg(dir.join("sim.png"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_diffusion_policy_baseline_acts_from_the_state_alone_with_the_shipped_model() {
    let dir = temp_dir("policy");
    let out = dips()
        .args(["episode", "--task", "card", "--method", "diffusion-policy"])
        .args(["--seed", "2", "--max-modes", "1", "--out"])
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
    assert_eq!(v["method"], "diffusion-policy");
    // No contact modes and no planning: one run of H = 8 actions, each the policy's own.
    assert_eq!(v["modes"], serde_json::json!(["policy"]));
    assert!(v.get("plans").is_none() && v["planning_s"].as_array().unwrap().is_empty());
    let steps = v["mode_runs"][0]["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 8);
    for s in steps {
        let dq = s["dq"].as_array().unwrap();
        assert_eq!(dq.len(), 8);
        assert!(dq.iter().any(|x| x.as_f64().unwrap() != 0.0), "{s}");
        assert!(s["solve_s"].as_f64().unwrap() > 0.0);
    }
    assert!(v["final_distance_m"].as_f64().unwrap().is_finite());
    // Its report reads the episode like any other.
    assert_assets_exist(&dir.join("report.html"));
    // --modes makes no sense for it.
    let o = dips()
        .args(["episode", "--task", "card", "--method", "diffusion-policy"])
        .args(["--modes", "index", "--out"])
        .arg(temp_dir("policy-modes"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no contact modes"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The `dips-firmware-sim` binary (built here when the test run did not build it).
fn firmware_sim() -> std::path::PathBuf {
    if let Ok(p) = dips_link::find_firmware() {
        return p;
    }
    let mut build = Command::new(env!("CARGO"));
    build.args(["build", "-p", "dips-firmware-sim"]);
    if !cfg!(debug_assertions) {
        build.arg("--release");
    }
    assert!(build.status().expect("run cargo").success());
    dips_link::find_firmware().expect("dips-firmware-sim after building it")
}

/// A result file without its wall times (`*_s`, `seconds`), which no two runs share.
fn without_times(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(map) => {
            map.retain(|k, _| !(k.ends_with("_s") || k == "seconds"));
            map.values_mut().for_each(without_times);
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(without_times),
        _ => {}
    }
}

/// A fast card `--method dips` episode (seed 8, `ddim:4`, two expansions per plan, no time
/// budget, so the plans do not depend on the machine's speed), the remote-kernel tests' run.
fn fast_card_dips_episode() -> Command {
    let mut c = dips();
    c.args([
        "episode", "--task", "card", "--method", "dips", "--seed", "8",
    ])
    .args([
        "--sampler",
        "ddim:4",
        "--node-budget",
        "2",
        "--time-budget-s",
        "0",
    ]);
    c
}

#[test]
fn a_dips_episode_planned_by_a_spawned_firmware_is_the_in_process_episode_bit_for_bit() {
    let firmware = firmware_sim();
    let run = |name: &str, kernel: &[&str]| {
        let dir = temp_dir(name);
        let out = fast_card_dips_episode()
            .args(["--max-modes", "2"])
            .args(kernel)
            .arg("--out")
            .arg(&dir)
            .output()
            .expect("run dips");
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(out.status.success(), "{err}");
        let text = std::fs::read_to_string(dir.join("result.json")).unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        without_times(&mut v);
        (v, err)
    };
    let (mut local, _) = run("local", &[]);
    let spawn = format!("spawn:{}", firmware.display());
    let (remote, err) = run("spawned", &["--kernel", &spawn]);
    assert!(err.contains("planning through dips-firmware-sim"), "{err}");
    // What the particles did is seen in process only (the firmware keeps it to itself); the
    // plans themselves must agree bit for bit.
    for plan in local["plans"].as_array_mut().unwrap() {
        let diag = plan
            .as_object_mut()
            .unwrap()
            .remove("particles_diagnostics");
        assert!(diag.is_some_and(|d| d["children"].as_u64() > Some(0)));
    }
    assert_eq!(remote, local);
    assert_eq!(local["plans"].as_array().unwrap().len(), 2);
}

#[test]
fn a_firmware_that_dies_mid_episode_is_an_error_naming_the_last_request() {
    let firmware = firmware_sim();
    // The firmware lives for 5 s: long enough to greet, take the models and plan the first
    // mode, not long enough for the episode's five (about 30 s).
    let script = temp_dir("dying").with_extension("sh");
    std::fs::write(
        &script,
        format!("#!/bin/sh\nexec timeout 5 {}\n", firmware.display()),
    )
    .unwrap();
    let mut perm = std::fs::metadata(&script).unwrap().permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perm, 0o755);
    std::fs::set_permissions(&script, perm).unwrap();
    let t0 = std::time::Instant::now();
    let out = fast_card_dips_episode()
        .arg("--kernel")
        .arg(format!("spawn:{}", script.display()))
        .arg("--out")
        .arg(temp_dir("dying-out"))
        .output()
        .expect("run dips");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("planning call 1"),
        "the first plan was made: {err}"
    );
    assert!(
        err.contains("closed the link while PlanRequest") && err.contains("planning before mode"),
        "{err}"
    );
    assert!(t0.elapsed() < std::time::Duration::from_secs(120));
}

/// The regrasp guard, as a user starts it: a card `middle` mode (the middle finger pushes, the
/// index regrasps) from the start, where both fingers rest on the card. `result.json` records
/// the guard; the index stays clear of the card until its touch-down step; every step the
/// guard changed names what it did per finger. (What the guard does to a command is the
/// unit tests' in `dips_exec::regrasp_guard`: here the plan keeps its clearance and the guard
/// need not act.)
#[test]
fn the_regrasp_guard_is_recorded_and_the_regrasping_finger_stays_clear() {
    let out = temp_dir("guard");
    let run = dips()
        .args([
            "episode",
            "--task",
            "card",
            "--method",
            "csvto-sampled",
            "--modes",
            "middle",
            "--regrasp-guard",
            "clearance",
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("run dips");
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    let result: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("result.json")).unwrap()).unwrap();
    assert_eq!(result["regrasp_guard"], "clearance");
    let steps = result["mode_runs"][0]["steps"].as_array().unwrap();
    for s in &steps[..steps.len() - 1] {
        let index_sdf = s["tip_sdf"][0].as_f64().unwrap();
        assert!(index_sdf > 2e-3, "the index touched the card early: {s:?}");
    }
    for s in steps.iter().filter_map(|s| s.get("guarded")) {
        let actions = s.as_array().unwrap();
        assert_eq!(actions.len(), 2);
        assert!(
            actions[1].is_null(),
            "the pushing middle finger is never guarded"
        );
        assert!(["lifted", "shortened"].contains(&actions[0].as_str().unwrap()));
    }
    assert!(
        steps.last().unwrap().get("guarded").is_none(),
        "the last step is free"
    );
    let _ = std::fs::remove_dir_all(&out);
}
