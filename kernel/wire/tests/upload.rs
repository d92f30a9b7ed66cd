//! Model upload: assembler happy path and every refusal.

use dips_wire::*;
use heapless::Vec;

fn blob(len: usize) -> std::vec::Vec<u8> {
    (0..len).map(|i| (i * 31 % 251) as u8).collect()
}

fn feed_all(
    asm: &mut ModelAssembler<'_>,
    model: &[u8],
    role: ModelRole,
) -> Result<ModelLoaded, UploadError> {
    let mut last = None;
    for msg in upload_messages(role, model).unwrap() {
        match msg {
            ToKernel::ModelBegin(b) => {
                asm.begin(&b)?;
            }
            ToKernel::ModelChunk(c) => {
                let ack = asm.chunk(&c)?;
                assert_eq!(ack.received_bytes, c.offset_bytes + c.bytes.len() as u32);
            }
            ToKernel::ModelEnd => last = Some(asm.end()?),
            other => panic!("unexpected {other:?}"),
        }
    }
    Ok(last.expect("upload ends"))
}

#[test]
fn crc32_is_the_standard_one() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
}

#[test]
fn happy_path_assembles_exact_bytes() {
    for len in [0usize, 1, MODEL_CHUNK_LEN, MODEL_CHUNK_LEN + 1, 5000] {
        let model = blob(len);
        let mut buf = vec![0u8; 6000];
        let mut asm = ModelAssembler::new(&mut buf);
        let loaded = feed_all(&mut asm, &model, ModelRole::Denoiser).unwrap();
        assert_eq!(loaded.len_bytes as usize, len);
        assert_eq!(loaded.crc32, crc32(&model));
        let (role, bytes) = asm.model().unwrap();
        assert_eq!(role, ModelRole::Denoiser);
        assert_eq!(bytes, &model[..]);
        assert_eq!(asm.model_crc32(), Some(crc32(&model)));
    }
}

#[test]
fn bad_crc_is_refused() {
    let model = blob(1500);
    let mut buf = vec![0u8; 2000];
    let mut asm = ModelAssembler::new(&mut buf);
    let mut msgs: std::vec::Vec<ToKernel> = upload_messages(ModelRole::Discriminator, &model)
        .unwrap()
        .collect();
    // Flip one payload byte in the second chunk.
    if let ToKernel::ModelChunk(c) = &mut msgs[2] {
        c.bytes[10] ^= 0x40;
    }
    let mut result = None;
    for m in msgs {
        match m {
            ToKernel::ModelBegin(b) => drop(asm.begin(&b).unwrap()),
            ToKernel::ModelChunk(c) => drop(asm.chunk(&c).unwrap()),
            ToKernel::ModelEnd => result = Some(asm.end()),
            _ => unreachable!(),
        }
    }
    let mut corrupted = model.clone();
    corrupted[MODEL_CHUNK_LEN + 10] ^= 0x40;
    assert_eq!(
        result.unwrap(),
        Err(UploadError::CrcMismatch {
            expected_crc32: crc32(&model),
            computed_crc32: crc32(&corrupted),
        })
    );
    assert!(asm.model().is_none());
}

#[test]
fn bad_offset_is_refused_and_resend_works() {
    let model = blob(1024);
    let mut buf = vec![0u8; 1024];
    let mut asm = ModelAssembler::new(&mut buf);
    asm.begin(&ModelBegin {
        role: ModelRole::Denoiser,
        total_len_bytes: 1024,
        crc32: crc32(&model),
    })
    .unwrap();
    let chunk = |offset: usize| ModelChunk {
        offset_bytes: offset as u32,
        bytes: Vec::from_slice(&model[offset..offset + 512]).unwrap(),
    };
    assert_eq!(
        asm.chunk(&chunk(512)),
        Err(UploadError::BadOffset {
            expected_offset_bytes: 0,
            got_offset_bytes: 512
        })
    );
    asm.chunk(&chunk(0)).unwrap();
    // A duplicate of the first chunk is refused too.
    assert_eq!(
        asm.chunk(&chunk(0)),
        Err(UploadError::BadOffset {
            expected_offset_bytes: 512,
            got_offset_bytes: 0
        })
    );
    asm.chunk(&chunk(512)).unwrap();
    assert!(asm.end().is_ok());
    assert_eq!(asm.model().unwrap().1, &model[..]);
}

#[test]
fn overflow_and_too_large_are_refused() {
    let mut buf = vec![0u8; 600];
    let mut asm = ModelAssembler::new(&mut buf);
    assert_eq!(
        asm.begin(&ModelBegin {
            role: ModelRole::Denoiser,
            total_len_bytes: 601,
            crc32: 0
        }),
        Err(UploadError::TooLarge {
            total_len_bytes: 601,
            capacity_bytes: 600
        })
    );
    asm.begin(&ModelBegin {
        role: ModelRole::Denoiser,
        total_len_bytes: 100,
        crc32: 0,
    })
    .unwrap();
    let chunk = ModelChunk {
        offset_bytes: 0,
        bytes: Vec::from_slice(&[1u8; 101]).unwrap(),
    };
    assert_eq!(
        asm.chunk(&chunk),
        Err(UploadError::Overflow {
            end_offset_bytes: 101,
            total_len_bytes: 100
        })
    );
}

