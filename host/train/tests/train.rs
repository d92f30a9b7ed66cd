//! Training on a tiny synthetic dataset: the loss falls, the export agrees with both engines,
//! a resumed run equals an uninterrupted one, bad input is a typed error.

use std::path::PathBuf;

use dips_dataset::{Dataset, read_dir};
use dips_kernel::mode::Task;
use dips_kernel::rng::KernelRng;
use dips_onnx::{KernelHostEngine, TractEngine, lower_proto};
use dips_train::{
    RunOptions, TrainError, TrainSettings, synthetic, train_denoiser, train_discriminator,
};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dips-train-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn dataset(task: Task, name: &str, demos: usize) -> (PathBuf, Dataset) {
    let dir = tmp(name);
    synthetic::write_dataset(&dir.join("data"), task, demos, 100, 3, 2, 4).unwrap();
    let ds = read_dir(&dir.join("data"), task).unwrap();
    (dir, ds)
}

fn tiny(task: Task) -> TrainSettings {
    let mut s = TrainSettings::default();
    s.net.widths = if task == Task::Card {
        vec![8, 16]
    } else {
        vec![8, 16, 16]
    };
    s.net.mid_blocks = 1;
    s.net.embed_dim = 16;
    s.net.time_embed_dim = 8;
    s.net.context_embed_dim = 8;
    s.held_out_fraction = 0.2;
    s.eval_samples = 64;
    s.checkpoint_every = 0;
    s.denoiser.diffusion_steps = 16;
    s.denoiser.batch = 32;
    s.denoiser.steps = 60;
    s.denoiser.lr = 3e-3;
    s.denoiser.ema_decay = 0.9;
    s.denoiser.ema_every = 1;
    s.discriminator.samples = 48;
    s.discriminator.eval_samples = 24;
    s.discriminator.batch = 16;
    s.discriminator.steps = 30;
    s
}

/// Max of |a−b| / (1e-4·|b| + 1e-5) (≤ 1 passes the contract's agreement rule).
fn worst(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / (1e-4 * y.abs() + 1e-5))
        .fold(0.0, f32::max)
}

fn normals(n: usize, rng: &mut KernelRng) -> Vec<f32> {
    (0..n).map(|_| rng.normal_f32()).collect()
}

