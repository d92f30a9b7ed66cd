//! COBS framing: encoding into a caller buffer, and a fixed-capacity accumulator that splits
//! an arbitrary byte stream into frames.
//!
//! Every encoded frame ends with a `0x00` delimiter and contains no other zero byte, so the
//! receiver resynchronises at the next delimiter after any corruption: a bad frame costs only
//! itself. Empty frames (consecutive delimiters) are ignored, so a sender may emit a leading
//! `0x00` to flush a half-received frame on the other side.

use serde::Serialize;

use crate::error::WireError;
use crate::messages::{Frame, FromKernel, Message, ToKernel};
use crate::size::{MaxSize, cobs_max_encoded_len, max};

/// Longest postcard-encoded frame (before COBS) in either direction.
pub const MAX_FRAME_LEN: usize = max(
    Frame::<ToKernel>::POSTCARD_MAX_SIZE,
    Frame::<FromKernel>::POSTCARD_MAX_SIZE,
);

/// Longest COBS-encoded frame in either direction, the `0x00` delimiter included: the buffer
/// size for [`encode_frame`] and the capacity for [`FrameAccumulator`].
pub const MAX_ENCODED_FRAME_LEN: usize = cobs_max_encoded_len(MAX_FRAME_LEN) + 1;

const _: () = assert!(MAX_ENCODED_FRAME_LEN <= u32::MAX as usize);
const _: () = assert!(
    MAX_ENCODED_FRAME_LEN < 1024,
    "frames must stay small for the MCU"
);

/// The request id of replies to frames whose own id could not be read (hosts number their
/// requests from 1).
pub const NO_REQUEST_ID: u32 = 0;

/// Encode `frame` (postcard, then COBS, then a `0x00` delimiter) into `out`; returns the
/// encoded bytes. Fails with [`WireError::TooLong`] (the frame's worst-case encoded length and
/// the buffer's length) when `out` is too small.
pub fn encode_frame<'o, B: Serialize>(
    frame: &Frame<B>,
    out: &'o mut [u8],
) -> Result<&'o mut [u8], WireError> {
    let out_len = out.len();
    postcard::to_slice_cobs(frame, out).map_err(|_| {
        let needed = postcard::experimental::serialized_size(frame).map_or(usize::MAX, |len| {
            cobs_max_encoded_len(len).saturating_add(1)
        });
        WireError::TooLong {
            len_bytes: u32::try_from(needed).unwrap_or(u32::MAX),
            max_bytes: u32::try_from(out_len).unwrap_or(u32::MAX),
        }
    })
}

/// Decode COBS in place; returns the decoded length, or `None` when `buf` is not valid COBS
/// (a zero byte, or a block running past the end).
pub fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    let mut read = 0;
    let mut write = 0;
    while read < buf.len() {
        let code = *buf.get(read)?;
        if code == 0 {
            return None;
        }
        read += 1;
        let run = usize::from(code) - 1;
        let block = buf.get(read..read + run)?;
        if block.contains(&0) {
            return None;
        }
        buf.copy_within(read..read + run, write);
        write += run;
        read += run;
        if code != 0xFF && read < buf.len() {
            *buf.get_mut(write)? = 0;
            write += 1;
        }
    }
    Some(write)
}

/// Why a received frame could not be decoded; carries the request id when it was readable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DecodeError {
    /// The frame's request id, if the payload got that far.
    pub request_id: Option<u32>,
    /// What was wrong.
    pub error: WireError,
}

/// Decode a COBS-decoded frame payload (as [`FrameAccumulator`] yields it).
///
/// Distinguishes an unknown variant ([`WireError::UnknownRequest`], a newer peer) from
/// garbage ([`WireError::DecodeFailed`]); trailing bytes after the message are garbage.
pub fn decode_frame<M: Message>(payload: &[u8]) -> Result<Frame<M>, DecodeError> {
    let failed = |request_id| DecodeError {
        request_id,
        error: WireError::DecodeFailed,
    };
    let (request_id, rest) = postcard::take_from_bytes::<u32>(payload).map_err(|_| failed(None))?;
    let (tag, _) = postcard::take_from_bytes::<u32>(rest).map_err(|_| failed(Some(request_id)))?;
    if tag >= M::VARIANT_COUNT {
        return Err(DecodeError {
            request_id: Some(request_id),
            error: WireError::UnknownRequest { tag },
        });
    }
    match postcard::take_from_bytes::<M>(rest) {
        Ok((body, [])) => Ok(Frame { request_id, body }),
        _ => Err(failed(Some(request_id))),
    }
}

