//! Planning calls through a [`Link`]: the models the kernel lacks, the prior and sampler it
//! needs, then `PlanRequest` and `Status`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use dips_kernel::budget::Clock;
use dips_kernel::mode::{ModeId, Task};
use dips_kernel::search::SearchStatus;
use dips_kernel::session::PlanSpec;
use dips_kernel::task::Objective;
use dips_kernel::wire_convert::{
    NoSearchStatus, prior_from_table, settings_from_sampler, table_from_prior,
};
use dips_onnx::{Expectation, ModelError, Role, lower_file};
use dips_planning::{PlanCallError, PlanOutcome, PlanService, model_file};
use dips_wire::{
    FromKernel, Hello, KernelStatus, LastPlan, ModelIdentity, ModelRole, PlanRequest, PriorTable,
    SamplerSettings, ToKernel, crc32, upload_messages,
};

use crate::transport::{Link, LinkError};

/// Why a planning call through a kernel over the wire failed. Each message names what the
/// kernel or the call did and what was expected.
#[derive(Debug, thiserror::Error)]
pub enum RemoteError {
    /// The link failed (the kernel died, stopped answering, or answered out of turn).
    #[error(transparent)]
    Link(#[from] LinkError),
    /// A model could not be lowered for the kernel.
    #[error("lowering {} for the kernel", file.display())]
    Lower {
        /// The `.onnx` file.
        file: PathBuf,
        /// Why.
        #[source]
        source: ModelError,
    },
    /// The kernel did not acknowledge the greeting.
    #[error("the kernel ({link}) answered Hello with {got}")]
    Hello {
        /// The link's name.
        link: String,
        /// What it answered.
        got: String,
    },
    /// A model is too large to upload.
    #[error("the {role:?} model ({bytes} bytes) is too large for the wire")]
    TooLarge {
        /// The model's role.
        role: ModelRole,
        /// Its size.
        bytes: usize,
    },
    /// The kernel's copy of an uploaded model is not what was sent.
    #[error("the kernel loaded a {role:?} with another CRC than sent")]
    Crc {
        /// The model's role.
        role: ModelRole,
    },
    /// The call's prior is not over its task's modes.
    #[error("the prior is not over the {task} modes")]
    PriorModes {
        /// The task.
        task: Task,
    },
    /// The call's prior would come back from the wire changed.
    #[error(
        "the prior does not survive the wire's row renormalisation bit for bit, so the kernel \
         would plan with another prior"
    )]
    PriorBits,
    /// The sampler's clip cannot be carried.
    #[error("the sampler's x̂₀ clip is not the default, which the wire cannot carry")]
    SamplerClip,
    /// The call's start cannot be carried with its goal.
    #[error(
        "this call's start yaw is unwrapped more than π from its goal; the wire's PlanRequest \
         carries the goal only (plan it in-process)"
    )]
    UnwrappedYaw,
    /// A call for another task than the planner's models.
    #[error("a {call} plan through a link set up for {models} models")]
    OtherTask {
        /// The call's task.
        call: Task,
        /// The models' task.
        models: Task,
    },
    /// The kernel's status after a plan names none.
    #[error("the kernel's status names no last plan after a plan")]
    NoLastPlan,
    /// The kernel answered a status that is no search status.
    #[error("{0}")]
    Status(#[from] NoSearchStatus),
}

impl From<RemoteError> for PlanCallError {
    fn from(e: RemoteError) -> Self {
        PlanCallError::Remote(Box::new(e))
    }
}

/// A kernel over a link, planning with the models of one models directory.
#[derive(Debug)]
pub struct RemotePlanner {
    link: Link,
    task: Task,
    /// The lowered (`.dipsm`) denoiser and discriminator the plans need.
    denoiser: Vec<u8>,
    discriminator: Vec<u8>,
    models_checked: bool,
    sent_prior: Option<PriorTable>,
    sent_sampler: Option<SamplerSettings>,
    uploads: u32,
}

