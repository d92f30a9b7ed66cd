//! `dips bench inference`: median seconds per call of the tract and kernel engines.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use dips_kernel::rng::KernelRng;

use dips_onnx::{AnyEngine, EngineKind, Expectation};

/// Arguments of `dips bench inference`.
#[derive(Debug, Args)]
pub struct InferenceArgs {
    /// The `.onnx` file.
    pub file: PathBuf,
    /// Batch size.
    #[arg(long, default_value_t = 96)]
    pub batch: usize,
    /// Timed calls per engine (after warm-up calls).
    #[arg(long, default_value_t = 50)]
    pub iters: usize,
    /// Print JSON instead of readable `key: value` lines.
    #[arg(long)]
    pub json: bool,
    /// Which copies of the kernel interpreter's op kernels run (the outputs are the same).
    #[arg(long, value_enum, default_value_t = crate::model::SimdArg::Auto)]
    pub simd: crate::model::SimdArg,
}

/// Median and minimum of the timings.
fn median_min(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0])
}

fn time_engine(
    kind: EngineKind,
    a: &InferenceArgs,
    inputs: &[Vec<f32>],
) -> anyhow::Result<((f64, f64), Vec<f32>)> {
    let mut e = AnyEngine::load(kind, &a.file, &Expectation::default())
        .with_context(|| format!("loading {}", a.file.display()))?;
    let refs: Vec<&[f32]> = inputs.iter().map(Vec::as_slice).collect();
    let mut out = vec![0.0; a.batch * e.contract().output_shape().iter().product::<usize>()];
    for _ in 0..3 {
        e.run(a.batch, &refs, &mut out)?;
    }
    let mut times = Vec::with_capacity(a.iters);
    for _ in 0..a.iters.max(1) {
        let t0 = Instant::now();
        e.run(a.batch, &refs, &mut out)?;
        times.push(t0.elapsed().as_secs_f64());
    }
    Ok((median_min(times), out))
}

/// Run `dips bench inference`.
pub fn run(a: &InferenceArgs) -> anyhow::Result<()> {
    anyhow::ensure!(a.batch > 0, "--batch must be positive");
    let simd = a.simd.apply();
    let (_, c) = dips_onnx::contract::load_contract(&a.file)
        .with_context(|| format!("loading {}", a.file.display()))?;
    let mut rng = KernelRng::seed_from_u64(7);
    let inputs: Vec<Vec<f32>> = c
        .role
        .input_names()
        .iter()
        .map(|n| {
            let len = a.batch
                * c.input_shape(n)
                    .unwrap_or_default()
                    .iter()
                    .product::<usize>();
            let mut v = vec![0.0; len];
            match *n {
                "t" => v
                    .iter_mut()
                    .for_each(|x| *x = rng.below(c.diffusion_steps as u32) as f32),
                "context" => v
                    .iter_mut()
                    .for_each(|x| *x = if rng.below(2) == 0 { -1.0 } else { 1.0 }),
                "cond_mask" => v.iter_mut().for_each(|x| *x = rng.below(2) as f32),
                _ => rng.fill_normal(&mut v),
            }
            v
        })
        .collect();
    let ((kernel_s, kernel_min_s), kernel_out) = time_engine(EngineKind::Kernel, a, &inputs)?;
    let ((tract_s, tract_min_s), tract_out) = time_engine(EngineKind::Tract, a, &inputs)?;
    let max_abs_diff = tract_out
        .iter()
        .zip(&kernel_out)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    crate::output::figures(
        a.json,
        &serde_json::json!({
            "bench": "inference",
            "file": a.file.display().to_string(),
            "role": c.role.name(),
            "task": c.task,
            "batch": a.batch,
            "simd": simd,
            "iters": a.iters,
            "tract_s": tract_s,
            "kernel_s": kernel_s,
            "tract_min_s": tract_min_s,
            "kernel_min_s": kernel_min_s,
            "kernel_over_tract": kernel_s / tract_s,
            "max_abs_diff": max_abs_diff,
        }),
    )?;
    Ok(())
}
