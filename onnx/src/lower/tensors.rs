//! Constant tensors of the ONNX graph (initializers, `Constant` nodes, folded shape
//! arithmetic), held as `f64` with a float/integer tag so shape maths stays exact.

use tract_onnx::pb;
use tract_onnx::pb::tensor_proto::DataType;

use crate::error::{ModelError, Result};

/// A constant tensor.
#[derive(Debug, Clone, PartialEq)]
pub struct Const {
    /// Dimensions.
    pub dims: Vec<usize>,
    /// Row-major values.
    pub data: Vec<f64>,
    /// Whether the ONNX type is a floating-point type (else integer or bool).
    pub float: bool,
}

impl Const {
    /// A float tensor.
    pub fn float(dims: Vec<usize>, data: Vec<f64>) -> Self {
        Const {
            dims,
            data,
            float: true,
        }
    }

    /// An integer tensor.
    pub fn int(dims: Vec<usize>, data: Vec<f64>) -> Self {
        Const {
            dims,
            data,
            float: false,
        }
    }

    /// Values as `i64` (for shapes, axes, pads).
    pub fn ints(&self) -> Vec<i64> {
        self.data.iter().map(|v| *v as i64).collect()
    }

    /// Values as `f32`.
    pub fn floats(&self) -> Vec<f32> {
        self.data.iter().map(|v| *v as f32).collect()
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether there are no elements.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
}

fn le_chunks<const N: usize>(raw: &[u8]) -> impl Iterator<Item = [u8; N]> + '_ {
    raw.chunks_exact(N).map(|c| {
        let mut a = [0u8; N];
        a.copy_from_slice(c);
        a
    })
}

fn f16_to_f64(bits: u16) -> f64 {
    let sign = if bits & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((bits >> 10) & 0x1f) as i32;
    let frac = (bits & 0x3ff) as f64;
    match exp {
        0 => sign * frac * 2f64.powi(-24),
        31 => {
            if frac == 0.0 {
                sign * f64::INFINITY
            } else {
                f64::NAN
            }
        }
        e => sign * (1.0 + frac / 1024.0) * 2f64.powi(e - 15),
    }
}

/// Decode a `TensorProto` (raw or typed data; external data is refused).
pub fn decode_tensor(t: &pb::TensorProto) -> Result<Const> {
    let name = if t.name.is_empty() {
        "<unnamed>"
    } else {
        &t.name
    };
    let bad = |why: String| ModelError::Contract(format!("tensor {name}: {why}"));
    if !t.external_data.is_empty() || t.data_location == Some(1) {
        return Err(bad("external data is not supported".into()));
    }
    let dims: Vec<usize> = t
        .dims
        .iter()
        .map(|d| usize::try_from(*d).map_err(|_| bad(format!("negative dimension {d}"))))
        .collect::<Result<_>>()?;
    let n = dims
        .iter()
        .try_fold(1usize, |a, d| a.checked_mul(*d))
        .ok_or_else(|| bad("too large".into()))?;
    let raw = &t.raw_data;
    let dt = DataType::try_from(t.data_type)
        .map_err(|_| bad(format!("unknown data type {}", t.data_type)))?;
    let (data, float): (Vec<f64>, bool) = match dt {
        DataType::Float => (
            if raw.is_empty() {
                t.float_data.iter().map(|v| *v as f64).collect()
            } else {
                le_chunks::<4>(raw)
                    .map(|b| f32::from_le_bytes(b) as f64)
                    .collect()
            },
            true,
        ),
        DataType::Double => (
            if raw.is_empty() {
                t.double_data.clone()
            } else {
                le_chunks::<8>(raw).map(f64::from_le_bytes).collect()
            },
            true,
        ),
        DataType::Float16 => (
            if raw.is_empty() {
                t.int32_data.iter().map(|v| f16_to_f64(*v as u16)).collect()
            } else {
                le_chunks::<2>(raw)
                    .map(|b| f16_to_f64(u16::from_le_bytes(b)))
                    .collect()
            },
            true,
        ),
        DataType::Int64 => (
            if raw.is_empty() {
                t.int64_data.iter().map(|v| *v as f64).collect()
            } else {
                le_chunks::<8>(raw)
                    .map(|b| i64::from_le_bytes(b) as f64)
                    .collect()
            },
            false,
        ),
        DataType::Int32
        | DataType::Int16
        | DataType::Int8
        | DataType::Uint8
        | DataType::Uint16
        | DataType::Bool => {
            let width = match dt {
                DataType::Int32 => 4,
                DataType::Int16 | DataType::Uint16 => 2,
                _ => 1,
            };
            let data = if raw.is_empty() {
                t.int32_data.iter().map(|v| *v as f64).collect()
            } else {
                raw.chunks_exact(width)
                    .map(|c| match (dt, c) {
                        (DataType::Int32, _) => i32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64,
                        (DataType::Int16, _) => i16::from_le_bytes([c[0], c[1]]) as f64,
                        (DataType::Uint16, _) => u16::from_le_bytes([c[0], c[1]]) as f64,
                        (DataType::Int8, _) => c[0] as i8 as f64,
                        _ => c[0] as f64,
                    })
                    .collect()
            };
            (data, false)
        }
        other => return Err(bad(format!("data type {other:?} is not supported"))),
    };
    if data.len() != n {
        return Err(bad(format!(
            "holds {} values, its dims {dims:?} need {n}",
            data.len()
        )));
    }
    Ok(Const { dims, data, float })
}

/// Refuse a model whose float initializers or `Constant` nodes hold NaN or infinity.
pub fn check_initializers_finite(proto: &pb::ModelProto) -> Result<()> {
    let Some(graph) = &proto.graph else {
        return Ok(());
    };
    let constants = graph
        .node
        .iter()
        .filter(|n| n.op_type == "Constant")
        .filter_map(|n| {
            n.attribute
                .iter()
                .find(|a| a.name == "value")
                .and_then(|a| a.t.as_ref())
        });
    for t in graph.initializer.iter().chain(constants) {
        let c = decode_tensor(t)?;
        if let Some(index) = c.data.iter().position(|v| c.float && !v.is_finite()) {
            return Err(ModelError::NonFiniteWeight {
                name: t.name.clone(),
                index,
            });
        }
    }
    Ok(())
}
