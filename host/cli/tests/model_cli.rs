//! `dips model check|run|lower` and `dips bench inference` end to end.

use std::path::PathBuf;
use std::process::Command;

fn fixture(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../onnx/tests/fixtures/torch-card-dynamo")
        .join(file)
}

fn dips(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_dips"))
        .args(args)
        .output()
        .unwrap()
}

fn assert_success(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn read_json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Every value within onnxruntime's reference (1e-4 relative, 1e-5 absolute floor).
fn assert_matches_reference(got: &serde_json::Value, want: &[f64], what: &str) {
    let got: Vec<f64> = serde_json::from_value(got.clone()).unwrap();
    for (g, w) in got.iter().zip(want) {
        assert!(
            (g - w).abs() <= (1e-4 * w.abs()).max(1e-5),
            "{what}: {g} vs {w}"
        );
    }
}

fn tmpdir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("dips-model-cli-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn check_prints_the_contract_as_json() {
    let out = dips(&["model", "check", fixture("denoiser.onnx").to_str().unwrap()]);
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["valid"], true);
    assert_eq!(v["contract"]["task"], "card");
    assert_eq!(v["contract"]["role"], "denoiser");
    assert_eq!(v["inputs"]["x"], serde_json::json!(["batch", 9, 29]));
}

#[test]
fn check_refuses_a_broken_file() {
    let d = tmpdir();
    let bad = d.join("broken.onnx");
    let bytes = std::fs::read(fixture("denoiser.onnx")).unwrap();
    std::fs::write(&bad, &bytes[..bytes.len() / 3]).unwrap();
    let out = dips(&["model", "check", bad.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("ONNX"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn run_with_both_engines_reproduces_the_reference_and_lower_writes_a_blob() {
    let d = tmpdir();
    let io = fixture("discriminator.io.json");
    let reference = read_json(&io);
    let want: Vec<f64> =
        serde_json::from_value(reference["outputs"]["p_real"]["data"].clone()).unwrap();
    for engine in ["tract", "kernel"] {
        let out_path = d.join(format!("out-{engine}.json"));
        let out = dips(&[
            "model",
            "run",
            fixture("discriminator.onnx").to_str().unwrap(),
            "--input",
            io.to_str().unwrap(),
            "--output",
            out_path.to_str().unwrap(),
            "--engine",
            engine,
        ]);
        assert_success(&out);
        let got = read_json(&out_path);
        assert_eq!(got["outputs"]["p_real"]["shape"], serde_json::json!([3, 1]));
        assert_matches_reference(&got["outputs"]["p_real"]["data"], &want, engine);
    }
    let blob = d.join("disc.dipsm");
    let out = dips(&[
        "model",
        "lower",
        fixture("discriminator.onnx").to_str().unwrap(),
        "--out",
        blob.to_str().unwrap(),
    ]);
    assert_success(&out);
    let bytes = std::fs::read(&blob).unwrap();
    assert!(dips_kernel::nn::model::parse(&bytes).is_ok());
    // The blob runs on its own (its contract travels with it).
    let out_path = d.join("out-blob.json");
    let out = dips(&[
        "model",
        "run",
        blob.to_str().unwrap(),
        "--input",
        io.to_str().unwrap(),
        "--output",
        out_path.to_str().unwrap(),
        "--engine",
        "kernel",
    ]);
    assert_success(&out);
    let got = read_json(&out_path);
    assert_matches_reference(&got["outputs"]["p_real"]["data"], &want, "blob");
}

#[test]
fn bench_inference_prints_both_engine_timings() {
    let out = dips(&[
        "bench",
        "inference",
        fixture("denoiser.onnx").to_str().unwrap(),
        "--batch",
        "4",
        "--iters",
        "2",
        "--json",
    ]);
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["tract_s"].as_f64().unwrap() > 0.0);
    assert!(v["kernel_s"].as_f64().unwrap() > 0.0);
    assert!(v["max_abs_diff"].as_f64().unwrap() < 1e-3);
}
