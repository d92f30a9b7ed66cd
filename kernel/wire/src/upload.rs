//! Model upload in chunks, checked by length, offsets and CRC-32.
//!
//! The host sends [`ModelBegin`] (role, total length, CRC-32 of the whole blob), then
//! [`ModelChunk`]s in order, then `ModelEnd`; the kernel acknowledges each step. On the
//! kernel side a [`ModelAssembler`] writes the chunks into a caller-provided buffer and
//! checks every step.

use core::fmt;

use crc::{CRC_32_ISO_HDLC, Crc};
use heapless::Vec;
use serde::{Deserialize, Serialize};

use crate::messages::ToKernel;
use crate::size::{MaxSize, vec_max_size};

/// Most payload bytes in one [`ModelChunk`].
pub const MODEL_CHUNK_LEN: usize = 512;

/// The CRC used for uploads: CRC-32/ISO-HDLC (the zlib/PNG/Ethernet CRC-32).
const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// CRC-32/ISO-HDLC of `bytes` (the checksum [`ModelBegin::crc32`] carries).
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// Which model an upload carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum ModelRole {
    /// The ε-predicting diffusion model.
    Denoiser,
    /// The discriminator Ψ.
    Discriminator,
}

impl fmt::Display for ModelRole {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Denoiser => "denoiser",
            Self::Discriminator => "discriminator",
        })
    }
}

/// Start an upload (replaces any upload in progress).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct ModelBegin {
    /// The model being uploaded.
    pub role: ModelRole,
    /// Length of the whole blob in bytes.
    pub total_len_bytes: u32,
    /// CRC-32/ISO-HDLC of the whole blob.
    pub crc32: u32,
}

/// One piece of the blob.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ModelChunk {
    /// Offset of the first byte in the blob; chunks arrive in order without gaps.
    pub offset_bytes: u32,
    /// The bytes (at most [`MODEL_CHUNK_LEN`]).
    pub bytes: Vec<u8, MODEL_CHUNK_LEN>,
}

impl MaxSize for ModelChunk {
    const POSTCARD_MAX_SIZE: usize = u32::POSTCARD_MAX_SIZE + vec_max_size::<u8, MODEL_CHUNK_LEN>();
}

/// Acknowledges a [`ModelBegin`] or a [`ModelChunk`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct ModelAck {
    /// The model being uploaded.
    pub role: ModelRole,
    /// Bytes received so far (the offset the next chunk must have).
    pub received_bytes: u32,
    /// Length announced by [`ModelBegin`].
    pub total_len_bytes: u32,
}

/// Acknowledges a complete, CRC-checked upload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct ModelLoaded {
    /// The model now loaded.
    pub role: ModelRole,
    /// Its length in bytes.
    pub len_bytes: u32,
    /// Its CRC-32.
    pub crc32: u32,
}

/// Why an upload step was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
#[non_exhaustive]
pub enum UploadError {
    /// A chunk or end arrived with no upload in progress.
    NotStarted,
    /// The announced blob does not fit the receiver's buffer.
    TooLarge {
        /// Announced length.
        total_len_bytes: u32,
        /// Receiver's buffer size.
        capacity_bytes: u32,
    },
    /// A chunk did not start where the previous one ended.
    BadOffset {
        /// The offset the receiver expected.
        expected_offset_bytes: u32,
        /// The chunk's offset.
        got_offset_bytes: u32,
    },
    /// A chunk reaches past the announced length.
    Overflow {
        /// Where the chunk would end.
        end_offset_bytes: u32,
        /// Announced length.
        total_len_bytes: u32,
    },
    /// The upload ended before all announced bytes arrived.
    Incomplete {
        /// Bytes received.
        received_bytes: u32,
        /// Announced length.
        total_len_bytes: u32,
    },
    /// The received bytes do not have the announced CRC.
    CrcMismatch {
        /// CRC announced by `ModelBegin`.
        expected_crc32: u32,
        /// CRC of the bytes received.
        computed_crc32: u32,
    },
}

