//! The host engine: tract-onnx straight from the `.onnx` file, one optimised plan per batch size.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use tract_onnx::pb;
use tract_onnx::prelude::*;

use crate::contract::{Contract, Expectation, load_contract, validate};
use crate::error::{ModelError, Result};
use crate::lower::tensors::check_initializers_finite;

fn tract_err(e: impl std::fmt::Display) -> ModelError {
    ModelError::Tract(format!("{e:#}"))
}

/// A contract-v1 model run by tract. Plans are built lazily per batch size and cached.
pub struct TractEngine {
    contract: Contract,
    model: InferenceModel,
    /// For each model input (in the graph's order), the index of the contract input.
    input_map: Vec<usize>,
    plans: HashMap<usize, Arc<TypedRunnableModel>>,
}

impl std::fmt::Debug for TractEngine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TractEngine")
            .field("contract", &self.contract)
            .field("cached_batches", &self.plans.keys().collect::<Vec<_>>())
            .finish()
    }
}

impl TractEngine {
    /// Load and validate a model file, refusing one that does not meet `expected`.
    pub fn load(path: &Path, expected: &Expectation) -> Result<Self> {
        let (proto, contract) = load_contract(path)?;
        contract.expect(expected)?;
        Self::from_proto(&proto, contract)
    }

    /// Build from an already decoded model.
    pub fn from_model_proto(proto: &pb::ModelProto) -> Result<Self> {
        let contract = validate(proto)?;
        Self::from_proto(proto, contract)
    }

    fn from_proto(proto: &pb::ModelProto, contract: Contract) -> Result<Self> {
        check_initializers_finite(proto)?;
        // Dynamo exports carry value_info with a symbolic batch that would clash with a
        // concrete input fact (spec/deps.md, addendum): ignore it and the output shapes.
        let model = tract_onnx::onnx()
            .with_ignore_value_info(true)
            .with_ignore_output_shapes(true)
            .model_for_proto_model(proto)
            .map_err(tract_err)?;
        let names = contract.role.input_names();
        let mut input_map = Vec::new();
        for outlet in model.input_outlets().map_err(tract_err)? {
            let name = &model.node(outlet.node).name;
            let ix = names.iter().position(|n| n == name).ok_or_else(|| {
                ModelError::Contract(format!("tract sees an unexpected input {name:?}"))
            })?;
            input_map.push(ix);
        }
        if input_map.len() != names.len() {
            return Err(ModelError::Contract(format!(
                "tract sees {} inputs, the contract has {}",
                input_map.len(),
                names.len()
            )));
        }
        Ok(TractEngine {
            contract,
            model,
            input_map,
            plans: HashMap::new(),
        })
    }

    /// The model's contract.
    pub fn contract(&self) -> &Contract {
        &self.contract
    }

    fn plan(&mut self, batch: usize) -> Result<Arc<TypedRunnableModel>> {
        if let Some(p) = self.plans.get(&batch) {
            return Ok(p.clone());
        }
        let mut model = self.model.clone();
        let names = self.contract.role.input_names();
        for (model_ix, contract_ix) in self.input_map.iter().enumerate() {
            let mut shape = vec![batch];
            shape.extend(
                self.contract
                    .input_shape(names[*contract_ix])
                    .unwrap_or_default(),
            );
            model
                .set_input_fact(model_ix, InferenceFact::dt_shape(f32::datum_type(), shape))
                .map_err(tract_err)?;
        }
        let plan = model
            .into_optimized()
            .map_err(tract_err)?
            .into_runnable()
            .map_err(tract_err)?;
        self.plans.insert(batch, plan.clone());
        Ok(plan)
    }

    /// Run the model on contract inputs (in contract order, each `[batch, ...]` flat) and
    /// write the output (`[batch, ...]` flat).
    pub fn run(&mut self, batch: usize, inputs: &[&[f32]], output: &mut [f32]) -> Result<()> {
        let names = self.contract.role.input_names();
        check_call(&self.contract, batch, inputs, output)?;
        let plan = self.plan(batch)?;
        let mut tensors = TVec::new();
        for contract_ix in &self.input_map {
            let mut shape = vec![batch];
            shape.extend(
                self.contract
                    .input_shape(names[*contract_ix])
                    .unwrap_or_default(),
            );
            let t = Tensor::from_shape(&shape, inputs[*contract_ix]).map_err(tract_err)?;
            tensors.push(t.into_tvalue());
        }
        let out = plan.run(tensors).map_err(tract_err)?;
        let first = out
            .first()
            .ok_or_else(|| ModelError::Tract("no output".into()))?;
        let view = first.to_plain_array_view::<f32>().map_err(tract_err)?;
        let mut want = vec![batch];
        want.extend(self.contract.output_shape());
        if view.shape() != want.as_slice() {
            return Err(ModelError::Contract(format!(
                "output {} has shape {:?}, the contract says {want:?}",
                self.contract.role.output_name(),
                view.shape()
            )));
        }
        for (o, v) in output.iter_mut().zip(view.iter()) {
            *o = *v;
        }
        Ok(())
    }
}

/// Check a call's buffers against the contract: one slice per input, each of the right length.
pub fn check_call(c: &Contract, batch: usize, inputs: &[&[f32]], output: &[f32]) -> Result<()> {
    let names = c.role.input_names();
    if batch == 0 {
        return Err(ModelError::BadInput {
            name: "batch".into(),
            reason: "batch must be at least 1".into(),
        });
    }
    if inputs.len() != names.len() {
        return Err(ModelError::BadInput {
            name: "inputs".into(),
            reason: format!(
                "{} inputs given, a {} takes {}",
                inputs.len(),
                c.role.name(),
                names.len()
            ),
        });
    }
    for (name, data) in names.iter().zip(inputs) {
        let per: usize = c.input_shape(name).unwrap_or_default().iter().product();
        if data.len() != per * batch {
            return Err(ModelError::BadInput {
                name: (*name).into(),
                reason: format!(
                    "{} floats given, batch {batch} needs {}",
                    data.len(),
                    per * batch
                ),
            });
        }
    }
    let per: usize = c.output_shape().iter().product();
    if output.len() != per * batch {
        return Err(ModelError::BadInput {
            name: c.role.output_name().into(),
            reason: format!(
                "output buffer holds {} floats, batch {batch} needs {}",
                output.len(),
                per * batch
            ),
        });
    }
    Ok(())
}

crate::engine::impl_engine_traits!(TractEngine);
