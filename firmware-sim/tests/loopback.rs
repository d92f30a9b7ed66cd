//! The firmware served in-process over byte buffers: bytes in, bytes out.

mod common;

use std::io::Read;

use common::frame_bytes;
use dips_firmware_sim::{FirmwareMemory, ServeStats, serve};
use dips_wire::*;

/// A reader that hands out its bytes in small pieces of varying size.
struct Trickle<'a> {
    data: &'a [u8],
    step: usize,
}

impl Read for Trickle<'_> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        self.step = self.step % 7 + 1;
        let n = self.step.min(out.len()).min(self.data.len());
        out[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        Ok(n)
    }
}

fn replies(bytes: &[u8]) -> Vec<Frame<FromKernel>> {
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut out = Vec::new();
    let mut window = bytes;
    loop {
        match acc.feed(window) {
            Feed::Consumed => break,
            Feed::Frame { payload, remaining } => {
                out.push(decode_frame::<FromKernel>(payload).expect("kernel replies decode"));
                window = remaining;
            }
            Feed::Error { error, .. } => panic!("kernel sent a bad frame: {error}"),
        }
    }
    assert_eq!(
        acc.pending_len(),
        0,
        "kernel output ends with a whole frame"
    );
    out
}

fn run(input: &[u8], model_capacity: usize, trickle: bool) -> (Vec<Frame<FromKernel>>, ServeStats) {
    let mut memory = FirmwareMemory::models(model_capacity);
    let mut fw = memory.firmware();
    let mut output = Vec::new();
    let stats = if trickle {
        serve(
            &mut fw,
            Trickle {
                data: input,
                step: 0,
            },
            &mut output,
        )
        .unwrap()
    } else {
        serve(&mut fw, input, &mut output).unwrap()
    };
    (replies(&output), stats)
}

fn plan_request() -> ToKernel {
    ToKernel::PlanRequest(PlanRequest {
        task: Task::Card,
        start_state: heapless::Vec::from_slice(&[0.1; 12]).unwrap(),
        goal: -0.06,
        settings: SearchSettings::default(),
        previous_mode: None,
        card_goals: Default::default(),
        first_modes: 0b1111,
    })
}

fn body_of(reply: &Frame<FromKernel>) -> &FromKernel {
    &reply.body
}

