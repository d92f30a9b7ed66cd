//! The hands of the `dips-mujoco` binary ([`MujocoHands`]: our world and the MuJoCo hand,
//! opened for `dips … --hand world|mujoco`), and CSVTO modes run on either
//! ([`run_csvto_modes`], what the tests check the MuJoCo hand with). The controller side sees
//! only [`Hand`]; commands files and scripted actions run through `dips_cli::sim` and
//! `dips_cli::bench_sim`, as `dips sim run` and `dips bench sim` do.

use std::time::Instant;

use dips_cli::hands::{CliHands, open_allegro};
use dips_world::hand::{EmulatedPlant, Hand, HandError, HandOptions, Hands, open_world};
use dips_world::scenes::SceneKind;
use serde::Serialize;

use crate::{MujocoHand, MujocoParams, PoseNoise};

/// Which hand executes the actions: `dips_world`'s type (one owner), re-exported here.
pub use dips_world::hand::HandKind;

/// The hands of the `dips-mujoco` binary: our world and the MuJoCo hand. Its `main` runs the
/// `dips` command line with them (`dips_cli::main_with`), so `--hand mujoco` works on
/// `dips episode`, `dips eval`, `dips sim run` and `dips bench sim`.
#[derive(Debug, Clone, Copy, Default)]
pub struct MujocoHands;

impl Hands for MujocoHands {
    fn has(&self, _kind: &HandKind) -> bool {
        true
    }

    fn open(
        &self,
        kind: &HandKind,
        scene: SceneKind,
        options: &HandOptions,
    ) -> Result<Box<dyn Hand>, HandError> {
        match kind {
            HandKind::World => open_world(scene, options),
            HandKind::Allegro(a) => open_allegro(a, scene, options, self.allegro_plant(a.plant)),
            HandKind::Mujoco => {
                let noise = options.noise.map(|n| PoseNoise {
                    position: n.position,
                    rotation: n.rotation,
                    seed: options.seed,
                });
                let mut params = MujocoParams::for_scene(scene);
                params.pose_noise = noise;
                let hand = MujocoHand::with_params(
                    scene,
                    dips_world::kinematics::HandModel::allegro_v4(),
                    params,
                )
                .map_err(|e| HandError::Other {
                    hand: "MuJoCo",
                    message: e.to_string(),
                })?;
                Ok(Box::new(hand))
            }
        }
    }
}

impl CliHands for MujocoHands {
    /// Both plants: the joint model and MuJoCo.
    fn allegro_plant(&self, plant: EmulatedPlant) -> dips_allegro::hand::PlantFactory<'_> {
        match plant {
            EmulatedPlant::JointModel => &dips_cli::hands::joint_model_plant,
            EmulatedPlant::Mujoco => &crate::plant::mujoco_plant,
        }
    }
}

/// One CSVTO mode executed closed-loop on a hand ([`dips_exec::run_mode`]: a
/// re-solve from the measured state at every step, the best particle's first step commanded).
#[derive(Debug, Clone, Serialize)]
pub struct ModeFigures {
    /// The mode's name.
    pub mode: String,
    /// Measured state row at the start of the mode.
    pub start_state: Vec<f64>,
    /// Measured state row at its end.
    pub end_state: Vec<f64>,
    /// Change of the object coordinates over the mode.
    pub object_change: [f64; 3],
    /// Each step's measured validity, all true when the object stayed valid.
    pub valid: bool,
    /// Largest distance (m) of a contact finger from the object after any step (CSVTO's
    /// `tip_sdf`, measured through our geometry at the measured state).
    pub worst_contact_gap: f64,
    /// Wall time of the whole mode (s): CSVTO's solves and the hand's actions.
    pub seconds: f64,
}

/// Run CSVTO `modes` (names of the scene's modes) one after the other on a fresh hand of
/// `kind`, with the task's execution settings and seed `seed` (the same as
/// `dips episode --method csvto-sampled` uses for each mode).
pub fn run_csvto_modes(
    kind: HandKind,
    scene: SceneKind,
    modes: &[String],
    seed: u64,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<ModeFigures>, Box<dyn std::error::Error>> {
    use dips_exec::problems::mode::parse_mode;
    use dips_exec::{ExecSettings, run_mode};
    let parsed = modes
        .iter()
        .map(|m| parse_mode(scene, m))
        .collect::<Result<Vec<_>, _>>()?;
    let mut hand = MujocoHands.open(&kind, scene, &HandOptions::default())?;
    let model = dips_world::kinematics::HandModel::allegro_v4();
    let settings = ExecSettings::for_task(scene);
    let mut rng = dips_kernel::rng::KernelRng::seed_from_u64(seed);
    let mut out = Vec::new();
    for mode in parsed {
        let t = Instant::now();
        let run = run_mode(
            hand.as_mut(),
            &model,
            mode,
            &settings,
            None,
            &mut rng,
            progress,
        )?;
        let a = scene.action_dim();
        let object_change = std::array::from_fn(|i| run.end_state[a + i] - run.start_state[a + i]);
        let contact: Vec<usize> = (0..scene.task_fingers().len())
            .filter(|&i| mode.contact_mode().in_contact(i))
            .collect();
        let worst_contact_gap = run
            .steps
            .iter()
            .flat_map(|s| {
                contact
                    .iter()
                    .map(|&i| s.tip_sdf.get(i).copied().unwrap_or(0.0))
            })
            .fold(0.0, f64::max);
        out.push(ModeFigures {
            mode: run.mode.to_string(),
            start_state: run.start_state.clone(),
            end_state: run.end_state.clone(),
            object_change,
            valid: run.steps.iter().all(|s| s.valid),
            worst_contact_gap,
            seconds: t.elapsed().as_secs_f64(),
        });
    }
    Ok(out)
}