impl fmt::Display for UploadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::NotStarted => f.write_str("model chunk or end without a model begin"),
            Self::TooLarge {
                total_len_bytes,
                capacity_bytes,
            } => write!(
                f,
                "model of {total_len_bytes} bytes does not fit the {capacity_bytes}-byte buffer"
            ),
            Self::BadOffset {
                expected_offset_bytes,
                got_offset_bytes,
            } => write!(
                f,
                "model chunk at offset {got_offset_bytes}, expected offset {expected_offset_bytes}"
            ),
            Self::Overflow {
                end_offset_bytes,
                total_len_bytes,
            } => write!(
                f,
                "model chunk ends at byte {end_offset_bytes}, past the announced {total_len_bytes} bytes"
            ),
            Self::Incomplete {
                received_bytes,
                total_len_bytes,
            } => write!(
                f,
                "model upload ended after {received_bytes} of {total_len_bytes} bytes"
            ),
            Self::CrcMismatch {
                expected_crc32,
                computed_crc32,
            } => write!(
                f,
                "model CRC-32 is {computed_crc32:#010x}, expected {expected_crc32:#010x}"
            ),
        }
    }
}

impl core::error::Error for UploadError {}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum AssemblerState {
    Idle,
    Receiving {
        role: ModelRole,
        total: u32,
        crc: u32,
        received: u32,
    },
    Complete {
        role: ModelRole,
        len: u32,
        crc: u32,
    },
}

/// Receiver side of an upload: assembles chunks into a caller-provided buffer.
///
/// A refused step leaves the assembler as it was (a bad chunk can be re-sent), except that a
/// failed [`ModelAssembler::end`] discards the upload. A [`ModelAssembler::begin`] always
/// starts over, discarding any previous model.
#[derive(Debug)]
pub struct ModelAssembler<'a> {
    buf: &'a mut [u8],
    state: AssemblerState,
}

impl<'a> ModelAssembler<'a> {
    /// An idle assembler writing into `buf` (its length is the largest model accepted).
    pub fn new(buf: &'a mut [u8]) -> Self {
        Self {
            buf,
            state: AssemblerState::Idle,
        }
    }

    /// Largest model this assembler accepts, in bytes (saturating at `u32::MAX`).
    pub fn capacity_bytes(&self) -> u32 {
        u32::try_from(self.buf.len()).unwrap_or(u32::MAX)
    }

    /// Start an upload; returns the acknowledgement to send.
    pub fn begin(&mut self, begin: &ModelBegin) -> Result<ModelAck, UploadError> {
        self.state = AssemblerState::Idle;
        if begin.total_len_bytes as usize > self.buf.len() {
            return Err(UploadError::TooLarge {
                total_len_bytes: begin.total_len_bytes,
                capacity_bytes: self.capacity_bytes(),
            });
        }
        self.state = AssemblerState::Receiving {
            role: begin.role,
            total: begin.total_len_bytes,
            crc: begin.crc32,
            received: 0,
        };
        Ok(ModelAck {
            role: begin.role,
            received_bytes: 0,
            total_len_bytes: begin.total_len_bytes,
        })
    }

    /// Store one chunk; returns the acknowledgement to send.
    pub fn chunk(&mut self, chunk: &ModelChunk) -> Result<ModelAck, UploadError> {
        let AssemblerState::Receiving {
            role,
            total,
            crc,
            received,
        } = self.state
        else {
            return Err(UploadError::NotStarted);
        };
        if chunk.offset_bytes != received {
            return Err(UploadError::BadOffset {
                expected_offset_bytes: received,
                got_offset_bytes: chunk.offset_bytes,
            });
        }
        // The chunk length is at most MODEL_CHUNK_LEN, so this cannot truncate.
        let len = chunk.bytes.len() as u32;
        let end = u64::from(received) + u64::from(len);
        if end > u64::from(total) {
            return Err(UploadError::Overflow {
                end_offset_bytes: u32::try_from(end).unwrap_or(u32::MAX),
                total_len_bytes: total,
            });
        }
        let end = end as u32;
        let Some(dest) = self.buf.get_mut(received as usize..end as usize) else {
            // `begin` checked `total` against the buffer, so this is unreachable; answer it
            // as an overflow rather than panic.
            return Err(UploadError::Overflow {
                end_offset_bytes: end,
                total_len_bytes: total,
            });
        };
        dest.copy_from_slice(&chunk.bytes);
        self.state = AssemblerState::Receiving {
            role,
            total,
            crc,
            received: end,
        };
        Ok(ModelAck {
            role,
            received_bytes: end,
            total_len_bytes: total,
        })
    }

