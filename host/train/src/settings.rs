//! Training settings and their validation.

use dips_kernel::engine::ObjectFrame;
use serde::{Deserialize, Serialize};

use crate::error::{Result, TrainError};

/// The network shape shared by the denoiser and the discriminator (spec §4.1, §4.5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NetSettings {
    /// Channels per resolution stage; the number of entries is the number of stages. The time
    /// axis of the denoiser is zero-padded to a multiple of `2^(stages−1)` and cropped back.
    pub widths: Vec<usize>,
    /// Residual blocks in the middle (at the coarsest resolution).
    pub mid_blocks: usize,
    /// Width of the shared conditioning embedding that every residual block reads.
    pub embed_dim: usize,
    /// Width of the sinusoidal step embedding (even).
    pub time_embed_dim: usize,
    /// Width of the context (contact-mode) embedding.
    pub context_embed_dim: usize,
    /// GroupNorm groups (every width must be a multiple).
    pub groups: usize,
    /// Denoiser only: width of an embedding of the start row's state columns joined to the
    /// conditioning embedding; 0 (the default) reads the start only through the convolutions.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub start_embed_dim: usize,
}

fn is_zero(v: &usize) -> bool {
    *v == 0
}

impl Default for NetSettings {
    fn default() -> Self {
        Self {
            widths: vec![48, 64, 96],
            mid_blocks: 2,
            embed_dim: 64,
            time_embed_dim: 32,
            context_embed_dim: 32,
            groups: 8,
            start_embed_dim: 0,
        }
    }
}

/// Settings of the denoiser's training.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DenoiserSettings {
    /// Diffusion steps `N` of the cosine schedule.
    pub diffusion_steps: usize,
    /// Probability of zeroing a sample's context embedding (classifier-free guidance).
    pub context_dropout: f32,
    /// Screwdriver only: add a uniform yaw offset in [−π, π) to every training trajectory.
    pub augment_yaw: bool,
    /// Trajectories per optimiser step.
    pub batch: usize,
    /// Optimiser steps.
    pub steps: usize,
    /// Adam learning rate.
    pub lr: f64,
    /// EMA decay per EMA update.
    pub ema_decay: f32,
    /// Steps between EMA updates.
    pub ema_every: usize,
    /// Steps during which the EMA is a plain copy; `None`: `min(1000, steps / 5)`.
    pub ema_warmup: Option<usize>,
    /// Weight of the object's state columns (pose: screwdriver roll, pitch, cos/sin yaw;
    /// card x, y, θ) in the ε loss, relative to 1 for every other column. The search reads
    /// its progress and costs from these few columns; with 1 the models predicted the object's
    /// motion poorly (`docs/training.md`).
    #[serde(default = "default_object_loss_weight")]
    pub object_loss_weight: f32,
    /// Probability that a training trajectory's start row is given (inpainted, as the planner
    /// always gives it) rather than denoised; the spec's 0.5 by default.
    #[serde(default = "default_start_given")]
    pub start_given: f32,
    /// A given start row gives its state columns only, as the planner inpaints row 0 (the
    /// controls stay noised and in the loss); `false`, the default, gives the whole row as
    /// the spec's masks do, so a given start row never looks like the planner's.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub start_state_only: bool,
    /// Min-SNR-γ loss weighting (Hang et al., 2023): a training trajectory noised to step `t`
    /// has its ε loss weighted by `min(SNR_t, γ) / SNR_t`, `SNR_t = ᾱ_t / (1 − ᾱ_t)`, which
    /// caps the weight the nearly clean steps get in the x₀ error the ε loss stands for and so
    /// leaves more of the fit to the noisy steps, where a sample's global shape (its motion
    /// from the inpainted start) is decided. `None`, the default, is the plain ε loss.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_snr_gamma: Option<f32>,
    /// Train the Diffusion Policy baseline instead of `M(c, s₀)`: trajectories are windows of
    /// a demo's executed rows concatenated across its modes ([`crate::data::policy_windows`]),
    /// with no contact-mode input (the context is zero). Only the denoiser is trained.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub policy: bool,
    /// Where the model measures the object's columns from (`dips.object_frame`): `world`, the
    /// default, or `segment-start`, where every training trajectory's object coordinates are
    /// taken less its row 0's ([`crate::data::to_object_frame`]), so the model learns how far
    /// a mode moves the object, not where it ends (`docs/training.md`, "The card's short
    /// pushes"). The sampler adds the start back (`dips_kernel::diffusion::sample`).
    #[serde(default, skip_serializing_if = "is_world")]
    pub object_frame: ObjectFrame,
}

