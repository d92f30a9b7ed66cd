//! Kernel-engine timing by hand (`--ignored --nocapture`); benchmarks proper are
//! `dips bench inference`. Min over repeats, which is robust to a busy machine.

mod common;

use common::{FIXTURES, ROLES, fixture, tiled};
use dips_onnx::io_json::TensorFile;
use dips_onnx::{Expectation, KernelHostEngine};

#[test]
#[ignore = "timing, run by hand"]
fn kernel_engine_min_time_batch_96() {
    for dir in FIXTURES {
        for role in ROLES {
            let mut e = KernelHostEngine::load_onnx(
                &fixture(dir, &format!("{role}.onnx")),
                &Expectation::default(),
            )
            .unwrap();
            let io = TensorFile::read(&fixture(dir, &format!("{role}.io.json"))).unwrap();
            let (batch, ins, want) = tiled(e.contract(), &io, 32);
            let refs: Vec<&[f32]> = ins.iter().map(Vec::as_slice).collect();
            let mut out = vec![0.0; want.len()];
            let mut best = f64::MAX;
            for _ in 0..40 {
                let t = std::time::Instant::now();
                e.run(batch, &refs, &mut out).unwrap();
                best = best.min(t.elapsed().as_secs_f64());
            }
            eprintln!(
                "{dir}/{role}: kernel min {:.2} ms at batch {batch}",
                best * 1e3
            );
        }
    }
}
