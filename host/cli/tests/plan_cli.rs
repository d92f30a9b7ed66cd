//! `dips plan` on the command line, with the exported fixture models (random weights: the
//! plans mean nothing, the pipeline and its determinism are what is checked).

use std::process::Command;

fn fixtures(dir: &str) -> String {
    format!(
        "{}/../../onnx/tests/fixtures/{dir}",
        env!("CARGO_MANIFEST_DIR")
    )
}

/// Run `dips plan` with `args`; the JSON on success, stderr on failure.
fn plan(args: &[&str]) -> Result<serde_json::Value, String> {
    let out = Command::new(env!("CARGO_BIN_EXE_dips"))
        .arg("plan")
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("run dips");
    if out.status.success() {
        Ok(serde_json::from_slice(&out.stdout).expect("JSON on stdout"))
    } else {
        Err(String::from_utf8_lossy(&out.stderr).into_owned())
    }
}

fn small(task: &str, dir: &str, seed: &str, engine: &str) -> serde_json::Value {
    let models = fixtures(dir);
    plan(&[
        "--task",
        task,
        "--models",
        &models,
        "--seed",
        seed,
        "--engine",
        engine,
        "--k",
        "4",
        "--node-budget",
        "2",
        "--sampler",
        "ddim:8",
        "--json",
    ])
    .unwrap_or_else(|e| panic!("{task}: {e}"))
}

/// The output without its wall time.
fn timeless(mut v: serde_json::Value) -> serde_json::Value {
    v.as_object_mut().unwrap().remove("planning_s");
    v
}

#[test]
fn plans_both_tasks_deterministically_with_either_engine() {
    for (task, dir, names) in [
        (
            "screwdriver",
            "torch-screwdriver-legacy",
            &["turn", "index-regrasp", "thumb-middle-regrasp"][..],
        ),
        (
            "card",
            "torch-card-dynamo",
            &["index", "middle", "both", "regrasp"][..],
        ),
    ] {
        let a = small(task, dir, "3", "kernel");
        assert_eq!(a["task"], task);
        let status = a["status"].as_str().unwrap();
        assert!(
            status == "Found" || status.starts_with("Approximate"),
            "{task}: {status}"
        );
        let modes = a["modes"].as_array().unwrap();
        assert!(!modes.is_empty(), "{task}: {a}");
        assert!(modes.iter().all(|m| names.contains(&m.as_str().unwrap())));
        let expanded = a["stats"]["nodes_expanded"].as_u64().unwrap();
        assert!((1..=2).contains(&expanded), "{task}: {a}");
        assert!(a["planning_s"].as_f64().unwrap() >= 0.0);
        // Same seed, same plan.
        assert_eq!(
            timeless(small(task, dir, "3", "kernel")),
            timeless(a.clone())
        );
        // The two engines agree to ~1e-5, so the search makes the same choices.
        let t = small(task, dir, "3", "tract");
        assert_eq!(t["modes"], a["modes"], "{task}");
        assert_eq!(t["status"], a["status"], "{task}");
    }
}

#[test]
fn bad_models_and_flags_are_clear_errors() {
    let card = fixtures("torch-card-dynamo");
    let err = plan(&["--task", "screwdriver", "--models", &card, "--json"]).unwrap_err();
    assert!(err.contains("screwdriver") && err.contains("card"), "{err}");
    let err = plan(&["--task", "card", "--models", "/nonexistent-dips-models"]).unwrap_err();
    assert!(
        err.contains("/nonexistent-dips-models/denoiser.onnx"),
        "{err}"
    );
    let err = plan(&["--task", "card", "--models", &card, "--sampler", "ddim:0"]).unwrap_err();
    assert!(err.contains("ddim:STEPS"), "{err}");
    let err = plan(&["--task", "card", "--models", &card, "--k", "17"]).unwrap_err();
    assert!(err.contains("16"), "{err}");
    let err = plan(&["--task", "pen", "--models", &card]).unwrap_err();
    assert!(err.contains("unknown task"), "{err}");
}