fn is_world(f: &ObjectFrame) -> bool {
    *f == ObjectFrame::World
}

fn default_start_given() -> f32 {
    0.5
}

fn default_object_loss_weight() -> f32 {
    1.0
}

impl Default for DenoiserSettings {
    fn default() -> Self {
        Self {
            diffusion_steps: 256,
            context_dropout: 0.25,
            augment_yaw: true,
            batch: 64,
            steps: 8_000,
            lr: 1e-3,
            ema_decay: 0.995,
            ema_every: 10,
            ema_warmup: None,
            object_loss_weight: 10.0,
            start_given: default_start_given(),
            start_state_only: false,
            min_snr_gamma: None,
            policy: false,
            object_frame: ObjectFrame::World,
        }
    }
}

impl DenoiserSettings {
    /// How the training masks give the start row.
    pub fn start_row(&self) -> crate::data::StartRow {
        crate::data::StartRow {
            given: self.start_given,
            state_only: self.start_state_only,
        }
    }
}

/// Settings of the discriminator's training.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiscriminatorSettings {
    /// Real training trajectories (and as many diffused ones) the discriminator learns from.
    pub samples: usize,
    /// Held-out real trajectories (and as many diffused ones) for accuracy and AUC.
    pub eval_samples: usize,
    /// Trajectories per optimiser step (half real, half diffused).
    pub batch: usize,
    /// Optimiser steps.
    pub steps: usize,
    /// Adam learning rate.
    pub lr: f64,
    /// Classifier-free guidance weight of the sampler that makes the diffused trajectories.
    pub guidance_weight: f32,
    /// Noise factor of the ancestral DDPM sampler (0.5 in the DIPS code).
    pub noise_factor: f32,
    /// DDIM step counts whose samples join the DDPM ones as diffused trajectories, so that
    /// Ψ has seen the planner's fast samplers too (empty: DDPM only).
    #[serde(default = "default_ddim_fakes")]
    pub ddim_fakes: Vec<usize>,
    /// Train on inputs forward-noised to a random diffusion step with the BCE weighted by
    /// `√β_t` (the authors' code); `false`: clean inputs only. Row 0's state stays clean.
    #[serde(default = "default_true")]
    pub noised_inputs: bool,
    /// Step counts `S` of the planner's strided DDPM (`--sampler ddpm:S`) whose samples join
    /// the negatives *as the planner draws them*: the start's symmetry angle clamped into the
    /// models' range and the task's start anchor applied afterwards
    /// (`dips_kernel::session::start_anchor`). Empty (the default): Ψ never sees the planner's
    /// own samples, only the paper's DDPM and `ddim_fakes`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub planner_fakes: Vec<usize>,
    /// Turn every training trajectory, real and diffused alike, about the task's symmetry angle
    /// (the screwdriver's yaw) by a uniform random angle, so that Ψ cannot tell real from
    /// diffused by the angle's level: the planner scores segments at yaws the demos never
    /// reached. An error for a task without such an angle.
    #[serde(default, skip_serializing_if = "is_false")]
    pub augment_yaw: bool,
}

fn is_false(v: &bool) -> bool {
    !*v
}

fn default_ddim_fakes() -> Vec<usize> {
    vec![8]
}

fn default_true() -> bool {
    true
}

impl Default for DiscriminatorSettings {
    fn default() -> Self {
        Self {
            samples: 1536,
            eval_samples: 512,
            batch: 128,
            steps: 1500,
            lr: 1e-3,
            guidance_weight: dips_kernel::diffusion::DEFAULT_GUIDANCE_WEIGHT,
            noise_factor: dips_kernel::diffusion::DEFAULT_NOISE_FACTOR,
            ddim_fakes: default_ddim_fakes(),
            noised_inputs: true,
            planner_fakes: Vec::new(),
            augment_yaw: false,
        }
    }
}

