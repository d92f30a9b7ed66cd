//! The models shipped in `onnx/models/<task>/`: they pass contract v1 for their task on both
//! engines, their prior loads, their model card and figures exist and meet the bars of
//! issue 11 (discriminator AUC ≥ 0.8), and their samples stay in range.

use std::path::PathBuf;

use dips_dataset::PriorFile;
use dips_kernel::diffusion::{SampleRequest, SamplerConfig, SamplerScratch, ScratchLayout, sample};
use dips_kernel::engine::DenoiserEngine;
use dips_kernel::mode::Task;
use dips_kernel::rng::KernelRng;
use dips_onnx::EngineKind;
use dips_planning::Models;

fn dir(task: Task) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../onnx/models")
        .join(task.name())
}

fn json(path: PathBuf) -> serde_json::Value {
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn shipped_models_load_on_both_engines_with_their_prior() {
    for task in Task::ALL {
        for kind in [EngineKind::Kernel, EngineKind::Tract] {
            let m = Models::load(kind, &dir(task), task)
                .unwrap_or_else(|e| panic!("{} {kind:?}: {e:#}", task.name()));
            assert!(m.prior.is_some(), "{}: no prior.json", task.name());
        }
        let (file, _) = PriorFile::load(&dir(task).join("prior.json"), task).unwrap();
        assert_eq!(file.p_min, 0.1);
        assert!(file.sequences > 0);
    }
}

#[test]
fn the_card_models_say_which_card_goals_they_were_trained_for() {
    use dips_kernel::task::CardGoals;
    use dips_planning::{models_card_goals, resolve_card_goals};
    let paper = dir(Task::Card).with_file_name("card-paper");
    let m = Models::load(EngineKind::Kernel, &paper, Task::Card).unwrap();
    assert_eq!(m.card_goals, Some(CardGoals::Paper));
    // The shipped card models predate the key: ours.
    assert_eq!(models_card_goals(&dir(Task::Card)).unwrap(), None);
    assert_eq!(
        resolve_card_goals(None, Some((&paper, m.trained_card_goals()))).unwrap(),
        CardGoals::Paper
    );
    let e =
        resolve_card_goals(Some(CardGoals::Capped), Some((&paper, CardGoals::Paper))).unwrap_err();
    assert_eq!((e.given, e.trained), (CardGoals::Capped, CardGoals::Paper));
    assert!(e.to_string().contains("card-paper"), "{e}");
}

#[test]
fn model_cards_carry_the_measured_figures() {
    for task in Task::ALL {
        let report = json(dir(task).join("train_report.json"));
        let auc = report["discriminator"]["held_out_auc"].as_f64().unwrap();
        assert!(auc >= 0.8, "{}: discriminator AUC {auc}", task.name());
        let (init, fin) = (
            report["denoiser"]["held_out_loss_initial"]
                .as_f64()
                .unwrap(),
            report["denoiser"]["held_out_loss"].as_f64().unwrap(),
        );
        assert!(
            fin < 0.5 * init,
            "{}: held-out loss {init} → {fin}",
            task.name()
        );
        let quality = json(dir(task).join("quality.json"));
        let sets = quality["sets"].as_array().unwrap();
        assert!(sets.iter().any(|s| s["name"] == "real"));
        assert!(sets.iter().any(|s| s["name"] == "ddpm-256"));
        assert!(
            !quality["open_loop"]["trials"]
                .as_array()
                .unwrap()
                .is_empty()
        );
        let card = std::fs::read_to_string(dir(task).join("MODEL_CARD.md")).unwrap();
        for needle in [
            "AUC",
            "held-out loss",
            "Open loop",
            "ddpm-256",
            "scripts/make-models.sh",
        ] {
            assert!(
                card.contains(needle),
                "{}: card lacks {needle:?}",
                task.name()
            );
        }
        assert!(
            card.contains(&format!("{:.4}", fin)),
            "{}: card lacks the held-out loss {fin:.4}",
            task.name()
        );
    }
}

#[test]
fn shipped_denoisers_sample_finite_in_range_trajectories() {
    for task in Task::ALL {
        let mut m = Models::load(EngineKind::Kernel, &dir(task), task).unwrap();
        let engine = &mut m.denoiser;
        let dims = DenoiserEngine::dims(engine);
        let n = 8;
        let f = dims.fingers;
        let mut context = vec![1.0f32; n * f];
        for (i, c) in context.iter_mut().enumerate() {
            if (i / f + i % f) % 3 == 2 {
                *c = -1.0;
            }
        }
        let norm = engine.normalization();
        let (mean, std) = (norm.mean.to_vec(), norm.std.to_vec());
        let starts: Vec<f32> = (0..n)
            .flat_map(|_| mean[..dims.state_dim].to_vec())
            .collect();
        let layout = ScratchLayout::new(dims, n);
        let mut buf = vec![0f32; layout.total()];
        let mut scratch = SamplerScratch::split(&mut buf, &layout).unwrap();
        let mut out = vec![0f32; n * dims.floats_per_trajectory()];
        sample(
            engine,
            &SamplerConfig::ddim(8),
            &SampleRequest {
                context: &context,
                start_states: Some(&starts),
            },
            &mut KernelRng::seed_from_u64(1),
            &mut scratch,
            &mut out,
        )
        .unwrap();
        let d = mean.len();
        let z: Vec<f32> = out
            .chunks(d)
            .flat_map(|row| {
                row.iter()
                    .zip(&mean)
                    .zip(&std)
                    .map(|((v, m), s)| ((v - m) / s).abs())
                    .collect::<Vec<_>>()
            })
            .collect();
        // The sampler's clip bounds every entry by 10 z; a model that samples well keeps
        // almost all of them within 5 z, as the data does (99.9 % within 7.3 z).
        let far = z.iter().filter(|&&v| v.is_nan() || v >= 5.0).count() as f64 / z.len() as f64;
        let worst = z.iter().fold(0.0f32, |a, &b| a.max(b));
        assert!(
            worst.is_finite() && far < 0.01,
            "{}: {:.2} % of entries beyond 5 z (worst {worst})",
            task.name(),
            100.0 * far
        );
    }
}

/// The screwdriver's start anchor (`session::start_anchor`) on the shipped denoiser, as the
/// planner and CSVTO's initialisation apply it: from a start yaw below the models' range, every
/// mode's segments begin exactly at the start, row 1 repeats the start's yaw and the joints of
/// the fingers in contact, and what the model drew is otherwise kept: the same samples without
/// the anchor differ by one rotation of the yaw and one shift per contact joint over rows 1..,
/// and the fingers that regrasp keep their rows bit for bit.
#[test]
fn screwdriver_samples_are_anchored_at_their_start() {
    use dips_kernel::adapters::{StartAnchor, segment_dims};
    use dips_planning::sample_trajectories;
    let task = Task::Screwdriver;
    let anchor = dips_kernel::session::start_anchor(task);
    assert!(anchor.angle.is_some() && anchor.contact_joints);
    let mut m = Models::load(EngineKind::Kernel, &dir(task), task).unwrap();
    let engine = &mut m.denoiser;
    let dims = DenoiserEngine::dims(engine);
    let (sd, d, f, td) = (
        dims.state_dim,
        dims.state_dim + dims.action_dim,
        dims.fingers,
        dims.floats_per_trajectory(),
    );
    let c = task.layout().angle_cos();
    let mut start = engine.normalization().mean[..sd].to_vec();
    let yaw0 = -1.4f32;
    (start[c], start[c + 1]) = (yaw0.cos(), yaw0.sin());
    let modes: Vec<_> = task.candidate_modes().collect();
    let n = 4 * modes.len();
    let mut context = vec![0f32; n * f];
    for (i, row) in context.chunks_mut(f).enumerate() {
        task.contact_mode(modes[i % modes.len()])
            .unwrap()
            .write_signs(row);
    }
    let starts: Vec<f32> = (0..n).flat_map(|_| start.clone()).collect();
    let sampler = SamplerConfig::ddim(8);
    let anchored = sample_trajectories(
        engine,
        &sampler,
        &context,
        &starts,
        anchor,
        &mut KernelRng::seed_from_u64(3),
    )
    .unwrap();
    let mut clamped = starts.clone();
    anchor
        .clamp_angle(sd)
        .unwrap()
        .clamp_starts(&mut clamped, sd);
    let raw = sample_trajectories(
        engine,
        &sampler,
        &context,
        &clamped,
        StartAnchor::NONE,
        &mut KernelRng::seed_from_u64(3),
    )
    .unwrap();
    assert!(anchor.is_active(&segment_dims(dims)));
    let yaw = |row: &[f32]| row[c + 1].atan2(row[c]);
    let wrap = |a: f32| {
        (a + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI
    };
    let mut jumps = 0.0f32;
    for ((seg, raw), signs) in anchored
        .chunks(td)
        .zip(raw.chunks(td))
        .zip(context.chunks(f))
    {
        assert_eq!(seg[..sd], start[..], "row 0 is the start");
        assert!(
            (wrap(yaw(&seg[d..]) - yaw0)).abs() < 1e-4,
            "row 1 repeats the yaw"
        );
        let turn = wrap(yaw(&seg[d..]) - yaw(&raw[d..]));
        for t in 1..dims.horizon {
            let (a, r) = (&seg[t * d..(t + 1) * d], &raw[t * d..(t + 1) * d]);
            assert!(
                (wrap(yaw(a) - yaw(r)) - turn).abs() < 1e-4,
                "one rotation, row {t}"
            );
            for (i, &sign) in signs.iter().enumerate() {
                for j in 4 * i..4 * i + 4 {
                    if sign > 0.0 {
                        let shift = start[j] - raw[d + j];
                        assert!((a[j] - (r[j] + shift)).abs() < 1e-5, "contact joint {j}");
                        jumps += (raw[d + j] - start[j]).abs();
                    } else {
                        assert_eq!(a[j], r[j], "a regrasping finger's joint {j} as drawn");
                    }
                }
            }
            assert_eq!(a[sd..], r[sd..], "the actions as drawn");
        }
    }
    assert!(
        jumps > 0.0,
        "the raw model's row 1 moved the contact joints"
    );
}
