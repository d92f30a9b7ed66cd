//! [`KernelEngine`]: the denoiser/discriminator engine over a lowered blob and caller memory.

use super::NnError;
use super::model::{ModelInfo, install, parse, run};
use crate::engine::{DenoiserEngine, DiscriminatorEngine, ModelDims, Normalization, ObjectFrame};

/// A lowered model ready to run: the blob, and caller memory holding its weights, the op
/// scratch and the activation arena. Runs any batch up to what that memory holds
/// ([`ModelInfo::max_batch`], reported as the engines' `max_batch()`).
#[derive(Debug)]
pub struct KernelEngine<'b, 'm> {
    blob: &'b [u8],
    mem: &'m mut [f32],
    info: ModelInfo,
    max_batch: usize,
}

impl<'b, 'm> KernelEngine<'b, 'm> {
    /// Validate `blob` and install its weights into `mem`
    /// (at least [`ModelInfo::memory_len`]`(1)` floats; more memory allows larger batches).
    pub fn new(blob: &'b [u8], mem: &'m mut [f32]) -> Result<Self, NnError> {
        let info = parse(blob)?;
        let max_batch = install(&info, blob, mem)?;
        Ok(Self {
            blob,
            mem,
            info,
            max_batch,
        })
    }

    /// The decoded model facts.
    pub fn info(&self) -> &ModelInfo {
        &self.info
    }

    fn weights(&self, w: super::format::W) -> &[f32] {
        super::model::weight_slice(self.mem, &w).unwrap_or(&[])
    }

    fn norm(&self) -> Normalization<'_> {
        Normalization {
            mean: self.weights(self.info.norm_mean),
            std: self.weights(self.info.norm_std),
        }
    }

    /// Run on contract inputs in contract order.
    pub fn run(
        &mut self,
        batch: usize,
        inputs: &[&[f32]],
        output: &mut [f32],
    ) -> Result<(), NnError> {
        run(&self.info, self.blob, self.mem, batch, inputs, output)
    }
}

impl DenoiserEngine for KernelEngine<'_, '_> {
    type Error = NnError;

    fn dims(&self) -> ModelDims {
        self.info.dims
    }

    fn normalization(&self) -> Normalization<'_> {
        self.norm()
    }

    fn object_frame(&self) -> ObjectFrame {
        self.info.object_frame
    }

    fn max_batch(&self) -> usize {
        self.max_batch
    }

    fn predict_eps(
        &mut self,
        batch: usize,
        x: &[f32],
        t: &[f32],
        context: &[f32],
        cond_mask: &[f32],
        eps: &mut [f32],
    ) -> Result<(), NnError> {
        if self.info.role != 0 {
            return Err(NnError::WrongRole);
        }
        self.run(batch, &[x, t, context, cond_mask], eps)
    }
}

impl DiscriminatorEngine for KernelEngine<'_, '_> {
    type Error = NnError;

    fn dims(&self) -> ModelDims {
        self.info.dims
    }

    fn normalization(&self) -> Normalization<'_> {
        self.norm()
    }

    fn max_batch(&self) -> usize {
        self.max_batch
    }

    fn p_real(
        &mut self,
        batch: usize,
        x: &[f32],
        context: &[f32],
        p_real: &mut [f32],
    ) -> Result<(), NnError> {
        if self.info.role != 1 {
            return Err(NnError::WrongRole);
        }
        self.run(batch, &[x, context], p_real)
    }
}