/// What one call of [`FrameAccumulator::feed`] produced.
#[derive(Debug, PartialEq, Eq)]
pub enum Feed<'buf, 'input> {
    /// All input was consumed without completing a frame.
    Consumed,
    /// A complete frame: its COBS-decoded payload, and the input not yet consumed.
    Frame {
        /// The decoded payload (pass it to [`decode_frame`]).
        payload: &'buf [u8],
        /// Input after the frame's delimiter; feed it next.
        remaining: &'input [u8],
    },
    /// A frame was dropped ([`WireError::BadFrame`] or [`WireError::TooLong`]).
    Error {
        /// Why it was dropped.
        error: WireError,
        /// Input after the frame's delimiter; feed it next.
        remaining: &'input [u8],
    },
}

/// Splits a byte stream into frames, in a fixed buffer of `N` bytes.
///
/// Feed it byte chunks of any size; each call stops after the first complete (or dropped)
/// frame and hands back the unconsumed input. A frame longer than `N` encoded bytes is
/// discarded up to its delimiter and reported as [`WireError::TooLong`].
#[derive(Debug)]
pub struct FrameAccumulator<const N: usize> {
    buf: [u8; N],
    len: usize,
    /// Bytes of the current frame that did not fit.
    dropped: usize,
}

impl<const N: usize> Default for FrameAccumulator<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameAccumulator<N> {
    /// An empty accumulator.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            dropped: 0,
        }
    }

    /// Bytes of an unfinished frame held now.
    pub fn pending_len(&self) -> usize {
        self.len + self.dropped
    }

    /// Forget any unfinished frame.
    pub fn reset(&mut self) {
        self.len = 0;
        self.dropped = 0;
    }

    /// Consume `input` up to and including the first frame delimiter.
    pub fn feed<'me, 'input>(&'me mut self, mut input: &'input [u8]) -> Feed<'me, 'input> {
        loop {
            let Some(end) = input.iter().position(|&b| b == 0) else {
                self.push(input);
                return Feed::Consumed;
            };
            let (body, rest) = input.split_at(end);
            let remaining = rest.get(1..).unwrap_or(&[]);
            self.push(body);
            let (len, dropped) = (self.len, self.dropped);
            self.reset();
            if dropped > 0 {
                // Encoded length plus the delimiter, as `MAX_ENCODED_FRAME_LEN` counts it.
                let total = (len + dropped).saturating_add(1);
                return Feed::Error {
                    error: WireError::TooLong {
                        len_bytes: u32::try_from(total).unwrap_or(u32::MAX),
                        max_bytes: u32::try_from(N).unwrap_or(u32::MAX),
                    },
                    remaining,
                };
            }
            if len == 0 {
                // An empty frame: a resynchronising delimiter. Keep going.
                input = remaining;
                continue;
            }
            let frame = self.buf.get_mut(..len).unwrap_or(&mut []);
            return match cobs_decode_in_place(frame) {
                Some(decoded) => Feed::Frame {
                    payload: frame.get(..decoded).unwrap_or(&[]),
                    remaining,
                },
                None => Feed::Error {
                    error: WireError::BadFrame,
                    remaining,
                },
            };
        }
    }

    fn push(&mut self, bytes: &[u8]) {
        // N counts the delimiter too, so at most N - 1 encoded bytes are kept.
        let room = N.saturating_sub(1).saturating_sub(self.len);
        if self.dropped == 0
            && bytes.len() <= room
            && let Some(dest) = self.buf.get_mut(self.len..self.len + bytes.len())
        {
            dest.copy_from_slice(bytes);
            self.len += bytes.len();
            return;
        }
        self.dropped = self.dropped.saturating_add(bytes.len());
    }
}
