//! ONNX export under model contract v1 (`docs/contracts.md` §3), written with `tract_onnx::pb`.

use std::path::Path;

use dips_kernel::engine::ObjectFrame;
use dips_kernel::mode::Task;
use dips_kernel::task::CardGoals;
use prost::Message;
use tract_onnx::pb;

use crate::data::Normalizer;
use crate::error::{Result, TrainError, io_err};
use crate::graph::{Graph, model, value_info};
use crate::net::{Denoiser, Discriminator};
use crate::params::ParamStore;

/// The contract metadata of a model for `task`; column names come from the contract's task
/// table (`dips_onnx::tasks`).
pub fn contract_metadata(
    task: Task,
    role: dips_onnx::Role,
    diffusion_steps: usize,
    norm: &Normalizer,
) -> Result<Vec<(String, String)>> {
    let layout = dips_onnx::tasks::task_layout(task.name()).ok_or_else(|| {
        TrainError::DatasetUnusable(format!("task {} has no contract layout", task.name()))
    })?;
    let kv = |k: &str, v: String| (format!("dips.{k}"), v);
    Ok(vec![
        kv(
            "contract",
            dips_onnx::contract::CONTRACT_VERSION.to_string(),
        ),
        kv("role", role.name().into()),
        kv("task", task.name().into()),
        kv("horizon", layout.horizon.to_string()),
        kv("state_dim", layout.state_columns.len().to_string()),
        kv("action_dim", layout.action_columns.len().to_string()),
        kv("fingers", layout.fingers.to_string()),
        kv("diffusion_steps", diffusion_steps.to_string()),
        kv("beta_schedule", "cosine".into()),
        kv("prediction", "epsilon".into()),
        kv("norm_mean", json(&norm.mean)),
        kv("norm_std", json(&norm.std)),
        kv("columns", json(&layout.columns())),
    ])
}

/// JSON of a metadata array (serialising numbers and strings cannot fail).
fn json<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_default()
}

/// The denoiser as a contract-v1 ONNX model (batch axis symbolic), with the card goals its
/// demos were made with as `dips.card_goals` when given
/// ([`dips_onnx::contract::CARD_GOALS_KEY`]), and its object frame as `dips.object_frame`
/// when it is not the world's ([`dips_onnx::contract::OBJECT_FRAME_KEY`]).
pub fn denoiser_model(
    net: &Denoiser,
    params: &ParamStore,
    task: Task,
    diffusion_steps: usize,
    norm: &Normalizer,
    card_goals: Option<CardGoals>,
    object_frame: ObjectFrame,
) -> Result<pb::ModelProto> {
    let dims = net.dims();
    let mut g = Graph::default();
    net.emit(&mut g, params);
    Ok(model(
        g,
        "dips_denoiser",
        vec![
            value_info("x", &[dims.horizon, dims.dim]),
            value_info("t", &[]),
            value_info("context", &[dims.fingers]),
            value_info("cond_mask", &[]),
        ],
        vec![value_info("eps", &[dims.horizon, dims.dim])],
        {
            let mut meta =
                contract_metadata(task, dips_onnx::Role::Denoiser, diffusion_steps, norm)?;
            if let Some(goals) = card_goals {
                meta.push((
                    dips_onnx::contract::CARD_GOALS_KEY.to_string(),
                    goals.name().to_string(),
                ));
            }
            if object_frame != ObjectFrame::World {
                meta.push((
                    dips_onnx::contract::OBJECT_FRAME_KEY.to_string(),
                    object_frame.name().to_string(),
                ));
            }
            meta
        },
    ))
}

/// The discriminator as a contract-v1 ONNX model (batch axis symbolic), with the samplers its
/// negatives came from as `dips.psi_negatives` (a JSON array of `--sampler` names, `+anchor`
/// where anchored as the planner anchors: [`dips_onnx::contract::PSI_NEGATIVES_KEY`]).
pub fn discriminator_model(
    net: &Discriminator,
    params: &ParamStore,
    task: Task,
    diffusion_steps: usize,
    norm: &Normalizer,
    negatives: &[String],
) -> Result<pb::ModelProto> {
    let dims = net.dims();
    let mut g = Graph::default();
    net.emit(&mut g, params);
    Ok(model(
        g,
        "dips_discriminator",
        vec![
            value_info("x", &[dims.horizon, dims.dim]),
            value_info("context", &[dims.fingers]),
        ],
        vec![value_info("p_real", &[1])],
        {
            let mut meta =
                contract_metadata(task, dips_onnx::Role::Discriminator, diffusion_steps, norm)?;
            meta.push((
                dips_onnx::contract::PSI_NEGATIVES_KEY.to_string(),
                json(&negatives),
            ));
            meta
        },
    ))
}

/// Validate a model against contract v1 and write it atomically.
pub fn write_model(path: &Path, proto: &pb::ModelProto) -> Result<dips_onnx::Contract> {
    let contract = dips_onnx::contract::validate(proto)?;
    dips_fs::write_atomic(path, &proto.encode_to_vec()).map_err(io_err(path))?;
    Ok(contract)
}
