//! Model contract v1 (`docs/contracts.md` §3): metadata, inputs and outputs, and their validation.

use std::path::Path;

use prost::Message;
use serde::Serialize;
use tract_onnx::pb;

use crate::error::{ModelError, Result};
use crate::tasks::task_layout;

/// The contract version this crate implements.
pub const CONTRACT_VERSION: u32 = 1;

/// Optional discriminator metadata: a JSON array naming the samplers Ψ's negatives came from,
/// as `--sampler` spells them, `+anchor` where the samples were anchored at their starts as
/// the planner anchors them (e.g. `["ddpm","ddim:8","ddpm:16+anchor"]`). Models written
/// before it existed have none ([`psi_negatives`]).
pub const PSI_NEGATIVES_KEY: &str = "dips.psi_negatives";

/// Denoiser metadata of a card model: where the pushes of its training demos aimed
/// (`paper` or `capped`, `dips_kernel::task::CardGoals`). The planner plans and executes with
/// the same goals. Card models written before it existed have none and were trained on ours,
/// `capped` ([`card_goals`]).
pub const CARD_GOALS_KEY: &str = "dips.card_goals";

/// Denoiser metadata: where the model measures the object's columns from (`world` or
/// `segment-start`, `dips_kernel::engine::ObjectFrame`). Models written before it existed have
/// none and measure in the world's frame ([`object_frame`]).
pub const OBJECT_FRAME_KEY: &str = "dips.object_frame";

/// The object frame of a model ([`OBJECT_FRAME_KEY`]): the world's when the model does not say;
/// an error when it names neither frame. ([`validate`] also refuses a discriminator that names
/// one: the frame is the denoiser's, and Ψ scores segments in the world's frame.)
pub fn object_frame(proto: &pb::ModelProto) -> Result<dips_kernel::engine::ObjectFrame> {
    optional_meta(proto, OBJECT_FRAME_KEY).map_or(
        Ok(dips_kernel::engine::ObjectFrame::World),
        |v| {
            v.parse()
                .map_err(|e| contract_err(format!("{OBJECT_FRAME_KEY}: {e}")))
        },
    )
}

/// The card goals a model was trained for ([`CARD_GOALS_KEY`]), `None` when the model does not
/// say; an error when it names none of them.
pub fn card_goals(proto: &pb::ModelProto) -> Result<Option<dips_kernel::task::CardGoals>> {
    optional_meta(proto, CARD_GOALS_KEY)
        .map(|v| {
            v.parse()
                .map_err(|e| contract_err(format!("{CARD_GOALS_KEY}: {e}")))
        })
        .transpose()
}

/// How [`PSI_NEGATIVES_KEY`] names the samples of `method`: the sampler's name as `--sampler`
/// spells it, with `+anchor` when they were anchored at their starts as the planner anchors
/// them (`dips_kernel::adapters::StartAnchor` other than `NONE`).
pub fn psi_sample_name(method: &dips_kernel::diffusion::SamplingMethod, anchored: bool) -> String {
    if anchored {
        format!("{method}+anchor")
    } else {
        method.to_string()
    }
}

/// The samplers a discriminator's negatives came from ([`PSI_NEGATIVES_KEY`]), `None` when the
/// model does not say; an error when it says something that is not a JSON array of strings.
pub fn psi_negatives(proto: &pb::ModelProto) -> Result<Option<Vec<String>>> {
    optional_meta(proto, PSI_NEGATIVES_KEY)
        .map(|v| {
            serde_json::from_str(v).map_err(|e| {
                contract_err(format!(
                    "{PSI_NEGATIVES_KEY} is not a JSON array of sampler names: {e}"
                ))
            })
        })
        .transpose()
}

/// What a model is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// ε-predicting denoiser: inputs `x, t, context, cond_mask`, output `eps`.
    Denoiser,
    /// Discriminator Ψ: inputs `x, context`, output `p_real`.
    Discriminator,
}

