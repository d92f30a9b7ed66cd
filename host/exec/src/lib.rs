//! `dips-exec`: the multi-finger problems and their closed-loop execution with CSVTO, on any
//! [`Hand`](dips_world::hand::Hand) (spec `algorithms.md` §1.3, §2): per contact mode a
//! warm-up solve, then one re-solve per executed step on the shrinking horizon, executing
//! `q_cmd = q + Δq₀` of the best particle. It knows nothing of the diffusion models or the
//! planner (`dips-planning` drives it).
//!
//! - [`problems`]: the Allegro contact trajectory-optimisation problems CSVTO solves;
//! - [`settings`]: per-task CSVTO settings (spec §1.6);
//! - [`mode_run`]: one contact mode executed on a hand;
//! - [`pose_estimate`]: the object pose each solve starts from (the tracker's, or fused with
//!   the mode's contacts);
//! - [`regrasp_guard`]: keeps regrasping fingers off the object until their touch-down step;
//! - [`episode`]: a sequence of modes (given or drawn from the task's prior) and its result.

pub mod episode;
pub mod mode_run;
pub mod pose_estimate;
pub mod press;
pub mod problems;
pub mod regrasp_guard;
pub mod settings;

pub use episode::{
    EpisodeResult, ParticleSummary, PlanRecord, SequenceSource, prior_sequence_for_seed,
    run_episode, run_episode_observed, run_episode_on, sample_markov_sequence,
    sample_prior_sequence, sequence_for_seed,
};
pub use mode_run::{
    ExecError, ModeRun, StepLog, StepParticles, fingertip_distances, hand_state, mode_goal,
    run_mode, run_mode_observed, true_hand_state,
};
pub use pose_estimate::PoseEstimate;
pub use press::Press;
pub use regrasp_guard::RegraspGuard;
pub use settings::{ExecProfile, ExecSettings, ProfileError};
