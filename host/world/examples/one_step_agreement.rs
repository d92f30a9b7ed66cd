//! One-step agreement of our world with a recorded episode (issue 37 item 5): every step of
//! every mode of the given `result.json` files (from `dips episode`/`dips eval`, on any hand)
//! is replayed on our world from the state the episode measured before it, with the command the
//! episode sent (`dq`), and our world's next state is set beside the recorded one (up to the
//! step where the recording went invalid, that step included). Run on
//! episodes executed by the MuJoCo hand, it says how far our world's one-step predictions are
//! from MuJoCo's along the states MuJoCo actually visits.
//!
//! ```sh
//! cargo run --release -p dips-world --example one_step_agreement -- OUT.json RESULT.json...
//! ```
//!
//! `OUT.json` gets, per task, every step (mode, object coordinates' change on both, joint
//! difference) and the summary `docs/mujoco.md` quotes: the screwdriver's per-step yaw slope
//! (recorded on ours, least squares through the origin), the ratio of the summed yaw changes
//! and their mean absolute difference; the card's displacement ratio along y, the mean
//! absolute differences of its `(x, y, θ)` changes; for both, the mean absolute difference of
//! the task joints after the step.

use std::collections::BTreeMap;
use std::process::ExitCode;

use dips_world::scenes::SceneKind;
use dips_world::world::World;
use serde_json::{Value, json};

/// One replayed step.
struct Step {
    mode: String,
    /// Change of the object coordinates on the recording's hand.
    recorded: [f64; 3],
    /// Change of the object coordinates on our world.
    ours: [f64; 3],
    /// Mean absolute difference of the task joints after the step (rad).
    joints: f64,
}

fn numbers(v: &Value, what: &str) -> Result<Vec<f64>, String> {
    v.as_array()
        .ok_or_else(|| format!("{what} is not an array"))?
        .iter()
        .map(|x| {
            x.as_f64()
                .ok_or_else(|| format!("{what} holds a non-number"))
        })
        .collect()
}

fn replay(path: &str) -> Result<(SceneKind, String, Vec<Step>), String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let r: Value = serde_json::from_str(&text).map_err(|e| format!("{path}: {e}"))?;
    let task = r["task"].as_str().ok_or(format!("{path}: no task"))?;
    let scene: SceneKind = task.parse().map_err(|e| format!("{path}: {e}"))?;
    let hand = r["hand"].as_str().unwrap_or("world").to_string();
    let a = scene.action_dim();
    let mut world = World::new(scene);
    let mut steps = Vec::new();
    // Steps taken after the recording went invalid (a dropped screwdriver) are not replayed:
    // neither world models what follows a drop.
    let mut valid = true;
    let runs = r["mode_runs"]
        .as_array()
        .ok_or(format!("{path}: no mode_runs"))?;
    for run in runs {
        let mode = run["mode"].as_str().unwrap_or("?").to_string();
        let mut before = numbers(&run["start_state"], "start_state")?;
        for step in run["steps"].as_array().ok_or("a mode without steps")? {
            let dq = numbers(&step["dq"], "dq")?;
            let after = numbers(&step["state"], "state")?;
            if !valid {
                break;
            }
            valid = step["valid"].as_bool().unwrap_or(true);
            world
                .set_state(&before)
                .map_err(|e| format!("{path}: {e}"))?;
            world.step_action(&dq).map_err(|e| format!("{path}: {e}"))?;
            let ours = world.state();
            let delta = |s: &[f64]| {
                [
                    s[a] - before[a],
                    s[a + 1] - before[a + 1],
                    s[a + 2] - before[a + 2],
                ]
            };
            let joints = (0..a).map(|i| (ours[i] - after[i]).abs()).sum::<f64>() / a as f64;
            steps.push(Step {
                mode: mode.clone(),
                recorded: delta(&after),
                ours: delta(&ours),
                joints,
            });
            before = after;
        }
    }
    Ok((scene, hand, steps))
}

/// A task's replayed files, the hands that recorded them, and their steps.
type Replayed = (Vec<String>, Vec<String>, Vec<Step>);

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Least-squares slope through the origin of `y` on `x`, the ratio of the sums, and the mean
/// absolute difference.
fn agreement(steps: &[&Step], k: usize) -> Value {
    let sxy: f64 = steps.iter().map(|s| s.ours[k] * s.recorded[k]).sum();
    let sxx: f64 = steps.iter().map(|s| s.ours[k] * s.ours[k]).sum();
    let sum_r: f64 = steps.iter().map(|s| s.recorded[k]).sum();
    let sum_o: f64 = steps.iter().map(|s| s.ours[k]).sum();
    json!({
        "steps": steps.len(),
        "slope_recorded_on_ours": sxy / sxx,
        "sum_recorded": sum_r,
        "sum_ours": sum_o,
        "ratio_of_sums": sum_r / sum_o,
        "mean_abs_difference": mean(steps.iter().map(|s| (s.recorded[k] - s.ours[k]).abs())),
    })
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: one_step_agreement OUT.json RESULT.json...");
        return ExitCode::from(2);
    }
    let mut by_task: BTreeMap<&'static str, Replayed> = BTreeMap::new();
    for path in &args[1..] {
        match replay(path) {
            Ok((scene, hand, steps)) => {
                let e = by_task.entry(scene.name()).or_default();
                e.0.push(path.clone());
                e.1.push(hand);
                e.2.extend(steps);
            }
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    let mut out = serde_json::Map::new();
    for (task, (files, hands, steps)) in &by_task {
        let all: Vec<&Step> = steps.iter().collect();
        let k = if *task == "screwdriver" { 2 } else { 1 };
        let mut summary = json!({
            "files": files,
            "recorded_on": hands,
            "all_steps": agreement(&all, k),
            "joints_mean_abs_difference_rad": mean(steps.iter().map(|s| s.joints)),
        });
        if *task == "screwdriver" {
            let turns: Vec<&Step> = steps.iter().filter(|s| s.mode == "turn").collect();
            summary["turn_steps"] = agreement(&turns, 2);
            summary["coordinate"] = json!("yaw (rad)");
        } else {
            summary["coordinate"] = json!("y (m)");
            summary["x_mean_abs_difference_m"] = json!(mean(
                steps.iter().map(|s| (s.recorded[0] - s.ours[0]).abs())
            ));
            summary["theta_mean_abs_difference_rad"] = json!(mean(
                steps.iter().map(|s| (s.recorded[2] - s.ours[2]).abs())
            ));
        }
        summary["per_step"] = steps
            .iter()
            .map(|s| json!({"mode": s.mode, "recorded": s.recorded, "ours": s.ours, "joints": s.joints}))
            .collect();
        println!(
            "{task}: {} steps, {}",
            steps.len(),
            serde_json::to_string(&summary["all_steps"]).unwrap_or_default()
        );
        out.insert(task.to_string(), summary);
    }
    let text = serde_json::to_string_pretty(&Value::Object(out)).unwrap_or_default();
    if let Err(e) = std::fs::write(&args[0], text + "\n") {
        eprintln!("error: {}: {e}", args[0]);
        return ExitCode::FAILURE;
    }
    ExitCode::SUCCESS
}
