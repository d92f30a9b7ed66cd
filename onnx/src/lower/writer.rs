//! Serialization of a lowered program into the kernel blob.

use std::path::Path;

use dips_kernel::nn::format::{
    BLOB_VERSION, Body, Buf, CHECKSUM, Header, MAGIC, MAX_INPUTS, Meta, Op, OpRef, Operand, W,
};

use super::emit::Program;
use super::plan::plan;
use crate::contract::{Contract, Role};
use crate::error::{ModelError, Result};

/// A lowered model: the blob and a few facts about it.
#[derive(Debug, Clone)]
pub struct LoweredModel {
    /// The contract the blob carries.
    pub contract: Contract,
    /// The `.dipsm` bytes.
    pub blob: Vec<u8>,
    /// Kernel ops.
    pub n_ops: usize,
    /// Weight floats.
    pub n_weights: usize,
    /// Arena floats per sample.
    pub arena_per_sample: usize,
    /// Batch-independent op scratch floats.
    pub temp_len: usize,
}

impl LoweredModel {
    /// Floats of memory the kernel needs for batches up to `max_batch`.
    pub fn memory_len(&self, max_batch: usize) -> usize {
        self.n_weights + self.temp_len + self.arena_per_sample * max_batch
    }

    /// Write the blob atomically (temporary file, then rename).
    pub fn write(&self, path: &Path) -> Result<()> {
        let tmp = path.with_extension("dipsm.tmp");
        let io = |source| ModelError::Io {
            action: "write kernel blob",
            path: path.to_path_buf(),
            cause: source,
        };
        std::fs::write(&tmp, &self.blob).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }
}

fn remap(op: &Op, offsets: &[usize]) -> Op {
    let m = |b: &Buf| Buf {
        off: offsets[b.off as usize] as u32,
        len: b.len,
    };
    let mut op = *op;
    op.refs_mut(|r| match r {
        OpRef::Reads(b) | OpRef::Writes(b) | OpRef::ReadsOperand(Operand::Act(b)) => *b = m(b),
        OpRef::ReadsOperand(Operand::Weight(_)) | OpRef::Weight(_) => {}
    });
    op
}

fn too_big(what: &str) -> ModelError {
    ModelError::Lowering {
        op: "graph".into(),
        node: String::new(),
        reason: format!("{what} exceeds the blob's 32-bit sizes"),
    }
}

pub(super) fn write(contract: &Contract, prog: Program) -> Result<LoweredModel> {
    let (offsets, arena) = plan(&prog.ops, &prog.storages, &prog.inputs, prog.output);
    let mut weights = prog.weights;
    let d = contract.dim() as u32;
    let norm_mean = W {
        off: weights.len() as u32,
        len: d,
    };
    weights.extend(&contract.norm_mean);
    let norm_std = W {
        off: weights.len() as u32,
        len: d,
    };
    weights.extend(&contract.norm_std);
    let buf = |st: usize| Buf {
        off: offsets[st] as u32,
        len: prog.storages[st] as u32,
    };
    let mut inputs = [Buf { off: 0, len: 0 }; MAX_INPUTS];
    for (slot, st) in inputs.iter_mut().zip(&prog.inputs) {
        *slot = buf(*st);
    }
    let mut ops_bytes = Vec::new();
    for op in &prog.ops {
        let bytes =
            postcard::to_allocvec(&remap(op, &offsets)).map_err(|e| too_big(&e.to_string()))?;
        ops_bytes.extend(bytes);
    }
    let weight_bytes: Vec<u8> = weights.iter().flat_map(|w| w.to_le_bytes()).collect();
    let columns_json =
        serde_json::to_string(&contract.columns).map_err(|e| ModelError::Json(e.to_string()))?;
    let u = |v: usize, what: &str| u32::try_from(v).map_err(|_| too_big(what));
    let body = Body {
        meta: Meta {
            contract: crate::contract::CONTRACT_VERSION,
            role: match contract.role {
                Role::Denoiser => 0,
                Role::Discriminator => 1,
            },
            task: &contract.task,
            horizon: u(contract.horizon, "horizon")?,
            state_dim: u(contract.state_dim, "state_dim")?,
            action_dim: u(contract.action_dim, "action_dim")?,
            fingers: u(contract.fingers, "fingers")?,
            diffusion_steps: u(contract.diffusion_steps, "diffusion_steps")?,
            beta_schedule: &contract.beta_schedule,
            prediction: &contract.prediction,
            columns_json: &columns_json,
            norm_mean,
            norm_std,
            object_frame: contract.object_frame.code(),
        },
        inputs,
        n_inputs: prog.inputs.len() as u8,
        output: buf(prog.output),
        arena_per_sample: u(arena, "arena")?,
        temp_len: u(prog.temp_len, "scratch")?,
        n_ops: u(prog.ops.len(), "op count")?,
        ops: &ops_bytes,
        n_weights: u(weights.len(), "weights")?,
        weights: &weight_bytes,
    };
    let mut blob = postcard::to_allocvec(&Header {
        magic: MAGIC,
        version: BLOB_VERSION,
    })
    .map_err(|e| too_big(&e.to_string()))?;
    blob.extend(postcard::to_allocvec(&body).map_err(|e| too_big(&e.to_string()))?);
    let crc = CHECKSUM.checksum(&blob);
    blob.extend(crc.to_le_bytes());
    Ok(LoweredModel {
        contract: contract.clone(),
        blob,
        n_ops: prog.ops.len(),
        n_weights: weights.len(),
        arena_per_sample: arena,
        temp_len: prog.temp_len,
    })
}
