//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

use dips_onnx::io_json::TensorFile;
use dips_onnx::{AnyEngine, Contract, EngineKind, Expectation};

pub(crate) fn fixture(dir: &str, file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(dir)
        .join(file)
}

pub(crate) const FIXTURES: [&str; 2] = ["torch-screwdriver-legacy", "torch-card-dynamo"];
pub(crate) const ROLES: [&str; 2] = ["denoiser", "discriminator"];

/// `|got − want| ≤ max(1e-5, 1e-4·|want|)` everywhere; returns the worst ratio to the bound.
pub(crate) fn assert_agree(got: &[f32], want: &[f32], what: &str) -> f32 {
    assert_eq!(got.len(), want.len(), "{what}: length");
    let mut worst = 0.0f32;
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        let bound = (1e-4 * w.abs()).max(1e-5);
        let r = (g - w).abs() / bound;
        assert!(r <= 1.0, "{what}: element {i}: got {g}, onnxruntime {w}");
        worst = worst.max(r);
    }
    worst
}

/// Inputs (contract order), batch and expected output of a fixture, tiled `reps` times.
pub(crate) fn tiled(
    c: &Contract,
    io: &TensorFile,
    reps: usize,
) -> (usize, Vec<Vec<f32>>, Vec<f32>) {
    let (batch, ins) = io.contract_inputs(c).unwrap();
    let ins = ins.iter().map(|d| d.repeat(reps)).collect();
    let out = io.outputs[c.role.output_name()].data.repeat(reps);
    (batch * reps, ins, out)
}

/// Load a model with the engine named `"tract"` or `"kernel"`.
pub(crate) fn load_engine(kind: &str, path: &std::path::Path) -> AnyEngine {
    let kind = if kind == "tract" {
        EngineKind::Tract
    } else {
        EngineKind::Kernel
    };
    AnyEngine::load(kind, path, &Expectation::default()).unwrap()
}
