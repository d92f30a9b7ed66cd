//! Training the denoiser: ε-prediction on forward-noised, inpainting-masked, normalised
//! trajectories with context dropout; Adam; EMA; checkpoints; the held-out loss.

use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

use burn::tensor::Device;
use dips_dataset::Dataset;
use dips_kernel::diffusion::schedule::fill_alpha_bar;
use dips_kernel::engine::ObjectFrame;
use dips_kernel::mode::{SegmentDims, Task};
use dips_kernel::task::CardGoals;
use serde::Serialize;

use crate::data::{
    Normalizer, Samples, angle_columns, batch_indices, noise_batch, purpose, rotate_yaw, stream,
    to_object_frame,
};
use crate::error::{Result, TrainError};
use crate::net::{Denoiser, NetDims, tensor};
use crate::params::{ParamStore, to_vec};
use crate::progress::RunOptions;
use crate::settings::TrainSettings;
use crate::stage::{self, Ema, Stage, checkpoint_dir, fingerprint};

/// Figures of a denoiser training run (`train_report.json`).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct DenoiserReport {
    /// Trainable scalars.
    pub params: usize,
    /// Training trajectories / held-out trajectories.
    pub train_samples: usize,
    /// Held-out trajectories (the loss is averaged over at most `eval_samples` of them).
    pub held_out_samples: usize,
    /// Optimiser steps.
    pub steps: usize,
    /// Epochs those steps amount to.
    pub epochs: f64,
    /// The step this run resumed from (0: fresh).
    pub resumed_from: usize,
    /// Held-out masked MSE of the initial network (fixed draws).
    pub held_out_loss_initial: Option<f32>,
    /// Held-out masked MSE of the raw (non-EMA) parameters at the end.
    pub held_out_loss_raw: Option<f32>,
    /// Held-out masked MSE of the EMA parameters at the end (the exported model).
    pub held_out_loss: Option<f32>,
    /// Mean training loss of the last (up to) 100 steps.
    pub train_loss_final: f32,
    /// Mean wall time of one optimiser step, over every run of this stage (seconds).
    pub step_time_s: f64,
    /// Wall time of this stage, summed over its runs when resumed (seconds).
    pub seconds: f64,
}

/// A trained denoiser: the network, its exported (EMA) parameters and normalisation.
#[derive(Debug, Clone)]
pub struct TrainedDenoiser {
    /// The task.
    pub task: Task,
    /// The network.
    pub net: Denoiser,
    /// The EMA parameters (what is exported).
    pub params: ParamStore,
    /// The normalisation.
    pub norm: Normalizer,
    /// Diffusion steps.
    pub diffusion_steps: usize,
    /// Figures.
    pub report: DenoiserReport,
    /// The card goals its demos were made with, written into the model as `dips.card_goals`
    /// ([`crate::run`] sets it for the card's planner model; `None`: not recorded).
    pub card_goals: Option<CardGoals>,
    /// Where it measures the object from (`dips.object_frame`, written when not the world's).
    pub object_frame: ObjectFrame,
}

impl TrainedDenoiser {
    /// The trainer's own forward pass (burn, no autodiff): `eps [B,T,D]` for flat contract
    /// inputs. Used to check the exported model against the trained function.
    pub fn forward(
        &self,
        batch: usize,
        x: &[f32],
        t: &[f32],
        context: &[f32],
        cond_mask: &[f32],
    ) -> Result<Vec<f32>> {
        let dev = Device::flex();
        let d = self.net.dims();
        let p = self.params.tensors(&dev, false);
        let y = self.net.fwd(
            &p,
            tensor(x.to_vec(), [batch, d.horizon, d.dim], &dev),
            tensor(t.to_vec(), [batch], &dev),
            tensor(context.to_vec(), [batch, d.fingers], &dev),
            tensor(cond_mask.to_vec(), [batch], &dev),
        );
        to_vec(y)
    }

    /// The contract-v1 ONNX model of this denoiser.
    pub fn onnx(&self) -> Result<tract_onnx::pb::ModelProto> {
        crate::export::denoiser_model(
            &self.net,
            &self.params,
            self.task,
            self.diffusion_steps,
            &self.norm,
            self.card_goals,
            self.object_frame,
        )
    }
}

/// The network's sizes for a task.
pub fn net_dims(dims: SegmentDims) -> NetDims {
    NetDims {
        horizon: dims.horizon,
        dim: dims.dim(),
        state_dim: dims.state_dim,
        fingers: dims.fingers,
    }
}

/// The min-SNR-γ weight of the ε loss at a step with cumulative signal `alpha_bar`:
/// `min(SNR, γ) / SNR` with `SNR = ᾱ / (1 − ᾱ)` (1 wherever `SNR ≤ γ`).
pub(crate) fn min_snr_weight(alpha_bar: f32, gamma: f32) -> f32 {
    let snr = alpha_bar / (1.0 - alpha_bar).max(f32::MIN_POSITIVE);
    if snr <= gamma { 1.0 } else { gamma / snr }
}