#[test]
fn incomplete_and_unstarted_are_refused() {
    let mut buf = vec![0u8; 600];
    let mut asm = ModelAssembler::new(&mut buf);
    let chunk = ModelChunk {
        offset_bytes: 0,
        bytes: Vec::from_slice(&[1u8; 10]).unwrap(),
    };
    assert_eq!(asm.chunk(&chunk), Err(UploadError::NotStarted));
    assert_eq!(asm.end(), Err(UploadError::NotStarted));
    asm.begin(&ModelBegin {
        role: ModelRole::Denoiser,
        total_len_bytes: 20,
        crc32: 0,
    })
    .unwrap();
    asm.chunk(&chunk).unwrap();
    assert_eq!(
        asm.end(),
        Err(UploadError::Incomplete {
            received_bytes: 10,
            total_len_bytes: 20
        })
    );
    // A failed end discards the upload.
    assert!(!asm.is_receiving());
    assert_eq!(asm.end(), Err(UploadError::NotStarted));
}

#[test]
fn errors_display_their_numbers() {
    let e = WireError::Upload(UploadError::BadOffset {
        expected_offset_bytes: 512,
        got_offset_bytes: 0,
    });
    let text = e.to_string();
    assert!(text.contains("512") && text.contains("offset"), "{text}");
    assert!(core::error::Error::source(&e).is_some());
}

mod assembler_properties {
    use dips_wire::*;
    use heapless::Vec;
    use proptest::prelude::*;

    #[derive(Debug, Clone)]
    enum Step {
        Begin { total: u32, crc: u32 },
        Chunk { offset: u32, len: usize, fill: u8 },
        End,
    }

    fn step() -> impl Strategy<Value = Step> {
        prop_oneof![
            (0u32..3000, any::<u32>()).prop_map(|(total, crc)| Step::Begin { total, crc }),
            (0u32..3000, 0usize..=MODEL_CHUNK_LEN, any::<u8>())
                .prop_map(|(offset, len, fill)| Step::Chunk { offset, len, fill }),
            Just(Step::End),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 512,
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        /// Any sequence of steps: no panic, acks count exactly the accepted bytes, and a
        /// model is reported only after an end whose CRC matched the bytes stored.
        #[test]
        fn random_steps_keep_the_invariants(steps in proptest::collection::vec(step(), 0..40)) {
            let mut buf = vec![0u8; 2048];
            let mut asm = ModelAssembler::new(&mut buf);
            let mut expected: Option<(u32, u32, u32)> = None; // (total, crc, received)
            for s in steps {
                match s {
                    Step::Begin { total, crc } => {
                        let r = asm.begin(&ModelBegin { role: ModelRole::Denoiser, total_len_bytes: total, crc32: crc });
                        prop_assert_eq!(r.is_ok(), total <= 2048);
                        expected = r.ok().map(|_| (total, crc, 0));
                        prop_assert!(asm.model().is_none());
                    }
                    Step::Chunk { offset, len, fill } => {
                        let chunk = ModelChunk { offset_bytes: offset, bytes: Vec::from_slice(&vec![fill; len]).unwrap() };
                        let r = asm.chunk(&chunk);
                        match &mut expected {
                            None => prop_assert_eq!(r, Err(UploadError::NotStarted)),
                            Some((total, _, received)) => {
                                let fits = offset == *received && offset as usize + len <= *total as usize;
                                prop_assert_eq!(r.is_ok(), fits, "{:?}", r);
                                if fits {
                                    *received += len as u32;
                                    prop_assert_eq!(r.unwrap().received_bytes, *received);
                                }
                            }
                        }
                    }
                    Step::End => {
                        let r = asm.end();
                        match expected.take() {
                            None => prop_assert_eq!(r, Err(UploadError::NotStarted)),
                            Some((total, crc, received)) => {
                                if received != total {
                                    prop_assert!(matches!(r, Err(UploadError::Incomplete { .. })), "{:?}", r);
                                } else if let Ok(loaded) = r {
                                    prop_assert_eq!(loaded.crc32, crc);
                                    let (_, bytes) = asm.model().unwrap();
                                    prop_assert_eq!(crc32(bytes), crc);
                                    prop_assert_eq!(bytes.len(), total as usize);
                                } else {
                                    prop_assert!(matches!(r, Err(UploadError::CrcMismatch { .. })), "{:?}", r);
                                    prop_assert!(asm.model().is_none());
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}
