//! Planning inside the firmware: the uploaded blobs run by the kernel's interpreter and
//! planned through the kernel's session builder (engines → adapters → planner,
//! [`dips_kernel::session::plan_with_engines`]), one call per request.
//!
//! Memory comes from the caller once ([`PlanMemory`]): the planner and one `f32` work area.
//! Every request splits the work area into the two engines' memory (weights, op scratch,
//! activations) and the adapters' buffers; nothing is allocated. Engines are rebuilt from
//! the blobs for every request (copying the weights, a few milliseconds), so a model swapped
//! by an upload is used by the next request.
//!
//! The prior and the sampler settings are the host's (`SetPrior`, `SetSampler`) or, until it
//! sends them, the paper's: [`MarkovPrior::paper`] and the default [`SamplerConfig`] (DDPM
//! over the model's diffusion steps, noise ×0.5, guidance 1.2). The prior is floored at the
//! request's `p_min`.

use dips_kernel::budget::Clock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::nn::NnError;
use dips_kernel::nn::engine::KernelEngine;
use dips_kernel::nn::model::{ModelInfo, parse};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::PaperPlanner;
use dips_kernel::session::{SessionError, SessionLayout, plan_with_engines};
use dips_kernel::wire_convert::PlanInputs;
use dips_wire::{ModelFault, ModelRole, PlanRequest, RequestField, WireError};

/// The prior and sampler a plan uses.
#[derive(Debug, Clone, Copy)]
pub struct PlanConfig<'a> {
    /// The task's prior before the `p_min` floor; `None`: the paper's.
    pub prior: Option<&'a MarkovPrior>,
    /// The diffusion sampler's settings.
    pub sampler: SamplerConfig,
}

/// `ModelInfo::role` of a denoiser blob.
const DENOISER_ROLE: u8 = 0;
/// `ModelInfo::role` of a discriminator blob.
const DISCRIMINATOR_ROLE: u8 = 1;

/// The memory the firmware plans in, given once by its owner.
#[derive(Debug)]
pub struct PlanMemory<'m> {
    /// The planner: `k ≤ 16`, 512 nodes, 256 open entries, segments up to 481 floats.
    pub planner: &'m mut PaperPlanner,
    /// Work area for both engines and the adapters, split anew for every request. A request
    /// needs `2·B` denoiser samples and `B` discriminator samples of activations for batches
    /// of `B ≤ modes·k` segments; with less memory the batch is split into smaller engine
    /// calls (same plan, more calls).
    pub work: &'m mut [f32],
}

fn rejected(role: ModelRole, fault: ModelFault) -> WireError {
    WireError::ModelRejected { role, fault }
}

fn saturating_u32(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

/// Parse a blob and check that it is a model of `role`.
pub fn model_info(role: ModelRole, blob: &[u8]) -> Result<ModelInfo, WireError> {
    let info = parse(blob).map_err(|_| rejected(role, ModelFault::Invalid))?;
    let expected = match role {
        ModelRole::Denoiser => DENOISER_ROLE,
        ModelRole::Discriminator => DISCRIMINATOR_ROLE,
    };
    if info.role != expected {
        return Err(rejected(role, ModelFault::WrongShape));
    }
    Ok(info)
}

/// How a work area of `capacity` floats is split for one request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Split {
    denoiser: usize,
    discriminator: usize,
    session: SessionLayout,
}

impl Split {
    fn total(&self) -> usize {
        self.denoiser + self.discriminator + self.session.total()
    }
}

/// The split with the largest engine batch (segments per engine call, halved from
/// `segments` until it fits) for sampler calls of `segments` segments.
fn split_for(
    den: &ModelInfo,
    disc: &ModelInfo,
    segments: usize,
    capacity: usize,
) -> Result<Split, WireError> {
    let at = |chunk: usize| -> Option<Split> {
        Some(Split {
            // Classifier-free guidance evaluates every segment twice per engine call.
            denoiser: den.memory_len(2 * chunk)?,
            discriminator: disc.memory_len(chunk)?,
            session: SessionLayout::new(den.dims, segments, chunk),
        })
    };
    let mut chunk = segments.max(1);
    loop {
        let split = at(chunk).ok_or(rejected(ModelRole::Denoiser, ModelFault::Invalid))?;
        if split.total() <= capacity {
            return Ok(split);
        }
        if chunk == 1 {
            // Name the larger of the two models.
            let role = if split.denoiser >= split.discriminator {
                ModelRole::Denoiser
            } else {
                ModelRole::Discriminator
            };
            return Err(rejected(
                role,
                ModelFault::TooLarge {
                    needed_floats: saturating_u32(split.total()),
                    capacity_floats: saturating_u32(capacity),
                },
            ));
        }
        chunk = chunk.div_ceil(2);
    }
}

