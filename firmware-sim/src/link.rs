//! [`serve`]: the firmware's byte link, with cancellation while a plan runs.
//!
//! A reader thread moves whatever arrives on the input into a channel; the serving loop keeps
//! the bytes it has not yet framed in [`Inbox`] and answers one frame at a time. While a plan
//! runs, the planner asks its clock before every expansion whether to stop; the clock drains
//! the channel into the inbox (never blocking) and looks for a `Cancel` frame among the frames
//! that arrived before the next `PlanRequest`. Those frames stay in the inbox and are answered
//! in order once the plan's reply is out, the `Cancel` itself with `Applied`. On the
//! controller the same role falls to the UART's receive interrupt filling a ring buffer.

use std::io::{self, Read, Write};
use std::sync::mpsc::{Receiver, TryRecvError, sync_channel};

use dips_kernel::budget::Clock;
use dips_wire::{
    Feed, Frame, FrameAccumulator, FromKernel, MAX_ENCODED_FRAME_LEN, NO_REQUEST_ID, ToKernel,
    decode_frame, encode_frame,
};

use crate::{Firmware, MonotonicClock};

/// Bytes read per call on the input.
const READ_CHUNK_LEN: usize = 256;
/// Chunks the reader may run ahead of the serving loop.
const CHANNEL_CHUNKS: usize = 1024;

/// Counts of one [`serve`] call (one connection).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ServeStats {
    /// Frames decoded into a request.
    pub requests: u64,
    /// Frames refused (bad COBS, too long, undecodable, unknown variant).
    pub bad_frames: u64,
    /// Replies written.
    pub replies: u64,
}

/// What the reader thread sends: bytes, the end of the input, or a read error.
#[derive(Debug)]
enum Chunk {
    Bytes(Vec<u8>),
    End,
    Failed(io::Error),
}

/// Bytes received and not yet framed, and the channel more arrive on (opaque outside
/// [`serve`]).
#[derive(Debug)]
pub struct Inbox {
    rx: Receiver<Chunk>,
    bytes: Vec<u8>,
    /// The input ended (or failed, with the error kept for the serving loop).
    ended: bool,
    failure: Option<io::Error>,
}

impl Inbox {
    fn take(&mut self, chunk: Chunk) {
        match chunk {
            Chunk::Bytes(b) => self.bytes.extend_from_slice(&b),
            Chunk::End => self.ended = true,
            Chunk::Failed(e) => {
                self.ended = true;
                self.failure = Some(e);
            }
        }
    }

    /// Wait for more bytes; `false` once the input has ended.
    fn fill(&mut self) -> bool {
        if self.ended {
            return false;
        }
        match self.rx.recv() {
            Ok(chunk) => self.take(chunk),
            Err(_) => self.ended = true,
        }
        !self.bytes.is_empty() || !self.ended
    }

    /// Take whatever has arrived, without waiting.
    fn drain(&mut self) {
        while !self.ended {
            match self.rx.try_recv() {
                Ok(chunk) => self.take(chunk),
                Err(TryRecvError::Empty) => return,
                Err(TryRecvError::Disconnected) => self.ended = true,
            }
        }
    }

    /// Whether a `Cancel` frame arrived before the next `PlanRequest` (frames are decoded on
    /// a scratch accumulator; the inbox is unchanged). The first bytes may be the tail of a
    /// frame already begun: that piece is dropped like any broken frame.
    fn holds_cancel(&self) -> bool {
        let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
        let mut window = &self.bytes[..];
        loop {
            match acc.feed(window) {
                Feed::Consumed => return false,
                Feed::Error { remaining, .. } => window = remaining,
                Feed::Frame { payload, remaining } => {
                    match decode_frame::<ToKernel>(payload) {
                        Ok(Frame {
                            body: ToKernel::Cancel,
                            ..
                        }) => return true,
                        Ok(Frame {
                            body: ToKernel::PlanRequest(_),
                            ..
                        }) => return false,
                        _ => {}
                    }
                    window = remaining;
                }
            }
        }
    }
}

/// The planner's clock while serving: the firmware's monotonic clock, and the link's cancel.
#[derive(Debug)]
pub struct LinkClock<'a> {
    clock: MonotonicClock,
    inbox: &'a mut Inbox,
}

