//! `dips-firmware-sim`: the kernel as the hand's controller runs it.
//!
//! [`Firmware`] is the controller's request handler: it owns fixed buffers for the uploaded
//! models (allocated once by the caller; nothing is allocated while serving) and answers each
//! [`ToKernel`] message with one [`FromKernel`] message. [`serve`] runs it over any byte
//! streams: COBS deframing with a fixed-capacity accumulator, postcard decoding, typed errors
//! for bad frames, and it keeps serving after any of them.
//!
//! A well-formed [`PlanRequest`] is answered with [`WireError::ModelNotLoaded`] until both
//! models are uploaded, then planned by the kernel with the uploaded models
//! ([`planning`]), the prior the host set for the task (`SetPrior`; the paper's until then)
//! and the sampler settings it set (`SetSampler`; the paper's until then). A firmware built
//! without planning memory ([`Firmware::new`]) answers [`WireError::PlannerUnavailable`]
//! instead.

pub mod planning;

use std::io::{self, Read, Write};

use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::Task;
use dips_kernel::prior::MarkovPrior;
use dips_kernel::wire_convert::{PlanInputs, prior_from_table, sampler_from_settings};
use dips_wire::{
    Feed, Frame, FrameAccumulator, FromKernel, Hello, HelloAck, MAX_ENCODED_FRAME_LEN,
    MODEL_CHUNK_LEN, ModelAssembler, ModelRole, NO_REQUEST_ID, PROTOCOL_VERSION, PlanRequest,
    SCHEMA_KEY, ToKernel, UploadError, WireError, decode_frame, encode_frame,
};
use planning::{MonotonicClock, PlanMemory};

/// Size of each static model buffer of the `dips-firmware-sim` binary, in bytes.
pub const MODEL_CAPACITY_BYTES: usize = 32 * 1024 * 1024;

/// Size of the static planning work area of the `dips-firmware-sim` binary, in `f32`s
/// (64 MiB). The paper's settings (k 16, four card modes) with the fixture-sized models need
/// about 2 M floats; see [`planning::PlanMemory`].
pub const WORK_FLOATS: usize = 16 * 1024 * 1024;

/// Bytes read from the input stream per read call.
const READ_CHUNK_LEN: usize = 256;

/// The controller's request handler and its state.
#[derive(Debug)]
pub struct Firmware<'m> {
    greeted: bool,
    denoiser: ModelAssembler<'m>,
    discriminator: ModelAssembler<'m>,
    active_upload: Option<ModelRole>,
    planning: Option<PlanMemory<'m>>,
    clock: MonotonicClock,
    /// Priors set by the host, per task (screwdriver, card); `None`: the paper's.
    priors: [Option<MarkovPrior>; 2],
    /// Sampler settings for every plan (the paper's until the host sets them).
    sampler: SamplerConfig,
}

fn task_slot(task: Task) -> usize {
    match task {
        Task::Screwdriver => 0,
        Task::Card => 1,
    }
}

impl<'m> Firmware<'m> {
    /// A firmware that stores uploaded models in the two given buffers (their lengths are
    /// the largest models accepted) and has no memory to plan in: plan requests are
    /// checked, then answered with [`WireError::PlannerUnavailable`].
    pub fn new(denoiser_buf: &'m mut [u8], discriminator_buf: &'m mut [u8]) -> Self {
        Self {
            greeted: false,
            denoiser: ModelAssembler::new(denoiser_buf),
            discriminator: ModelAssembler::new(discriminator_buf),
            active_upload: None,
            planning: None,
            clock: MonotonicClock::new(),
            priors: [None, None],
            sampler: SamplerConfig::default(),
        }
    }

    /// A firmware that stores uploaded models in the two buffers and plans with them in
    /// `memory`.
    pub fn with_planning(
        denoiser_buf: &'m mut [u8],
        discriminator_buf: &'m mut [u8],
        memory: PlanMemory<'m>,
    ) -> Self {
        Self {
            planning: Some(memory),
            ..Self::new(denoiser_buf, discriminator_buf)
        }
    }

    /// Start a new session (a new connection): a new `Hello` is required and any upload in
    /// progress is abandoned. Loaded models stay loaded.
    pub fn reset_session(&mut self) {
        self.greeted = false;
        if let Some(role) = self.active_upload.take() {
            // Ending an unfinished upload discards it (the error is the point).
            let _ = self.assembler_mut(role).end();
        }
    }

    /// Whether a `Hello` with the right version has been received.
    pub fn greeted(&self) -> bool {
        self.greeted
    }

    /// The loaded model of a role (its bytes, CRC-checked).
    pub fn model(&self, role: ModelRole) -> Option<&[u8]> {
        self.assembler(role).model().map(|(_, bytes)| bytes)
    }

