//! Bad input gets a typed error, never a panic: corrupt or truncated `.onnx`, contract
//! violations, non-finite weights, blobs with a wrong version or checksum or hostile bytes,
//! and inputs of the wrong shape.

mod common;

use common::fixture;
use dips_kernel::nn::NnError;
use dips_kernel::nn::model::{ModelInfo, install, parse};
use dips_onnx::{
    Expectation, KernelHostEngine, ModelError, TractEngine, contract, lower_file, lower_proto,
};
use proptest::prelude::*;
use prost::Message;
use tract_onnx::pb;

fn tmp(name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("dips-onnx-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn card_bytes() -> Vec<u8> {
    std::fs::read(fixture("torch-card-dynamo", "discriminator.onnx")).unwrap()
}

fn blob() -> Vec<u8> {
    lower_file(
        &fixture("torch-card-dynamo", "discriminator.onnx"),
        &Expectation::default(),
    )
    .unwrap()
    .blob
}

fn reseal(b: &mut [u8]) {
    let n = b.len() - 4;
    let crc = dips_kernel::nn::format::CHECKSUM.checksum(&b[..n]);
    b[n..].copy_from_slice(&crc.to_le_bytes());
}

#[test]
fn truncated_and_corrupt_onnx_are_typed_errors() {
    let bytes = card_bytes();
    for (name, data) in [
        ("half.onnx", bytes[..bytes.len() / 2].to_vec()),
        ("head.onnx", bytes[..100].to_vec()),
        ("empty.onnx", vec![]),
        (
            "garbage.onnx",
            (0..5000u32)
                .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
                .collect(),
        ),
    ] {
        let p = tmp(name, &data);
        let e = TractEngine::load(&p, &Expectation::default()).unwrap_err();
        assert!(
            matches!(e, ModelError::Protobuf(_) | ModelError::Contract(_)),
            "{name}: {e}"
        );
        let e = KernelHostEngine::load_onnx(&p, &Expectation::default()).unwrap_err();
        assert!(
            matches!(e, ModelError::Protobuf(_) | ModelError::Contract(_)),
            "{name}: {e}"
        );
    }
    let e = TractEngine::load(
        std::path::Path::new("/nonexistent/m.onnx"),
        &Expectation::default(),
    )
    .unwrap_err();
    assert!(matches!(e, ModelError::Io { .. }));
}

fn with_meta(key: &str, value: &str) -> pb::ModelProto {
    let mut m = pb::ModelProto::decode(&*card_bytes()).unwrap();
    for p in &mut m.metadata_props {
        if p.key == key {
            p.value = value.into();
        }
    }
    m
}

#[test]
fn contract_violations_name_the_field() {
    for (key, value, needle) in [
        ("dips.contract", "2", "dips.contract"),
        ("dips.role", "critic", "dips.role"),
        ("dips.task", "door", "door"),
        ("dips.horizon", "10", "dips.horizon"),
        ("dips.norm_std", "[1,2]", "dips.norm_std"),
        ("dips.columns", "[\"a\"]", "dips.columns"),
    ] {
        let e = contract::validate(&with_meta(key, value)).unwrap_err();
        assert!(e.to_string().contains(needle), "{key}: {e}");
    }
    let mut cols: Vec<String> = serde_json::from_str(
        &with_meta("", "")
            .metadata_props
            .iter()
            .find(|p| p.key == "dips.columns")
            .unwrap()
            .value,
    )
    .unwrap();
    cols.swap(0, 1);
    let e = contract::validate(&with_meta(
        "dips.columns",
        &serde_json::to_string(&cols).unwrap(),
    ))
    .unwrap_err();
    assert!(e.to_string().contains("dips.columns[0]"), "{e}");
    // An object frame that is none of the two names both.
    let mut m = with_meta("", "");
    m.metadata_props.push(pb::StringStringEntryProto {
        key: contract::OBJECT_FRAME_KEY.into(),
        value: "rotating".into(),
    });
    let e = contract::validate(&m).unwrap_err().to_string();
    assert!(
        e.contains("dips.object_frame") && e.contains("rotating") && e.contains("segment-start"),
        "{e}"
    );
    let mut m = with_meta("", "");
    m.graph.as_mut().unwrap().input[1].name = "ctx".into();
    let e = contract::validate(&m).unwrap_err();
    assert!(e.to_string().contains("ctx"), "{e}");
}

#[test]
fn non_finite_weights_are_refused_by_both_engines() {
    for bad in [f32::NAN, f32::INFINITY] {
        let mut m = pb::ModelProto::decode(&*card_bytes()).unwrap();
        let init = m
            .graph
            .as_mut()
            .unwrap()
            .initializer
            .iter_mut()
            .find(|t| t.dims.len() == 3)
            .unwrap();
        if init.raw_data.is_empty() {
            init.float_data[5] = bad;
        } else {
            init.raw_data[20..24].copy_from_slice(&bad.to_le_bytes());
        }
        let name = init.name.clone();
        let e = TractEngine::from_model_proto(&m).unwrap_err();
        assert!(
            matches!(&e, ModelError::NonFiniteWeight { name: n, .. } if *n == name),
            "{e}"
        );
        let e = lower_proto(&m).unwrap_err();
        assert!(matches!(e, ModelError::NonFiniteWeight { .. }), "{e}");
    }
    // A blob whose weights were altered after lowering (checksum resealed) is refused at install.
    let mut b = blob();
    let info = parse(&b).unwrap();
    let n = b.len();
    b[n - 8..n - 4].copy_from_slice(&f32::NAN.to_le_bytes());
    reseal(&mut b);
    let info2 = parse(&b).unwrap();
    assert_eq!(info, info2);
    let mut mem = vec![0.0; info.memory_len(1).unwrap()];
    assert!(matches!(
        install(&info2, &b, &mut mem),
        Err(NnError::NonFiniteWeight { .. })
    ));
}

#[test]
fn blob_version_checksum_and_truncation_are_typed_errors() {
    let b = blob();
    let mut v = b.clone();
    v[4] = 9; // version varint
    assert_eq!(
        parse(&v),
        Err(NnError::UnsupportedVersion {
            found: 9,
            supported: 2
        })
    );
    // A blob of version 1 (before the object frame) is named as such.
    v[4] = 1;
    let e = parse(&v).unwrap_err();
    assert_eq!(
        e,
        NnError::UnsupportedVersion {
            found: 1,
            supported: 2
        }
    );
    assert!(e.to_string().contains("lower"), "{e}");
    let mut m = b.clone();
    m[0] = b'X';
    assert_eq!(parse(&m), Err(NnError::BadMagic));
    let mut c = b.clone();
    let mid = c.len() / 2;
    c[mid] ^= 0x40;
    assert!(matches!(parse(&c), Err(NnError::ChecksumMismatch { .. })));
    for cut in [0, 3, 8, b.len() / 3, b.len() - 1] {
        assert!(parse(&b[..cut]).is_err(), "cut at {cut}");
    }
    let info: ModelInfo = parse(&b).unwrap();
    let mut small = vec![0.0; info.memory_len(1).unwrap() - 1];
    assert!(matches!(
        install(&info, &b, &mut small),
        Err(NnError::MemoryTooSmall { .. })
    ));
}

#[test]
fn wrong_input_shapes_are_typed_errors() {
    let p = fixture("torch-card-dynamo", "discriminator.onnx");
    let mut t = TractEngine::load(&p, &Expectation::default()).unwrap();
    let mut k = KernelHostEngine::load_onnx(&p, &Expectation::default()).unwrap();
    let x = vec![0.0; 2 * 9 * 29];
    let ctx = vec![1.0; 2 * 2];
    let mut out = vec![0.0; 2];
    assert!(t.run(2, &[&x, &ctx], &mut out).is_ok());
    for (xs, cs, os, b) in [
        (&x[1..], &ctx[..], 2, 2),
        (&x[..], &ctx[1..], 2, 2),
        (&x[..], &ctx[..], 3, 2),
        (&x[..], &ctx[..], 0, 0),
    ] {
        let mut o = vec![0.0; os];
        assert!(matches!(
            t.run(b, &[xs, cs], &mut o),
            Err(ModelError::BadInput { .. })
        ));
        assert!(matches!(
            k.run(b, &[xs, cs], &mut o),
            Err(ModelError::BadInput { .. })
        ));
    }
    assert!(matches!(
        k.run(2, &[&x], &mut out),
        Err(ModelError::BadInput { .. })
    ));
    // The no_std interpreter checks lengths itself too.
    let b = blob();
    let info = parse(&b).unwrap();
    let mut mem = vec![0.0; info.memory_len(4).unwrap()];
    install(&info, &b, &mut mem).unwrap();
    let r = dips_kernel::nn::model::run(&info, &b, &mut mem, 2, &[&x[1..], &ctx], &mut out);
    assert!(matches!(r, Err(NnError::BadLength { which: 0, .. })));
    let r = dips_kernel::nn::model::run(&info, &b, &mut mem, 5, &[&x, &ctx], &mut out);
    assert!(matches!(r, Err(NnError::BadBatch { batch: 5, max: 4 })));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// Hostile bytes: mutate a valid blob anywhere (resealing the checksum so decoding gets
    /// past it); parsing, installing and running must return, never panic.
    #[test]
    fn mutated_blobs_never_panic(pos in 0usize..100_000, val in any::<u8>(), cut in 0usize..64) {
        thread_local!(static BLOB: Vec<u8> = blob());
        let mut b = BLOB.with(|b| b.clone());
        let body = b.len() - 4;
        let i = pos % body;
        b[i] = val;
        b.truncate(b.len() - cut.min(8));
        if cut < 8 { reseal_any(&mut b); }
        if let Ok(info) = parse(&b) {
            let mut mem = vec![0.0; info.memory_len(2).unwrap_or(0).min(1 << 22)];
            if install(&info, &b, &mut mem).is_ok() {
                let x = vec![0.5; info.input_len(0) * 2];
                let c = vec![1.0; info.input_len(1) * 2];
                let mut o = vec![0.0; info.output_len() * 2];
                let _ = dips_kernel::nn::model::run(&info, &b, &mut mem, 2, &[&x, &c], &mut o);
            }
        }
    }
}

fn reseal_any(b: &mut [u8]) {
    if b.len() >= 4 {
        reseal(b);
    }
}

#[test]
fn unsupported_ops_are_named_with_their_node() {
    let mut m = pb::ModelProto::decode(&*card_bytes()).unwrap();
    let node = m
        .graph
        .as_mut()
        .unwrap()
        .node
        .iter_mut()
        .find(|n| n.op_type == "Sigmoid")
        .unwrap();
    node.op_type = "HardSigmoid".into();
    let want = if node.name.is_empty() {
        node.output[0].clone()
    } else {
        node.name.clone()
    };
    match lower_proto(&m).unwrap_err() {
        ModelError::UnsupportedOp { op, node } => {
            assert_eq!(op, "HardSigmoid");
            assert_eq!(node, want);
        }
        e => panic!("expected UnsupportedOp, got {e}"),
    }
    // A supported op used in an unsupported way names the node and the reason.
    let mut m = pb::ModelProto::decode(&*card_bytes()).unwrap();
    let conv = m
        .graph
        .as_mut()
        .unwrap()
        .node
        .iter_mut()
        .find(|n| n.op_type == "Conv")
        .unwrap();
    conv.attribute
        .iter_mut()
        .find(|a| a.name == "group")
        .unwrap()
        .i = 2;
    let e = lower_proto(&m).unwrap_err();
    assert!(
        matches!(e, ModelError::Lowering { ref op, .. } if op == "Conv"),
        "{e}"
    );
    assert!(e.to_string().contains("grouped"), "{e}");
}