/// Everything a training run is made of. `Default` gives the shipped defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainSettings {
    /// Seed of everything random: initialisation, data order, masks, noise, the split is by
    /// demo seed and does not use it.
    pub seed: u64,
    /// Fraction of demos held out (by demo seed).
    pub held_out_fraction: f64,
    /// Held-out trajectories the held-out denoiser loss is averaged over (fixed draws).
    pub eval_samples: usize,
    /// Lower bound of a column's normalisation std (constant columns).
    pub std_floor: f32,
    /// Optimiser steps between checkpoints (0: only at the end).
    pub checkpoint_every: usize,
    /// The network shape (both models).
    pub net: NetSettings,
    /// The denoiser's training.
    pub denoiser: DenoiserSettings,
    /// The discriminator's training.
    pub discriminator: DiscriminatorSettings,
    /// The sequence sources (a demo's `sequences` metadata: `pattern`, `markov`,
    /// `turn-runs`; a demo without it counts as `pattern`) whose demos the contact-mode prior
    /// is fitted from. Absent: every demo. The models always learn from every demo; this keeps
    /// demos drawn to teach the models rare transitions from also making the planner's prior
    /// favour them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_sources: Option<Vec<String>>,
    /// Leave out the trajectories of the modes after a demo's first invalid mode (the object
    /// already fell: states the planner never plans from); the mode in which it fell is kept.
    /// Default false (every trajectory).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub drop_modes_after_invalid: bool,
    /// Z-score the cos/sin columns of angles like every other column. `false`, the default,
    /// leaves them raw (mean 0, std 1) as the spec does, which suits data whose angles cover
    /// the circle (yaw augmentation); without it the screwdriver's cos/sin yaw vary with a std
    /// of about 0.3, a third of every z-scored column's, and the noise buries the object's
    /// turn earliest of all columns.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub normalize_angles: bool,
    /// Train on the trajectories recorded at online step `k ≥` this of their mode only: their
    /// first `k` rows are what the world executed, the rest the particle's plan from there
    /// (`docs/datagen.md`). 0, the default, keeps every step, so most trajectories are plans
    /// made early in a mode, which on the screwdriver overstate late turns and understate
    /// first ones against what the world gives. The task's horizon minus one keeps the last
    /// step's: the executed mode with one planned row. Must leave a trajectory (checked
    /// against the data).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub min_executed_rows: usize,
}

impl Default for TrainSettings {
    fn default() -> Self {
        Self {
            seed: 0,
            held_out_fraction: 0.1,
            eval_samples: 2048,
            std_floor: 1e-4,
            checkpoint_every: 500,
            net: NetSettings::default(),
            denoiser: DenoiserSettings::default(),
            discriminator: DiscriminatorSettings::default(),
            prior_sources: None,
            drop_modes_after_invalid: false,
            normalize_angles: false,
            min_executed_rows: 0,
        }
    }
}

fn bad(field: &str, reason: impl Into<String>) -> TrainError {
    TrainError::Settings {
        field: field.to_string(),
        reason: reason.into(),
    }
}

impl NetSettings {
    /// Check the network shape.
    pub fn validate(&self) -> Result<()> {
        if self.widths.is_empty() || self.widths.len() > 6 {
            return Err(bad("net.widths", "needs 1 to 6 stages"));
        }
        if self.groups == 0 {
            return Err(bad("net.groups", "must be positive"));
        }
        for (i, &w) in self.widths.iter().enumerate() {
            if w == 0 || w % self.groups != 0 || w > 4096 {
                return Err(bad(
                    "net.widths",
                    format!(
                        "widths[{i}] = {w} must be a positive multiple of net.groups = {} (≤ 4096)",
                        self.groups
                    ),
                ));
            }
        }
        if self.embed_dim == 0 || self.context_embed_dim == 0 {
            return Err(bad(
                "net.embed_dim",
                "embed_dim and context_embed_dim must be positive",
            ));
        }
        if self.time_embed_dim < 4 || !self.time_embed_dim.is_multiple_of(2) {
            return Err(bad("net.time_embed_dim", "must be even and at least 4"));
        }
        if self.start_embed_dim > 4096 {
            return Err(bad("net.start_embed_dim", "must be 0 (none) to 4096"));
        }
        Ok(())
    }

    /// Stages (resolutions).
    pub fn stages(&self) -> usize {
        self.widths.len()
    }
}