#[test]
fn session_with_uploads_and_garbage() {
    let denoiser: Vec<u8> = (0..3000u32).map(|i| (i * 7 % 256) as u8).collect();
    let discriminator: Vec<u8> = (0..700u32).map(|i| (i * 13 % 256) as u8).collect();
    let mut input = Vec::new();
    let mut expected_ids = Vec::new();
    let mut push = |input: &mut Vec<u8>, id: u32, body: ToKernel| {
        input.extend(frame_bytes(id, body));
        expected_ids.push(id);
    };
    // Before the handshake: refused.
    push(&mut input, 1, plan_request());
    push(&mut input, 2, ToKernel::Hello(Hello::current()));
    // Garbage between good frames: random bytes then a delimiter.
    input.extend([0x13, 0x37, 0xFE, 0x01, 0x00]);
    push(&mut input, 3, plan_request());
    let mut id = 10;
    for msg in upload_messages(ModelRole::Denoiser, &denoiser).unwrap() {
        push(&mut input, id, msg);
        id += 1;
    }
    input.extend([0x00, 0x00]); // resync delimiters are ignored
    push(&mut input, 100, plan_request());
    for msg in upload_messages(ModelRole::Discriminator, &discriminator).unwrap() {
        push(&mut input, id, msg);
        id += 1;
    }
    push(&mut input, 101, plan_request());

    for trickle in [false, true] {
        let (out, stats) = run(&input, 4096, trickle);
        // One reply per good frame plus one for the garbage frame.
        assert_eq!(out.len(), expected_ids.len() + 1, "{out:#?}");
        assert_eq!(stats.bad_frames, 1);
        assert_eq!(stats.requests, expected_ids.len() as u64);
        assert_eq!(
            out[0],
            Frame {
                request_id: 1,
                body: FromKernel::Error(WireError::HandshakeRequired)
            }
        );
        assert!(matches!(
            body_of(&out[1]),
            FromKernel::HelloAck(HelloAck { protocol_version: PROTOCOL_VERSION, schema_key, .. })
                if *schema_key == SCHEMA_KEY
        ));
        // The garbage frame: its id could not be read.
        assert_eq!(out[2].request_id, NO_REQUEST_ID);
        assert!(matches!(body_of(&out[2]), FromKernel::Error(_)));
        assert_eq!(
            out[3].body,
            FromKernel::Error(WireError::ModelNotLoaded {
                role: ModelRole::Denoiser
            })
        );
        // Replies echo request ids in order.
        let ids: Vec<u32> = out
            .iter()
            .filter(|f| f.request_id != NO_REQUEST_ID)
            .map(|f| f.request_id)
            .collect();
        assert_eq!(ids, expected_ids);
        // The uploads arrive whole and CRC-checked, but they are not models: each is refused
        // at its end by the interpreter's checks and never becomes the model in use.
        let rejected: Vec<&FromKernel> = out
            .iter()
            .map(body_of)
            .filter(|b| matches!(b, FromKernel::Error(WireError::ModelRejected { .. })))
            .collect();
        assert_eq!(
            rejected,
            vec![
                &FromKernel::Error(WireError::ModelRejected {
                    role: ModelRole::Denoiser,
                    fault: ModelFault::Invalid
                }),
                &FromKernel::Error(WireError::ModelRejected {
                    role: ModelRole::Discriminator,
                    fault: ModelFault::Invalid
                }),
            ]
        );
        assert!(
            !out.iter()
                .any(|f| matches!(f.body, FromKernel::ModelLoaded(_)))
        );
        let acks = out
            .iter()
            .filter(|f| matches!(f.body, FromKernel::ModelAck(_)))
            .count();
        // Begin + 6 chunks for 3000 bytes, begin + 2 chunks for 700.
        assert_eq!(acks, 7 + 3);
        let plan_replies: Vec<&FromKernel> = out
            .iter()
            .filter(|f| f.request_id == 100 || f.request_id == 101)
            .map(body_of)
            .collect();
        assert_eq!(
            plan_replies,
            vec![
                &FromKernel::Error(WireError::ModelNotLoaded {
                    role: ModelRole::Denoiser
                }),
                &FromKernel::Error(WireError::ModelNotLoaded {
                    role: ModelRole::Denoiser
                }),
            ]
        );
    }
}

#[test]
fn version_mismatch_is_refused_and_session_recovers() {
    let mut input = frame_bytes(
        1,
        ToKernel::Hello(Hello {
            protocol_version: PROTOCOL_VERSION + 1,
            schema_key: SCHEMA_KEY,
        }),
    );
    input.extend(frame_bytes(2, ToKernel::ModelEnd));
    input.extend(frame_bytes(3, ToKernel::Hello(Hello::current())));
    input.extend(frame_bytes(4, ToKernel::ModelEnd));
    let (out, _) = run(&input, 1024, false);
    assert_eq!(
        out[0].body,
        FromKernel::Error(WireError::VersionMismatch {
            kernel_version: PROTOCOL_VERSION,
            host_version: PROTOCOL_VERSION + 1,
            kernel_schema_key: SCHEMA_KEY,
            host_schema_key: SCHEMA_KEY,
        })
    );
    assert_eq!(out[1].body, FromKernel::Error(WireError::HandshakeRequired));
    assert!(matches!(out[2].body, FromKernel::HelloAck(_)));
    assert_eq!(
        out[3].body,
        FromKernel::Error(WireError::Upload(UploadError::NotStarted))
    );
}

