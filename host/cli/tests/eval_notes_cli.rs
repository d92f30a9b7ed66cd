//! `dips eval` says what differs on resume and what a summary lacks (issue 36).

use std::process::Command;

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

#[test]
fn resume_names_the_differing_setting_and_summaries_name_missing_trials() {
    let dir = std::env::temp_dir().join(format!("dips-eval-notes-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.to_str().unwrap();
    let base = [
        "eval",
        "--task",
        "card",
        "--methods",
        "csvto-sampled",
        "--max-modes",
        "1",
        "--jobs",
        "1",
        "--quiet",
        "--out",
        out,
    ];
    let with = |extra: &[&str]| {
        let mut a = base.to_vec();
        a.extend_from_slice(extra);
        dips(&a)
    };
    let (code, err) = with(&["--trials", "1"]);
    assert_eq!(code, Some(0), "{err}");

    let (code, err) = with(&["--trials", "1", "--sampler", "ddim:8"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("--sampler is \"ddpm:16\" there and \"ddim:8\" here"),
        "{err}"
    );
    assert!(!err.contains("\"time_budget_s\""), "no JSON dump: {err}");

    let (code, err) = dips(&["eval", "--summarize-only", "--trials", "3", "--out", out]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("csvto-sampled: 1 of 3 trials finished"),
        "{err}"
    );
    assert!(err.contains("asked for 1 trials"), "{err}");
    let (code, err) = dips(&["eval", "--summarize-only", "--out", out]);
    assert_eq!(code, Some(0), "{err}");
    assert!(!err.contains("trials finished"), "all there: {err}");
    let _ = std::fs::remove_dir_all(&dir);
}