/// The split's samples; errors when there is nothing to train on.
pub(crate) fn split_samples(ds: &Dataset, settings: &TrainSettings) -> Result<(Samples, Samples)> {
    let split = ds.split(settings.held_out_fraction);
    let gather = if settings.denoiser.policy {
        Samples::gather_policy
    } else {
        Samples::gather
    };
    let train = gather(ds, &split.train);
    let held = gather(ds, &split.held_out);
    if train.n == 0 {
        return Err(TrainError::DatasetUnusable(
            "no training trajectories after the held-out split".into(),
        ));
    }
    Ok((train, held))
}

/// Fixed held-out draws: a normalised, noised, masked batch with the context kept.
struct EvalSet {
    batch: crate::data::NoisedBatch,
    n: usize,
}

fn eval_set(
    held: &Samples,
    settings: &TrainSettings,
    norm: &Normalizer,
    dims: SegmentDims,
    alpha_bar: &[f32],
) -> Option<EvalSet> {
    if held.n == 0 {
        return None;
    }
    let s = held.subset(settings.eval_samples, dims);
    let mut x0 = s.x;
    norm.normalize(&mut x0);
    let mut rng = stream(settings.seed, purpose::EVAL, 0);
    let batch = noise_batch(
        &x0,
        s.context,
        dims,
        alpha_bar,
        0.0,
        settings.denoiser.start_row(),
        &mut rng,
    );
    Some(EvalSet { batch, n: s.n })
}

/// Masked MSE of `params` on the fixed held-out draws (chunks of 256, no autodiff).
fn eval_loss(net: &Denoiser, params: &ParamStore, e: &EvalSet) -> Result<f32> {
    let dev = Device::flex();
    let p = params.tensors(&dev, false);
    let d = net.dims();
    let (td, f) = (d.horizon * d.dim, d.fingers);
    let (mut num, mut den) = (0f64, 0f64);
    let mut i = 0;
    while i < e.n {
        let b = (e.n - i).min(256);
        let nb = &e.batch;
        let y = net.fwd(
            &p,
            tensor(
                nb.x_t[i * td..(i + b) * td].to_vec(),
                [b, d.horizon, d.dim],
                &dev,
            ),
            tensor(nb.t[i..i + b].to_vec(), [b], &dev),
            tensor(nb.context[i * f..(i + b) * f].to_vec(), [b, f], &dev),
            tensor(vec![1.0; b], [b], &dev),
        );
        let y = to_vec(y)?;
        for (k, yk) in y.iter().enumerate() {
            let j = i * td + k;
            let w = f64::from(nb.weight[j]);
            let r = f64::from(yk - nb.eps[j]);
            num += w * r * r;
            den += w;
        }
        i += b;
    }
    Ok((num / den.max(1.0)) as f32)
}