#[test]
fn upload_errors_are_answered_and_serving_continues() {
    let model = vec![5u8; 2000];
    let mut input = frame_bytes(1, ToKernel::Hello(Hello::current()));
    // Too large for a 1024-byte buffer.
    input.extend(frame_bytes(
        2,
        upload_messages(ModelRole::Denoiser, &model)
            .unwrap()
            .next()
            .unwrap(),
    ));
    // A corrupted upload: bad CRC announced.
    let small = vec![9u8; 600];
    let mut msgs: Vec<ToKernel> = upload_messages(ModelRole::Denoiser, &small)
        .unwrap()
        .collect();
    if let ToKernel::ModelBegin(b) = &mut msgs[0] {
        b.crc32 ^= 1;
    }
    for (i, m) in msgs.into_iter().enumerate() {
        input.extend(frame_bytes(10 + i as u32, m));
    }
    // An unknown request variant (a newer host): request id 50, tag 200 (varint c8 01).
    let mut raw = [0u8; 16];
    let n = postcard_cobs(&[50u8, 0xC8, 0x01, 0x01], &mut raw);
    input.extend(&raw[..n]);
    input.extend(frame_bytes(60, plan_request()));
    let (out, stats) = run(&input, 1024, true);
    assert_eq!(
        out[1].body,
        FromKernel::Error(WireError::Upload(UploadError::TooLarge {
            total_len_bytes: 2000,
            capacity_bytes: 1024
        }))
    );
    let end_reply = out.iter().find(|f| f.request_id == 13).unwrap();
    assert!(matches!(
        end_reply.body,
        FromKernel::Error(WireError::Upload(UploadError::CrcMismatch { .. }))
    ));
    let unknown = out.iter().find(|f| f.request_id == 50).unwrap();
    assert_eq!(
        unknown.body,
        FromKernel::Error(WireError::UnknownRequest { tag: 200 })
    );
    assert_eq!(stats.bad_frames, 1);
    let last = out.last().unwrap();
    assert_eq!(last.request_id, 60);
    assert_eq!(
        last.body,
        FromKernel::Error(WireError::ModelNotLoaded {
            role: ModelRole::Denoiser
        })
    );
}

/// COBS-encode raw payload bytes (plus the delimiter), for hand-made frames.
fn postcard_cobs(payload: &[u8], out: &mut [u8]) -> usize {
    // Simple COBS encoder: payloads here are short and contain no zero bytes.
    assert!(payload.len() < 254 && !payload.contains(&0));
    out[0] = payload.len() as u8 + 1;
    out[1..=payload.len()].copy_from_slice(payload);
    out[payload.len() + 1] = 0;
    payload.len() + 2
}

#[test]
fn invalid_plan_fields_are_named() {
    let mut input = frame_bytes(1, ToKernel::Hello(Hello::current()));
    let ToKernel::PlanRequest(mut bad) = plan_request() else {
        unreachable!()
    };
    bad.start_state.pop();
    input.extend(frame_bytes(2, ToKernel::PlanRequest(bad.clone())));
    bad.start_state.push(0.0).unwrap();
    bad.goal = f32::NAN;
    input.extend(frame_bytes(3, ToKernel::PlanRequest(bad.clone())));
    bad.goal = -1.0;
    bad.settings.k = 0;
    input.extend(frame_bytes(4, ToKernel::PlanRequest(bad.clone())));
    bad.settings.k = 16;
    // The card has modes 0..=3.
    bad.previous_mode = Some(4);
    input.extend(frame_bytes(5, ToKernel::PlanRequest(bad)));
    let (out, _) = run(&input, 16, false);
    for (i, field) in [
        (1, RequestField::StartState),
        (2, RequestField::Goal),
        (3, RequestField::Settings),
        (4, RequestField::PreviousMode),
    ] {
        assert_eq!(
            out[i].body,
            FromKernel::Error(WireError::InvalidRequest { field }),
            "reply {i}"
        );
    }
}

mod garbage {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 128,
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        /// Hello frames separated by arbitrary garbage (each garbage run ended by a delimiter):
        /// every Hello is answered with its own id, whatever the garbage and the read sizes.
        #[test]
        fn garbage_between_frames_costs_only_itself(
            garbage in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..200), 1..6),
        ) {
            let mut input = Vec::new();
            for (i, junk) in garbage.iter().enumerate() {
                input.extend(frame_bytes(i as u32 + 1, ToKernel::Hello(Hello::current())));
                input.extend(junk);
                input.push(0);
            }
            for trickle in [false, true] {
                let (out, _) = run(&input, 64, trickle);
                let acks: Vec<u32> = out
                    .iter()
                    .filter(|f| matches!(f.body, FromKernel::HelloAck(_)))
                    .map(|f| f.request_id)
                    .collect();
                let want: Vec<u32> = (1..=garbage.len() as u32).collect();
                prop_assert_eq!(acks, want);
            }
        }
    }
}
