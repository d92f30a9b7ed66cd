//! Helpers shared by the firmware-sim integration tests.
#![allow(dead_code)]

use dips_wire::{Frame, MAX_ENCODED_FRAME_LEN, ToKernel, encode_frame};

/// One request as the host sends it: postcard + COBS + the `0x00` delimiter.
pub(crate) fn frame_bytes(request_id: u32, body: ToKernel) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED_FRAME_LEN];
    encode_frame(&Frame { request_id, body }, &mut buf)
        .unwrap()
        .to_vec()
}
