//! The fixtures' JSON tensor files: `{"inputs": {name: {"shape": [..], "data": [..]}}}` and
//! `{"outputs": {...}}`.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::contract::Contract;
use crate::error::{ModelError, Result};

/// One named tensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JsonTensor {
    /// Dimensions, batch first.
    pub shape: Vec<usize>,
    /// Row-major values.
    pub data: Vec<f32>,
}

/// A file of inputs and/or outputs.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TensorFile {
    /// Inputs by name.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub inputs: BTreeMap<String, JsonTensor>,
    /// Outputs by name.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub outputs: BTreeMap<String, JsonTensor>,
}

impl TensorFile {
    /// Read a file.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
            action: "read tensor file",
            path: path.to_path_buf(),
            cause: source,
        })?;
        let f: TensorFile = serde_json::from_str(&text)
            .map_err(|e| ModelError::Json(format!("{}: {e}", path.display())))?;
        for (name, t) in f.inputs.iter().chain(&f.outputs) {
            if t.shape.iter().product::<usize>() != t.data.len() {
                return Err(ModelError::Json(format!(
                    "{name}: shape {:?} does not hold {} values",
                    t.shape,
                    t.data.len()
                )));
            }
        }
        Ok(f)
    }

    /// Write a file atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string(self).map_err(|e| ModelError::Json(e.to_string()))?;
        let tmp = path.with_extension("json.tmp");
        let io = |source| ModelError::Io {
            action: "write tensor file",
            path: path.to_path_buf(),
            cause: source,
        };
        std::fs::write(&tmp, text).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }

    /// The contract inputs in contract order with the batch, checking every shape.
    pub fn contract_inputs(&self, c: &Contract) -> Result<(usize, Vec<&[f32]>)> {
        let mut batch = None;
        let mut out = Vec::new();
        for name in c.role.input_names() {
            let t = self.inputs.get(*name).ok_or_else(|| ModelError::BadInput {
                name: (*name).into(),
                reason: "missing".into(),
            })?;
            let mut want = vec![*t.shape.first().unwrap_or(&0)];
            want.extend(c.input_shape(name).unwrap_or_default());
            if t.shape != want || want[0] == 0 {
                return Err(ModelError::BadInput {
                    name: (*name).into(),
                    reason: format!(
                        "shape {:?}, the model needs [batch{}]",
                        t.shape,
                        want[1..]
                            .iter()
                            .map(|d| format!(", {d}"))
                            .collect::<String>()
                    ),
                });
            }
            if *batch.get_or_insert(want[0]) != want[0] {
                return Err(ModelError::BadInput {
                    name: (*name).into(),
                    reason: "batch differs between inputs".into(),
                });
            }
            out.push(t.data.as_slice());
        }
        Ok((batch.unwrap_or(0), out))
    }
}