/// Train the denoiser on `ds` (split by demo seed) and return it with its figures.
///
/// Checkpoints go to `out_dir/checkpoints/denoiser.safetensors` every
/// `settings.checkpoint_every` steps and at the end; an existing checkpoint of the same run
/// (same settings and data) is resumed, and the result equals an uninterrupted run bit for bit.
pub fn train_denoiser(
    ds: &Dataset,
    settings: &TrainSettings,
    out_dir: &Path,
    opts: &RunOptions,
) -> Result<TrainedDenoiser> {
    settings.validate()?;
    let started = Instant::now();
    let task = ds.task;
    let dims = ds.dims();
    let (mut train, mut held) = split_samples(ds, settings)?;
    let s = &settings.denoiser;
    to_object_frame(&mut train, s.object_frame, dims);
    to_object_frame(&mut held, s.object_frame, dims);
    let norm = Normalizer::fit(&train, task, settings.std_floor, settings.normalize_angles)?;
    let mut alpha_bar = vec![0f32; s.diffusion_steps];
    fill_alpha_bar(s.diffusion_steps, &mut alpha_bar);

    let mut params = ParamStore::default();
    let net = Denoiser::new(
        &mut params,
        net_dims(dims),
        &settings.net,
        &mut stream(settings.seed, purpose::INIT_DENOISER, 0),
    );
    let eval = eval_set(&held, settings, &norm, dims, &alpha_bar);
    let initial = match &eval {
        Some(e) => Some(eval_loss(&net, &params, e)?),
        None => None,
    };

    let meta = HashMap::from([
        ("settings".to_string(), settings.denoiser_key()),
        ("task".to_string(), task.name().to_string()),
        ("data".to_string(), fingerprint(&[&train.x, &train.context])),
    ]);
    let stage = Stage {
        name: "denoiser",
        loss_name: "loss",
        steps: s.steps,
        lr: s.lr,
        ema: Some(Ema {
            decay: s.ema_decay,
            every: s.ema_every,
            warmup: settings.ema_warmup(),
        }),
        checkpoint: checkpoint_dir(out_dir)?.join("denoiser.safetensors"),
        checkpoint_every: settings.checkpoint_every,
        meta,
        started,
        opts,
    };

    let yaw = if s.augment_yaw && task == Task::Screwdriver {
        angle_columns(task).first().copied()
    } else {
        None
    };
    let (td, f, d) = (dims.floats(), dims.fingers, dims.dim());
    let object_cols = task.layout().object()..task.layout().state_dim();
    let mut order_cache = None;
    let trained = stage::train(stage, params, |step, p, dev| {
        let mut rng = stream(settings.seed, purpose::STEP, step as u64);
        let idx = batch_indices(
            settings.seed,
            purpose::ORDER,
            step,
            s.batch,
            train.n,
            &mut order_cache,
        );
        let mut x0 = Vec::with_capacity(s.batch * td);
        let mut ctx = Vec::with_capacity(s.batch * f);
        for &i in &idx {
            x0.extend_from_slice(&train.x[i * td..(i + 1) * td]);
            ctx.extend_from_slice(&train.context[i * f..(i + 1) * f]);
        }
        if let Some((c, sn)) = yaw {
            for traj in x0.chunks_exact_mut(td) {
                let delta = (rng.uniform_f32() * 2.0 - 1.0) * std::f32::consts::PI;
                rotate_yaw(traj, d, c, sn, delta);
            }
        }
        norm.normalize(&mut x0);
        let mut nb = noise_batch(
            &x0,
            ctx,
            dims,
            &alpha_bar,
            s.context_dropout,
            s.start_row(),
            &mut rng,
        );
        if let Some(gamma) = s.min_snr_gamma {
            for (w, &t) in nb.weight.chunks_exact_mut(td).zip(&nb.t) {
                let scale = min_snr_weight(alpha_bar[t as usize], gamma);
                w.iter_mut().for_each(|v| *v *= scale);
            }
        }
        if s.object_loss_weight != 1.0 {
            for row in nb.weight.chunks_exact_mut(d) {
                for w in &mut row[object_cols.clone()] {
                    *w *= s.object_loss_weight;
                }
            }
        }
        let wsum: f32 = nb.weight.iter().sum();
        let b = s.batch;
        let pred = net.fwd(
            p,
            tensor(nb.x_t, [b, dims.horizon, d], dev),
            tensor(nb.t, [b], dev),
            tensor(nb.context, [b, f], dev),
            tensor(nb.cond_mask, [b], dev),
        );
        let diff = pred - tensor(nb.eps, [b, dims.horizon, d], dev);
        Ok(
            (diff.powi_scalar(2) * tensor(nb.weight, [b, dims.horizon, d], dev))
                .sum()
                .div_scalar(wsum.max(1.0)),
        )
    })?;
    let params = trained.params;
    let ema = ParamStore {
        data: trained.optim.ema,
        ..params.clone()
    };
    let (held_out_loss, held_out_loss_raw) = match &eval {
        Some(e) => (
            Some(eval_loss(&net, &ema, e)?),
            Some(eval_loss(&net, &params, e)?),
        ),
        None => (None, None),
    };
    let report = DenoiserReport {
        params: params.count(),
        train_samples: train.n,
        held_out_samples: held.n,
        steps: s.steps,
        epochs: (s.steps * s.batch) as f64 / train.n as f64,
        resumed_from: trained.resumed_from,
        held_out_loss_initial: initial,
        held_out_loss_raw,
        held_out_loss,
        train_loss_final: trained.train_loss_final,
        step_time_s: trained.step_time_s,
        seconds: trained.clock.run_seconds(),
    };
    Ok(TrainedDenoiser {
        task,
        net,
        params: ema,
        norm,
        diffusion_steps: s.diffusion_steps,
        report,
        card_goals: None,
        object_frame: s.object_frame,
    })
}

#[cfg(test)]
mod tests {
    use super::min_snr_weight;

    #[test]
    fn min_snr_weight_caps_the_clean_steps_only() {
        // ᾱ = 0.5: SNR 1 ≤ γ, full weight; ᾱ = 0.99: SNR 99, weight γ / 99.
        assert_eq!(min_snr_weight(0.5, 5.0), 1.0);
        assert!((min_snr_weight(0.99, 5.0) - 5.0 / 99.0).abs() < 1e-4);
        assert_eq!(min_snr_weight(0.01, 5.0), 1.0);
        assert!(min_snr_weight(1.0, 5.0).is_finite());
    }
}
