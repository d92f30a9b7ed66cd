//! Kernel configuration sent by the host: the Markov prior over contact modes and the
//! diffusion sampler's settings. Until the host sends them the kernel uses the paper's.

use heapless::Vec;
use serde::{Deserialize, Serialize};

use crate::plan::Task;
use crate::size::{MaxSize, vec_max_size};

/// Most contact modes of a task (the card's four).
pub const MAX_PRIOR_MODES: usize = 4;
/// Most floats of a [`PriorTable`]: `p(c₀)` and one transition row per mode.
pub const MAX_PRIOR_FLOATS: usize = MAX_PRIOR_MODES * (MAX_PRIOR_MODES + 1);

/// A Markov prior over one task's contact modes (mode ids as in plan replies), replacing the
/// kernel's default for that task until the next `SetPrior` for it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PriorTable {
    /// The task whose modes these are.
    pub task: Task,
    /// `modes + modes²` values, row-major: `p(c₀ = j)` for every mode `j`, then
    /// `p(c_n = j | c_{n−1} = i)` for every `i`, `j`. Non-negative and finite; each row is
    /// renormalised to sum to one, and the plan request's `p_min` floor is applied when
    /// planning.
    pub probabilities: Vec<f32, MAX_PRIOR_FLOATS>,
}

impl MaxSize for PriorTable {
    const POSTCARD_MAX_SIZE: usize =
        Task::POSTCARD_MAX_SIZE + vec_max_size::<f32, MAX_PRIOR_FLOATS>();
}

/// How the diffusion sampler denoises.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, MaxSize)]
pub enum SamplerMethod {
    /// Ancestral DDPM over every training step, the posterior noise scaled by `noise_factor`
    /// (the paper's: 0.5).
    Ddpm {
        /// Multiplier of the posterior standard deviation, in `[0, 1]`.
        noise_factor: f32,
    },
    /// DDIM over `steps` evenly spaced training steps, deterministic (η = 0).
    Ddim {
        /// Denoising steps, at least 1 and at most the model's training steps.
        steps: u16,
    },
    /// DDIM over `steps` evenly spaced training steps with stochasticity `eta` in `[0, 1]`
    /// (1 matches DDPM's variance). Appended.
    DdimEta {
        /// Denoising steps, at least 1 and at most the model's training steps.
        steps: u16,
        /// Stochasticity η in `[0, 1]`.
        eta: f32,
    },
    /// Ancestral DDPM over `steps` evenly spaced training steps, each jump's posterior noise
    /// scaled by `noise_factor` (the hosts' `ddpm:S`; their default is `ddpm:16`). Appended.
    DdpmStrided {
        /// Denoising steps, at least 1 and at most the model's training steps.
        steps: u16,
        /// Multiplier of the posterior standard deviation, in `[0, 1]`.
        noise_factor: f32,
    },
}

/// The diffusion sampler's settings, for every later plan request.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, MaxSize)]
pub struct SamplerSettings {
    /// Denoising method.
    pub method: SamplerMethod,
    /// Classifier-free guidance weight `w` (finite; the paper's: 1.2).
    pub guidance_weight: f32,
}
