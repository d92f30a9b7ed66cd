//! Both engines agree with onnxruntime's reference outputs in the fixtures (both PyTorch
//! exporters), at the fixtures' batch and tiled to batch 96.

mod common;

use common::{FIXTURES, ROLES, assert_agree, fixture, load_engine, tiled};
use dips_onnx::io_json::TensorFile;

fn check(engine: &str) {
    for dir in FIXTURES {
        for role in ROLES {
            let path = fixture(dir, &format!("{role}.onnx"));
            let io = TensorFile::read(&fixture(dir, &format!("{role}.io.json"))).unwrap();
            let mut e = load_engine(engine, &path);
            let c = e.contract().clone();
            for reps in [1, 32] {
                let (batch, ins, want) = tiled(&c, &io, reps);
                let refs: Vec<&[f32]> = ins.iter().map(Vec::as_slice).collect();
                let mut out = vec![0.0; want.len()];
                e.run(batch, &refs, &mut out).unwrap();
                let worst =
                    assert_agree(&out, &want, &format!("{engine} {dir}/{role} batch {batch}"));
                eprintln!(
                    "{engine} {dir}/{role} batch {batch}: worst error {worst:.3} of the tolerance"
                );
            }
        }
    }
}

#[test]
fn tract_engine_matches_onnxruntime() {
    check("tract");
}

#[test]
fn kernel_engine_matches_onnxruntime() {
    check("kernel");
}
