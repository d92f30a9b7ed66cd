//! COBS framing: resynchronisation after corruption, oversized frames, chunked input.

mod common;

use common::*;
use dips_wire::framing::cobs_decode_in_place;
use dips_wire::*;
use proptest::prelude::*;

fn hello(id: u32) -> (Frame<ToKernel>, Vec<u8>) {
    let body = ToKernel::Hello(Hello::current());
    (
        Frame {
            request_id: id,
            body: body.clone(),
        },
        encode(id, body),
    )
}

#[test]
fn cobs_decoder_matches_postcard_encoder() {
    for len in [0usize, 1, 253, 254, 255, 600] {
        let data: Vec<u8> = (0..len).map(|i| (i % 7) as u8).collect();
        let nonzero: Vec<u8> = (0..len).map(|i| (i % 255 + 1) as u8).collect();
        for payload in [data, nonzero] {
            let mut out = vec![0u8; len + len / 254 + 8];
            let encoded = postcard::to_slice_cobs(&payload.as_slice(), &mut out).unwrap();
            let mut body = encoded[..encoded.len() - 1].to_vec();
            let n = cobs_decode_in_place(&mut body).unwrap();
            let back: Vec<u8> = postcard::from_bytes::<&[u8]>(&body[..n]).unwrap().to_vec();
            assert_eq!(back, payload);
        }
    }
}

#[test]
fn invalid_cobs_is_rejected() {
    assert_eq!(cobs_decode_in_place(&mut [3, 1]), None); // block runs past the end
    assert_eq!(cobs_decode_in_place(&mut [2, 0]), None); // zero inside
}

#[test]
fn corrupted_frame_costs_only_itself() {
    let (f1, b1) = hello(1);
    let (_, mut b2) = hello(2);
    let (f3, b3) = hello(3);
    // Break frame 2's COBS structure: its first code byte now points past the end.
    b2[0] = 0xFE;
    let stream: Vec<u8> = [b1, b2, b3].concat();
    for chunk in [1usize, 2, 5, 64, 4096] {
        let out = deframe::<ToKernel>(&stream, &[chunk]);
        assert_eq!(out.len(), 3, "chunk {chunk}: {out:?}");
        assert_eq!(out[0], Ok(f1.clone()));
        assert_eq!(out[1], Err(WireError::BadFrame));
        assert_eq!(out[2], Ok(f3.clone()));
    }
}

#[test]
fn garbage_payload_is_decode_failed_with_request_id() {
    let (_, bytes) = hello(77);
    let mut payload = bytes[..bytes.len() - 1].to_vec();
    let n = cobs_decode_in_place(&mut payload).unwrap();
    let mut long = payload[..n].to_vec();
    long.push(0x55); // trailing byte
    let err = decode_frame::<ToKernel>(&long).unwrap_err();
    assert_eq!(err.request_id, Some(77));
    assert_eq!(err.error, WireError::DecodeFailed);
}

#[test]
fn unknown_variant_is_unknown_request() {
    // request id 9, variant tag 42, then anything.
    let err = decode_frame::<ToKernel>(&[9, 42, 1, 2, 3]).unwrap_err();
    assert_eq!(err.request_id, Some(9));
    assert_eq!(err.error, WireError::UnknownRequest { tag: 42 });
    assert_eq!(
        decode_frame::<ToKernel>(&[]).unwrap_err(),
        DecodeError {
            request_id: None,
            error: WireError::DecodeFailed
        }
    );
}

#[test]
fn oversized_frame_is_too_long_and_stream_recovers() {
    let (f1, b1) = hello(1);
    let junk = vec![0x11u8; MAX_ENCODED_FRAME_LEN * 3];
    let stream: Vec<u8> = [junk, vec![0], b1].concat();
    for chunk in [1usize, 100, 100_000] {
        let out = deframe::<ToKernel>(&stream, &[chunk]);
        assert_eq!(out.len(), 2, "{out:?}");
        assert_eq!(
            out[0],
            Err(WireError::TooLong {
                len_bytes: (MAX_ENCODED_FRAME_LEN * 3 + 1) as u32,
                max_bytes: MAX_ENCODED_FRAME_LEN as u32
            })
        );
        assert_eq!(out[1], Ok(f1.clone()));
    }
}

#[test]
fn leading_and_repeated_delimiters_are_ignored() {
    let (f1, b1) = hello(5);
    let stream: Vec<u8> = [vec![0, 0, 0], b1.clone(), vec![0, 0], b1].concat();
    let out = deframe::<ToKernel>(&stream, &[3]);
    assert_eq!(out, vec![Ok(f1.clone()), Ok(f1)]);
}

#[test]
fn encode_into_small_buffer_is_an_error() {
    let mut small = [0u8; 4];
    let frame = Frame {
        request_id: 1,
        body: ToKernel::Hello(Hello::current()),
    };
    // Hello: id 1, tag 0, version 1, the schema key's varint (9 or 10 bytes, depending on
    // the key); COBS adds 1 (frames this short), the delimiter 1.
    let payload = 3 + dips_wire::size::varint_len(SCHEMA_KEY);
    assert_eq!(
        encode_frame(&frame, &mut small),
        Err(WireError::TooLong {
            len_bytes: payload as u32 + 2,
            max_bytes: 4
        })
    );
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Good frames with one corrupted frame (random bytes overwritten, delimiters kept) in
    /// the middle, fed in random chunk sizes: every good frame still decodes, and the
    /// corrupted one produces at most its own outcomes.
    #[test]
    fn one_corrupt_frame_among_good_ones(
        before in proptest::collection::vec((any::<u32>(), to_kernel()), 0..4),
        bad in to_kernel(),
        after in proptest::collection::vec((any::<u32>(), to_kernel()), 0..4),
        flips in proptest::collection::vec((any::<usize>(), 1u8..=255), 1..6),
        chunks in proptest::collection::vec(1usize..300, 1..6),
    ) {
        let mut bad_bytes = encode(0xBAD, bad);
        let body_len = bad_bytes.len() - 1;
        for (pos, value) in flips {
            bad_bytes[pos % body_len] = value; // nonzero: the frame boundary survives
        }
        let mut stream = Vec::new();
        for (id, m) in &before { stream.extend(encode(*id, m.clone())); }
        stream.extend(&bad_bytes);
        for (id, m) in &after { stream.extend(encode(*id, m.clone())); }
        let out = deframe::<ToKernel>(&stream, &chunks);
        // Exactly one outcome per frame: the corrupted frame yields one (error or a frame).
        prop_assert_eq!(out.len(), before.len() + 1 + after.len());
        for (i, (id, m)) in before.iter().enumerate() {
            prop_assert_eq!(&out[i], &Ok(Frame { request_id: *id, body: m.clone() }));
        }
        for (i, (id, m)) in after.iter().enumerate() {
            prop_assert_eq!(&out[before.len() + 1 + i], &Ok(Frame { request_id: *id, body: m.clone() }));
        }
    }
}
