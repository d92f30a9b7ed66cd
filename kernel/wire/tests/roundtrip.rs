//! Every message round-trips through postcard + COBS, and hostile bytes never panic.

mod common;

use common::*;
use dips_wire::size::MaxSize;
use dips_wire::*;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 512,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn to_kernel_round_trips(id in any::<u32>(), msg in to_kernel()) {
        let bytes = encode(id, msg.clone());
        prop_assert!(bytes.len() <= MAX_ENCODED_FRAME_LEN);
        let frames = deframe::<ToKernel>(&bytes, &[bytes.len()]);
        prop_assert_eq!(frames, vec![Ok(Frame { request_id: id, body: msg })]);
    }

    #[test]
    fn from_kernel_round_trips(id in any::<u32>(), msg in from_kernel()) {
        let bytes = encode(id, msg.clone());
        prop_assert!(bytes.len() <= MAX_ENCODED_FRAME_LEN);
        let frames = deframe::<FromKernel>(&bytes, &[bytes.len()]);
        prop_assert_eq!(frames, vec![Ok(Frame { request_id: id, body: msg })]);
    }

    /// Any float bit pattern (NaN payloads included) survives the trip bit for bit.
    #[test]
    fn float_bits_survive(bits in proptest::collection::vec(any::<u32>(), 0..=MAX_STATE_DIM)) {
        let floats: std::vec::Vec<f32> = bits.iter().map(|&b| f32::from_bits(b)).collect();
        let msg = ToKernel::PlanRequest(PlanRequest {
            task: Task::Card,
            start_state: heapless::Vec::from_slice(&floats).unwrap(),
            goal: f32::from_bits(bits.first().copied().unwrap_or(0)),
            settings: SearchSettings::default(),
            previous_mode: None,
            card_goals: Default::default(),
            first_modes: 0b1111,
        });
        let bytes = encode(1, msg);
        let frames = deframe::<ToKernel>(&bytes, &[3]);
        let Ok(Frame { body: ToKernel::PlanRequest(back), .. }) = &frames[0] else {
            panic!("did not decode: {frames:?}");
        };
        let back_bits: std::vec::Vec<u32> = back.start_state.iter().map(|f| f.to_bits()).collect();
        prop_assert_eq!(back_bits, bits);
    }

    /// Arbitrary payloads never panic the decoder, in either direction.
    #[test]
    fn arbitrary_payload_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..700)) {
        let _ = decode_frame::<ToKernel>(&bytes);
        let _ = decode_frame::<FromKernel>(&bytes);
    }

    /// Arbitrary byte streams in arbitrary chunkings never panic the accumulator, and every
    /// outcome is a frame or a typed error.
    #[test]
    fn arbitrary_stream_never_panics(
        bytes in proptest::collection::vec(any::<u8>(), 0..3000),
        chunks in proptest::collection::vec(1usize..700, 1..8),
    ) {
        let _ = deframe::<ToKernel>(&bytes, &chunks);
        let _ = deframe::<FromKernel>(&bytes, &chunks);
    }
}

#[test]
fn max_sizes_are_bounds() {
    // The largest messages, encoded, fit the computed bounds.
    let big_chunk = ToKernel::ModelChunk(ModelChunk {
        offset_bytes: u32::MAX,
        bytes: heapless::Vec::from_slice(&[0u8; MODEL_CHUNK_LEN]).unwrap(),
    });
    let big_request = ToKernel::PlanRequest(PlanRequest {
        task: Task::Screwdriver,
        start_state: heapless::Vec::from_slice(&[f32::MAX; MAX_STATE_DIM]).unwrap(),
        goal: 1.0,
        settings: SearchSettings {
            seed: u64::MAX,
            node_budget: u32::MAX,
            time_budget_ms: u32::MAX,
            k: u16::MAX,
            ..SearchSettings::default()
        },
        previous_mode: Some(u8::MAX),
        card_goals: Default::default(),
        first_modes: 0b111,
    });
    for msg in [big_chunk, big_request] {
        let mut buf = [0u8; 4096];
        let plain = postcard::to_slice(
            &Frame {
                request_id: u32::MAX,
                body: msg.clone(),
            },
            &mut buf,
        )
        .unwrap();
        assert!(plain.len() <= Frame::<ToKernel>::POSTCARD_MAX_SIZE);
        assert!(encode(u32::MAX, msg).len() <= MAX_ENCODED_FRAME_LEN);
    }
    // All-0xFF payload bytes make COBS grow the most.
    let worst = ToKernel::ModelChunk(ModelChunk {
        offset_bytes: u32::MAX,
        bytes: heapless::Vec::from_slice(&[0xFFu8; MODEL_CHUNK_LEN]).unwrap(),
    });
    assert!(encode(u32::MAX, worst).len() <= MAX_ENCODED_FRAME_LEN);
}
