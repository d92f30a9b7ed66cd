//! `--hand world|mujoco`: which hand executes the actions of `dips episode`, `dips eval`,
//! `dips sim run` and `dips bench sim`. The `dips` binary has only our world; for another hand
//! it runs the `dips-mujoco` binary (the same command line with the MuJoCo hand registered,
//! `host/mujoco`) with the same arguments (docs/mujoco.md).

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;

use dips_allegro::emu::{JointModel, Plant, PlantError};
use dips_allegro::hand::{AllegroHand, PlantFactory};
use dips_world::hand::{
    AllegroOptions, EmulatedPlant, Hand, HandError, HandKind, HandOptions, Hands, TrackerNoise,
    open_world,
};
use dips_world::kinematics::HandJoints;
use dips_world::scenes::SceneKind;
use dips_world::world::World;

/// The binary that has the MuJoCo hand.
pub const MUJOCO_BINARY: &str = "dips-mujoco";

/// The hand flags of `dips episode` and `dips eval`.
#[derive(Debug, Clone, Args)]
pub struct HandArgs {
    /// Which hand executes the actions: `world` (our quasi-static world, the default) or
    /// `mujoco` (MuJoCo 3.17, through the dips-mujoco binary). The planner, the models and
    /// CSVTO's internal model are ours either way; `result.json` records the hand.
    #[arg(long, value_name = "HAND", value_parser = parse_hand)]
    pub hand: Option<HandKind>,
    /// Tracker noise (`--hand mujoco`): position σ (m) of the reported object pose, seeded
    /// with the episode's seed; the outcome is scored on the true pose.
    #[arg(long, value_name = "M")]
    pub noise_position: Option<f64>,
    /// Tracker noise (`--hand mujoco`): rotation σ (rad per axis) of the reported object pose.
    #[arg(long, value_name = "RAD")]
    pub noise_rotation: Option<f64>,
}

/// `--hand`'s parser: a hand's name, or the command line's words for one that is not
/// ([`crate::words::unknown_hand`]).
pub fn parse_hand(s: &str) -> Result<HandKind, String> {
    s.parse().map_err(|e| crate::words::unknown_hand(&e))
}

impl HandArgs {
    /// The hand (default: our world).
    pub fn kind(&self) -> HandKind {
        self.hand.clone().unwrap_or_default()
    }

    /// The tracker noise of the flags, `None` when both are 0 or absent.
    pub fn noise(&self) -> anyhow::Result<Option<TrackerNoise>> {
        Ok(TrackerNoise::new(
            self.noise_position.unwrap_or(0.0),
            self.noise_rotation.unwrap_or(0.0),
        )?)
    }

    /// How to open the hand of an episode of `seed`.
    pub fn options(&self, seed: u64) -> anyhow::Result<HandOptions> {
        Ok(HandOptions {
            noise: self.noise()?,
            seed,
        })
    }
}

/// The emulated Allegro hand's plant in this binary: the joint model, with the object moved by
/// our quasi-static world (`dips_allegro::emu::joint_model`).
pub fn joint_model_plant(
    scene: SceneKind,
    start: HandJoints,
) -> Result<Box<dyn Plant>, PlantError> {
    let mut world = World::new(scene);
    world.set_joints(&start);
    Ok(Box::new(JointModel::new(scene, start).with_world(world)))
}

/// Open the Allegro hand of `options` with `plant` behind an emulated bus; tracker noise is
/// refused (a real tracker has its own).
pub fn open_allegro(
    options: &AllegroOptions,
    scene: SceneKind,
    hand_options: &HandOptions,
    plant: PlantFactory<'_>,
) -> Result<Box<dyn Hand>, HandError> {
    if hand_options.noise.is_some() {
        return Err(dips_allegro::hand::OpenError::Noise.into());
    }
    // A hand fault ends the process at once, torques zeroed (the episode may be planning).
    Ok(Box::new(AllegroHand::open(
        options,
        scene,
        plant,
        dips_allegro::controller::OnFault::ExitProcess,
    )?))
}