/// The held-out loss falls with the plain ε loss and with min-SNR-γ weighting, and the
/// weighting changes what is learnt.
#[test]
fn training_lowers_the_held_out_loss() {
    let (dir, ds) = dataset(Task::Card, "loss", 10);
    let mut s = tiny(Task::Card);
    s.net.widths = vec![16, 32];
    s.denoiser.steps = 250;
    let plain = train_denoiser(&ds, &s, &dir.join("plain"), &RunOptions::default()).unwrap();
    s.denoiser.min_snr_gamma = Some(5.0);
    let weighted = train_denoiser(&ds, &s, &dir.join("weighted"), &RunOptions::default()).unwrap();
    for d in [&plain, &weighted] {
        let r = &d.report;
        eprintln!("{r:?}");
        let (init, fin) = (r.held_out_loss_initial.unwrap(), r.held_out_loss.unwrap());
        assert!(fin < 0.85 * init, "held-out loss {init} → {fin}");
    }
    assert_ne!(
        plain.report.held_out_loss, weighted.report.held_out_loss,
        "the weighting must change what is learnt"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn angle_columns_are_raw_unless_normalize_angles() {
    use dips_train::data::{Normalizer, Samples, angle_columns};
    let (dir, ds) = dataset(Task::Screwdriver, "angles", 4);
    let all: Vec<usize> = (0..ds.demos.len()).collect();
    let samples = Samples::gather(&ds, &all);
    let pairs = angle_columns(Task::Screwdriver);
    assert!(!pairs.is_empty());
    let raw = Normalizer::fit(&samples, Task::Screwdriver, 1e-4, false).unwrap();
    let scored = Normalizer::fit(&samples, Task::Screwdriver, 1e-4, true).unwrap();
    let d = Task::Screwdriver.dims().dim();
    for &(c, s_) in &pairs {
        for j in [c, s_] {
            assert_eq!((raw.mean[j], raw.std[j]), (0.0, 1.0));
            // Z-scored: the column's own mean and std, as every other column gets.
            let col: Vec<f64> = samples.x.chunks_exact(d).map(|r| f64::from(r[j])).collect();
            let m = col.iter().sum::<f64>() / col.len() as f64;
            let v = col.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / col.len() as f64;
            assert!(
                (f64::from(scored.mean[j]) - m).abs() < 1e-4,
                "mean of column {j}"
            );
            assert!(
                (f64::from(scored.std[j]) - v.sqrt().max(1e-4)).abs() < 1e-4,
                "std of column {j}"
            );
        }
    }
    // Every other column is the same either way.
    let others = (0..d).filter(|j| !pairs.iter().any(|&(c, s_)| *j == c || *j == s_));
    for j in others {
        assert_eq!((raw.mean[j], raw.std[j]), (scored.mean[j], scored.std[j]));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Train tiny models and check their exports on tract and the kernel against burn;
/// `start_embed_dim` > 0 also trains with state-only start rows.
fn check_export(task: Task, start_embed_dim: usize) {
    let (dir, ds) = dataset(task, &format!("{}-{start_embed_dim}", task.name()), 6);
    let mut s = tiny(task);
    s.net.start_embed_dim = start_embed_dim;
    s.denoiser.start_state_only = start_embed_dim > 0;
    let opts = RunOptions::default();
    let den = train_denoiser(&ds, &s, &dir, &opts).unwrap();
    let disc = train_discriminator(&ds, &s, &den, &dir, &opts).unwrap();
    eprintln!("{:?}", disc.report);

    let dims = task.dims();
    let (b, td, f) = (5, dims.floats(), dims.fingers);
    let mut rng = KernelRng::seed_from_u64(9);
    let x = normals(b * td, &mut rng);
    let t: Vec<f32> = (0..b).map(|i| (i * 3) as f32).collect();
    let ctx: Vec<f32> = (0..b * f)
        .map(|i| if i % 3 == 0 { -1.0 } else { 1.0 })
        .collect();
    let cond = vec![1.0, 0.0, 1.0, 1.0, 0.0];

    // Denoiser: contract, tract, kernel.
    let proto = den.onnx().unwrap();
    let c = dips_onnx::contract::validate(&proto).unwrap();
    assert_eq!(c.norm_mean, den.norm.mean);
    let want = den.forward(b, &x, &t, &ctx, &cond).unwrap();
    let mut got = vec![0.0; b * td];
    TractEngine::from_model_proto(&proto)
        .unwrap()
        .run(b, &[&x, &t, &ctx, &cond], &mut got)
        .unwrap();
    let wt = worst(&got, &want);
    let mut kernel = KernelHostEngine::from_lowered(lower_proto(&proto).unwrap()).unwrap();
    kernel.run(b, &[&x, &t, &ctx, &cond], &mut got).unwrap();
    let wk = worst(&got, &want);
    eprintln!(
        "{} denoiser: worst/tolerance tract {wt}, kernel {wk}",
        task.name()
    );
    assert!(wt <= 1.0 && wk <= 1.0, "tract {wt}, kernel {wk}");

    // Discriminator.
    let proto = disc.onnx().unwrap();
    dips_onnx::contract::validate(&proto).unwrap();
    let want = disc.forward(b, &x, &ctx).unwrap();
    let mut got = vec![0.0; b];
    TractEngine::from_model_proto(&proto)
        .unwrap()
        .run(b, &[&x, &ctx], &mut got)
        .unwrap();
    let wt = worst(&got, &want);
    let mut kernel = KernelHostEngine::from_lowered(lower_proto(&proto).unwrap()).unwrap();
    kernel.run(b, &[&x, &ctx], &mut got).unwrap();
    let wk = worst(&got, &want);
    eprintln!(
        "{} discriminator: worst/tolerance tract {wt}, kernel {wk}",
        task.name()
    );
    assert!(wt <= 1.0 && wk <= 1.0, "tract {wt}, kernel {wk}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A card denoiser in the segment-start frame: trained on the object's motion from each start,
/// it says so in its metadata, both engines (tract and the lowered blob) report the frame, the
/// sampler returns world-frame rows from the start, and Ψ, which scores world-frame segments,
/// keeps the world's frame with a normalisation of its own.
#[test]
fn a_segment_start_denoiser_is_trained_exported_and_sampled_in_its_frame() {
    use dips_kernel::diffusion::{
        SampleRequest, SamplerConfig, SamplerScratch, ScratchLayout, sample,
    };
    use dips_kernel::engine::{DenoiserEngine, ObjectFrame};
    let (dir, ds) = dataset(Task::Card, "object-frame", 6);
    let mut s = tiny(Task::Card);
    s.denoiser.steps = 20;
    s.discriminator.steps = 5;
    s.denoiser.object_frame = ObjectFrame::SegmentStart;
    let opts = RunOptions::default();
    let den = train_denoiser(&ds, &s, &dir, &opts).unwrap();
    assert_eq!(den.object_frame, ObjectFrame::SegmentStart);
    let world = {
        let mut w = s.clone();
        w.denoiser.object_frame = ObjectFrame::World;
        train_denoiser(&ds, &w, &dir.join("world"), &opts).unwrap()
    };
    let card = Task::Card.dims();
    let cols = ObjectFrame::SegmentStart.start_columns(card.fingers, card.state_dim);
    for c in cols.clone() {
        assert_ne!(
            den.norm.mean[c], world.norm.mean[c],
            "column {c} is normalised as motion from the start"
        );
    }
    let proto = den.onnx().unwrap();
    assert_eq!(
        dips_onnx::contract::object_frame(&proto).unwrap(),
        ObjectFrame::SegmentStart
    );
    let mut tract = TractEngine::from_model_proto(&proto).unwrap();
    let kernel = KernelHostEngine::from_lowered(lower_proto(&proto).unwrap()).unwrap();
    assert_eq!(
        DenoiserEngine::object_frame(&tract),
        ObjectFrame::SegmentStart
    );
    assert_eq!(
        DenoiserEngine::object_frame(&kernel),
        ObjectFrame::SegmentStart
    );
    // A world-frame model says nothing, and reads as the world's.
    let plain = world.onnx().unwrap();
    assert!(
        !plain
            .metadata_props
            .iter()
            .any(|p| p.key == dips_onnx::contract::OBJECT_FRAME_KEY)
    );
    assert_eq!(
        dips_onnx::contract::object_frame(&plain).unwrap(),
        ObjectFrame::World
    );

    // Sampled from a start far from the origin, rows come back in the world's frame.
    let dims = DenoiserEngine::dims(&tract);
    let start: Vec<f32> = ds.demos[0].trajectories[..dims.state_dim].to_vec();
    let mut far = start.clone();
    far[cols.start + 1] -= 0.05;
    let n = 8;
    let starts: Vec<f32> = (0..n).flat_map(|_| far.iter().copied()).collect();
    let context: Vec<f32> = (0..n * dims.fingers).map(|_| 1.0).collect();
    let layout = ScratchLayout::new(dims, n);
    let mut buf = vec![0f32; layout.total()];
    let mut scratch = SamplerScratch::split(&mut buf, &layout).unwrap();
    let mut out = vec![0f32; n * dims.floats_per_trajectory()];
    sample(
        &mut tract,
        &SamplerConfig::ddim(4),
        &SampleRequest {
            context: &context,
            start_states: Some(&starts),
        },
        &mut KernelRng::seed_from_u64(3),
        &mut scratch,
        &mut out,
    )
    .unwrap();
    let d = dims.dim();
    let td = dims.floats_per_trajectory();
    let mean_y = |row: usize| {
        out.chunks(td)
            .map(|t| t[row * d + cols.start + 1])
            .sum::<f32>()
            / n as f32
    };
    assert_eq!(&out[..dims.state_dim], &far[..], "row 0 is the start");
    // The model learnt motion from the start: its rows stay near the (moved) start, not
    // where the demos' cards lie.
    let last = mean_y(dims.horizon - 1);
    assert!(
        (last - far[cols.start + 1]).abs() < 0.04,
        "the last row's y {last} is near the start's {}",
        far[cols.start + 1]
    );

    // Ψ: the world's frame, its own normalisation (the world model's).
    let disc = train_discriminator(&ds, &s, &den, &dir, &opts).unwrap();
    assert_eq!(disc.norm, world.norm);
    let psi = disc.onnx().unwrap();
    assert_eq!(
        dips_onnx::contract::object_frame(&psi).unwrap(),
        ObjectFrame::World
    );
    // A discriminator that claimed a frame would be refused.
    let mut claims = psi.clone();
    claims
        .metadata_props
        .push(tract_onnx::pb::StringStringEntryProto {
            key: dips_onnx::contract::OBJECT_FRAME_KEY.into(),
            value: "segment-start".into(),
        });
    let e = dips_onnx::contract::validate(&claims)
        .unwrap_err()
        .to_string();
    assert!(e.contains("discriminator"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn card_export_agrees_with_both_engines() {
    check_export(Task::Card, 0);
}

#[test]
fn screwdriver_export_agrees_with_both_engines() {
    check_export(Task::Screwdriver, 0);
}

/// The start embedding (a Slice of `x`'s row 0, Flatten, Gemm, Mish) exports op for op.
#[test]
fn start_embedding_export_agrees_with_both_engines() {
    check_export(Task::Screwdriver, 8);
}

#[test]
fn resumed_run_equals_uninterrupted_run() {
    let (dir, ds) = dataset(Task::Screwdriver, "resume", 5);
    let mut s = tiny(Task::Screwdriver);
    s.denoiser.steps = 12;
    s.discriminator.steps = 10;
    s.checkpoint_every = 5;
    let opts = RunOptions::default();
    let (a, b) = (dir.join("a"), dir.join("b"));
    let whole = train_denoiser(&ds, &s, &a, &opts).unwrap();
    let killed = RunOptions {
        stop_after: Some(7),
        ..RunOptions::default()
    };
    assert!(matches!(
        train_denoiser(&ds, &s, &b, &killed),
        Err(TrainError::Stopped { step: 7 })
    ));
    let resumed = train_denoiser(&ds, &s, &b, &opts).unwrap();
    assert_eq!(resumed.report.resumed_from, 7);
    assert_eq!(resumed.params, whole.params, "EMA parameters differ");
    assert_eq!(resumed.report.held_out_loss, whole.report.held_out_loss);

    let dw = train_discriminator(&ds, &s, &whole, &a, &opts).unwrap();
    let killed = RunOptions {
        stop_after: Some(4),
        ..RunOptions::default()
    };
    assert!(matches!(
        train_discriminator(&ds, &s, &resumed, &b, &killed),
        Err(TrainError::Stopped { step: 4 })
    ));
    let dr = train_discriminator(&ds, &s, &resumed, &b, &opts).unwrap();
    assert_eq!(dr.report.resumed_from, 4);
    assert_eq!(dr.params, dw.params, "discriminator parameters differ");

    // Another run's checkpoint is refused, not silently resumed.
    let mut other = s.clone();
    other.denoiser.lr *= 2.0;
    let e = train_denoiser(&ds, &other, &b, &opts).unwrap_err();
    assert!(matches!(e, TrainError::Checkpoint { .. }), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_settings_and_bad_files_are_typed_errors() {
    let mut s = TrainSettings::default();
    assert!(s.validate().is_ok());
    s.net.widths = vec![12, 16];
    let e = s.validate().unwrap_err();
    assert!(
        matches!(&e, TrainError::Settings { field, .. } if field == "net.widths"),
        "{e}"
    );
    let mut s = TrainSettings::default();
    s.denoiser.lr = f64::NAN;
    assert!(matches!(s.validate(), Err(TrainError::Settings { .. })));
    let mut s = TrainSettings::default();
    s.denoiser.min_snr_gamma = Some(-1.0);
    let e = s.validate().unwrap_err();
    assert!(
        matches!(&e, TrainError::Settings { field, .. } if field == "denoiser.min_snr_gamma"),
        "{e}"
    );
    let s = TrainSettings {
        held_out_fraction: 1.0,
        ..TrainSettings::default()
    };
    assert!(matches!(s.validate(), Err(TrainError::Settings { .. })));
    for (sources, said) in [(vec![], "at least one"), (vec!["dagger"], "\"dagger\"")] {
        let s = TrainSettings {
            prior_sources: Some(sources.into_iter().map(String::from).collect()),
            ..TrainSettings::default()
        };
        let e = s.validate().unwrap_err();
        assert!(
            matches!(&e, TrainError::Settings { field, .. } if field == "prior_sources")
                && e.to_string().contains(said),
            "{e}"
        );
    }

    let dir = tmp("bad");
    let e = dips_train::run(
        Task::Card,
        &dir.join("nowhere"),
        &dir.join("out"),
        &TrainSettings::default(),
        &RunOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, TrainError::Dataset(_)), "{e}");
    std::fs::create_dir_all(dir.join("data/demos")).unwrap();
    std::fs::write(dir.join("data/demos/broken.safetensors"), b"\x10\0\0\0").unwrap();
    let e = dips_train::run(
        Task::Card,
        &dir.join("data"),
        &dir.join("out"),
        &TrainSettings::default(),
        &RunOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("broken.safetensors"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn run_writes_the_model_directory() {
    let (dir, _) = dataset(Task::Card, "run", 5);
    let mut s = tiny(Task::Card);
    s.denoiser.steps = 10;
    s.discriminator.steps = 5;
    let out = dir.join("models");
    let data = dir.join("data");
    let run = |out: &std::path::Path, s: &TrainSettings| {
        dips_train::run(Task::Card, &data, out, s, &RunOptions::default())
    };
    // The prior is fitted from the chosen sources' demos only: these demos carry no source
    // (pattern), so a markov-only prior has nothing to fit and says so before training.
    let markov_only = TrainSettings {
        prior_sources: Some(vec!["markov".to_string()]),
        ..s.clone()
    };
    let e = run(&out, &markov_only).unwrap_err();
    assert!(e.to_string().contains("no demo of the 5 demos"), "{e}");
    s.prior_sources = Some(vec!["pattern".to_string(), "markov".to_string()]);
    let r = run(&out, &s).unwrap();
    assert_eq!(r.demos, 5);
    assert_eq!(r.prior.sequences, 5);
    assert_eq!(r.dropped_early_steps, 0);
    let all = r.samples;
    // The demos record online steps 0 and 1: 1 keeps step 1's half, 2 keeps nothing and
    // says which steps there are.
    let past = TrainSettings {
        min_executed_rows: 2,
        ..s.clone()
    };
    let e = run(&out, &past).unwrap_err();
    assert!(
        matches!(&e, TrainError::Settings { field, .. } if field == "min_executed_rows")
            && e.to_string().contains("steps 0 to 1"),
        "{e}"
    );
    let executed = TrainSettings {
        min_executed_rows: 1,
        ..s.clone()
    };
    let r = run(&dir.join("models-executed"), &executed).unwrap();
    assert_eq!((r.samples, r.dropped_early_steps), (all / 2, all / 2));
    for f in ["denoiser.onnx", "discriminator.onnx", "train_report.json"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let e = dips_onnx::contract::Expectation::new(dips_onnx::Role::Denoiser, "card");
    TractEngine::load(&out.join("denoiser.onnx"), &e).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `planner_fakes` adds the planner's anchored strided-DDPM samples to Ψ's negatives and the
/// model names every source in `dips.psi_negatives`; `augment_yaw` trains (screwdriver) or is
/// refused with the field's name (card, which has no symmetry angle).
#[test]
fn psi_negatives_and_yaw_augmentation() {
    let (dir, _) = dataset(Task::Screwdriver, "psi-negatives", 5);
    let data = dir.join("data");
    let mut s = tiny(Task::Screwdriver);
    s.denoiser.steps = 10;
    s.discriminator.steps = 5;
    s.discriminator.planner_fakes = vec![4];
    s.discriminator.augment_yaw = true;
    let out = dir.join("models");
    let r = dips_train::run(Task::Screwdriver, &data, &out, &s, &RunOptions::default()).unwrap();
    assert_eq!(r.discriminator.steps, 5);
    let proto = dips_onnx::contract::read_proto(&out.join("discriminator.onnx")).unwrap();
    assert_eq!(
        dips_onnx::contract::psi_negatives(&proto).unwrap(),
        Some(vec![
            "ddpm".to_string(),
            "ddim:8".to_string(),
            "ddpm:4+anchor".to_string()
        ])
    );
    // The planner's fakes were sampled and cached beside the paper's.
    assert!(
        out.join("checkpoints/disc_fakes_train.planner-ddpm4.safetensors")
            .is_file()
    );
    // Steps beyond the denoiser's are refused before anything runs.
    let mut too_many = s.clone();
    too_many.discriminator.planner_fakes = vec![17];
    let e = dips_train::run(
        Task::Screwdriver,
        &data,
        &dir.join("m2"),
        &too_many,
        &RunOptions::default(),
    )
    .unwrap_err();
    assert!(
        matches!(&e, TrainError::Settings { field, .. } if field == "discriminator.planner_fakes"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();

    let (dir, _) = dataset(Task::Card, "psi-augment-card", 5);
    let mut s = tiny(Task::Card);
    s.denoiser.steps = 5;
    s.discriminator.steps = 5;
    s.discriminator.augment_yaw = true;
    let e = dips_train::run(
        Task::Card,
        &dir.join("data"),
        &dir.join("models"),
        &s,
        &RunOptions::default(),
    )
    .unwrap_err();
    assert!(
        matches!(&e, TrainError::Settings { field, .. } if field == "discriminator.augment_yaw"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