#[test]
fn each_task_plans_with_its_own_search_settings() {
    let settings = |task, dir| small(task, dir, "1", "kernel")["settings"].clone();
    let sd = settings("screwdriver", "torch-screwdriver-legacy");
    assert_eq!(sd["alpha"].as_f64(), Some(1e4));
    assert_eq!(sd["beta"].as_f64(), Some(1e3));
    assert_eq!(sd["max_depth"].as_u64(), Some(7));
    let card = settings("card", "torch-card-dynamo");
    assert_eq!(card["alpha"].as_f64(), Some(1e5));
    assert_eq!(card["beta"].as_f64(), Some(0.0));
    assert_eq!(card["max_depth"].as_u64(), Some(5));
    // The cost-to-come is the task's unless --cost-to-come says otherwise.
    assert_eq!(sd["cost_to_come"].as_str(), Some("cumulative"));
    assert_eq!(card["cost_to_come"].as_str(), Some("last-segment"));
    for form in ["cumulative", "last-segment"] {
        let models = fixtures("torch-card-dynamo");
        let out = plan(&[
            "--task",
            "card",
            "--models",
            &models,
            "--k",
            "4",
            "--node-budget",
            "1",
            "--sampler",
            "ddim:8",
            "--cost-to-come",
            form,
            "--json",
        ])
        .unwrap();
        assert_eq!(out["settings"]["cost_to_come"].as_str(), Some(form));
    }
    let err = plan(&["--task", "card", "--cost-to-come", "sum"]).unwrap_err();
    assert!(
        err.contains("`sum`") && err.contains("cumulative") && err.contains("last-segment"),
        "{err}"
    );
}

#[test]
fn a_sampler_beyond_the_models_steps_is_refused() {
    // The shipped card models are trained with 256 diffusion steps.
    let err = plan(&["--task", "card", "--sampler", "ddim:1000", "--json"]).unwrap_err();
    assert!(
        err.contains("ddim:1000") && err.contains("256") && err.contains("1 ≤ S ≤ 256"),
        "{err}"
    );
    let err = plan(&["--task", "card", "--sampler", "ddim:8:2"]).unwrap_err();
    assert!(err.contains("0 ≤ ETA ≤ 1"), "{err}");
    // The strided DDPM takes its steps as DDIM does, and the same bound.
    let err = plan(&["--task", "card", "--sampler", "ddpm:300"]).unwrap_err();
    assert!(
        err.contains("ddpm:300") && err.contains("1 ≤ S ≤ 256"),
        "{err}"
    );
    let err = plan(&["--task", "card", "--sampler", "ddpm:0"]).unwrap_err();
    assert!(err.contains("`ddpm:STEPS`"), "{err}");
    let models = fixtures("torch-card-dynamo");
    let out = plan(&[
        "--task",
        "card",
        "--models",
        &models,
        "--k",
        "4",
        "--node-budget",
        "1",
        "--sampler",
        "ddpm:8",
        "--json",
    ])
    .unwrap();
    assert_eq!(out["sampler"].as_str(), Some("ddpm:8"));
}

#[test]
fn search_settings_out_of_range_name_the_limit() {
    let err = plan(&["--task", "card", "--depth", "17"]).unwrap_err();
    assert!(err.contains("max_depth must be in 1..=16"), "{err}");
    let err = plan(&["--task", "card", "--k", "17"]).unwrap_err();
    assert!(err.contains("at most 16 particles"), "{err}");
    // A negative seed is a bad value of --seed, not an unknown argument.
    let err = plan(&["--task", "card", "--seed", "-1"]).unwrap_err();
    assert!(err.contains("invalid value '-1' for '--seed"), "{err}");
    let err = plan(&["--task", "card", "--threads", "0"]).unwrap_err();
    assert!(err.contains("--threads") && err.contains("≥ 1"), "{err}");
}

#[test]
fn goals_beyond_a_half_turn_plan_modes() {
    // From yaw 0 a goal of −3.5 rad (or a full turn) is far away, not already met on another
    // branch of the angle.
    for goal in ["-3.5", "-6.28"] {
        let v = plan(&[
            "--task",
            "screwdriver",
            "--goal",
            goal,
            "--k",
            "4",
            "--node-budget",
            "2",
            "--sampler",
            "ddim:4",
            "--json",
        ])
        .unwrap_or_else(|e| panic!("--goal {goal}: {e}"));
        assert!(
            !v["modes"].as_array().unwrap().is_empty(),
            "--goal {goal}: no modes planned: {v}"
        );
        assert!(
            v["status"].as_str().unwrap().contains("NodeBudget"),
            "--goal {goal}: two expansions cannot reach it: {v}"
        );
    }
}

#[test]
fn a_call_over_a_second_reports_progress_on_stderr_and_keeps_stdout_the_result() {
    // The shipped card models over a 2.5 s budget: lines on stderr while it runs. With the
    // cumulative cost-to-come a call from the card's start needs 50+ expansions (5 s or more
    // here), so it runs into the budget on any machine.
    let out = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args([
            "plan",
            "--task",
            "card",
            "--seed",
            "1",
            "--cost-to-come",
            "cumulative",
            "--time-budget-s",
            "2.5",
            "--json",
        ])
        .output()
        .expect("run dips");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let err = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("planning: "))
        .collect();
    assert!(!lines.is_empty(), "no progress on stderr: {err}");
    assert!(
        lines[0].contains("expansions started (budget 2.5 s)"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("only JSON on stdout");
    assert!(v["planning_s"].as_f64().unwrap() >= 1.0);
}