/// The hands of the `dips` binary: our world, and the Allegro driver with its emulated hand on
/// the joint model ([`joint_model_plant`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct DipsHands;

impl Hands for DipsHands {
    fn has(&self, kind: &HandKind) -> bool {
        match kind {
            HandKind::World => true,
            HandKind::Allegro(a) => a.plant == EmulatedPlant::JointModel,
            HandKind::Mujoco => false,
        }
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
            other => Err(HandError::NotInBinary {
                kind: other.clone(),
            }),
        }
    }
}

impl CliHands for DipsHands {
    /// The joint model for either: `plant=mujoco` never gets here, [`DipsHands::has`] sends
    /// it to `dips-mujoco`.
    fn allegro_plant(&self, _plant: EmulatedPlant) -> PlantFactory<'_> {
        &joint_model_plant
    }
}

/// The hands a `dips` command line opens: a [`Hands`] factory that also gives the plant the
/// emulated Allegro hand moves with (`dips hand` opens the driver without a [`Hand`]).
pub trait CliHands: Hands {
    /// The factory of `plant`, for an Allegro hand [`Hands::has`] accepts.
    fn allegro_plant(&self, plant: EmulatedPlant) -> PlantFactory<'_>;
}

/// Where the `dips-mujoco` binary is: next to `exe`, else on `path` (`PATH`'s value).
pub fn find_binary(name: &str, exe: &Path, path: Option<OsString>) -> Option<PathBuf> {
    let sibling = exe.parent().map(|d| d.join(name));
    sibling
        .into_iter()
        .chain(
            path.iter()
                .flat_map(std::env::split_paths)
                .filter(|d| !d.as_os_str().is_empty())
                .map(|d| d.join(name)),
        )
        .find(|p| p.is_file())
}

/// Run this command line again in the binary that has `kind` (`dips-mujoco`), with the same
/// arguments, stdin, stdout and stderr, and exit with its exit code. Returns only on an error:
/// the binary is not there, or it could not be started.
pub fn delegate(kind: HandKind) -> anyhow::Result<()> {
    let exe = std::env::current_exe().context("finding this binary")?;
    let Some(bin) = find_binary(MUJOCO_BINARY, &exe, std::env::var_os("PATH")) else {
        anyhow::bail!(
            "--hand {kind} needs the {MUJOCO_BINARY} binary (build it: scripts/mujoco-test.sh), \
             not found next to {} or on PATH",
            exe.display()
        );
    };
    let status = std::process::Command::new(&bin)
        .args(std::env::args_os().skip(1))
        .status()
        .with_context(|| format!("running {}", bin.display()))?;
    std::process::exit(exit_code(status))
}

/// The exit code to pass on: the child's, or 128 + the signal that ended it.
fn exit_code(status: std::process::ExitStatus) -> i32 {
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        if let Some(signal) = status.signal() {
            return 128 + signal;
        }
    }
    status.code().unwrap_or(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_binary_is_looked_for_next_to_this_one_then_on_path() {
        let dir = std::env::temp_dir().join(format!("dips-find-{}", std::process::id()));
        let (here, there) = (dir.join("here"), dir.join("there"));
        std::fs::create_dir_all(&here).unwrap();
        std::fs::create_dir_all(&there).unwrap();
        let exe = here.join("dips");
        let path = Some(std::env::join_paths([&there]).unwrap());
        assert_eq!(find_binary("x", &exe, path.clone()), None);
        std::fs::write(there.join("x"), "").unwrap();
        assert_eq!(find_binary("x", &exe, path.clone()), Some(there.join("x")));
        std::fs::write(here.join("x"), "").unwrap();
        assert_eq!(find_binary("x", &exe, path), Some(here.join("x")));
        assert_eq!(find_binary("x", &dir.join("dips"), None), None);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
