//! The boundary between the diffusion sampler / discriminator scorer and the network engines
//! that evaluate the models (the no_std interpreter in this crate, tract on the host).
//!
//! Tensors are flat, row-major `f32` slices in the layout of the model contract
//! (`docs/contracts.md` §3): `x` is `[batch, horizon, dim]`, `t` and `cond_mask` are `[batch]`,
//! `context` is `[batch, fingers]`, `eps` is `[batch, horizon, dim]`, `p_real` is `[batch]`
//! (the contract's `[B, 1]` output, flattened).
//! Sizes are run-time values so a model of other dimensions needs no recompilation.

/// Dimensions a model was exported with (contract metadata `dips.horizon`, ...).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelDims {
    /// Rows per trajectory segment, `T = H + 1`.
    pub horizon: usize,
    /// State columns per row (angles that wrap count twice: cos and sin).
    pub state_dim: usize,
    /// Action columns per row.
    pub action_dim: usize,
    /// Fingers in the contact-mode vector (`context` width).
    pub fingers: usize,
    /// Diffusion steps the denoiser was trained with (0 for a discriminator).
    pub diffusion_steps: usize,
}

impl ModelDims {
    /// Columns per row, `D = state_dim + action_dim`.
    pub const fn dim(&self) -> usize {
        self.state_dim + self.action_dim
    }

    /// Floats in one trajectory, `T * D`.
    pub const fn floats_per_trajectory(&self) -> usize {
        self.horizon * self.dim()
    }
}

/// Where a denoiser's object columns are measured from (contract metadata `dips.object_frame`).
///
/// The diffusion sampler ([`crate::diffusion::sample`]) applies it, so every caller of the
/// sampler gets raw §2 rows whatever the model's frame.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum ObjectFrame {
    /// The world's: every row holds the object's pose as it is (every model before the
    /// frame existed).
    #[default]
    World,
    /// The segment's start: the object's two plain coordinates (the card's `x, y`; columns
    /// [`crate::mode::RowLayout::object`] and the one after it) of every row are measured from
    /// row 0's, so row 0 holds zeros there and a segment says how far the object moves, not
    /// where it is. Its angle stays the world's. The sampler inpaints the start with those
    /// columns at zero and adds the start's back to every row of the result.
    SegmentStart,
}

impl ObjectFrame {
    /// Both frames.
    pub const ALL: [ObjectFrame; 2] = [ObjectFrame::World, ObjectFrame::SegmentStart];

    /// The frame's name in model metadata, settings and reports: `world` or `segment-start`.
    pub const fn name(self) -> &'static str {
        match self {
            ObjectFrame::World => "world",
            ObjectFrame::SegmentStart => "segment-start",
        }
    }

    /// Both names, in [`ObjectFrame::ALL`] order.
    pub const NAMES: [&'static str; 2] =
        [ObjectFrame::World.name(), ObjectFrame::SegmentStart.name()];

    /// The frame's code in a lowered model blob (`nn::format::Meta::object_frame`).
    pub const fn code(self) -> u8 {
        match self {
            ObjectFrame::World => 0,
            ObjectFrame::SegmentStart => 1,
        }
    }

    /// The frame of a blob code, `None` for an unknown one.
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(ObjectFrame::World),
            1 => Some(ObjectFrame::SegmentStart),
            _ => None,
        }
    }

    /// The state columns this frame measures from row 0, for segments of `fingers` fingers and
    /// `state_dim` state columns: empty for [`ObjectFrame::World`], and when the columns do not
    /// lie inside the state (then the frame changes nothing, in training, inpainting and the
    /// sampler's output alike).
    pub const fn start_columns(self, fingers: usize, state_dim: usize) -> core::ops::Range<usize> {
        let first = crate::mode::RowLayout {
            fingers,
            env_force: false,
        }
        .object();
        match self {
            ObjectFrame::SegmentStart if first + 2 <= state_dim => first..first + 2,
            _ => 0..0,
        }
    }
}

impl core::str::FromStr for ObjectFrame {
    type Err = crate::name::UnknownValue;