    fn assembler(&self, role: ModelRole) -> &ModelAssembler<'m> {
        match role {
            ModelRole::Denoiser => &self.denoiser,
            ModelRole::Discriminator => &self.discriminator,
        }
    }

    fn assembler_mut(&mut self, role: ModelRole) -> &mut ModelAssembler<'m> {
        match role {
            ModelRole::Denoiser => &mut self.denoiser,
            ModelRole::Discriminator => &mut self.discriminator,
        }
    }

    /// Answer one request.
    pub fn handle(&mut self, request: &ToKernel) -> FromKernel {
        match self.try_handle(request) {
            Ok(reply) => reply,
            Err(error) => FromKernel::Error(error),
        }
    }

    fn try_handle(&mut self, request: &ToKernel) -> Result<FromKernel, WireError> {
        if let ToKernel::Hello(hello) = request {
            return self.hello(hello);
        }
        if !self.greeted {
            return Err(WireError::HandshakeRequired);
        }
        match request {
            ToKernel::Hello(_) => Err(WireError::HandshakeRequired),
            ToKernel::PlanRequest(plan) => self.plan(plan),
            ToKernel::ModelBegin(begin) => {
                self.active_upload = Some(begin.role);
                let result = self.assembler_mut(begin.role).begin(begin);
                if result.is_err() {
                    self.active_upload = None;
                }
                Ok(FromKernel::ModelAck(result?))
            }
            ToKernel::ModelChunk(chunk) => {
                let role = self.active_upload.ok_or(UploadError::NotStarted)?;
                Ok(FromKernel::ModelAck(self.assembler_mut(role).chunk(chunk)?))
            }
            ToKernel::ModelEnd => {
                let role = self.active_upload.take().ok_or(UploadError::NotStarted)?;
                Ok(FromKernel::ModelLoaded(self.assembler_mut(role).end()?))
            }
            ToKernel::SetPrior(table) => {
                let (task, prior) =
                    prior_from_table(table).map_err(|field| WireError::InvalidRequest { field })?;
                self.priors[task_slot(task)] = Some(prior);
                Ok(FromKernel::Applied)
            }
            ToKernel::SetSampler(settings) => {
                self.sampler = sampler_from_settings(settings)
                    .map_err(|field| WireError::InvalidRequest { field })?;
                Ok(FromKernel::Applied)
            }
        }
    }

    fn hello(&mut self, hello: &Hello) -> Result<FromKernel, WireError> {
        if hello.protocol_version != PROTOCOL_VERSION || hello.schema_key != SCHEMA_KEY {
            self.greeted = false;
            return Err(WireError::VersionMismatch {
                kernel_version: PROTOCOL_VERSION,
                host_version: hello.protocol_version,
                kernel_schema_key: SCHEMA_KEY,
                host_schema_key: hello.schema_key,
            });
        }
        self.greeted = true;
        Ok(FromKernel::HelloAck(HelloAck {
            protocol_version: PROTOCOL_VERSION,
            schema_key: SCHEMA_KEY,
            max_frame_len_bytes: MAX_ENCODED_FRAME_LEN as u32,
            model_chunk_len_bytes: MODEL_CHUNK_LEN as u32,
        }))
    }

    fn plan(&mut self, plan: &PlanRequest) -> Result<FromKernel, WireError> {
        // The kernel's own request checks (start state, goal, settings, previous mode).
        let inputs =
            PlanInputs::from_request(plan).map_err(|field| WireError::InvalidRequest { field })?;
        let Self {
            denoiser,
            discriminator,
            planning,
            clock,
            priors,
            sampler,
            ..
        } = self;
        let den = loaded(denoiser, ModelRole::Denoiser)?;
        let disc = loaded(discriminator, ModelRole::Discriminator)?;
        let memory = planning.as_mut().ok_or(WireError::PlannerUnavailable)?;
        let config = planning::PlanConfig {
            prior: priors[task_slot(inputs.task)].as_ref(),
            sampler: *sampler,
        };
        planning::plan(memory, den, disc, plan, &config, clock).map(FromKernel::PlanReply)
    }
}

/// The bytes of a loaded model, or the error naming the missing one.
fn loaded<'a>(assembler: &'a ModelAssembler<'_>, role: ModelRole) -> Result<&'a [u8], WireError> {
    assembler
        .model()
        .map(|(_, bytes)| bytes)
        .ok_or(WireError::ModelNotLoaded { role })
}

/// Counts of what [`serve`] saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ServeStats {
    /// Frames that decoded to a request.
    pub requests: u64,
    /// Frames dropped or refused as undecodable (bad COBS, too long, bad payload).
    pub bad_frames: u64,
    /// Replies written.
    pub replies: u64,
}

/// Serve requests from `reader` until it ends, writing one reply frame per input frame to
/// `writer` (flushed after every read). Returns when the input ends; I/O errors end it early.
pub fn serve<R: Read, W: Write>(
    firmware: &mut Firmware<'_>,
    mut reader: R,
    mut writer: W,
) -> io::Result<ServeStats> {
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut rx = [0u8; READ_CHUNK_LEN];
    let mut tx = [0u8; MAX_ENCODED_FRAME_LEN];
    let mut stats = ServeStats::default();
    loop {
        let n = match reader.read(&mut rx) {
            Ok(0) => return Ok(stats),
            Ok(n) => n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        let mut window = rx.get(..n).unwrap_or(&[]);
        loop {
            let reply = match acc.feed(window) {
                Feed::Consumed => break,
                Feed::Frame { payload, remaining } => {
                    window = remaining;
                    match decode_frame::<ToKernel>(payload) {
                        Ok(frame) => {
                            stats.requests += 1;
                            Frame {
                                request_id: frame.request_id,
                                body: firmware.handle(&frame.body),
                            }
                        }
                        Err(e) => {
                            stats.bad_frames += 1;
                            Frame {
                                request_id: e.request_id.unwrap_or(NO_REQUEST_ID),
                                body: FromKernel::Error(e.error),
                            }
                        }
                    }
                }
                Feed::Error { error, remaining } => {
                    window = remaining;
                    stats.bad_frames += 1;
                    Frame {
                        request_id: NO_REQUEST_ID,
                        body: FromKernel::Error(error),
                    }
                }
            };
            let bytes = encode_frame(&reply, &mut tx)
                .map_err(|e| io::Error::other(format!("reply does not fit a frame: {e}")))?;
            writer.write_all(bytes)?;
            stats.replies += 1;
        }
        writer.flush()?;
    }
}
