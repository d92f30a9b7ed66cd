//! Timing of one action (all sub-steps) in each scene, for `dips bench sim`.

use std::time::Instant;

use serde::Serialize;

use super::{CommandProfile, ConeActivation, World, WorldError, WorldParams, scripted};
use crate::kinematics::HandModel;
use crate::scenes::SceneKind;

/// Figures for one scripted scenario.
#[derive(Debug, Clone, Serialize)]
pub struct ScenarioTiming {
    /// Scene name.
    pub scene: String,
    /// Scenario: `hold` (zero deltas) or `manipulate` (pinch-and-turn / press-and-slide).
    pub scenario: String,
    /// Actions timed.
    pub actions: usize,
    /// Mean wall time per action (ms).
    pub mean_ms: f64,
    /// Median wall time per action (ms).
    pub median_ms: f64,
    /// Slowest action (ms).
    pub max_ms: f64,
    /// Mean sub-steps solved per action (early stop makes it < substeps).
    pub mean_substeps: f64,
    /// Mean Clarabel solves per action.
    pub mean_solves: f64,
    /// Mean interior-point iterations per action.
    pub mean_iterations: f64,
    /// Deepest penetration after any timed action (mm).
    pub max_penetration_mm: f64,
    /// Actions that carried a flag (reduced accuracy, unconverged friction, tilt limit).
    pub flagged_actions: usize,
}

/// The whole benchmark.
#[derive(Debug, Clone, Serialize)]
pub struct SimBench {
    /// Benchmark name.
    pub bench: String,
    /// The contact model timed.
    pub contact_model: ContactModel,
    /// Target time per action (ms).
    pub target_ms: f64,
    /// Scenarios.
    pub scenarios: Vec<ScenarioTiming>,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() { 0.0 } else { v[v.len() / 2] }
}

/// Which contact model the benchmark times.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ContactModel {
    /// The world's defaults.
    Default,
    /// The model before issue 10, for comparison: friction on every candidate within the
    /// contact margin and the command applied as a step ([`ConeActivation::All`],
    /// [`CommandProfile::Step`]).
    PlainCone,
}

impl ContactModel {
    /// The world parameters of this model for a scene.
    pub fn params(self, scene: SceneKind) -> WorldParams {
        let mut p = WorldParams::for_scene(scene);
        if self == ContactModel::PlainCone {
            p.cone_activation = ConeActivation::All;
            p.command_profile = CommandProfile::Step;
        }
        p
    }
}

fn time_scenario(
    scene: SceneKind,
    manipulate: bool,
    actions: usize,
    model: ContactModel,
) -> Result<ScenarioTiming, WorldError> {
    let fresh = || World::with_model(scene, HandModel::allegro_v4(), model.params(scene));
    let mut world = fresh()?;
    let mut times = Vec::with_capacity(actions);
    let (mut subs, mut solves, mut iters) = (0usize, 0u64, 0u64);
    let (mut pen, mut flagged): (f64, usize) = (0.0, 0);
    for k in 0..actions {
        // Restart periodically so the manipulation stays in the scene's working range.
        if manipulate && k % 6 == 0 {
            world = fresh()?;
        }
        let dq = match (scene, manipulate) {
            (_, false) => vec![0.0; scene.action_dim()],
            (SceneKind::Screwdriver, true) => scripted::pinch_turn_action(&world, 0.004, 0.005),
            (SceneKind::Card, true) => scripted::card_push_action(&world, -0.006, 0.003),
        };
        let t = Instant::now();
        let rep = world.step_action(&dq)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
        subs += rep.substeps_run;
        solves += u64::from(rep.solves);
        iters += u64::from(rep.iterations);
        pen = pen.max(rep.max_penetration);
        flagged += usize::from(!rep.flags.is_empty());
    }
    let n = times.len().max(1) as f64;
    let mean = times.iter().sum::<f64>() / n;
    let max = times.iter().copied().fold(0.0, f64::max);
    Ok(ScenarioTiming {
        scene: scene.name().into(),
        scenario: if manipulate { "manipulate" } else { "hold" }.into(),
        actions,
        mean_ms: mean,
        median_ms: median(&mut times),
        max_ms: max,
        mean_substeps: subs as f64 / n,
        mean_solves: solves as f64 / n,
        mean_iterations: iters as f64 / n,
        max_penetration_mm: pen * 1e3,
        flagged_actions: flagged,
    })
}

/// Time `actions` actions of each scenario in each scene under a contact model.
pub fn run(actions: usize, model: ContactModel) -> Result<SimBench, WorldError> {
    let mut scenarios = Vec::new();
    for scene in SceneKind::ALL {
        for manipulate in [false, true] {
            scenarios.push(time_scenario(scene, manipulate, actions, model)?);
        }
    }
    Ok(SimBench {
        bench: "sim".into(),
        contact_model: model,
        target_ms: 5.0,
        scenarios,
    })
}
