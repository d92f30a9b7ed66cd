//! Training the discriminator Ψ (spec §4.5) on real (label 1) versus diffused (label 0)
//! trajectories, BCE on the logit.
//!
//! The diffused trajectories come from the planner's own sampler: the trained denoiser is
//! exported to ONNX, loaded by tract (`dips_onnx::TractEngine`) and sampled with
//! `dips_kernel::diffusion::sample` (ancestral DDPM with the settings' noise factor and
//! guidance weight, then DDIM at each of `ddim_fakes` step counts), row 0's state inpainted
//! with the real start state and conditioned on the real context. They are cached in
//! `checkpoints/disc_fakes_*.safetensors`.
//!
//! With `noised_inputs` (the default, as in the authors' code) every training input is
//! forward-noised to a random diffusion step and its BCE weighted by `√β_t`: trained on clean
//! inputs only, Ψ learned to detect the DDPM sampler's fine texture (AUC 1.0) and scored DDIM
//! samples as real, which collapsed the particle weights (`docs/training.md`). Ψ is used, and
//! evaluated here, on clean inputs.

use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

use burn::tensor::Device;
use burn::tensor::activation::{sigmoid, softplus};
use dips_dataset::Dataset;
use dips_kernel::adapters::StartAnchor;
use dips_kernel::diffusion::schedule::fill_alpha_bar;
use dips_kernel::diffusion::{
    SampleRequest, SamplerConfig, SamplerScratch, SamplingMethod, ScratchLayout, sample,
};
use dips_kernel::mode::{SegmentDims, Task};
use safetensors::{Dtype, SafeTensors, tensor::TensorView};
use serde::Serialize;

use crate::data::{Normalizer, Samples, angle_columns, batch_indices, purpose, rotate_yaw, stream};
use crate::denoiser::{TrainedDenoiser, net_dims, split_samples};
use crate::error::{Result, TrainError, io_err};
use crate::net::{Discriminator, tensor};
use crate::params::{ParamStore, to_vec};
use crate::progress::{RunOptions, bar};
use crate::settings::TrainSettings;
use crate::stage::{self, Stage, checkpoint_dir, fingerprint};

/// Trajectories per sampler call (each step evaluates twice as many: guidance).
const SAMPLER_CHUNK: usize = 96;

/// Figures of a discriminator training run.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct DiscriminatorReport {
    /// Trainable scalars.
    pub params: usize,
    /// Real (and as many diffused) training trajectories.
    pub train_pairs: usize,
    /// Real (and as many diffused) held-out trajectories.
    pub eval_pairs: usize,
    /// Optimiser steps.
    pub steps: usize,
    /// The step this run resumed from.
    pub resumed_from: usize,
    /// Seconds spent sampling diffused trajectories (0 when cached).
    pub sampling_s: f64,
    /// Mean training BCE of the last (up to) 100 steps.
    pub train_loss_final: f32,
    /// Held-out BCE.
    pub held_out_loss: Option<f32>,
    /// Held-out accuracy at p = 0.5.
    pub held_out_accuracy: Option<f32>,
    /// Held-out ROC AUC (real versus diffused).
    pub held_out_auc: Option<f32>,
    /// Training-set accuracy at p = 0.5.
    pub train_accuracy: f32,
    /// Mean wall time of one optimiser step, over every run of this stage (seconds).
    pub step_time_s: f64,
    /// Wall time of this stage, summed over its runs when resumed (seconds).
    pub seconds: f64,
}

/// A trained discriminator.
#[derive(Debug, Clone)]
pub struct TrainedDiscriminator {
    /// The task.
    pub task: Task,
    /// The network.
    pub net: Discriminator,
    /// Its parameters.
    pub params: ParamStore,
    /// The normalisation (the denoiser's).
    pub norm: Normalizer,
    /// Diffusion steps of the denoiser it was trained against (contract metadata).
    pub diffusion_steps: usize,
    /// The samplers its negatives came from ([`negative_samplers`]), written to the model as
    /// `dips.psi_negatives`.
    pub negatives: Vec<String>,
    /// Figures.
    pub report: DiscriminatorReport,
}

