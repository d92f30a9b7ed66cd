//! A small ONNX graph builder over `tract_onnx::pb` (the prost-generated protobuf).

use tract_onnx::pb;

/// ONNX opset the exporter writes (21: GroupNormalization's scale/bias are per channel).
pub const OPSET: i64 = 21;

/// Nodes and initializers under construction; every node has one output.
#[derive(Debug, Default)]
pub(crate) struct Graph {
    pub(crate) nodes: Vec<pb::NodeProto>,
    pub(crate) inits: Vec<pb::TensorProto>,
    counter: usize,
}

/// An ONNX attribute.
pub(crate) enum Attr {
    Int(&'static str, i64),
    Ints(&'static str, Vec<i64>),
    Float(&'static str, f32),
}

impl Attr {
    fn proto(self) -> pb::AttributeProto {
        use pb::attribute_proto::AttributeType as A;
        match self {
            Attr::Int(n, v) => pb::AttributeProto {
                name: n.into(),
                r#type: A::Int as i32,
                i: v,
                ..Default::default()
            },
            Attr::Ints(n, v) => pb::AttributeProto {
                name: n.into(),
                r#type: A::Ints as i32,
                ints: v,
                ..Default::default()
            },
            Attr::Float(n, v) => pb::AttributeProto {
                name: n.into(),
                r#type: A::Float as i32,
                f: v,
                ..Default::default()
            },
        }
    }
}

impl Graph {
    /// A float initializer.
    pub(crate) fn f32(&mut self, name: &str, dims: &[usize], data: &[f32]) -> String {
        self.inits.push(pb::TensorProto {
            name: name.into(),
            dims: dims.iter().map(|&d| d as i64).collect(),
            data_type: pb::tensor_proto::DataType::Float as i32,
            float_data: data.to_vec(),
            ..Default::default()
        });
        name.into()
    }

    /// An int64 initializer (shapes, axes, pads).
    pub(crate) fn i64(&mut self, data: &[i64]) -> String {
        self.counter += 1;
        let name = format!("const_{}", self.counter);
        self.inits.push(pb::TensorProto {
            name: name.clone(),
            dims: vec![data.len() as i64],
            data_type: pb::tensor_proto::DataType::Int64 as i32,
            int64_data: data.to_vec(),
            ..Default::default()
        });
        name
    }

    /// Append a node; returns its output's name.
    pub(crate) fn node(&mut self, op: &str, inputs: &[&str], attrs: Vec<Attr>) -> String {
        self.counter += 1;
        let out = format!("{}_{}", op.to_lowercase(), self.counter);
        self.node_named(op, inputs, attrs, &out);
        out
    }

    /// Append a node whose output has a given name (the graph outputs).
    pub(crate) fn node_named(&mut self, op: &str, inputs: &[&str], attrs: Vec<Attr>, out: &str) {
        self.nodes.push(pb::NodeProto {
            name: format!("{op}_{}", self.nodes.len()),
            op_type: op.into(),
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: vec![out.into()],
            attribute: attrs.into_iter().map(Attr::proto).collect(),
            ..Default::default()
        });
    }

    /// `Unsqueeze(x, axes)`.
    pub(crate) fn unsqueeze(&mut self, x: &str, axes: &[i64]) -> String {
        let a = self.i64(axes);
        self.node("Unsqueeze", &[x, &a], vec![])
    }
}

/// A float32 value info with a symbolic batch axis `B` and fixed inner axes.
pub(crate) fn value_info(name: &str, inner: &[usize]) -> pb::ValueInfoProto {
    use pb::tensor_shape_proto::{Dimension, dimension::Value};
    let mut dims = vec![Dimension {
        value: Some(Value::DimParam("B".into())),
        ..Default::default()
    }];
    dims.extend(inner.iter().map(|&d| Dimension {
        value: Some(Value::DimValue(d as i64)),
        ..Default::default()
    }));
    pb::ValueInfoProto {
        name: name.into(),
        r#type: Some(pb::TypeProto {
            value: Some(pb::type_proto::Value::TensorType(pb::type_proto::Tensor {
                elem_type: pb::tensor_proto::DataType::Float as i32,
                shape: Some(pb::TensorShapeProto { dim: dims }),
            })),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// Assemble a model.
pub(crate) fn model(
    g: Graph,
    name: &str,
    inputs: Vec<pb::ValueInfoProto>,
    outputs: Vec<pb::ValueInfoProto>,
    metadata: Vec<(String, String)>,
) -> pb::ModelProto {
    pb::ModelProto {
        ir_version: 10,
        producer_name: "dips-train".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        opset_import: vec![pb::OperatorSetIdProto {
            domain: String::new(),
            version: OPSET,
        }],
        metadata_props: metadata
            .into_iter()
            .map(|(key, value)| pb::StringStringEntryProto { key, value })
            .collect(),
        graph: Some(pb::GraphProto {
            name: name.into(),
            node: g.nodes,
            initializer: g.inits,
            input: inputs,
            output: outputs,
            ..Default::default()
        }),
        ..Default::default()
    }
}
