//! `dips-firmware-core`: the firmware of the hand's controller, everything but its byte link.
//!
//! `#![no_std]` without `alloc`; it builds for `thumbv7em-none-eabihf`. [`Firmware`] is the
//! controller's request handler: it owns fixed buffers for the uploaded models (given once by
//! the caller; nothing is allocated while serving) and answers each [`ToKernel`] message with
//! one [`FromKernel`] message. The link around it (deframing, a clock, cancellation) is the
//! platform's: `dips-firmware-sim` serves it over stdio or TCP on a host, a controller would
//! over its UART.
//!
//! A well-formed [`PlanRequest`] is answered with [`WireError::ModelNotLoaded`] until both
//! models are uploaded, then planned by the kernel with the uploaded models
//! ([`planning`]), the prior the host set for the task (`SetPrior`; the paper's until then)
//! and the sampler settings it set (`SetSampler`; the paper's until then). A firmware built
//! without planning memory ([`Firmware::new`]) answers [`WireError::PlannerUnavailable`]
//! instead.

#![no_std]

pub mod planning;

use dips_kernel::budget::Clock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::Task;
use dips_kernel::nn::model::parse;
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::{ApproximateReason, PaperPlanner, SearchReport, SearchStatus};
use dips_kernel::wire_convert::{PlanInputs, prior_from_table, sampler_from_settings};
use dips_wire::{
    FrameCounts, FromKernel, Hello, HelloAck, KernelStatus, LastPlan, MAX_ENCODED_FRAME_LEN,
    MODEL_CHUNK_LEN, MemoryUse, ModelAck, ModelAssembler, ModelBegin, ModelIdentity, ModelLoaded,
    ModelRole, PROTOCOL_VERSION, PlanReply, PlanRequest, PlanStatus, SCHEMA_KEY, ToKernel,
    UploadError, WireError,
};
use planning::PlanMemory;

/// A loaded model's buffer: the bytes of the last upload of its role that passed every check.
#[derive(Debug)]
struct ModelSlot<'m> {
    buf: &'m mut [u8],
    /// Length and CRC-32 of the model it holds, `None` before the first.
    held: Option<(usize, u32)>,
}

impl<'m> ModelSlot<'m> {
    fn new(buf: &'m mut [u8]) -> Self {
        Self { buf, held: None }
    }

    fn bytes(&self) -> Option<&[u8]> {
        self.held.and_then(|(len, _)| self.buf.get(..len))
    }

    fn capacity_bytes(&self) -> u32 {
        u32::try_from(self.buf.len()).unwrap_or(u32::MAX)
    }
}

/// The controller's request handler and its state.
///
/// An upload is assembled in a staging buffer and checked (length, CRC, then the model's own
/// header and weights) before it replaces the model of its role, so a broken, restarted,
/// abandoned or refused upload leaves the model in use as it was.
#[derive(Debug)]
pub struct Firmware<'m> {
    greeted: bool,
    denoiser: ModelSlot<'m>,
    discriminator: ModelSlot<'m>,
    staging: ModelAssembler<'m>,
    active_upload: Option<ModelRole>,
    planning: Option<PlanMemory<'m>>,
    /// Priors set by the host, per task (screwdriver, card); `None`: the paper's.
    priors: [Option<MarkovPrior>; 2],
    /// Sampler settings for every plan (the paper's until the host sets them).
    sampler: SamplerConfig,
    /// Frames handled since the firmware started (all connections).
    frames: FrameCounts,
    /// The last planning call.
    last_plan: Option<LastPlan>,
    /// Work-area floats the last planning call used.
    work_floats_used: u32,
}

fn task_slot(task: Task) -> usize {
    match task {
        Task::Screwdriver => 0,
        Task::Card => 1,
    }
}

impl<'m> Firmware<'m> {
    /// A firmware that keeps its models in the two given buffers, assembles uploads in
    /// `staging_buf` (the largest model accepted is the smallest of the three), and has no
    /// memory to plan in: plan requests are checked, then answered with
    /// [`WireError::PlannerUnavailable`].
    pub fn new(
        denoiser_buf: &'m mut [u8],
        discriminator_buf: &'m mut [u8],
        staging_buf: &'m mut [u8],
    ) -> Self {
        Self {
            greeted: false,
            denoiser: ModelSlot::new(denoiser_buf),
            discriminator: ModelSlot::new(discriminator_buf),
            staging: ModelAssembler::new(staging_buf),
            active_upload: None,
            planning: None,
            priors: [None, None],
            sampler: SamplerConfig::default(),
            frames: FrameCounts::default(),
            last_plan: None,
            work_floats_used: 0,
        }
    }

