//! The size / held-out loss / inference-time trade-off of `docs/training.md` (ignored: minutes).
//! `cargo test --release -p dips-train --test measure -- --ignored --nocapture`

use std::time::Instant;

use dips_kernel::mode::Task;
use dips_kernel::rng::KernelRng;
use dips_onnx::{KernelHostEngine, TractEngine, lower_proto};
use dips_train::{RunOptions, TrainSettings, synthetic, train_denoiser};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
#[ignore]
fn size_loss_inference_trade_off() {
    let task = Task::Screwdriver;
    let dir = std::env::temp_dir().join(format!("dips-measure-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    synthetic::write_dataset(&dir.join("data"), task, 40, 1, 7, 3, 8).unwrap();
    let ds = dips_dataset::read_dir(&dir.join("data"), task).unwrap();
    let steps: usize = std::env::var("MEASURE_STEPS").map_or(600, |v| v.parse().unwrap());
    for (widths, embed) in [
        (vec![16, 32, 64], 32),
        (vec![32, 64, 128], 64),
        (vec![64, 128, 256], 128),
    ] {
        // MEASURE_WIDTH=16 measures only the net whose first width is 16.
        if let Ok(w) = std::env::var("MEASURE_WIDTH")
            && w.parse::<usize>().ok() != Some(widths[0])
        {
            continue;
        }
        let mut s = TrainSettings::default();
        s.net.widths = widths.clone();
        s.net.embed_dim = embed;
        s.eval_samples = 1024;
        s.checkpoint_every = 0;
        s.denoiser.batch = 64;
        s.denoiser.steps = steps;
        let out = dir.join(format!("m{}", widths[0]));
        let d = train_denoiser(&ds, &s, &out, &RunOptions::default()).unwrap();
        let proto = d.onnx().unwrap();
        let dims = task.dims();
        let b = 96;
        let mut rng = KernelRng::seed_from_u64(1);
        let x: Vec<f32> = (0..b * dims.floats()).map(|_| rng.normal_f32()).collect();
        let t: Vec<f32> = (0..b).map(|i| (i % 256) as f32).collect();
        let c = vec![1.0f32; b * dims.fingers];
        let m = vec![1.0f32; b];
        let mut y = vec![0.0f32; b * dims.floats()];
        // Kernel first (docs/onnx.md: tract leaves the vector state dirty for the kernel).
        let mut k = KernelHostEngine::from_lowered(lower_proto(&proto).unwrap()).unwrap();
        let mut kt = Vec::new();
        for _ in 0..30 {
            let t0 = Instant::now();
            k.run(b, &[&x, &t, &c, &m], &mut y).unwrap();
            kt.push(t0.elapsed().as_secs_f64());
        }
        let mut tr = TractEngine::from_model_proto(&proto).unwrap();
        let mut tt = Vec::new();
        for _ in 0..30 {
            let t0 = Instant::now();
            tr.run(b, &[&x, &t, &c, &m], &mut y).unwrap();
            tt.push(t0.elapsed().as_secs_f64());
        }
        let t0 = Instant::now();
        let _ = d.forward(b, &x, &t, &c, &m).unwrap();
        let burn_s = t0.elapsed().as_secs_f64();
        println!(
            "{{\"widths\":{widths:?},\"embed\":{embed},\"params\":{},\"steps\":{steps},\"batch\":64,\"step_time_s\":{:.4},\"held_out_initial\":{:.4},\"held_out_ema\":{:.4},\"held_out_raw\":{:.4},\"train_loss_final\":{:.4},\"kernel_b96_ms\":{:.2},\"tract_b96_ms\":{:.2},\"burn_b96_ms\":{:.2}}}",
            d.report.params,
            d.report.step_time_s,
            d.report.held_out_loss_initial.unwrap(),
            d.report.held_out_loss.unwrap(),
            d.report.held_out_loss_raw.unwrap(),
            d.report.train_loss_final,
            median(kt) * 1e3,
            median(tt) * 1e3,
            burn_s * 1e3,
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