impl Role {
    /// The contract's name for the role.
    pub fn name(self) -> &'static str {
        match self {
            Role::Denoiser => "denoiser",
            Role::Discriminator => "discriminator",
        }
    }

    /// Input names in contract order.
    pub fn input_names(self) -> &'static [&'static str] {
        match self {
            Role::Denoiser => &["x", "t", "context", "cond_mask"],
            Role::Discriminator => &["x", "context"],
        }
    }

    /// Output name.
    pub fn output_name(self) -> &'static str {
        match self {
            Role::Denoiser => "eps",
            Role::Discriminator => "p_real",
        }
    }
}

/// The validated contract metadata of a model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Contract {
    /// `dips.role`.
    pub role: Role,
    /// `dips.task`.
    pub task: String,
    /// `dips.horizon` (T).
    pub horizon: usize,
    /// `dips.state_dim`.
    pub state_dim: usize,
    /// `dips.action_dim`.
    pub action_dim: usize,
    /// `dips.fingers` (F).
    pub fingers: usize,
    /// `dips.diffusion_steps`.
    pub diffusion_steps: usize,
    /// `dips.beta_schedule`.
    pub beta_schedule: String,
    /// `dips.prediction`.
    pub prediction: String,
    /// `dips.norm_mean`, D entries.
    pub norm_mean: Vec<f32>,
    /// `dips.norm_std`, D entries, all positive.
    pub norm_std: Vec<f32>,
    /// `dips.columns`, D names.
    pub columns: Vec<String>,
    /// `dips.object_frame` (the world's when absent; always the world's for a discriminator).
    pub object_frame: dips_kernel::engine::ObjectFrame,
}

impl Contract {
    /// Columns per row, `D`.
    pub fn dim(&self) -> usize {
        self.state_dim + self.action_dim
    }

    /// The kernel's view of the dimensions.
    pub fn dims(&self) -> dips_kernel::engine::ModelDims {
        dips_kernel::engine::ModelDims {
            horizon: self.horizon,
            state_dim: self.state_dim,
            action_dim: self.action_dim,
            fingers: self.fingers,
            diffusion_steps: self.diffusion_steps,
        }
    }

    /// Per-sample shape of a contract input (without the batch axis).
    pub fn input_shape(&self, name: &str) -> Option<Vec<usize>> {
        match name {
            "x" => Some(vec![self.horizon, self.dim()]),
            "t" | "cond_mask" => Some(vec![]),
            "context" => Some(vec![self.fingers]),
            _ => None,
        }
    }

    /// Per-sample shape of the contract output (without the batch axis).
    pub fn output_shape(&self) -> Vec<usize> {
        match self.role {
            Role::Denoiser => vec![self.horizon, self.dim()],
            Role::Discriminator => vec![1],
        }
    }

    /// Check the dimensions and column names against the task's layout (`docs/contracts.md` §2).
    pub fn check_task(&self) -> Result<()> {
        let (task, horizon, fingers) = (&self.task, self.horizon, self.fingers);
        let (state_dim, action_dim) = (self.state_dim, self.action_dim);
        let layout = task_layout(task).ok_or_else(|| {
            contract_err(format!(
                "dips.task {task:?} is not a known task ({})",
                crate::tasks::KNOWN_TASKS.join(", ")
            ))
        })?;
        if layout.horizon != horizon {
            return Err(contract_err(format!(
                "dips.horizon is {horizon}, task {task} has T = {}",
                layout.horizon
            )));
        }
        if layout.fingers != fingers {
            return Err(contract_err(format!(
                "dips.fingers is {fingers}, task {task} has {}",
                layout.fingers
            )));
        }
        if layout.state_columns.len() != state_dim || layout.action_columns.len() != action_dim {
            return Err(contract_err(format!(
                "dips.state_dim/action_dim are {state_dim}/{action_dim}, task {task} has {}/{}",
                layout.state_columns.len(),
                layout.action_columns.len()
            )));
        }
        if self.columns.len() != state_dim + action_dim {
            return Err(contract_err(format!(
                "dips.columns has {} names, D = {}",
                self.columns.len(),
                state_dim + action_dim
            )));
        }
        for (i, (got, want)) in self.columns.iter().zip(layout.columns()).enumerate() {
            if *got != want {
                return Err(contract_err(format!(
                    "dips.columns[{i}] is {got:?}, task {task} has {want:?}"
                )));
            }
        }
        Ok(())
    }

