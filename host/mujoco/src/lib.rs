//! dips-mujoco: the MuJoCo hand of issue 37. [`MujocoHand`] is a `dips_world::hand::Hand`
//! backed by MuJoCo 3.17 (through `mujoco-rs`): the scenes are generated at run time from our
//! own data ([`scene::scene_xml`]) and each action is executed as on the real Allegro hand, a
//! host-side joint PD at 333 Hz tracking a linearly interpolated target with gravity and full
//! dynamics on. The library comes from `scripts/fetch-mujoco.sh`; a missing or wrong-version
//! library is an error naming that script ([`locate`], [`check_version`]). See
//! `docs/mujoco.md`.

pub mod hand;
pub mod locate;
pub mod plant;
pub mod run;
pub mod scene;

pub use hand::MujocoHand;
pub use scene::{MujocoParams, PoseNoise};

/// Errors of the MuJoCo hand.
#[derive(Debug, thiserror::Error)]
pub enum MujocoError {
    /// The MuJoCo library is missing or not the version this crate needs.
    #[error("{0}")]
    Library(String),
    /// MuJoCo rejected the generated scene, or it lacks a named element.
    #[error("MuJoCo scene: {0}")]
    Model(String),
    /// A parameter is out of range.
    #[error("MuJoCo hand parameter: {0}")]
    Settings(String),
    /// A joint target is NaN or infinite.
    #[error("joint target {index} is not finite ({value})")]
    Target {
        /// Index in finger-major order (index, middle, ring, thumb; 4 joints each).
        index: usize,
        /// The value.
        value: f64,
    },
    /// MuJoCo's state diverged (it counted a bad acceleration, position or velocity and
    /// reset the state).
    #[error("MuJoCo diverged at t = {time:.4} s (bad acceleration, position or velocity)")]
    Diverged {
        /// Simulation time of the failure (s).
        time: f64,
    },
}

/// The version number (`mj_version()`) of the MuJoCo library this process linked.
#[allow(unsafe_code)]
pub fn linked_version() -> u32 {
    // SAFETY: mj_version is a pure query of a constant in the loaded library (mujoco-rs's
    // own version assertion calls it the same way).
    let v = unsafe { mujoco_rs::mujoco_c::mj_version() };
    u32::try_from(v).unwrap_or(0)
}

/// Check that the linked library is MuJoCo [`locate::MUJOCO_VERSION`]: mujoco-rs panics on a
/// mismatch, so every entry point calls this first.
pub fn check_version() -> Result<(), MujocoError> {
    check_version_number(linked_version())
}

/// [`check_version`] for a given `mj_version()` number.
pub fn check_version_number(found: u32) -> Result<(), MujocoError> {
    match locate::version_mismatch(found) {
        Some(message) => Err(MujocoError::Library(message)),
        None => Ok(()),
    }
}
