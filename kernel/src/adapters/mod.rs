//! The glue between the search and the model engines: [`DiffusionSegmentSampler`] is the
//! search's [`crate::search::SegmentSampler`] over any [`crate::engine::DenoiserEngine`]
//! (through the diffusion sampler), [`DiscriminatorScorer`] its
//! [`crate::search::SegmentScorer`] over any [`crate::engine::DiscriminatorEngine`].
//!
//! Both work on raw segments in the `docs/contracts.md` §2 layout, which is also the models'
//! layout: angles that wrap are `(cos, sin)` pairs in both, so no column is converted; only
//! the models' column normalization is applied (and undone). All memory is caller-provided
//! and nothing allocates. A model whose sizes differ from the problem's is refused with a
//! typed [`DimsMismatch`] (and the planner reports `InvalidProblem` before sampling).

pub mod anchor;
pub mod error;
pub mod sampler;
pub mod scorer;

pub use anchor::{InvariantAngle, StartAnchor};
pub use error::{AdapterBuffer, AdapterError, DimField, DimsMismatch, SegmentModelError};
pub use sampler::{DiffusionSegmentSampler, SamplerAdapterLayout};
pub use scorer::{DiscriminatorScorer, ScorerAdapterLayout};

use crate::engine::ModelDims;
use crate::mode::SegmentDims;

/// The segment sizes of a model (its `T`, state and action columns, and fingers).
pub const fn segment_dims(model: ModelDims) -> SegmentDims {
    SegmentDims {
        horizon: model.horizon,
        state_dim: model.state_dim,
        action_dim: model.action_dim,
        fingers: model.fingers,
    }
}

/// Check that a model was exported for segments of `problem`'s sizes; the first field that
/// differs is named.
pub fn check_dims(model: ModelDims, problem: &SegmentDims) -> Result<(), DimsMismatch> {
    let fields = [
        (DimField::Horizon, model.horizon, problem.horizon),
        (DimField::StateDim, model.state_dim, problem.state_dim),
        (DimField::ActionDim, model.action_dim, problem.action_dim),
        (DimField::Fingers, model.fingers, problem.fingers),
    ];
    for (field, model, problem) in fields {
        if model != problem {
            return Err(DimsMismatch {
                field,
                model,
                problem,
            });
        }
    }
    Ok(())
}