    /// Finish the upload: checks the length and the CRC.
    pub fn end(&mut self) -> Result<ModelLoaded, UploadError> {
        let AssemblerState::Receiving {
            role,
            total,
            crc,
            received,
        } = self.state
        else {
            return Err(UploadError::NotStarted);
        };
        self.state = AssemblerState::Idle;
        if received != total {
            return Err(UploadError::Incomplete {
                received_bytes: received,
                total_len_bytes: total,
            });
        }
        let computed = crc32(self.buf.get(..total as usize).unwrap_or(&[]));
        if computed != crc {
            return Err(UploadError::CrcMismatch {
                expected_crc32: crc,
                computed_crc32: computed,
            });
        }
        self.state = AssemblerState::Complete {
            role,
            len: total,
            crc,
        };
        Ok(ModelLoaded {
            role,
            len_bytes: total,
            crc32: crc,
        })
    }

    /// The role and bytes of the last complete upload, if the assembler holds one.
    pub fn model(&self) -> Option<(ModelRole, &[u8])> {
        match self.state {
            AssemblerState::Complete { role, len, .. } => {
                self.buf.get(..len as usize).map(|bytes| (role, bytes))
            }
            _ => None,
        }
    }

    /// The CRC-32 of the last complete upload.
    pub fn model_crc32(&self) -> Option<u32> {
        match self.state {
            AssemblerState::Complete { crc, .. } => Some(crc),
            _ => None,
        }
    }

    /// Whether an upload is in progress.
    pub fn is_receiving(&self) -> bool {
        matches!(self.state, AssemblerState::Receiving { .. })
    }
}

/// Sender side: the messages that upload `model` (begin, chunks, end), in order.
///
/// Returns `None` when the model is longer than `u32::MAX` bytes.
pub fn upload_messages(role: ModelRole, model: &[u8]) -> Option<UploadMessages<'_>> {
    let total_len_bytes = u32::try_from(model.len()).ok()?;
    Some(UploadMessages {
        begin: Some(ModelBegin {
            role,
            total_len_bytes,
            crc32: crc32(model),
        }),
        model,
        offset: 0,
        ended: false,
    })
}

/// Iterator returned by [`upload_messages`].
#[derive(Debug, Clone)]
pub struct UploadMessages<'a> {
    begin: Option<ModelBegin>,
    model: &'a [u8],
    offset: usize,
    ended: bool,
}

impl Iterator for UploadMessages<'_> {
    type Item = ToKernel;

    fn next(&mut self) -> Option<ToKernel> {
        if let Some(begin) = self.begin.take() {
            return Some(ToKernel::ModelBegin(begin));
        }
        if self.offset < self.model.len() {
            let end = (self.offset + MODEL_CHUNK_LEN).min(self.model.len());
            let bytes = Vec::from_slice(self.model.get(self.offset..end)?).ok()?;
            let chunk = ModelChunk {
                // upload_messages checked that the model length fits u32.
                offset_bytes: self.offset as u32,
                bytes,
            };
            self.offset = end;
            return Some(ToKernel::ModelChunk(chunk));
        }
        if !self.ended {
            self.ended = true;
            return Some(ToKernel::ModelEnd);
        }
        None
    }
}
