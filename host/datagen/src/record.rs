//! One demo: an episode driven by the task's prior, executed closed-loop by CSVTO in the
//! world, with one training trajectory per CSVTO particle at every online step.
//!
//! A trajectory has the `docs/contracts.md` §2 layout, `T = H + 1` rows `[s_t, u_t]`: the rows the
//! mode has already executed (its measured states `s_0 … s_{k−1}` with the controls that were
//! commanded from them: the executed `Δq` and the planned contact forces), then the particle's
//! plan from the measured state `s_k` (spec §4.3: executed prefix ⧺ plan, controls shifted so
//! row `t` holds the control applied from `s_t`; the last row's control is zero).

use std::collections::BTreeMap;

use dips_dataset::DemoRecord;
use dips_exec::problems::Mode;
use dips_exec::problems::contract::{contract_dims, to_contract};
use dips_exec::{
    EpisodeResult, ExecError, ExecSettings, SequenceSource, StepParticles, run_episode_observed,
    sequence_for_seed,
};
use dips_world::scenes::SceneKind;
use dips_world::world::World;
use serde::Serialize;

/// What a demo's episode did (the demo file's `outcome` metadata).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoOutcome {
    /// The object stayed valid at every step.
    pub valid: bool,
    /// Screwdriver: final yaw (rad, clockwise negative).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_yaw: Option<f64>,
    /// Card: final distance to the goal (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_distance_m: Option<f64>,
    /// Per executed mode: start and end state (raw, angles unwrapped) and validity.
    pub modes: Vec<ModeOutcome>,
}

/// One executed mode of a demo.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModeOutcome {
    /// Mode name.
    pub mode: String,
    /// World state at the start of the mode.
    pub start_state: Vec<f64>,
    /// World state at its end.
    pub end_state: Vec<f64>,
    /// Valid at every step.
    pub valid: bool,
}

impl DemoOutcome {
    fn of(result: &EpisodeResult) -> DemoOutcome {
        DemoOutcome {
            valid: result.valid,
            final_yaw: result.final_yaw,
            final_distance_m: result.final_distance_m,
            modes: result
                .mode_runs
                .iter()
                .map(|r| ModeOutcome {
                    mode: r.mode.to_string(),
                    start_state: r.start_state.clone(),
                    end_state: r.end_state.clone(),
                    valid: r.steps.iter().all(|s| s.valid),
                })
                .collect(),
        }
    }
}

/// Collects the trajectories of one episode.
struct Recorder {
    d: usize,
    modes: Vec<Mode>,
    /// The executed rows of the current mode (`D` values each).
    prefix: Vec<f64>,
    current_mode: Option<usize>,
    trajectories: Vec<f32>,
    contexts: Vec<f32>,
    mode_index: Vec<i64>,
    step: Vec<i64>,
    particle: Vec<i64>,
}

impl Recorder {
    fn observe(&mut self, mode_index: usize, s: StepParticles<'_>) {
        if self.current_mode != Some(mode_index) {
            self.current_mode = Some(mode_index);
            self.prefix.clear();
        }
        let mode = self.modes[mode_index].contact_mode();
        let mut context = vec![0.0f32; mode.fingers()];
        mode.write_signs(&mut context);
        let mut best_row0 = None;
        for (j, x) in s.particles.iter().enumerate() {
            let plan = to_contract(s.problem, x);
            if j == 0 {
                best_row0 = Some(plan[..self.d].to_vec());
            }
            self.trajectories
                .extend(self.prefix.iter().chain(&plan).map(|v| *v as f32));
            self.contexts.extend_from_slice(&context);
            self.mode_index.push(mode_index as i64);
            self.step.push(s.step as i64);
            self.particle.push(j as i64);
        }
        // The best particle is executed: its first row (the measured state and the commanded
        // control) joins the prefix of the mode's later trajectories.
        if let Some(row) = best_row0 {
            self.prefix.extend(row);
        }
    }
}

/// Record demo `seed` of `task`: the sequence `sequences` gives that seed
/// ([`sequence_for_seed`]; with [`SequenceSource::Pattern`] it is
/// [`prior_sequence_for_seed`](dips_exec::prior_sequence_for_seed), executed as `dips episode --method csvto-sampled --seed seed`
/// executes it: same modes, same states, bit for bit), with every particle of every online
/// step as a trajectory. `progress` receives the episode's per-step lines.
pub fn record_demo(
    task: SceneKind,
    seed: u64,
    sequences: SequenceSource,
    settings: &ExecSettings,
    progress: &mut dyn FnMut(&str),
) -> Result<(DemoRecord, DemoOutcome), ExecError> {
    let modes = sequence_for_seed(task, seed, sequences);
    let (ds, du) = contract_dims(task);
    let mut rec = Recorder {
        d: ds + du,
        modes: modes.clone(),
        prefix: Vec::new(),
        current_mode: None,
        trajectories: Vec::new(),
        contexts: Vec::new(),
        mode_index: Vec::new(),
        step: Vec::new(),
        particle: Vec::new(),
    };
    let mut world = World::new(task);
    let result = run_episode_observed(
        &mut world,
        "csvto-sampled",
        seed,
        &modes,
        settings,
        progress,
        &mut |i, s| rec.observe(i, s),
    )?;
    let outcome = DemoOutcome::of(&result);
    let mut metadata = BTreeMap::new();
    metadata.insert(
        dips_dataset::OUTCOME_KEY.to_string(),
        serde_json::to_string(&outcome).unwrap_or_default(),
    );
    // Timing is kept apart from the outcome: it is the only thing that differs between runs.
    metadata.insert(
        "csvto_seconds".to_string(),
        format!("{:.3}", result.csvto_step_s.iter().sum::<f64>()),
    );
    metadata.insert(
        dips_dataset::SEQUENCES_KEY.to_string(),
        sequences.name().to_string(),
    );
    metadata.insert(
        dips_dataset::EXEC_SETTINGS_KEY.to_string(),
        serde_json::to_string(settings).unwrap_or_default(),
    );
    let record = DemoRecord {
        task: task.task(),
        seed,
        modes: modes.iter().map(|m| m.name().to_string()).collect(),
        trajectories: rec.trajectories,
        contexts: rec.contexts,
        mode_index: rec.mode_index,
        step: rec.step,
        particle: rec.particle,
        metadata,
    };
    Ok((record, outcome))
}