    /// The contract a kernel blob carries (checked against the task like an ONNX file's).
    pub fn from_blob(blob: &[u8]) -> Result<Contract> {
        let body = dips_kernel::nn::model::decode(blob)?;
        let m = &body.meta;
        let weight = |w: dips_kernel::nn::format::W| -> Result<Vec<f32>> {
            let bytes = body
                .weights
                .get(w.off as usize * 4..(w.off as usize + w.len as usize) * 4)
                .ok_or_else(|| contract_err("the blob's normalization lies outside its weights"))?;
            Ok(bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect())
        };
        let role = match m.role {
            0 => Role::Denoiser,
            1 => Role::Discriminator,
            r => return Err(contract_err(format!("the blob has role {r}"))),
        };
        let columns: Vec<String> = serde_json::from_str(m.columns_json).map_err(|e| {
            contract_err(format!(
                "the blob's columns are not a JSON array of strings: {e}"
            ))
        })?;
        let c = Contract {
            role,
            task: m.task.to_string(),
            horizon: m.horizon as usize,
            state_dim: m.state_dim as usize,
            action_dim: m.action_dim as usize,
            fingers: m.fingers as usize,
            diffusion_steps: m.diffusion_steps as usize,
            beta_schedule: m.beta_schedule.to_string(),
            prediction: m.prediction.to_string(),
            norm_mean: weight(m.norm_mean)?,
            norm_std: weight(m.norm_std)?,
            columns,
            object_frame: dips_kernel::engine::ObjectFrame::from_code(m.object_frame).ok_or_else(
                || {
                    contract_err(format!(
                        "the blob's object frame code {} is unknown",
                        m.object_frame
                    ))
                },
            )?,
        };
        c.check_task()?;
        Ok(c)
    }

    /// Refuse a model made for another task or role, naming the mismatch.
    pub fn expect(&self, expected: &Expectation) -> Result<()> {
        if let Some(role) = expected.role
            && role != self.role
        {
            return Err(ModelError::Mismatch(format!(
                "expected a {} model, this is a {}",
                role.name(),
                self.role.name()
            )));
        }
        if let Some(task) = &expected.task
            && task != &self.task
        {
            return Err(ModelError::Mismatch(format!(
                "expected a model for task {task:?}, this one is for task {:?}",
                self.task
            )));
        }
        Ok(())
    }
}

/// What the caller needs a model to be (any field `None` accepts everything).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Expectation {
    /// Required role.
    pub role: Option<Role>,
    /// Required task name.
    pub task: Option<String>,
}

impl Expectation {
    /// A model of this role for this task.
    pub fn new(role: Role, task: &str) -> Self {
        Expectation {
            role: Some(role),
            task: Some(task.to_string()),
        }
    }
}

/// Read and decode an `.onnx` file.
pub fn read_proto(path: &Path) -> Result<pb::ModelProto> {
    let bytes = std::fs::read(path).map_err(|source| ModelError::Io {
        action: "read model file",
        path: path.to_path_buf(),
        cause: source,
    })?;
    decode_proto(&bytes)
}

/// Decode `.onnx` bytes.
pub fn decode_proto(bytes: &[u8]) -> Result<pb::ModelProto> {
    let proto = pb::ModelProto::decode(bytes).map_err(|e| ModelError::Protobuf(e.to_string()))?;
    if proto.graph.is_none() {
        return Err(ModelError::Protobuf("the model has no graph".into()));
    }
    Ok(proto)
}

fn contract_err(msg: impl Into<String>) -> ModelError {
    ModelError::Contract(msg.into())
}

/// The value of metadata property `key`, `None` when the model has none.
fn optional_meta<'a>(proto: &'a pb::ModelProto, key: &str) -> Option<&'a str> {
    proto
        .metadata_props
        .iter()
        .find(|p| p.key == key)
        .map(|p| p.value.as_str())
}

/// The value of a required metadata property; an error naming it when missing.
fn meta<'a>(proto: &'a pb::ModelProto, key: &str) -> Result<&'a str> {
    optional_meta(proto, key)
        .ok_or_else(|| contract_err(format!("metadata property {key} is missing")))
}