    /// A firmware as [`Self::new`] that plans with its models in `memory`.
    pub fn with_planning(
        denoiser_buf: &'m mut [u8],
        discriminator_buf: &'m mut [u8],
        staging_buf: &'m mut [u8],
        memory: PlanMemory<'m>,
    ) -> Self {
        Self {
            planning: Some(memory),
            ..Self::new(denoiser_buf, discriminator_buf, staging_buf)
        }
    }

    /// Start a new session (a new connection): a new `Hello` is required and any upload in
    /// progress is abandoned. Loaded models stay loaded.
    pub fn reset_session(&mut self) {
        self.greeted = false;
        if self.active_upload.take().is_some() {
            // Ending an unfinished upload discards it (the error is the point); the models in
            // use are untouched.
            let _ = self.staging.end();
        }
    }

    /// Whether a `Hello` with the right version has been received.
    pub fn greeted(&self) -> bool {
        self.greeted
    }

    /// The loaded model of a role (its bytes, CRC-checked and accepted by the interpreter).
    pub fn model(&self, role: ModelRole) -> Option<&[u8]> {
        self.slot(role).bytes()
    }

    fn slot(&self, role: ModelRole) -> &ModelSlot<'m> {
        match role {
            ModelRole::Denoiser => &self.denoiser,
            ModelRole::Discriminator => &self.discriminator,
        }
    }

    /// Start an upload into the staging buffer (any upload in progress is abandoned).
    fn begin_upload(&mut self, begin: &ModelBegin) -> Result<ModelAck, WireError> {
        self.active_upload = None;
        let capacity = self.slot(begin.role).capacity_bytes();
        if begin.total_len_bytes > capacity {
            let _ = self.staging.end();
            return Err(UploadError::TooLarge {
                total_len_bytes: begin.total_len_bytes,
                capacity_bytes: capacity.min(self.staging.capacity_bytes()),
            }
            .into());
        }
        let ack = self.staging.begin(begin)?;
        self.active_upload = Some(begin.role);
        Ok(ack)
    }

    /// Finish the upload: length and CRC ([`ModelAssembler::end`]), then the model's own
    /// checks ([`planning::model_info`]); only then does it replace the model of its role.
    fn end_upload(&mut self) -> Result<ModelLoaded, WireError> {
        let role = self.active_upload.take().ok_or(UploadError::NotStarted)?;
        let loaded = self.staging.end()?;
        let Some((_, bytes)) = self.staging.model() else {
            return Err(UploadError::NotStarted.into());
        };
        planning::model_info(role, bytes)?;
        let slot = match role {
            ModelRole::Denoiser => &mut self.denoiser,
            ModelRole::Discriminator => &mut self.discriminator,
        };
        let capacity_bytes = slot.capacity_bytes();
        let dest = slot
            .buf
            .get_mut(..bytes.len())
            .ok_or(UploadError::TooLarge {
                total_len_bytes: loaded.len_bytes,
                capacity_bytes,
            })?;
        dest.copy_from_slice(bytes);
        slot.held = Some((bytes.len(), loaded.crc32));
        Ok(loaded)
    }

    /// Answer request `request_id`; a plan reads `clock` for its time budget and asks it
    /// before every expansion whether it has been cancelled (the link's clock: a `Cancel`
    /// frame that arrived while planning).
    pub fn handle(
        &mut self,
        request_id: u32,
        request: &ToKernel,
        clock: &mut impl Clock,
    ) -> FromKernel {
        match self.try_handle(request_id, request, clock) {
            Ok(reply) => reply,
            Err(error) => FromKernel::Error(error),
        }
    }

    /// Count a decoded request (the link calls it).
    pub fn count_request(&mut self) {
        self.frames.requests = self.frames.requests.saturating_add(1);
    }

    /// Count a refused frame (the link calls it).
    pub fn count_bad_frame(&mut self) {
        self.frames.bad_frames = self.frames.bad_frames.saturating_add(1);
    }

    /// Count a reply written (the link calls it).
    pub fn count_reply(&mut self) {
        self.frames.replies = self.frames.replies.saturating_add(1);
    }

    /// What `Status` answers: the loaded models, memory, the last plan, frame counts.
    pub fn status(&self) -> KernelStatus {
        let identity = |role| {
            let slot = self.slot(role);
            Some(model_identity(slot.bytes()?, slot.held?.1))
        };
        let models_bytes = [ModelRole::Denoiser, ModelRole::Discriminator]
            .iter()
            .filter_map(|&r| self.model(r))
            .map(|b| b.len())
            .sum::<usize>();
        KernelStatus {
            denoiser: identity(ModelRole::Denoiser),
            discriminator: identity(ModelRole::Discriminator),
            memory: MemoryUse {
                model_capacity_bytes: self
                    .denoiser
                    .capacity_bytes()
                    .min(self.discriminator.capacity_bytes())
                    .min(self.staging.capacity_bytes()),
                models_bytes: u32::try_from(models_bytes).unwrap_or(u32::MAX),
                planner_bytes: self.planning.as_ref().map_or(0, |_| {
                    u32::try_from(core::mem::size_of::<PaperPlanner>()).unwrap_or(u32::MAX)
                }),
                work_floats: self
                    .planning
                    .as_ref()
                    .map_or(0, |p| u32::try_from(p.work.len()).unwrap_or(u32::MAX)),
                work_floats_used: self.work_floats_used,
            },
            last_plan: self.last_plan,
            frames: self.frames,
        }
    }

    fn try_handle(
        &mut self,
        request_id: u32,
        request: &ToKernel,
        clock: &mut impl Clock,
    ) -> Result<FromKernel, WireError> {
        if let ToKernel::Hello(hello) = request {
            return self.hello(hello);
        }
        if !self.greeted {
            return Err(WireError::HandshakeRequired);
        }
        match request {
            ToKernel::Hello(_) => Err(WireError::HandshakeRequired),
            ToKernel::PlanRequest(plan) => self.plan(request_id, plan, clock),
            ToKernel::ModelBegin(begin) => Ok(FromKernel::ModelAck(self.begin_upload(begin)?)),
            ToKernel::ModelChunk(chunk) => {
                self.active_upload.ok_or(UploadError::NotStarted)?;
                Ok(FromKernel::ModelAck(self.staging.chunk(chunk)?))
            }
            ToKernel::ModelEnd => Ok(FromKernel::ModelLoaded(self.end_upload()?)),
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
            ToKernel::Status => Ok(FromKernel::Status(self.status())),
            // A running plan saw it through its clock (the link's); here there is nothing left
            // to stop.
            ToKernel::Cancel => Ok(FromKernel::Applied),
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

    fn plan(
        &mut self,
        request_id: u32,
        plan: &PlanRequest,
        clock: &mut impl Clock,
    ) -> Result<FromKernel, WireError> {
        // The kernel's own request checks (start state, goal, settings, previous mode).
        let inputs =
            PlanInputs::from_request(plan).map_err(|field| WireError::InvalidRequest { field })?;
        let Self {
            denoiser,
            discriminator,
            planning,
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
        let done = planning::plan(memory, den, disc, plan, &config, clock)?;
        let reply = PlanReply::from(&done.report);
        self.work_floats_used = u32::try_from(done.work_floats).unwrap_or(u32::MAX);
        self.last_plan = Some(last_plan(request_id, &done.report, &reply));
        if done.report.status == SearchStatus::Approximate(ApproximateReason::Cancelled) {
            self.frames.cancelled_plans = self.frames.cancelled_plans.saturating_add(1);
        }
        Ok(FromKernel::PlanReply(reply))
    }
}

/// A loaded model's identity: its length and CRC, and the shapes its header declares.
fn model_identity(bytes: &[u8], crc32: u32) -> ModelIdentity {
    let dims = parse(bytes).ok().map(|info| info.dims);
    let u16_of = |v: usize| u16::try_from(v).unwrap_or(u16::MAX);
    let task = dims.and_then(|d| {
        Task::ALL.into_iter().find(|t| {
            let td = t.dims();
            (td.state_dim, td.action_dim, td.fingers) == (d.state_dim, d.action_dim, d.fingers)
        })
    });
    ModelIdentity {
        len_bytes: u32::try_from(bytes.len()).unwrap_or(u32::MAX),
        crc32,
        task: task.map(Into::into),
        horizon: dims.map_or(0, |d| u16_of(d.horizon)),
        state_dim: dims.map_or(0, |d| u16_of(d.state_dim)),
        action_dim: dims.map_or(0, |d| u16_of(d.action_dim)),
        fingers: dims.map_or(0, |d| u16_of(d.fingers)),
        diffusion_steps: dims.map_or(0, |d| u16_of(d.diffusion_steps)),
    }
}

/// The last plan's figures for `Status`.
fn last_plan(request_id: u32, report: &SearchReport, reply: &PlanReply) -> LastPlan {
    let status: PlanStatus = reply.status;
    LastPlan {
        request_id,
        status,
        elapsed_ms: report.stats.elapsed_ms,
        nodes_expanded: report.stats.nodes_expanded,
        segments_sampled: report.stats.segments_sampled,
        particles: report.particles,
        effective_particles: report.effective_particles,
        expected_progress: report.expected_progress,
        terminal_cost: report.terminal_cost,
        cost_to_come: report.cost_to_come,
        heuristic: report.heuristic,
    }
}

/// The bytes of a loaded model, or the error naming the missing one.
fn loaded<'a>(slot: &'a ModelSlot<'_>, role: ModelRole) -> Result<&'a [u8], WireError> {
    slot.bytes().ok_or(WireError::ModelNotLoaded { role })
}
