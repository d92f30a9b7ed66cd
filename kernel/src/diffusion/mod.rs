//! The diffusion sampler `M(c, s₀)`: DDPM/DDIM over an ε-predicting denoiser with
//! classifier-free guidance and start-state inpainting (`spec/algorithms.md` §4.2, §4.3).
//!
//! Generic over [`crate::engine::DenoiserEngine`]; all memory is caller-provided
//! ([`SamplerScratch`], sized by [`ScratchLayout`]); randomness comes from
//! [`crate::rng::KernelRng`], so the same seed gives the same bits.

pub mod config;
pub mod error;
pub mod normalize;
pub mod sampler;
pub mod schedule;
pub mod scratch;

pub use config::{
    DEFAULT_DENOISED_CLIP, DEFAULT_GUIDANCE_WEIGHT, DEFAULT_NOISE_FACTOR, SamplerConfig,
    SamplerNameError, SamplingMethod,
};
pub use error::{SampleError, SamplerError, ScratchBuffer};
pub use normalize::{denormalize_in_place, normalize_in_place};
pub use sampler::{SampleRequest, sample};
pub use scratch::{SamplerScratch, ScratchLayout};