fn meta_usize(proto: &pb::ModelProto, key: &str) -> Result<usize> {
    let v = meta(proto, key)?;
    v.trim().parse::<usize>().map_err(|_| {
        contract_err(format!(
            "metadata {key}={v:?} is not a non-negative integer"
        ))
    })
}

fn meta_floats(proto: &pb::ModelProto, key: &str, len: usize) -> Result<Vec<f32>> {
    let v = meta(proto, key)?;
    let xs: Vec<f64> = serde_json::from_str(v).map_err(|e| {
        contract_err(format!(
            "metadata {key} is not a JSON array of numbers: {e}"
        ))
    })?;
    if xs.len() != len {
        return Err(contract_err(format!(
            "metadata {key} has {} entries, D = {len}",
            xs.len()
        )));
    }
    if let Some(i) = xs.iter().position(|x| !x.is_finite()) {
        return Err(contract_err(format!("metadata {key}[{i}] is not finite")));
    }
    Ok(xs.into_iter().map(|x| x as f32).collect())
}

/// Contract dimension of an ONNX value: `None` for a symbolic (dynamic) axis.
fn value_dims(v: &pb::ValueInfoProto) -> Result<(i32, Vec<Option<i64>>)> {
    use pb::type_proto::Value;
    let Some(Value::TensorType(t)) = v.r#type.as_ref().and_then(|t| t.value.as_ref()) else {
        return Err(contract_err(format!("{} is not a tensor", v.name)));
    };
    let dims = t
        .shape
        .as_ref()
        .map(|s| {
            s.dim
                .iter()
                .map(|d| match d.value {
                    Some(pb::tensor_shape_proto::dimension::Value::DimValue(n)) => Some(n),
                    _ => None,
                })
                .collect()
        })
        .ok_or_else(|| contract_err(format!("{} has no shape", v.name)))?;
    Ok((t.elem_type, dims))
}

fn check_value(v: &pb::ValueInfoProto, want: &[usize], strict_inner: bool) -> Result<()> {
    let (elem, dims) = value_dims(v)?;
    if elem != pb::tensor_proto::DataType::Float as i32 {
        return Err(contract_err(format!(
            "{} must be float32 (ONNX type 1), found type {elem}",
            v.name
        )));
    }
    if dims.len() != want.len() + 1 {
        return Err(contract_err(format!(
            "{} must have rank {} ([batch{}]), found rank {}",
            v.name,
            want.len() + 1,
            want.iter().map(|d| format!(",{d}")).collect::<String>(),
            dims.len()
        )));
    }
    if let Some(Some(b)) = dims.first()
        && *b < 1
    {
        return Err(contract_err(format!("{} has batch axis {b}", v.name)));
    }
    for (axis, (got, want)) in dims[1..].iter().zip(want).enumerate() {
        match got {
            Some(g) if *g != *want as i64 => {
                return Err(contract_err(format!(
                    "{} axis {} is {g}, the metadata says {want}",
                    v.name,
                    axis + 1
                )));
            }
            None if strict_inner => {
                return Err(contract_err(format!(
                    "{} axis {} must be fixed ({want})",
                    v.name,
                    axis + 1
                )));
            }
            _ => {}
        }
    }
    Ok(())
}