    /// A frame by its name ([`ObjectFrame::name`]); the error names the value and both names.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        crate::name::UnknownValue::find("object frame", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl core::fmt::Display for ObjectFrame {
    /// The frame's name ([`ObjectFrame::name`]).
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// Per-column normalization of the contract: `normalized = (raw - mean) / std`.
#[derive(Debug, Clone, Copy)]
pub struct Normalization<'a> {
    /// `dips.norm_mean`, one entry per column.
    pub mean: &'a [f32],
    /// `dips.norm_std`, one entry per column.
    pub std: &'a [f32],
}

/// An ε-predicting denoiser (contract role `denoiser`).
pub trait DenoiserEngine {
    /// The engine's error type.
    type Error: core::fmt::Debug;

    /// The dimensions the model was exported with.
    fn dims(&self) -> ModelDims;

    /// The model's column normalization.
    fn normalization(&self) -> Normalization<'_>;

    /// Where the model measures the object's columns from (`dips.object_frame`); the world's
    /// unless the model says otherwise.
    fn object_frame(&self) -> ObjectFrame {
        ObjectFrame::World
    }

    /// The largest batch one call accepts (`usize::MAX` when unbounded). The batch counts
    /// samples: the diffusion sampler evaluates each trajectory's conditioned and
    /// unconditioned copy in one call, so it needs at least 2 and sends at most
    /// `max_batch / 2` trajectories per call.
    fn max_batch(&self) -> usize;

    /// Predict the noise for a batch: `x` `[batch,T,D]` normalized noisy trajectories,
    /// `t` `[batch]` step indices as floats, `context` `[batch,F]` contact modes (±1),
    /// `cond_mask` `[batch]` (1 conditioned, 0 unconditional). Writes `eps` `[batch,T,D]`.
    fn predict_eps(
        &mut self,
        batch: usize,
        x: &[f32],
        t: &[f32],
        context: &[f32],
        cond_mask: &[f32],
        eps: &mut [f32],
    ) -> Result<(), Self::Error>;
}

/// A discriminator Ψ (contract role `discriminator`).
// `dims`, `normalization` and `max_batch` repeat `DenoiserEngine`'s on purpose: each trait is
// complete on its own, so an engine that loads either role implements both independently.
pub trait DiscriminatorEngine {
    /// The engine's error type.
    type Error: core::fmt::Debug;

    /// The dimensions the model was exported with.
    fn dims(&self) -> ModelDims;

    /// The model's column normalization.
    fn normalization(&self) -> Normalization<'_>;

    /// The largest batch one call accepts (`usize::MAX` when unbounded).
    fn max_batch(&self) -> usize;

    /// Score a batch of normalized clean trajectories `x` `[batch,T,D]` with their contact
    /// modes `context` `[batch,F]`; writes `p_real` `[batch]`, each in (0, 1).
    fn p_real(
        &mut self,
        batch: usize,
        x: &[f32],
        context: &[f32],
        p_real: &mut [f32],
    ) -> Result<(), Self::Error>;
}

/// A mutable reference to an engine is an engine, so adapters can borrow one.
impl<E: DenoiserEngine + ?Sized> DenoiserEngine for &mut E {
    type Error = E::Error;

    fn dims(&self) -> ModelDims {
        (**self).dims()
    }

    fn normalization(&self) -> Normalization<'_> {
        (**self).normalization()
    }

    fn object_frame(&self) -> ObjectFrame {
        (**self).object_frame()
    }

    fn max_batch(&self) -> usize {
        (**self).max_batch()
    }

    fn predict_eps(
        &mut self,
        batch: usize,
        x: &[f32],
        t: &[f32],
        context: &[f32],
        cond_mask: &[f32],
        eps: &mut [f32],
    ) -> Result<(), Self::Error> {
        (**self).predict_eps(batch, x, t, context, cond_mask, eps)
    }
}

/// A mutable reference to an engine is an engine, so adapters can borrow one.
impl<E: DiscriminatorEngine + ?Sized> DiscriminatorEngine for &mut E {
    type Error = E::Error;

    fn dims(&self) -> ModelDims {
        (**self).dims()
    }

    fn normalization(&self) -> Normalization<'_> {
        (**self).normalization()
    }

    fn max_batch(&self) -> usize {
        (**self).max_batch()
    }

    fn p_real(
        &mut self,
        batch: usize,
        x: &[f32],
        context: &[f32],
        p_real: &mut [f32],
    ) -> Result<(), Self::Error> {
        (**self).p_real(batch, x, context, p_real)
    }
}