impl TrainedDiscriminator {
    /// The trainer's own forward pass: `p_real [B]` for normalised `x [B,T,D]`, `context`.
    pub fn forward(&self, batch: usize, x: &[f32], context: &[f32]) -> Result<Vec<f32>> {
        let dev = Device::flex();
        let d = self.net.dims();
        let p = self.params.tensors(&dev, false);
        let z = self.net.logit(
            &p,
            tensor(x.to_vec(), [batch, d.horizon, d.dim], &dev),
            tensor(context.to_vec(), [batch, d.fingers], &dev),
        );
        to_vec(sigmoid(z))
    }

    /// The contract-v1 ONNX model of this discriminator.
    pub fn onnx(&self) -> Result<tract_onnx::pb::ModelProto> {
        crate::export::discriminator_model(
            &self.net,
            &self.params,
            self.task,
            self.diffusion_steps,
            &self.norm,
            &self.negatives,
        )
    }
}

/// Sample one diffused trajectory per real one (same context, same start state), raw units.
///
/// `anchor` makes each trajectory continue from its start as the planner's sampler does
/// (start angle clamped before sampling, [`StartAnchor::apply`] after);
/// [`StartAnchor::NONE`] keeps the model's rows.
pub fn diffuse_like(
    denoiser: &TrainedDenoiser,
    real: &Samples,
    config: &SamplerConfig,
    anchor: StartAnchor,
    seed: u64,
    opts: &RunOptions,
    what: &str,
) -> Result<Vec<f32>> {
    let proto = denoiser.onnx()?;
    let mut engine = dips_onnx::TractEngine::from_model_proto(&proto)?;
    let dims = denoiser.task.dims();
    let mdims = engine.contract().dims();
    let (td, f, sd) = (dims.floats(), dims.fingers, dims.state_dim);
    let layout = ScratchLayout::new(mdims, SAMPLER_CHUNK);
    let mut buf = vec![0f32; layout.total()];
    let mut out = vec![0f32; real.n * td];
    let pb = bar(opts, real.n as u64, what);
    for (c, start) in (0..real.n).step_by(SAMPLER_CHUNK).enumerate() {
        let n = (real.n - start).min(SAMPLER_CHUNK);
        let starts: Vec<f32> = (start..start + n)
            .flat_map(|i| real.x[i * td..i * td + sd].iter().copied())
            .collect();
        let mut canonical = starts.clone();
        if let Some(a) = anchor.clamp_angle(sd) {
            a.clamp_starts(&mut canonical, sd);
        }
        let context = &real.context[start * f..(start + n) * f];
        let request = SampleRequest {
            context,
            start_states: Some(&canonical),
        };
        let mut scratch = SamplerScratch::split(&mut buf, &layout)
            .map_err(|e| TrainError::Sampler(e.to_string()))?;
        let mut rng = stream(seed, purpose::SAMPLER, c as u64);
        sample(
            &mut engine,
            config,
            &request,
            &mut rng,
            &mut scratch,
            &mut out[start * td..(start + n) * td],
        )
        .map_err(|e| TrainError::Sampler(e.to_string()))?;
        anchor.apply(
            &mut out[start * td..(start + n) * td],
            &starts,
            context,
            &dims,
        );
        pb.inc(n as u64);
    }
    pb.finish_and_clear();
    Ok(out)
}

/// Ψ's normalisation: the denoiser's when it measures in the world's frame (Ψ scores what the
/// denoiser draws, so one normalisation serves both), else one fitted on the world-frame
/// training rows: Ψ scores segments in the world's frame, and the denoiser's statistics of
/// object motion from the start would put the object's level far out in its tails.
fn psi_normalizer(
    denoiser: &TrainedDenoiser,
    train: &Samples,
    settings: &TrainSettings,
) -> Result<Normalizer> {
    if denoiser.object_frame == dips_kernel::engine::ObjectFrame::World {
        return Ok(denoiser.norm.clone());
    }
    Normalizer::fit(
        train,
        denoiser.task,
        settings.std_floor,
        settings.normalize_angles,
    )
}