impl TrainSettings {
    /// Check every setting; the error names the field.
    pub fn validate(&self) -> Result<()> {
        self.net.validate()?;
        if self.denoiser.policy && self.denoiser.object_frame != ObjectFrame::World {
            return Err(bad(
                "denoiser.object_frame",
                "the Diffusion Policy baseline has no start to measure from; use world",
            ));
        }
        if let Some(sources) = &self.prior_sources {
            if sources.is_empty() {
                return Err(bad(
                    "prior_sources",
                    "must name at least one source (or be left out: every demo)",
                ));
            }
            if let Some(s) = sources
                .iter()
                .find(|s| !dips_dataset::SEQUENCE_SOURCES.contains(&s.as_str()))
            {
                return Err(bad(
                    "prior_sources",
                    format!(
                        "unknown source {s:?}; allowed: {}",
                        dips_dataset::SEQUENCE_SOURCES.join(", ")
                    ),
                ));
            }
        }
        let d = &self.denoiser;
        if !(2..=100_000).contains(&d.diffusion_steps) {
            return Err(bad("denoiser.diffusion_steps", "must be in 2..=100000"));
        }
        if !(0.0..1.0).contains(&d.context_dropout) {
            return Err(bad("denoiser.context_dropout", "must be in [0, 1)"));
        }
        if d.batch == 0 {
            return Err(bad("denoiser.batch", "must be positive"));
        }
        if d.steps == 0 {
            return Err(bad("denoiser.steps", "must be positive"));
        }
        if !(d.lr.is_finite() && d.lr > 0.0) {
            return Err(bad("denoiser.lr", "must be positive and finite"));
        }
        if !(0.0..1.0).contains(&d.ema_decay) {
            return Err(bad("denoiser.ema_decay", "must be in [0, 1)"));
        }
        if !(d.object_loss_weight.is_finite() && d.object_loss_weight > 0.0) {
            return Err(bad(
                "denoiser.object_loss_weight",
                "must be positive and finite",
            ));
        }
        if d.min_snr_gamma.is_some_and(|g| !(g.is_finite() && g > 0.0)) {
            return Err(bad("denoiser.min_snr_gamma", "must be positive and finite"));
        }
        if !(0.0..=1.0).contains(&d.start_given) {
            return Err(bad("denoiser.start_given", "must be in [0, 1]"));
        }
        if d.ema_every == 0 {
            return Err(bad("denoiser.ema_every", "must be positive"));
        }
        let s = &self.discriminator;
        if s.samples == 0 || s.batch < 2 || s.steps == 0 {
            return Err(bad(
                "discriminator",
                "samples and steps must be positive and batch at least 2",
            ));
        }
        if !(s.lr.is_finite() && s.lr > 0.0) {
            return Err(bad("discriminator.lr", "must be positive and finite"));
        }
        if !(s.guidance_weight.is_finite() && s.noise_factor.is_finite() && s.noise_factor >= 0.0) {
            return Err(bad(
                "discriminator.guidance_weight",
                "guidance weight and noise factor must be finite, noise factor ≥ 0",
            ));
        }
        if let Some(&k) = s
            .ddim_fakes
            .iter()
            .find(|&&k| k == 0 || k > d.diffusion_steps.min(usize::from(u16::MAX)))
        {
            return Err(bad(
                "discriminator.ddim_fakes",
                format!(
                    "{k} DDIM steps: each entry must be in 1..={}",
                    d.diffusion_steps
                ),
            ));
        }
        if let Some(&k) = s
            .planner_fakes
            .iter()
            .find(|&&k| k == 0 || k > d.diffusion_steps.min(usize::from(u16::MAX)))
        {
            return Err(bad(
                "discriminator.planner_fakes",
                format!(
                    "{k} DDPM steps: each entry must be in 1..={}",
                    d.diffusion_steps
                ),
            ));
        }
        if !(0.0..1.0).contains(&self.held_out_fraction) {
            return Err(bad("held_out_fraction", "must be in [0, 1)"));
        }
        if self.eval_samples == 0 {
            return Err(bad("eval_samples", "must be positive"));
        }
        if !(self.std_floor.is_finite() && self.std_floor > 0.0) {
            return Err(bad("std_floor", "must be positive and finite"));
        }
        Ok(())
    }

    /// What the denoiser's checkpoint must agree on to be resumed: every setting but the
    /// discriminator's (retraining Ψ alone keeps the denoiser).
    pub fn denoiser_key(&self) -> String {
        #[derive(Serialize)]
        struct Key<'a> {
            seed: u64,
            held_out_fraction: f64,
            eval_samples: usize,
            std_floor: f32,
            checkpoint_every: usize,
            net: &'a NetSettings,
            denoiser: &'a DenoiserSettings,
        }
        serde_json::to_string(&Key {
            seed: self.seed,
            held_out_fraction: self.held_out_fraction,
            eval_samples: self.eval_samples,
            std_floor: self.std_floor,
            checkpoint_every: self.checkpoint_every,
            net: &self.net,
            denoiser: &self.denoiser,
        })
        .unwrap_or_default()
    }

    /// The EMA warm-up in steps.
    pub fn ema_warmup(&self) -> usize {
        self.denoiser
            .ema_warmup
            .unwrap_or((self.denoiser.steps / 5).min(1000))
    }
}
