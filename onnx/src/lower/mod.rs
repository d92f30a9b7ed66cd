//! Lowering: ONNX protobuf → kernel blob (`.dipsm`, see `dips_kernel::nn::format`).
//!
//! We lower from the ONNX protobuf with our own constant folding rather than from tract's
//! decluttered `TypedModel`: the ONNX op set of the exporters is small and stable, maps 1:1
//! onto the kernel ops (Conv stays a Conv with its pads, InstanceNormalization stays one op
//! instead of tract's reduce/sub/mul chain), and nothing depends on tract's internal op
//! structs, which change between releases. tract stays the independent host engine we check
//! the kernel against.
//!
//! The graph is evaluated symbolically at a probe batch: values are constants (initializers,
//! `Constant`, and everything computed from constants and shapes: `Shape`, `Gather`,
//! `Concat`, `ConstantOfShape`, `Reshape`, ... are folded) or activations with a per-sample
//! shape. Only activations become kernel ops. The lowering runs at two probe batches and
//! requires identical programs, which proves the program is independent of the batch: the
//! kernel then runs any batch up to what the caller's memory holds.

mod attrs;
pub mod copyplan;
mod emit;
mod fold;
mod fuse;
mod plan;
pub mod tensors;
mod writer;

use std::path::Path;

use tract_onnx::pb;

use crate::contract::{Contract, Expectation, validate};
use crate::error::{ModelError, Result};
pub use writer::LoweredModel;

/// Probe batches; any two distinct values that no model dimension is likely to equal.
const PROBE_BATCHES: [usize; 2] = [5, 7];

/// Lower a validated model to a kernel blob.
pub fn lower_proto(proto: &pb::ModelProto) -> Result<LoweredModel> {
    let contract = validate(proto)?;
    tensors::check_initializers_finite(proto)?;
    lower_with_contract(proto, contract)
}

/// Read, validate (against `expected`) and lower a model file.
pub fn lower_file(path: &Path, expected: &Expectation) -> Result<LoweredModel> {
    let (proto, contract) = crate::contract::load_contract(path)?;
    contract.expect(expected)?;
    tensors::check_initializers_finite(&proto)?;
    lower_with_contract(&proto, contract)
}

fn lower_with_contract(proto: &pb::ModelProto, contract: Contract) -> Result<LoweredModel> {
    let opset = proto
        .opset_import
        .iter()
        .find(|o| o.domain.is_empty() || o.domain == "ai.onnx")
        .map_or(13, |o| o.version);
    let graph = proto
        .graph
        .as_ref()
        .ok_or_else(|| ModelError::Protobuf("no graph".into()))?;
    let nodes = fuse::fuse_patterns(&graph.node);
    let mut a = emit::Builder::build(graph, &nodes, &contract, opset, PROBE_BATCHES[0])?;
    let mut b = emit::Builder::build(graph, &nodes, &contract, opset, PROBE_BATCHES[1])?;
    for p in [&mut a, &mut b] {
        fuse::fuse_group_norm(p);
        fuse::compact_weights(p);
    }
    if a.ops != b.ops || a.weights != b.weights || a.storages != b.storages {
        return Err(ModelError::Lowering {
            op: "graph".into(),
            node: graph.name.clone(),
            reason: "the computation depends on the batch size beyond the batch axis (a reshape or constant mixes samples)".into(),
        });
    }
    writer::write(&contract, a)
}