impl RemotePlanner {
    /// Greet the kernel over `link` and lower `denoiser.onnx` and `discriminator.onnx` of
    /// `models_dir` for `task` (uploaded at the first plan, if the kernel lacks them).
    pub fn new(mut link: Link, models_dir: &Path, task: Task) -> Result<Self, RemoteError> {
        let lower = |role| {
            let file = models_dir.join(model_file(role));
            lower_file(&file, &Expectation::new(role, task.name()))
                .map(|l| l.blob)
                .map_err(|source| RemoteError::Lower { file, source })
        };
        let denoiser = lower(Role::Denoiser)?;
        let discriminator = lower(Role::Discriminator)?;
        let timeout = link.timeouts().reply;
        match link.request(&ToKernel::Hello(Hello::current()), timeout)? {
            FromKernel::HelloAck(_) => {}
            other => {
                return Err(RemoteError::Hello {
                    link: link.name().to_string(),
                    got: format!("{other:?}"),
                });
            }
        }
        Ok(Self {
            link,
            task,
            denoiser,
            discriminator,
            models_checked: false,
            sent_prior: None,
            sent_sampler: None,
            uploads: 0,
        })
    }

    /// The link.
    pub fn link_mut(&mut self) -> &mut Link {
        &mut self.link
    }

    /// Models uploaded so far (0 when the kernel already held both).
    pub fn uploads(&self) -> u32 {
        self.uploads
    }

    /// The kernel's status.
    pub fn status(&mut self) -> Result<KernelStatus, LinkError> {
        let timeout = self.link.timeouts().reply;
        match self.link.request(&ToKernel::Status, timeout)? {
            FromKernel::Status(s) => Ok(s),
            other => Err(self.unexpected("Status", &other)),
        }
    }

    fn unexpected(&self, request: &str, got: &FromKernel) -> LinkError {
        LinkError::Unexpected {
            link: self.link.name().to_string(),
            request: request.to_string(),
            id: 0,
            got: format!("{got:?}"),
        }
    }

    /// Upload each model the kernel does not hold already (same length and CRC-32).
    fn ensure_models(&mut self) -> Result<(), RemoteError> {
        if self.models_checked {
            return Ok(());
        }
        let status = self.status()?;
        let same = |held: Option<ModelIdentity>, blob: &[u8]| {
            held.is_some_and(|m| m.len_bytes as usize == blob.len() && m.crc32 == crc32(blob))
        };
        for role in [ModelRole::Denoiser, ModelRole::Discriminator] {
            let (held, blob): (_, &[u8]) = match role {
                ModelRole::Denoiser => (status.denoiser, &self.denoiser),
                ModelRole::Discriminator => (status.discriminator, &self.discriminator),
            };
            if same(held, blob) {
                continue;
            }
            let crc = crc32(blob);
            let messages = upload_messages(role, blob).ok_or(RemoteError::TooLarge {
                role,
                bytes: blob.len(),
            })?;
            let timeout = self.link.timeouts().reply;
            for m in messages {
                let reply = self.link.request(&m, timeout)?;
                match (&m, &reply) {
                    (ToKernel::ModelEnd, FromKernel::ModelLoaded(l)) => {
                        if l.crc32 != crc {
                            return Err(RemoteError::Crc { role });
                        }
                    }
                    (ToKernel::ModelEnd, other) | (_, other @ FromKernel::ModelLoaded(_)) => {
                        return Err(self.unexpected("ModelEnd", other).into());
                    }
                    (_, FromKernel::ModelAck(_)) => {}
                    (_, other) => return Err(self.unexpected("a model upload", other).into()),
                }
            }
            self.uploads += 1;
        }
        self.models_checked = true;
        Ok(())
    }

