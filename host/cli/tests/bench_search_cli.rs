//! `dips bench search --json` runs and prints the figures it promises.

use std::process::Command;

#[test]
fn bench_search_prints_json_figures() {
    let out = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args([
            "bench",
            "search",
            "--json",
            "--seconds",
            "0.2",
            "--depth",
            "3",
        ])
        .output()
        .expect("run dips");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    assert_eq!(v["bench"], "search");
    assert_eq!(v["settings"]["k"], 16);
    assert_eq!(v["settings"]["horizon_T"], 13);
    assert_eq!(v["settings"]["dim_D"], 37);
    assert!(v["expansions"].as_u64().unwrap() > 0);
    assert!(v["expansions_per_s"].as_f64().unwrap() > 0.0);
    assert!(v["planner"]["size_of_bytes"].as_u64().unwrap() > 100_000);

    let bad = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(["bench", "search", "--task", "valve", "--json"])
        .output()
        .expect("run dips");
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown task"));

    let k17 = Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(["bench", "search", "--k", "17", "--json"])
        .output()
        .expect("run dips");
    assert!(!k17.status.success());
    let err = String::from_utf8_lossy(&k17.stderr);
    assert!(err.contains("--k 17") && err.contains("1 to 16"), "{err}");
    assert!(!err.contains("CapacityExceeded"), "{err}");
}
