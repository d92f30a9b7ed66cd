//! What the two host engines share: the kernel engine traits implemented once over
//! `contract()` and `run()`, and [`AnyEngine`] to pick one at run time.

use std::path::Path;

use crate::contract::{Contract, Expectation};
use crate::error::Result;
use crate::kernel_engine::KernelHostEngine;
use crate::tract_engine::TractEngine;

/// Implement `DenoiserEngine` and `DiscriminatorEngine` for a host engine type with
/// `contract(&self) -> &Contract` and `run(&mut self, batch, inputs, output) -> Result<()>`
/// (inputs in contract order). The role is checked on every call.
macro_rules! impl_engine_traits {
    ($ty:ty) => {
        impl dips_kernel::engine::DenoiserEngine for $ty {
            type Error = $crate::error::ModelError;

            fn dims(&self) -> dips_kernel::engine::ModelDims {
                self.contract().dims()
            }

            fn normalization(&self) -> dips_kernel::engine::Normalization<'_> {
                let c = self.contract();
                dips_kernel::engine::Normalization {
                    mean: &c.norm_mean,
                    std: &c.norm_std,
                }
            }

            fn max_batch(&self) -> usize {
                usize::MAX
            }

            fn predict_eps(
                &mut self,
                batch: usize,
                x: &[f32],
                t: &[f32],
                context: &[f32],
                cond_mask: &[f32],
                eps: &mut [f32],
            ) -> $crate::error::Result<()> {
                if self.contract().role != $crate::contract::Role::Denoiser {
                    return Err($crate::error::ModelError::Mismatch(
                        "predict_eps called on a discriminator".into(),
                    ));
                }
                self.run(batch, &[x, t, context, cond_mask], eps)
            }
        }

        impl dips_kernel::engine::DiscriminatorEngine for $ty {
            type Error = $crate::error::ModelError;

            fn dims(&self) -> dips_kernel::engine::ModelDims {
                self.contract().dims()
            }

            fn normalization(&self) -> dips_kernel::engine::Normalization<'_> {
                let c = self.contract();
                dips_kernel::engine::Normalization {
                    mean: &c.norm_mean,
                    std: &c.norm_std,
                }
            }

            fn max_batch(&self) -> usize {
                usize::MAX
            }

            fn p_real(
                &mut self,
                batch: usize,
                x: &[f32],
                context: &[f32],
                p_real: &mut [f32],
            ) -> $crate::error::Result<()> {
                if self.contract().role != $crate::contract::Role::Discriminator {
                    return Err($crate::error::ModelError::Mismatch(
                        "p_real called on a denoiser".into(),
                    ));
                }
                self.run(batch, &[x, context], p_real)
            }
        }
    };
}
pub(crate) use impl_engine_traits;

/// Which engine runs a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EngineKind {
    /// tract-onnx on the `.onnx` file.
    Tract,
    /// The `dips-kernel` interpreter on the lowered blob.
    Kernel,
}

/// A loaded engine of either kind.
#[derive(Debug)]
pub enum AnyEngine {
    /// tract.
    Tract(TractEngine),
    /// The kernel interpreter.
    Kernel(KernelHostEngine),
}

impl AnyEngine {
    /// Load and validate `file` (against `expected`) with the chosen engine; the kernel engine
    /// also takes a lowered `.dipsm`.
    pub fn load(kind: EngineKind, file: &Path, expected: &Expectation) -> Result<Self> {
        Ok(match kind {
            EngineKind::Tract => AnyEngine::Tract(TractEngine::load(file, expected)?),
            EngineKind::Kernel => AnyEngine::Kernel(KernelHostEngine::load(file, expected)?),
        })
    }

    /// The model's contract.
    pub fn contract(&self) -> &Contract {
        match self {
            AnyEngine::Tract(e) => e.contract(),
            AnyEngine::Kernel(e) => e.contract(),
        }
    }

    /// Let each call use up to `threads` threads. The kernel engine splits a call's batch
    /// (the same bits as one thread, [`KernelHostEngine`]); tract runs on the calling thread
    /// and ignores it.
    pub fn set_threads(&mut self, threads: usize) {
        if let AnyEngine::Kernel(e) = self {
            e.set_threads(threads);
        }
    }

    /// Run on contract inputs in contract order.
    pub fn run(&mut self, batch: usize, inputs: &[&[f32]], output: &mut [f32]) -> Result<()> {
        match self {
            AnyEngine::Tract(e) => e.run(batch, inputs, output),
            AnyEngine::Kernel(e) => e.run(batch, inputs, output),
        }
    }
}

impl_engine_traits!(AnyEngine);