fn engine_fault(role: ModelRole, e: NnError) -> WireError {
    match e {
        NnError::MemoryTooSmall { needed, given } => rejected(
            role,
            ModelFault::TooLarge {
                needed_floats: saturating_u32(needed),
                capacity_floats: saturating_u32(given),
            },
        ),
        _ => rejected(role, ModelFault::Invalid),
    }
}

/// Plan `request` with the uploaded `denoiser` and `discriminator` blobs in `memory`.
///
/// Refusals are errors: a bad request field ([`WireError::InvalidRequest`]) or a model that
/// cannot run ([`WireError::ModelRejected`]). Every outcome of the search, including models
/// of another task ([`dips_wire::PlanStatus::InvalidProblem`]), is a [`dips_wire::PlanReply`] (made from the returned [`Planned`]).
pub fn plan(
    memory: &mut PlanMemory<'_>,
    denoiser: &[u8],
    discriminator: &[u8],
    request: &PlanRequest,
    config: &PlanConfig<'_>,
    clock: &mut impl Clock,
) -> Result<Planned, WireError> {
    let inputs =
        PlanInputs::from_request(request).map_err(|field| WireError::InvalidRequest { field })?;
    let den = model_info(ModelRole::Denoiser, denoiser)?;
    let disc = model_info(ModelRole::Discriminator, discriminator)?;
    let mut sizes = disc.dims;
    sizes.diffusion_steps = den.dims.diffusion_steps;
    if sizes != den.dims {
        return Err(rejected(ModelRole::Discriminator, ModelFault::WrongShape));
    }
    let p_min = inputs.config.p_min;
    let prior = match config.prior {
        Some(prior) => prior.with_floor(p_min),
        None => MarkovPrior::paper(inputs.task, p_min),
    }
    .map_err(|_| WireError::InvalidRequest {
        field: RequestField::Settings,
    })?;
    if prior.modes() != inputs.task.mode_count() {
        return Err(WireError::InvalidRequest {
            field: RequestField::Prior,
        });
    }
    let spec = inputs.into_spec(prior, config.sampler);
    let segments = spec.segments_per_call();
    let split = split_for(&den, &disc, segments, memory.work.len())?;
    let (den_mem, rest) = memory.work.split_at_mut(split.denoiser);
    let (disc_mem, rest) = rest.split_at_mut(split.discriminator);
    let session_mem = &mut rest[..split.session.total()];
    let den_engine =
        KernelEngine::new(denoiser, den_mem).map_err(|e| engine_fault(ModelRole::Denoiser, e))?;
    let disc_engine = KernelEngine::new(discriminator, disc_mem)
        .map_err(|e| engine_fault(ModelRole::Discriminator, e))?;
    let report = plan_with_engines(
        memory.planner,
        &spec,
        den_engine,
        disc_engine,
        &split.session,
        session_mem,
        clock,
    )
    .map_err(|e| match e {
        SessionError::Sampler(_) => rejected(ModelRole::Denoiser, ModelFault::WrongShape),
        SessionError::Scorer(_) => rejected(ModelRole::Discriminator, ModelFault::WrongShape),
    })?;
    Ok(Planned {
        report,
        work_floats: split.total(),
    })
}

/// A finished planning call: the search's report (the reply is made from it) and the work
/// area it used.
#[derive(Debug, Clone)]
pub struct Planned {
    /// The search's report.
    pub report: dips_kernel::search::SearchReport,
    /// Floats of the work area the call used.
    pub work_floats: usize,
}
