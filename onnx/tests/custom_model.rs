//! A model that is not one of the fixtures (other channels, depth, op mix; built by
//! `tests/data/gen_custom.py` with onnx.helper, reference by onnxruntime) runs on both engines.

mod common;

use std::path::PathBuf;

use common::{assert_agree, load_engine, tiled};
use dips_onnx::io_json::TensorFile;

fn data(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(file)
}

#[test]
fn custom_architecture_matches_onnxruntime_on_both_engines() {
    let io = TensorFile::read(&data("custom_card.io.json")).unwrap();
    for engine in ["tract", "kernel"] {
        let mut e = load_engine(engine, &data("custom_card.onnx"));
        let c = e.contract().clone();
        for reps in [1, 24] {
            let (batch, ins, want) = tiled(&c, &io, reps);
            let refs: Vec<&[f32]> = ins.iter().map(Vec::as_slice).collect();
            let mut out = vec![0.0; want.len()];
            e.run(batch, &refs, &mut out).unwrap();
            assert_agree(&out, &want, &format!("{engine} custom batch {batch}"));
        }
    }
}

#[test]
fn group_normalization_op_matches_onnxruntime_on_both_engines() {
    let io = TensorFile::read(&data("groupnorm21_card.io.json")).unwrap();
    for engine in ["tract", "kernel"] {
        let mut e = load_engine(engine, &data("groupnorm21_card.onnx"));
        let c = e.contract().clone();
        for reps in [1, 32] {
            let (batch, ins, want) = tiled(&c, &io, reps);
            let refs: Vec<&[f32]> = ins.iter().map(Vec::as_slice).collect();
            let mut out = vec![0.0; want.len()];
            e.run(batch, &refs, &mut out).unwrap();
            assert_agree(
                &out,
                &want,
                &format!("{engine} GroupNormalization batch {batch}"),
            );
        }
    }
}

#[test]
fn kernel_runs_smaller_batches_than_its_memory_holds() {
    let io = TensorFile::read(&data("custom_card.io.json")).unwrap();
    let mut e = load_engine("kernel", &data("custom_card.onnx"));
    let c = e.contract().clone();
    let (batch, ins, want) = tiled(&c, &io, 8);
    let refs: Vec<&[f32]> = ins.iter().map(Vec::as_slice).collect();
    let mut out = vec![0.0; want.len()];
    e.run(batch, &refs, &mut out).unwrap();
    // Now a batch of 1 in the memory sized for 32: sample 2 alone.
    let per: Vec<usize> = refs.iter().map(|r| r.len() / batch).collect();
    let one: Vec<&[f32]> = refs
        .iter()
        .zip(&per)
        .map(|(r, p)| &r[2 * p..3 * p])
        .collect();
    let op = want.len() / batch;
    let mut out1 = vec![0.0; op];
    e.run(1, &one, &mut out1).unwrap();
    assert_agree(
        &out1,
        &want[2 * op..3 * op],
        "kernel batch 1 after batch 32",
    );
}