impl Clock for LinkClock<'_> {
    fn now_us(&mut self) -> u64 {
        self.clock.now_us()
    }

    fn cancelled(&mut self) -> bool {
        self.inbox.drain();
        self.inbox.holds_cancel()
    }
}

/// Serve `firmware` over a byte stream until the input ends: deframe, decode, answer one
/// frame per input frame, flush after each reply, keep serving after any bad frame. A
/// `Cancel` that arrives while a plan runs stops it at its next expansion.
pub fn serve<R: Read + Send, W: Write>(
    firmware: &mut Firmware<'_>,
    mut reader: R,
    mut writer: W,
) -> io::Result<ServeStats> {
    let (tx, rx) = sync_channel::<Chunk>(CHANNEL_CHUNKS);
    std::thread::scope(|scope| {
        scope.spawn(move || {
            let mut buf = [0u8; READ_CHUNK_LEN];
            loop {
                let chunk = match reader.read(&mut buf) {
                    Ok(0) => Chunk::End,
                    Ok(n) => Chunk::Bytes(buf[..n].to_vec()),
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(e) => Chunk::Failed(e),
                };
                let last = !matches!(chunk, Chunk::Bytes(_));
                if tx.send(chunk).is_err() || last {
                    return;
                }
            }
        });
        let mut inbox = Inbox {
            rx,
            bytes: Vec::new(),
            ended: false,
            failure: None,
        };
        let result = serve_inbox(firmware, &mut inbox, &mut writer);
        // Dropping the receiver ends the reader at its next chunk.
        drop(inbox);
        result
    })
}

fn serve_inbox<W: Write>(
    firmware: &mut Firmware<'_>,
    inbox: &mut Inbox,
    writer: &mut W,
) -> io::Result<ServeStats> {
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut tx = [0u8; MAX_ENCODED_FRAME_LEN];
    let mut payload = [0u8; MAX_ENCODED_FRAME_LEN];
    let mut stats = ServeStats::default();
    let clock = MonotonicClock::new();
    loop {
        if inbox.bytes.is_empty() && !inbox.fill() {
            return match inbox.failure.take() {
                Some(e) => Err(e),
                None => Ok(stats),
            };
        }
        // Frame the inbox: the frame's payload is copied out so that the inbox can grow while
        // it is answered.
        let (consumed, frame) = {
            let window = &inbox.bytes[..];
            match acc.feed(window) {
                Feed::Consumed => (window.len(), None),
                Feed::Frame {
                    payload: p,
                    remaining,
                } => {
                    let n = p.len();
                    payload[..n].copy_from_slice(p);
                    (window.len() - remaining.len(), Some(Ok(n)))
                }
                Feed::Error { error, remaining } => {
                    (window.len() - remaining.len(), Some(Err(error)))
                }
            }
        };
        inbox.bytes.drain(..consumed);
        let reply = match frame {
            None => continue,
            Some(Ok(n)) => match decode_frame::<ToKernel>(&payload[..n]) {
                Ok(frame) => {
                    stats.requests += 1;
                    firmware.count_request();
                    let mut clock = LinkClock { clock, inbox };
                    Frame {
                        request_id: frame.request_id,
                        body: firmware.handle(frame.request_id, &frame.body, &mut clock),
                    }
                }
                Err(e) => {
                    stats.bad_frames += 1;
                    firmware.count_bad_frame();
                    Frame {
                        request_id: e.request_id.unwrap_or(NO_REQUEST_ID),
                        body: FromKernel::Error(e.error),
                    }
                }
            },
            Some(Err(error)) => {
                stats.bad_frames += 1;
                firmware.count_bad_frame();
                Frame {
                    request_id: NO_REQUEST_ID,
                    body: FromKernel::Error(error),
                }
            }
        };
        let bytes = encode_frame(&reply, &mut tx)
            .map_err(|e| io::Error::other(format!("reply does not fit a frame: {e}")))?;
        writer.write_all(bytes)?;
        writer.flush()?;
        stats.replies += 1;
        firmware.count_reply();
    }
}
