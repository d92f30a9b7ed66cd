//! `dips eval --write-protocol` and `dips eval --protocol` (issue 38): a protocol written from
//! flags, refused until committed, refused when a flag or a model differs, and a tiny run
//! (one card episode of one mode) whose `results.json` carries the registration.

use std::path::Path;
use std::process::Command;

fn dips(dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_dips"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn git(dir: &Path, args: &[&str]) -> String {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args([
            "-c",
            "user.name=dips test",
            "-c",
            "user.email=test@example.invalid",
            "-c",
            "commit.gpgsign=false",
        ])
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "git {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

#[test]
fn a_protocol_is_written_refused_until_committed_and_registers_its_run() {
    let repo = std::env::temp_dir().join(format!("dips-protocol-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&repo);
    std::fs::create_dir_all(&repo).unwrap();
    git(&repo, &["init", "-q", "."]);
    let protocol = "protocols/card-10000.json";

    let (code, err) = dips(
        &repo,
        &[
            "eval",
            "--write-protocol",
            protocol,
            "--task",
            "card",
            "--methods",
            "csvto-sampled",
            "--max-modes",
            "1",
            "--trials",
            "1",
        ],
    );
    assert_eq!(code, Some(1), "a protocol names its seeds: {err}");
    assert!(err.contains("--first-seed"), "{err}");
    let write = [
        "eval",
        "--write-protocol",
        protocol,
        "--task",
        "card",
        "--methods",
        "csvto-sampled",
        "--max-modes",
        "1",
        "--trials",
        "1",
        "--first-seed",
        "10000",
    ];
    let (code, err) = dips(&repo, &write);
    assert_eq!(code, Some(0), "{err}");
    let text = std::fs::read_to_string(repo.join(protocol)).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["name"], "card-10000");
    assert_eq!(json["eval"]["first_seed"], 10000);
    assert_eq!(json["eval"]["episode"]["max_modes"], 1);
    let (code, err) = dips(&repo, &write);
    assert_eq!(code, Some(1), "never overwritten: {err}");

    // Task, methods and seeds come from the protocol; the other flags must agree with it.
    let run = |out: &str, extra: &[&str]| {
        let mut a = vec![
            "eval",
            "--protocol",
            protocol,
            "--max-modes",
            "1",
            "--jobs",
            "1",
            "--quiet",
            "--out",
            out,
        ];
        a.extend_from_slice(extra);
        dips(&repo, &a)
    };
    let (code, err) = run("results/card", &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("is not tracked by git"), "{err}");
    assert!(err.contains("commit it"), "{err}");
    assert!(!repo.join("results/card").exists());

    git(&repo, &["add", protocol]);
    git(&repo, &["commit", "-q", "-m", "register card-10000"]);
    let (code, err) = run("results/card", &["--sampler", "ddim:8"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("--sampler is \"ddpm:16\" in the protocol and \"ddim:8\" in this run"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    let (code, err) = run("results/card", &["--first-seed", "10001"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--first-seed is 10000"), "{err}");

    let (code, err) = run("results/card", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("labelled registered"), "{err}");
    let results: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo.join("results/card/results.json")).unwrap(),
    )
    .unwrap();
    let r = &results["registration"];
    assert_eq!(r["status"], "registered", "{results}");
    assert_eq!(r["protocol"], protocol);
    assert_eq!(
        r["protocol_sha256"],
        dips_eval::protocol::sha256_bytes(&std::fs::read(repo.join(protocol)).unwrap())
    );
    assert_eq!(r["commit"], git(&repo, &["rev-parse", "HEAD"]));
    assert_eq!(r["dirty"], false);
    assert!(r["cpu"].as_str().is_some_and(|c| !c.is_empty()), "{r}");
    assert_eq!(r["settings"]["episode"]["sampler"], "ddpm:16");
    assert_eq!(r["settings"]["first_seed"], 10000);
    assert_eq!(results["trials"].as_array().map(Vec::len), Some(1));
    let md = std::fs::read_to_string(repo.join("results/card/results.md")).unwrap();
    assert!(md.contains("**registered**"), "{md}");

    // Committed, the results spend the range. The registered run resumed in its own
    // directory (a session that committed partial results) stays registered and adds nothing
    // that is done; anywhere else the same protocol is a rerun.
    git(&repo, &["add", "results/card/registration.json"]);
    git(&repo, &["commit", "-q", "-m", "card-10000 results"]);
    let (code, err) = run("results/card", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("labelled registered"), "{err}");
    assert!(err.contains("0 episodes run"), "{err}");
    let (code, err) = run("results/card-again", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("labelled rerun"), "{err}");

    // A model whose hash is not the protocol's is named with both hashes (refused before any
    // model is loaded or any episode runs).
    let dips_protocol = "protocols/card-dips.json";
    let (code, err) = dips(
        &repo,
        &[
            "eval",
            "--write-protocol",
            dips_protocol,
            "--task",
            "card",
            "--methods",
            "dips",
            "--trials",
            "1",
            "--first-seed",
            "10100",
        ],
    );
    assert_eq!(code, Some(0), "{err}");
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(repo.join(dips_protocol)).unwrap()).unwrap();
    let shipped = json["models"]["denoiser.onnx"]
        .as_str()
        .unwrap()
        .to_string();
    json["models"]["denoiser.onnx"] = "0".repeat(64).into();
    std::fs::write(repo.join(dips_protocol), json.to_string()).unwrap();
    let (code, err) = dips(
        &repo,
        &[
            "eval",
            "--protocol",
            dips_protocol,
            "--protocol-uncommitted",
            "--out",
            "results/dips",
        ],
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("denoiser.onnx: sha256"), "{err}");
    assert!(err.contains(&shipped), "{err}");
    assert!(err.contains(&"0".repeat(64)), "{err}");
    assert!(!repo.join("results/dips").exists());
    let _ = std::fs::remove_dir_all(&repo);
}

/// `--first-mode touching` is written into the protocol (absent: the paper's `any`), so a
/// registered run and its resume plan with the same rule.
#[test]
fn the_first_mode_rule_is_written_into_the_protocol() {
    let dir = std::env::temp_dir().join(format!("dips-first-mode-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let write = |file: &str, extra: &[&str]| {
        let mut a = vec![
            "eval",
            "--write-protocol",
            file,
            "--task",
            "card",
            "--methods",
            "dips",
            "--trials",
            "2",
            "--first-seed",
            "10000",
        ];
        a.extend_from_slice(extra);
        let (code, err) = dips(&dir, &a);
        assert_eq!(code, Some(0), "{err}");
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()["eval"]["episode"].clone()
    };
    let touching = write("touching.json", &["--first-mode", "touching"]);
    assert_eq!(touching["first_mode"], "touching");
    let paper = write("paper.json", &[]);
    assert!(paper.get("first_mode").is_none(), "{paper}");
    let _ = std::fs::remove_dir_all(&dir);
}
