//! The offline pipeline from nothing, as a user runs it: `dips datagen` (two real card demos
//! with the default CSVTO settings), `dips train` (a tiny network, a few steps, from a
//! settings file), then `dips model check` and `dips plan` on what it wrote; the demos are made
//! with the paper's card goals, which travel from the demos to the models to the planner. Also
//! the CLI's errors for bad flags.

use std::path::{Path, PathBuf};
use std::process::Command;

use dips_train::TrainSettings;

fn dips(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(args)
        .output()
        .expect("dips runs")
}

fn tmp(name: &str) -> PathBuf {
    let p = std::env::temp_dir().join(format!("dips-offline-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&p);
    std::fs::create_dir_all(&p).unwrap();
    p
}

fn tiny_settings(path: &Path) {
    let mut s = TrainSettings::default();
    s.net.widths = vec![8, 16];
    s.net.mid_blocks = 1;
    s.net.embed_dim = 16;
    s.net.time_embed_dim = 8;
    s.net.context_embed_dim = 8;
    s.held_out_fraction = 0.5;
    s.eval_samples = 64;
    s.checkpoint_every = 0;
    s.denoiser.diffusion_steps = 16;
    s.denoiser.batch = 32;
    s.denoiser.steps = 20;
    s.discriminator.samples = 32;
    s.discriminator.eval_samples = 16;
    s.discriminator.batch = 16;
    s.discriminator.steps = 10;
    std::fs::write(path, serde_json::to_string(&s).unwrap()).unwrap();
}

#[test]
fn datagen_then_train_then_check_and_plan() {
    let dir = tmp("pipeline");
    let data = dir.join("data");
    let out = dips(&[
        "datagen",
        "--task",
        "card",
        "--card-goals",
        "paper",
        "--demos",
        "2",
        "--out",
        data.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let settings: serde_json::Value =
        serde_json::from_slice(&std::fs::read(data.join("datagen.json")).unwrap()).unwrap();
    assert_eq!(settings["batches"][0]["exec"]["card_goals"], "paper");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["generated"], 2);
    assert_eq!(report["manifest"]["seeds"], serde_json::json!([0, 1]));
    assert_eq!(report["manifest"]["trajectories"], 2 * 5 * 8 * 16);
    // Run again: everything is there already.
    let again = dips(&[
        "datagen",
        "--task",
        "card",
        "--card-goals",
        "paper",
        "--demos",
        "2",
        "--out",
        data.to_str().unwrap(),
        "--quiet",
    ]);
    let again: serde_json::Value = serde_json::from_slice(&again.stdout).unwrap();
    assert_eq!(
        (again["generated"].as_u64(), again["skipped"].as_u64()),
        (Some(0), Some(2))
    );
    // The same seeds with our goals would mix two kinds of demos: refused, naming both.
    let ours = dips(&[
        "datagen",
        "--task",
        "card",
        "--demos",
        "2",
        "--out",
        data.to_str().unwrap(),
        "--quiet",
    ]);
    let err = String::from_utf8_lossy(&ours.stderr);
    assert!(
        !ours.status.success() && err.contains("card_goals") && err.contains("paper"),
        "{err}"
    );

    let settings = dir.join("tiny.json");
    tiny_settings(&settings);
    let models = dir.join("models");
    let out = dips(&[
        "train",
        "--task",
        "card",
        "--data",
        data.to_str().unwrap(),
        "--out",
        models.to_str().unwrap(),
        "--settings",
        settings.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for role in ["denoiser", "discriminator"] {
        let file = models.join(format!("{role}.onnx"));
        let out = dips(&["model", "check", file.to_str().unwrap()]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains(role) && text.contains("card"), "{text}");
        let summary: serde_json::Value = serde_json::from_str(&text).unwrap();
        if role == "denoiser" {
            assert_eq!(summary["trained"]["card_goals"], "paper", "{text}");
        }
    }
    let out = dips(&[
        "plan",
        "--task",
        "card",
        "--models",
        models.to_str().unwrap(),
        "--seed",
        "0",
        "--node-budget",
        "20",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The models say which goals they were trained for; other goals are refused, naming both.
    let out = dips(&[
        "plan",
        "--task",
        "card",
        "--models",
        models.to_str().unwrap(),
        "--card-goals",
        "capped",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("--card-goals capped")
            && err.contains("card goals paper"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_offline_flags_are_clear_errors() {
    let dir = tmp("flags");
    let cases: [(&[&str], &str); 6] = [
        (
            &["datagen", "--task", "cube", "--demos", "1", "--out", "x"],
            "unknown task",
        ),
        (
            &[
                "datagen",
                "--task",
                "card",
                "--card-goals",
                "flat",
                "--demos",
                "1",
                "--out",
                "x",
            ],
            "unknown card goals `flat` (expected paper or capped)",
        ),
        (
            &[
                "datagen",
                "--task",
                "screwdriver",
                "--card-goals",
                "paper",
                "--demos",
                "1",
                "--out",
                "x",
            ],
            "the screwdriver has no pushes",
        ),
        (
            &[
                "datagen", "--task", "card", "--demos", "1", "--out", "x", "--shard", "3/2",
            ],
            "I/N",
        ),
        (
            &["datagen", "--task", "card", "--demos", "0", "--out", "x"],
            "--demos",
        ),
        (
            &[
                "train",
                "--task",
                "card",
                "--data",
                "/nonexistent",
                "--out",
                "x",
            ],
            "/nonexistent",
        ),
    ];
    for (args, expect) in cases {
        let out = Command::new(env!("CARGO_BIN_EXE_dips"))
            .args(args)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?} succeeded");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
