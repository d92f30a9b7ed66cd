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

            fn object_frame(&self) -> dips_kernel::engine::ObjectFrame {
                self.contract().object_frame
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

impl EngineKind {
    /// Both engines.
    pub const ALL: [EngineKind; 2] = [EngineKind::Tract, EngineKind::Kernel];

    /// The engine's name in settings files (`eval.json`) and on the command line: `tract` or
    /// `kernel`.
    pub const fn name(self) -> &'static str {
        match self {
            EngineKind::Tract => "tract",
            EngineKind::Kernel => "kernel",
        }
    }

    /// Both engines' names, in [`EngineKind::ALL`] order.
    pub const NAMES: [&'static str; 2] = [EngineKind::Tract.name(), EngineKind::Kernel.name()];
}

impl std::str::FromStr for EngineKind {
    type Err = dips_kernel::name::UnknownValue;

    /// An engine by its name ([`EngineKind::name`]); the error names the value and the engines.
    fn from_str(name: &str) -> std::result::Result<Self, Self::Err> {
        dips_kernel::name::UnknownValue::find("engine", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl std::fmt::Display for EngineKind {
    /// The engine's name ([`EngineKind::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn engines_read_back_their_names_and_a_bad_one_lists_them() {
        for kind in EngineKind::ALL {
            assert_eq!(kind.to_string().parse::<EngineKind>(), Ok(kind));
        }
        assert_eq!(
            "onnx".parse::<EngineKind>().unwrap_err().to_string(),
            "unknown engine `onnx` (expected tract or kernel)"
        );
    }
}