    /// Send `SetPrior` and `SetSampler` when they differ from what the kernel last got.
    fn ensure_settings(&mut self, spec: &PlanSpec) -> Result<(), RemoteError> {
        let table = table_from_prior(spec.task, &spec.prior)
            .ok_or(RemoteError::PriorModes { task: spec.task })?;
        // The kernel renormalises a table's rows; a prior that does not come back bit for
        // bit would plan differently there than here.
        match prior_from_table(&table) {
            Ok((_, back)) if back == spec.prior => {}
            _ => return Err(RemoteError::PriorBits),
        }
        let timeout = self.link.timeouts().reply;
        if self.sent_prior.as_ref() != Some(&table) {
            match self
                .link
                .request(&ToKernel::SetPrior(table.clone()), timeout)?
            {
                FromKernel::Applied => self.sent_prior = Some(table),
                other => return Err(self.unexpected("SetPrior", &other).into()),
            }
        }
        let sampler = settings_from_sampler(&spec.sampler).ok_or(RemoteError::SamplerClip)?;
        if self.sent_sampler != Some(sampler) {
            match self.link.request(&ToKernel::SetSampler(sampler), timeout)? {
                FromKernel::Applied => self.sent_sampler = Some(sampler),
                other => return Err(self.unexpected("SetSampler", &other).into()),
            }
        }
        Ok(())
    }

    /// The plan request of `spec` ([`PlanSpec::to_request`]); an error when the wire cannot
    /// say it (a screwdriver start yaw unwrapped beyond what the goal implies).
    fn request_of(spec: &PlanSpec) -> Result<PlanRequest, RemoteError> {
        if Objective::for_goal(spec.task, &spec.start, spec.goal(), spec.card_goals())
            != Some(spec.objective)
        {
            return Err(RemoteError::UnwrappedYaw);
        }
        Ok(spec.to_request())
    }

    /// How long a plan may take before the link gives up on it.
    fn plan_timeout(&self, spec: &PlanSpec) -> Duration {
        let t = self.link.timeouts();
        match spec.search.time_budget_ms {
            0 => t.unbudgeted_plan,
            ms => Duration::from_millis(u64::from(ms)) + t.plan_margin,
        }
    }
}

impl PlanService for RemotePlanner {
    fn plan_call(
        &mut self,
        spec: &PlanSpec,
        _clock: &mut dyn Clock,
    ) -> Result<PlanOutcome, PlanCallError> {
        Ok(self.plan_remote(spec)?)
    }

    fn location(&self) -> String {
        self.link.name().to_string()
    }
}

impl RemotePlanner {
    /// [`PlanService::plan_call`] with the link's own error.
    pub fn plan_remote(&mut self, spec: &PlanSpec) -> Result<PlanOutcome, RemoteError> {
        if spec.task != self.task {
            return Err(RemoteError::OtherTask {
                call: spec.task,
                models: self.task,
            });
        }
        self.ensure_models()?;
        self.ensure_settings(spec)?;
        let request = Self::request_of(spec)?;
        let timeout = self.plan_timeout(spec);
        let reply = match self
            .link
            .request(&ToKernel::PlanRequest(request), timeout)?
        {
            FromKernel::PlanReply(r) => r,
            other => return Err(self.unexpected("PlanRequest", &other).into()),
        };
        let last: LastPlan = self.status()?.last_plan.ok_or(RemoteError::NoLastPlan)?;
        let status = SearchStatus::try_from(reply.status)?;
        Ok(PlanOutcome {
            status,
            modes: reply.modes.iter().map(|&m| ModeId(m)).collect(),
            terminal_state: reply.terminal_state.to_vec(),
            expected_progress: last.expected_progress,
            nodes_expanded: reply.stats.nodes_expanded,
            nodes_generated: reply.stats.nodes_generated,
            sampler_calls: reply.stats.sampler_calls,
            scorer_calls: reply.stats.discriminator_calls,
            segments_sampled: last.segments_sampled,
            particles: last.particles,
            effective_particles: last.effective_particles,
        })
    }
}
