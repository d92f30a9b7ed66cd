//! The Diffusion Policy baseline (`--method diffusion-policy`, spec §5): a receding-horizon
//! diffusion policy with no contact modes and no search. Its denoiser (`<models>/policy/
//! denoiser.onnx`, trained by `dips train --policy` on windows of the demos' executed rows
//! concatenated across modes) is conditioned on the current state only, through inpainting
//! of row 0's state, with a zero contact-mode context. At every action one trajectory is
//! sampled from the measured state and row 0's joint deltas are executed: the observation
//! horizon is 1 and the action horizon is 1, as the paper ran it.
//!
//! The episode lasts as many actions as the task's mode limit allows CSVTO (7 × 12 for the
//! screwdriver, 5 × 8 for the card); `result.json` groups them into "policy" runs of `H`
//! actions so the same tables and pictures read it. The policy plans no contact forces and no
//! clearance, so `tip_sdf` and `planned_state` are empty and `solve_s` is the sampling time.

use std::time::Instant;

use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::engine::DenoiserEngine;
use dips_kernel::rng::KernelRng;
use dips_onnx::AnyEngine;

use crate::{SampleError, sample_trajectories};
use dips_exec::episode::{EpisodeResult, SCREWDRIVER_SUCCESS_YAW};
use dips_exec::mode_run::command_deltas;
use dips_exec::problems::contract::contract_state;
use dips_exec::{ExecSettings, ModeRun, StepLog, hand_state, true_hand_state};
use dips_world::hand::{Hand, HandError};
use dips_world::scenes::SceneKind;

/// The name of the policy's runs in `result.json`'s `modes`.
pub const POLICY_RUN: &str = "policy";

/// Why a policy episode stopped.
#[derive(Debug, thiserror::Error)]
pub enum PolicyError {
    /// The model's rows are too narrow for the task's hand.
    #[error(
        "the policy model has {state} state and {action} action columns; the {task} task needs \
         at least {needed}"
    )]
    Columns {
        /// The model's state columns.
        state: usize,
        /// The model's action columns.
        action: usize,
        /// The task.
        task: SceneKind,
        /// The columns of both the task needs (4 joints per finger).
        needed: usize,
    },
    /// Sampling the policy failed.
    #[error("diffusion policy sample")]
    Sample(#[source] SampleError),
    /// The policy drew an action that is not a number.
    #[error("the policy sampled a non-finite action at run {run} step {step}")]
    NonFinite {
        /// The run (0-based).
        run: usize,
        /// The step in the run (0-based).
        step: usize,
    },
    /// The hand did not take the command.
    #[error(transparent)]
    Hand(#[from] HandError),
}

/// The object goal drawn for a policy run: the task's success line (screwdriver yaw −π/3
/// from the start) or the card's goal.
fn run_goal(scene: SceneKind, start: &[f64]) -> [f64; 3] {
    let o = &start[start.len() - 3..];
    match scene {
        SceneKind::Screwdriver => [0.0, 0.0, o[2] + SCREWDRIVER_SUCCESS_YAW],
        SceneKind::Card => [0.0, f64::from(dips_kernel::task::CARD_GOAL_Y), 0.0],
    }
}

/// Run the policy on `hand` for `runs` runs of `exec.horizon` actions each.
#[allow(clippy::too_many_arguments)]
pub fn run_policy_episode<H: Hand + ?Sized>(
    hand: &mut H,
    policy: &mut AnyEngine,
    seed: u64,
    exec: &ExecSettings,
    sampler: &SamplerConfig,
    runs: usize,
    progress: &mut dyn FnMut(&str),
) -> Result<EpisodeResult, PolicyError> {
    let scene = hand.scene();
    let dims = DenoiserEngine::dims(policy);
    let nq = 4 * scene.task_fingers().len();
    if dims.state_dim < nq || dims.action_dim < nq {
        return Err(PolicyError::Columns {
            state: dims.state_dim,
            action: dims.action_dim,
            task: scene,
            needed: nq,
        });
    }
    let anchor = dips_kernel::session::start_anchor(scene.task());
    let context = vec![0f32; dims.fingers];
    let mut rng = KernelRng::seed_from_u64(seed ^ 0xd1ff_0901);
    let start = hand_state(hand);
    // Scored on the true pose (a simulated tracker may be noisy); run on the measured.
    let start_truth = true_hand_state(hand);
    let mut valid = hand.true_object_pose().valid(scene);
    let mut mode_runs = Vec::with_capacity(runs);
    let mut step_s = Vec::new();
    for r in 0..runs {
        let run_start = hand_state(hand);
        let mut steps = Vec::with_capacity(exec.horizon);
        for k in 0..exec.horizon {
            let state = hand_state(hand);
            let s0: Vec<f32> = contract_state(&state).iter().map(|&v| v as f32).collect();
            let t0 = Instant::now();
            let out = sample_trajectories(policy, sampler, &context, &s0, anchor, &mut rng)
                .map_err(PolicyError::Sample)?;
            let solve_s = t0.elapsed().as_secs_f64();
            let dq: Vec<f64> = out[dims.state_dim..dims.state_dim + nq]
                .iter()
                .map(|&v| f64::from(v))
                .collect();
            if dq.iter().any(|v| !v.is_finite()) {
                return Err(PolicyError::NonFinite { run: r, step: k });
            }
            command_deltas(hand, &dq)?;
            let after = hand_state(hand);
            let ok = hand.true_object_pose().valid(scene);
            valid &= ok;
            let o = &after[nq..];
            progress(&format!(
                "policy run {}/{runs} step {}/{}: sample {solve_s:.3}s, object {:?}{}",
                r + 1,
                k + 1,
                exec.horizon,
                o.iter()
                    .map(|v| (v * 1e3).round() / 1e3)
                    .collect::<Vec<_>>(),
                if ok { "" } else { " INVALID" }
            ));
            step_s.push(solve_s);
            steps.push(StepLog {
                solve_s,
                iters: 0,
                max_eq_violation: 0.0,
                max_ineq_violation: 0.0,
                dq,
                planned_state: Vec::new(),
                state: after,
                tip_sdf: Vec::new(),
                valid: ok,
                guarded: Vec::new(),
                contacts: hand.contact_readings().unwrap_or_default(),
            });
        }
        mode_runs.push(ModeRun {
            mode: POLICY_RUN,
            goal: run_goal(scene, &start),
            start_state: run_start,
            end_state: hand_state(hand),
            steps,
            regrasp_target_distance: Vec::new(),
        });
    }
    let end = true_hand_state(hand);
    Ok(EpisodeResult::assemble(
        scene,
        "diffusion-policy",
        seed,
        &start_truth,
        &end,
        mode_runs,
        Vec::new(),
        step_s,
        valid,
    ))
}
