//! One training stage: the optimiser loop that the denoiser and the discriminator share.
//!
//! A stage resumes from its checkpoint when one of the same run exists, then steps Adam (and
//! the EMA, where the stage keeps one) on the loss its model computes for each step's batch,
//! shows its progress, writes checkpoints, and stops where [`RunOptions::stop_after`] says.
//! What a model trains on and how its loss is computed stay in its own module; the batch of
//! step `k` is a function of `(seed, k)` there, so a resumed stage equals an uninterrupted
//! one bit for bit.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::tensor::{Device, Tensor};

use crate::error::{Result, TrainError, io_err};
use crate::params::{Checkpoint, OptimState, ParamStore, to_vec};
use crate::progress::{RunClock, RunOptions, bar};

/// The exponential moving average a stage keeps of its parameters
/// ([`OptimState::ema_update`] after every optimiser step).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ema {
    /// The decay.
    pub(crate) decay: f32,
    /// Update every this many steps.
    pub(crate) every: usize,
    /// Steps during which the EMA is a plain copy.
    pub(crate) warmup: usize,
}

/// What a stage runs: its name, optimiser, checkpoint and options.
#[derive(Debug)]
pub(crate) struct Stage<'a> {
    /// The progress bar's prefix.
    pub(crate) name: &'static str,
    /// The loss's name in the progress bar's message.
    pub(crate) loss_name: &'static str,
    /// Optimiser steps in all.
    pub(crate) steps: usize,
    /// Adam's learning rate.
    pub(crate) lr: f64,
    /// The EMA of the parameters, if the stage keeps one.
    pub(crate) ema: Option<Ema>,
    /// The checkpoint file.
    pub(crate) checkpoint: PathBuf,
    /// Write a checkpoint every this many steps (0: only at the end or a stop).
    pub(crate) checkpoint_every: usize,
    /// What a checkpoint must record to be resumed by this run (settings, task, data).
    pub(crate) meta: HashMap<String, String>,
    /// When the stage started (its wall time counts from here).
    pub(crate) started: Instant,
    /// How the stage runs.
    pub(crate) opts: &'a RunOptions,
}

/// A finished stage.
#[derive(Debug)]
pub(crate) struct Trained {
    /// The parameters after the last step.
    pub(crate) params: ParamStore,
    /// Adam's state and the EMA after the last step.
    pub(crate) optim: OptimState,
    /// The step this run resumed from (0: fresh).
    pub(crate) resumed_from: usize,
    /// Mean training loss of the last (up to) 100 steps.
    pub(crate) train_loss_final: f32,
    /// Mean wall time of one optimiser step, over every run of this stage (seconds).
    pub(crate) step_time_s: f64,
    /// The stage's clock (its wall time over all its runs).
    pub(crate) clock: RunClock,
}

/// Run `stage` from `params` (fresh from their initialisation) or from its checkpoint:
/// `loss(step, params, device)` builds step `step`'s batch and returns its loss over `params`
/// (leaf tensors with gradients on `device`).
pub(crate) fn train<F>(stage: Stage<'_>, mut params: ParamStore, mut loss: F) -> Result<Trained>
where
    F: FnMut(usize, &[Tensor<1>], &Device) -> Result<Tensor<1>>,
{
    let opts = stage.opts;
    let mut optim = OptimState::new(&params);
    let mut clock = RunClock::start(stage.started, None);
    if let Some(ck) = resume(&stage.checkpoint, &params, &stage.meta, opts)? {
        clock = RunClock::start(stage.started, Some(&ck.meta));
        params = ck.params;
        optim = ck.optim;
    }
    let resumed_from = optim.step;

    let dev = Device::flex().autodiff();
    let pb = bar(opts, stage.steps as u64, stage.name);
    pb.set_position(optim.step as u64);
    let mut recent: Vec<f32> = Vec::new();
    clock.loop_started();
    while optim.step < stage.steps {
        let step = optim.step;
        let p = params.tensors(&dev, true);
        let loss = loss(step, &p, &dev)?;
        let grads = loss.backward();
        let lv = to_vec(loss.detach())?.first().copied().unwrap_or(f32::NAN);
        if !lv.is_finite() {
            return Err(TrainError::Diverged { step, loss: lv });
        }
        let g: Vec<Option<Vec<f32>>> = p
            .iter()
            .map(|t| t.grad(&grads).map(to_vec).transpose())
            .collect::<Result<_>>()?;
        optim.adam(&mut params, &g, stage.lr);
        if let Some(e) = stage.ema {
            optim.ema_update(&params, e.decay, e.every, e.warmup);
        }
        recent.push(lv);
        if recent.len() > 100 {
            recent.remove(0);
        }
        pb.set_position(optim.step as u64);
        pb.set_message(format!("{} {lv:.4}", stage.loss_name));
        let done = optim.step == stage.steps;
        let every = stage.checkpoint_every;
        let stop = opts.stop_after == Some(optim.step);
        if done || stop || (every > 0 && optim.step.is_multiple_of(every)) {
            Checkpoint {
                params: params.clone(),
                optim: optim.clone(),
                meta: clock.stamp(&stage.meta, &recent),
            }
            .save(&stage.checkpoint)?;
        }
        if stop && !done {
            pb.finish_and_clear();
            return Err(TrainError::Stopped { step: optim.step });
        }
    }
    pb.finish_and_clear();
    Ok(Trained {
        params,
        optim,
        resumed_from,
        train_loss_final: clock.train_loss(&recent),
        step_time_s: clock.loop_seconds() / stage.steps.max(1) as f64,
        clock,
    })
}

/// A fingerprint of training data (FNV-1a over the float bits), stored in checkpoints.
pub(crate) fn fingerprint(parts: &[&[f32]]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in parts {
        for v in *p {
            for b in v.to_bits().to_le_bytes() {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    format!("{h:016x}")
}

/// Load a checkpoint if one exists and belongs to this run; `None` to start fresh.
fn resume(
    path: &Path,
    template: &ParamStore,
    meta: &HashMap<String, String>,
    opts: &RunOptions,
) -> Result<Option<Checkpoint>> {
    if opts.fresh || !path.exists() {
        return Ok(None);
    }
    let ck = Checkpoint::load(path, template)?;
    for (k, v) in meta {
        if ck.meta.get(k) != Some(v) {
            return Err(TrainError::Checkpoint {
                path: path.to_path_buf(),
                reason: format!(
                    "its {k} differs from this run's (delete it, or pass `fresh`, to start over)"
                ),
            });
        }
    }
    Ok(Some(ck))
}

/// `out_dir/checkpoints`, created.
pub(crate) fn checkpoint_dir(out_dir: &Path) -> Result<PathBuf> {
    let d = out_dir.join("checkpoints");
    std::fs::create_dir_all(&d).map_err(io_err(&d))?;
    Ok(d)
}