/// Area under the ROC curve of scores for positives versus negatives (ties count half).
pub fn auc(pos: &[f32], neg: &[f32]) -> f32 {
    if pos.is_empty() || neg.is_empty() {
        return f32::NAN;
    }
    let mut all: Vec<(f32, bool)> = pos
        .iter()
        .map(|&p| (p, true))
        .chain(neg.iter().map(|&n| (n, false)))
        .collect();
    all.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Mann–Whitney U with average ranks for ties.
    let mut rank_sum_pos = 0f64;
    let mut i = 0;
    while i < all.len() {
        let mut j = i;
        while j < all.len() && all[j].0 == all[i].0 {
            j += 1;
        }
        let avg = (i + j + 1) as f64 / 2.0; // ranks i+1..=j
        rank_sum_pos += avg * all[i..j].iter().filter(|e| e.1).count() as f64;
        i = j;
    }
    let (np, nn) = (pos.len() as f64, neg.len() as f64);
    ((rank_sum_pos - np * (np + 1.0) / 2.0) / (np * nn)) as f32
}

/// The cached diffused trajectories of `key` and the seconds it took to sample them.
fn read_cache(path: &Path, key: &str, len: usize) -> Option<(Vec<f32>, f64)> {
    let buf = std::fs::read(path).ok()?;
    let (_, md) = SafeTensors::read_metadata(&buf).ok()?;
    let meta = md.metadata().as_ref()?;
    if meta.get("key")? != key {
        return None;
    }
    let secs = meta
        .get("seconds")
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(0.0);
    let st = SafeTensors::deserialize(&buf).ok()?;
    let v = st.tensor("fakes").ok()?;
    if v.dtype() != Dtype::F32 || v.data().len() != len * 4 {
        return None;
    }
    Some((
        v.data()
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        secs,
    ))
}

