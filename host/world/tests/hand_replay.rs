//! Hand I/O: recording a world through the `Hand` trait and replaying the log.

use dips_world::hand::{Hand, HandError, Recorder, replay};
use dips_world::kinematics::HandJoints;
use dips_world::scenes::SceneKind;
use dips_world::world::{World, scripted};

fn targets_from(world: &World, dq: &[f64]) -> HandJoints {
    let mut t = world.joints();
    for (k, f) in world.scene().task_fingers().iter().enumerate() {
        for j in 0..4 {
            t[f.index()][j] += dq[4 * k + j];
        }
    }
    t
}

fn record(scene: SceneKind, path: &std::path::Path, steps: usize) -> Vec<Vec<f64>> {
    let world = World::new(scene);
    let params = world.params().clone();
    let mut rec = Recorder::create(world, path, Some(params)).unwrap();
    let mut states = vec![rec.inner().state()];
    for _ in 0..steps {
        let dq = match scene {
            SceneKind::Screwdriver => scripted::pinch_turn_action(rec.inner(), 0.004, 0.005),
            SceneKind::Card => scripted::card_push_action(rec.inner(), -0.006, 0.003),
        };
        let targets = targets_from(rec.inner(), &dq);
        rec.command(&targets).unwrap();
        states.push(rec.inner().state());
    }
    rec.finish().unwrap();
    states
}

#[test]
fn replay_reproduces_recorded_states() {
    let dir = std::env::temp_dir().join(format!("dips-hand-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for scene in SceneKind::ALL {
        let path = dir.join(format!("{}.jsonl", scene.name()));
        let states = record(scene, &path, 4);
        // Something happened, so the check is not vacuous.
        let moved: f64 = states[0]
            .iter()
            .zip(states.last().unwrap())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(moved > 1e-3, "{scene:?} did not move");
        let rep = replay(&path).unwrap();
        assert_eq!(rep.steps, 4);
        assert!(rep.max_deviation < 1e-9, "{}", rep.max_deviation);
        for (a, b) in rep.states.iter().zip(&states) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() < 1e-9);
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn tampered_or_broken_logs_are_reported() {
    let dir = std::env::temp_dir().join(format!("dips-hand-tamper-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("card.jsonl");
    record(SceneKind::Card, &path, 2);
    // Change the second step's target of the index's second joint: replay must diverge.
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut v: serde_json::Value = serde_json::from_str(&lines[2]).unwrap();
    let t = v["targets"][0][1].as_f64().unwrap();
    v["targets"][0][1] = serde_json::json!(t + 0.05);
    lines[2] = v.to_string();
    std::fs::write(&path, lines.join("\n")).unwrap();
    assert!(matches!(
        replay(&path),
        Err(HandError::Diverged { step: 1, .. })
    ));
    std::fs::write(&path, "not json\n").unwrap();
    assert!(matches!(
        replay(&path),
        Err(HandError::Format { line: 1, .. })
    ));
    assert!(matches!(
        replay(&dir.join("missing.jsonl")),
        Err(HandError::Io { .. })
    ));
    std::fs::remove_dir_all(&dir).ok();
}