/// Validate contract v1 on a decoded model: metadata, column names against the task,
/// inputs and outputs. Returns the contract.
pub fn validate(proto: &pb::ModelProto) -> Result<Contract> {
    let version = meta(proto, "dips.contract")?;
    if version.trim() != CONTRACT_VERSION.to_string() {
        return Err(contract_err(format!(
            "dips.contract is {version:?}, this build reads version {CONTRACT_VERSION}"
        )));
    }
    let role = match meta(proto, "dips.role")? {
        "denoiser" => Role::Denoiser,
        "discriminator" => Role::Discriminator,
        other => {
            return Err(contract_err(format!(
                "dips.role is {other:?}, expected \"denoiser\" or \"discriminator\""
            )));
        }
    };
    let task = meta(proto, "dips.task")?.to_string();
    let horizon = meta_usize(proto, "dips.horizon")?;
    let state_dim = meta_usize(proto, "dips.state_dim")?;
    let action_dim = meta_usize(proto, "dips.action_dim")?;
    let fingers = meta_usize(proto, "dips.fingers")?;
    let diffusion_steps = meta_usize(proto, "dips.diffusion_steps")?;
    let beta_schedule = meta(proto, "dips.beta_schedule")?.to_string();
    let prediction = meta(proto, "dips.prediction")?.to_string();
    if horizon == 0 || state_dim + action_dim == 0 || fingers == 0 {
        return Err(contract_err(
            "dips.horizon, dips.fingers and D must be positive",
        ));
    }
    if role == Role::Denoiser && diffusion_steps == 0 {
        return Err(contract_err("a denoiser needs dips.diffusion_steps > 0"));
    }
    if beta_schedule != "cosine" {
        return Err(contract_err(format!(
            "dips.beta_schedule is {beta_schedule:?}, contract v1 knows \"cosine\""
        )));
    }
    if prediction != "epsilon" {
        return Err(contract_err(format!(
            "dips.prediction is {prediction:?}, contract v1 knows \"epsilon\""
        )));
    }
    let d = state_dim + action_dim;
    let norm_mean = meta_floats(proto, "dips.norm_mean", d)?;
    let norm_std = meta_floats(proto, "dips.norm_std", d)?;
    if let Some(i) = norm_std.iter().position(|s| *s <= 0.0) {
        return Err(contract_err(format!("dips.norm_std[{i}] is not positive")));
    }
    let columns_raw = meta(proto, "dips.columns")?;
    let columns: Vec<String> = serde_json::from_str(columns_raw)
        .map_err(|e| contract_err(format!("dips.columns is not a JSON array of strings: {e}")))?;
    if columns.len() != d {
        return Err(contract_err(format!(
            "dips.columns has {} names, D = {d}",
            columns.len()
        )));
    }
    let object_frame = object_frame(proto)?;
    if role == Role::Discriminator && object_frame != dips_kernel::engine::ObjectFrame::World {
        return Err(contract_err(format!(
            "{OBJECT_FRAME_KEY} is {object_frame} on a discriminator: Ψ scores segments in the world's frame"
        )));
    }
    let contract = Contract {
        role,
        task,
        horizon,
        state_dim,
        action_dim,
        fingers,
        diffusion_steps,
        beta_schedule,
        prediction,
        norm_mean,
        norm_std,
        columns,
        object_frame,
    };
    contract.check_task()?;
    check_io(proto, &contract)?;
    Ok(contract)
}

fn check_io(proto: &pb::ModelProto, c: &Contract) -> Result<()> {
    let graph = proto
        .graph
        .as_ref()
        .ok_or_else(|| contract_err("the model has no graph"))?;
    let initializers: std::collections::HashSet<&str> =
        graph.initializer.iter().map(|i| i.name.as_str()).collect();
    let inputs: Vec<&pb::ValueInfoProto> = graph
        .input
        .iter()
        .filter(|i| !initializers.contains(i.name.as_str()))
        .collect();
    let want = c.role.input_names();
    let names: Vec<&str> = inputs.iter().map(|i| i.name.as_str()).collect();
    let mut sorted_got = names.clone();
    sorted_got.sort_unstable();
    let mut sorted_want = want.to_vec();
    sorted_want.sort_unstable();
    if sorted_got != sorted_want {
        return Err(contract_err(format!(
            "a {} must have inputs {want:?}, this model has {names:?}",
            c.role.name()
        )));
    }
    for i in &inputs {
        let shape = c.input_shape(&i.name).unwrap_or_default();
        check_value(i, &shape, true)?;
    }
    let outs: Vec<&str> = graph.output.iter().map(|o| o.name.as_str()).collect();
    if outs != [c.role.output_name()] {
        return Err(contract_err(format!(
            "a {} must have the single output {:?}, this model has {outs:?}",
            c.role.name(),
            c.role.output_name()
        )));
    }
    // Exporters may leave inner output axes symbolic; the engines check the computed shape.
    check_value(&graph.output[0], &c.output_shape(), false)
}

/// Read, decode and validate a model file.
pub fn load_contract(path: &Path) -> Result<(pb::ModelProto, Contract)> {
    let proto = read_proto(path)?;
    let contract = validate(&proto)?;
    Ok((proto, contract))
}