fn write_cache(path: &Path, key: &str, v: &[f32], seconds: f64) -> Result<()> {
    let bytes = dips_dataset::f32_bytes(v);
    let view =
        TensorView::new(Dtype::F32, vec![v.len()], &bytes).map_err(|e| TrainError::Checkpoint {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
    let meta = HashMap::from([
        ("key".to_string(), key.to_string()),
        ("seconds".to_string(), seconds.to_string()),
    ]);
    let buf = safetensors::serialize([("fakes", view)], Some(meta)).map_err(|e| {
        TrainError::Checkpoint {
            path: path.to_path_buf(),
            reason: e.to_string(),
        }
    })?;
    dips_fs::write_atomic(path, &buf).map_err(io_err(path))
}

/// Real and diffused trajectories, normalised: `fake` holds one set of `n` per sampler,
/// set `j`'s trajectory `i` made from real trajectory `i`.
struct Pairs {
    real: Vec<f32>,
    fake: Vec<f32>,
    context: Vec<f32>,
    n: usize,
    sets: usize,
}

/// One source of Ψ's negatives: a sampler, how its samples continue from their starts, and
/// the tag of its cache key and file.
struct FakeSource {
    tag: String,
    config: SamplerConfig,
    anchor: StartAnchor,
}

/// The sources of Ψ's negatives: the paper's DDPM (cache tag empty: its key and file keep
/// their first form), then each DDIM count, then each of the planner's strided DDPM counts
/// with the task's start anchor.
fn fake_sources(settings: &TrainSettings, task: Task) -> Vec<FakeSource> {
    let s = &settings.discriminator;
    let base = SamplerConfig {
        guidance_weight: s.guidance_weight,
        ..SamplerConfig::default()
    };
    let steps_of = |k: usize| u16::try_from(k).unwrap_or(u16::MAX);
    let source = |tag: String, method, anchor| FakeSource {
        tag,
        config: SamplerConfig { method, ..base },
        anchor,
    };
    let mut v = vec![source(
        String::new(),
        SamplingMethod::Ddpm {
            noise_factor: s.noise_factor,
        },
        StartAnchor::NONE,
    )];
    for &steps in &s.ddim_fakes {
        v.push(source(
            format!("ddim{steps}"),
            SamplingMethod::Ddim {
                steps: steps_of(steps),
                eta: 0.0,
            },
            StartAnchor::NONE,
        ));
    }
    for &steps in &s.planner_fakes {
        v.push(source(
            format!("planner-ddpm{steps}"),
            SamplingMethod::DdpmStrided {
                steps: steps_of(steps),
                noise_factor: s.noise_factor,
            },
            dips_kernel::session::start_anchor(task),
        ));
    }
    v
}

/// The names of the samplers Ψ's negatives came from ([`dips_onnx::contract::psi_sample_name`]):
/// recorded in the discriminator's metadata (`dips.psi_negatives`).
pub fn negative_samplers(settings: &TrainSettings, task: Task) -> Vec<String> {
    fake_sources(settings, task)
        .iter()
        .map(|f| {
            dips_onnx::contract::psi_sample_name(&f.config.method, f.anchor != StartAnchor::NONE)
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn pairs(
    real: Samples,
    denoiser: &TrainedDenoiser,
    norm: &Normalizer,
    settings: &TrainSettings,
    cache: &Path,
    seed: u64,
    opts: &RunOptions,
    what: &str,
) -> Result<(Pairs, f64)> {
    let s = &settings.discriminator;
    let samplers = fake_sources(settings, denoiser.task);
    let den_fp = fingerprint(
        &denoiser
            .params
            .data
            .iter()
            .map(Vec::as_slice)
            .collect::<Vec<_>>(),
    );
    let real_fp = fingerprint(&[&real.x, &real.context]);
    let mut fake = Vec::with_capacity(real.x.len() * samplers.len());
    let mut seconds = 0.0;
    for FakeSource {
        tag,
        config,
        anchor,
    } in &samplers
    {
        // `v2`: the sampler zeroes the last row's action (older caches are stale). DDPM's key
        // and file keep their first form.
        let key = format!(
            "v2{tag}-{:?}-{den_fp}-{real_fp}-{}-{}-{seed}",
            config.clip_denoised, s.noise_factor, s.guidance_weight
        );
        let path = if tag.is_empty() {
            cache.to_path_buf()
        } else {
            cache.with_extension(format!("{tag}.safetensors"))
        };
        // The seconds are the sampling's, also when the trajectories come from the cache.
        let (v, secs) = match read_cache(&path, &key, real.x.len()) {
            Some(cached) => cached,
            None => {
                let t0 = Instant::now();
                let label = if tag.is_empty() {
                    what.to_string()
                } else {
                    format!("{what} ({tag})")
                };
                let v = diffuse_like(denoiser, &real, config, *anchor, seed, opts, &label)?;
                let secs = t0.elapsed().as_secs_f64();
                write_cache(&path, &key, &v, secs)?;
                (v, secs)
            }
        };
        fake.extend(v);
        seconds += secs;
    }
    let mut r = real.x;
    norm.normalize(&mut r);
    norm.normalize(&mut fake);
    Ok((
        Pairs {
            real: r,
            fake,
            context: real.context,
            n: real.n,
            sets: samplers.len(),
        },
        seconds,
    ))
}

/// Forward-noise `x` (normalised, `b` trajectories) in place to one random diffusion step per
/// trajectory, row 0's state kept clean as the sampler keeps it; returns `√β_t` per trajectory.
fn forward_noise(
    x: &mut [f32],
    dims: SegmentDims,
    alpha_bar: &[f32],
    rng: &mut dips_kernel::rng::KernelRng,
) -> Vec<f32> {
    let (td, sd) = (dims.floats(), dims.state_dim);
    x.chunks_exact_mut(td)
        .map(|traj| {
            let t = rng.below(alpha_bar.len() as u32) as usize;
            let (sa, sb) = (alpha_bar[t].sqrt(), (1.0 - alpha_bar[t]).sqrt());
            for v in &mut traj[sd..] {
                *v = sa * *v + sb * rng.normal_f32();
            }
            let prev = if t == 0 { 1.0 } else { alpha_bar[t - 1] };
            (1.0 - alpha_bar[t] / prev).clamp(0.0, 1.0).sqrt()
        })
        .collect()
}

/// Scores of real and diffused trajectories, and the mean BCE.
fn evaluate(
    net: &Discriminator,
    params: &ParamStore,
    p: &Pairs,
    dims: SegmentDims,
) -> Result<(Vec<f32>, Vec<f32>, f32)> {
    let dev = Device::flex();
    let pt = params.tensors(&dev, false);
    let (td, f) = (dims.floats(), dims.fingers);
    let mut scores = [Vec::new(), Vec::new()];
    let sets = [(0, &p.real, 1), (1, &p.fake, p.sets)];
    for (k, x, count) in sets {
        for j in 0..count {
            let x = &x[j * p.n * td..(j + 1) * p.n * td];
            let mut i = 0;
            while i < p.n {
                let b = (p.n - i).min(256);
                let z = net.logit(
                    &pt,
                    tensor(
                        x[i * td..(i + b) * td].to_vec(),
                        [b, dims.horizon, dims.dim()],
                        &dev,
                    ),
                    tensor(p.context[i * f..(i + b) * f].to_vec(), [b, f], &dev),
                );
                scores[k].extend(to_vec(z)?);
                i += b;
            }
        }
    }
    // BCE from logits: softplus(z) − y·z.
    let sp = |z: f32| z.max(0.0) + (-z.abs()).exp().ln_1p();
    let bce = scores[0].iter().map(|&z| sp(z) - z).sum::<f32>()
        + scores[1].iter().map(|&z| sp(z)).sum::<f32>();
    let [real, fake] = scores;
    let n = (real.len() + fake.len()).max(1) as f32;
    Ok((real, fake, bce / n))
}

fn accuracy(real: &[f32], fake: &[f32]) -> f32 {
    let ok = real.iter().filter(|&&z| z > 0.0).count() + fake.iter().filter(|&&z| z <= 0.0).count();
    ok as f32 / (real.len() + fake.len()).max(1) as f32
}

/// The `(cos, sin)` columns that `discriminator.augment_yaw` turns for `task`, `None` when it
/// is off; an error naming the setting when the task has no symmetry angle.
pub fn augment_columns(task: Task, settings: &TrainSettings) -> Result<Option<(usize, usize)>> {
    if !settings.discriminator.augment_yaw {
        return Ok(None);
    }
    angle_columns(task)
        .first()
        .copied()
        .filter(|_| dips_kernel::session::start_anchor(task).angle.is_some())
        .map(Some)
        .ok_or_else(|| TrainError::Settings {
            field: "discriminator.augment_yaw".into(),
            reason: format!(
                "task {} has no symmetry angle to turn about; only the screwdriver's yaw is \
                 one (set it to false)",
                task.name()
            ),
        })
}

/// Train the discriminator against the diffused trajectories of `denoiser`.
///
/// Checkpoints go to `out_dir/checkpoints/discriminator.safetensors` (resumed like the
/// denoiser's); the diffused trajectories are cached beside it.
pub fn train_discriminator(
    ds: &Dataset,
    settings: &TrainSettings,
    denoiser: &TrainedDenoiser,
    out_dir: &Path,
    opts: &RunOptions,
) -> Result<TrainedDiscriminator> {
    settings.validate()?;
    let started = Instant::now();
    let task = ds.task;
    let dims = ds.dims();
    let s = &settings.discriminator;
    let yaw = augment_columns(task, settings)?;
    let (train, held) = split_samples(ds, settings)?;
    let norm = psi_normalizer(denoiser, &train, settings)?;
    let ckd = checkpoint_dir(out_dir)?;
    let (tp, mut sampling_s) = pairs(
        train.subset(s.samples, dims),
        denoiser,
        &norm,
        settings,
        &ckd.join("disc_fakes_train.safetensors"),
        settings.seed,
        opts,
        "diffuse train",
    )?;
    let ep = if held.n > 0 {
        let (p, secs) = pairs(
            held.subset(s.eval_samples, dims),
            denoiser,
            &norm,
            settings,
            &ckd.join("disc_fakes_held_out.safetensors"),
            settings.seed ^ 0x5eed,
            opts,
            "diffuse eval",
        )?;
        sampling_s += secs;
        Some(p)
    } else {
        None
    };

    let mut params = ParamStore::default();
    let net = Discriminator::new(
        &mut params,
        net_dims(dims),
        &settings.net,
        &mut stream(settings.seed, purpose::INIT_DISCRIMINATOR, 0),
    );
    let meta = HashMap::from([
        (
            "settings".to_string(),
            serde_json::to_string(settings).unwrap_or_default(),
        ),
        ("task".to_string(), task.name().to_string()),
        (
            "data".to_string(),
            fingerprint(&[&tp.real, &tp.fake, &tp.context]),
        ),
    ]);
    let stage = Stage {
        name: "discriminator",
        loss_name: "bce",
        steps: s.steps,
        lr: s.lr,
        ema: None,
        checkpoint: ckd.join("discriminator.safetensors"),
        checkpoint_every: settings.checkpoint_every,
        meta,
        started,
        opts,
    };

    let (td, f) = (dims.floats(), dims.fingers);
    let mut alpha_bar = vec![0f32; denoiser.diffusion_steps];
    fill_alpha_bar(denoiser.diffusion_steps, &mut alpha_bar);
    let half = s.batch / 2;
    let b = 2 * half;
    let mut labels = vec![1.0f32; half];
    labels.extend(vec![0.0f32; half]);
    let mut cache = None;
    let trained = stage::train(stage, params, |step, p, dev| {
        let idx = batch_indices(
            settings.seed,
            purpose::DISC_ORDER,
            step,
            half,
            tp.n,
            &mut cache,
        );
        let mut x = Vec::with_capacity(b * td);
        let mut c = Vec::with_capacity(b * f);
        for &i in &idx {
            x.extend_from_slice(&tp.real[i * td..(i + 1) * td]);
        }
        // The negatives cycle through the samplers' sets.
        for (k, &i) in idx.iter().enumerate() {
            let j = (step * half + k) % tp.sets * tp.n + i;
            x.extend_from_slice(&tp.fake[j * td..(j + 1) * td]);
        }
        for _ in 0..2 {
            for &i in &idx {
                c.extend_from_slice(&tp.context[i * f..(i + 1) * f]);
            }
        }
        if let Some((cos_col, sin_col)) = yaw {
            let mut rng = stream(settings.seed, purpose::DISC_AUGMENT, step as u64);
            norm.denormalize(&mut x);
            for traj in x.chunks_exact_mut(td) {
                let delta = (rng.uniform_f32() * 2.0 - 1.0) * std::f32::consts::PI;
                rotate_yaw(traj, dims.dim(), cos_col, sin_col, delta);
            }
            norm.normalize(&mut x);
        }
        let w = if s.noised_inputs {
            let mut rng = stream(settings.seed, purpose::DISC_NOISE, step as u64);
            let w = forward_noise(&mut x, dims, &alpha_bar, &mut rng);
            let mean = w.iter().sum::<f32>() / w.len() as f32;
            w.into_iter().map(|v| v / mean.max(1e-12)).collect()
        } else {
            vec![1.0; b]
        };
        let z = net.logit(
            p,
            tensor(x, [b, dims.horizon, dims.dim()], dev),
            tensor(c, [b, f], dev),
        );
        let y = tensor(labels.clone(), [b, 1], dev);
        let w = tensor(w, [b, 1], dev);
        Ok(((softplus(z.clone(), 1.0) - z * y) * w).mean())
    })?;
    let params = trained.params;
    let (tr, tf, _) = evaluate(&net, &params, &tp, dims)?;
    let (held_out_loss, held_out_accuracy, held_out_auc) = match &ep {
        Some(ep) => {
            let (r, f_, l) = evaluate(&net, &params, ep, dims)?;
            (Some(l), Some(accuracy(&r, &f_)), Some(auc(&r, &f_)))
        }
        None => (None, None, None),
    };
    let report = DiscriminatorReport {
        params: params.count(),
        train_pairs: tp.n,
        eval_pairs: ep.as_ref().map_or(0, |p| p.n),
        steps: s.steps,
        resumed_from: trained.resumed_from,
        sampling_s,
        train_loss_final: trained.train_loss_final,
        held_out_loss,
        held_out_accuracy,
        held_out_auc,
        train_accuracy: accuracy(&tr, &tf),
        step_time_s: trained.step_time_s,
        seconds: trained.clock.run_seconds(),
    };
    Ok(TrainedDiscriminator {
        task,
        net,
        params,
        norm,
        diffusion_steps: denoiser.diffusion_steps,
        negatives: negative_samplers(settings, task),
        report,
    })
}
