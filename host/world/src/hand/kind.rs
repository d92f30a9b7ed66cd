//! Which hand executes the actions ([`HandKind`]), and the factory that opens one
//! ([`Hands`]): `dips episode`, `dips eval`, `dips sim run` and `dips bench sim` take
//! `--hand world|mujoco` and open the hand through a [`Hands`]. The `dips` binary has only
//! our world ([`WorldHands`]); `dips-mujoco` (`host/mujoco`, a workspace of its own) is the
//! same command line with the MuJoCo hand registered (docs/mujoco.md).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::hand::{Hand, HandError};
use crate::scenes::SceneKind;
use crate::world::World;

/// Which hand executes the actions. The planner, the models and CSVTO's internal model are
/// the same for every kind: they model our world.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HandKind {
    /// Our quasi-static world ([`World`]).
    #[default]
    World,
    /// MuJoCo 3.17 with the 333 Hz host PD (`dips_mujoco::MujocoHand`).
    Mujoco,
}

impl HandKind {
    /// Every kind, in the order the help lists them.
    pub const ALL: [HandKind; 2] = [HandKind::World, HandKind::Mujoco];

    /// The name on the command line and in `result.json` / `eval.json`.
    pub fn name(self) -> &'static str {
        match self {
            HandKind::World => "world",
            HandKind::Mujoco => "mujoco",
        }
    }
}

impl fmt::Display for HandKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is not a hand.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UnknownHand {
    /// No hand has this name.
    #[error("unknown hand `{0}` (allowed: {allowed})", allowed = allowed_hands())]
    Name(String),
    /// A file path: a hand description (the kinematic model), which is not a hand kind.
    #[error(
        "`{0}` is not a hand (allowed: {allowed}); a hand description file is the hand model",
        allowed = allowed_hands()
    )]
    File(String),
}

/// The hands' names, as the errors list them (`world, mujoco`).
fn allowed_hands() -> String {
    HandKind::ALL.map(HandKind::name).join(", ")
}

impl FromStr for HandKind {
    type Err = UnknownHand;

    fn from_str(s: &str) -> Result<HandKind, UnknownHand> {
        if let Some(k) = HandKind::ALL.into_iter().find(|k| k.name() == s) {
            return Ok(k);
        }
        // `dips sim run --hand FILE` was the hand description before `--hand` named the hand.
        if s.contains('/') || s.contains('\\') || s.ends_with(".json") {
            return Err(UnknownHand::File(s.to_string()));
        }
        Err(UnknownHand::Name(s.to_string()))
    }
}

/// A simulated tracker's noise on the reported object pose (the true pose still scores the
/// episode, [`Hand::true_object_pose`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackerNoise {
    /// Position σ (m).
    pub position: f64,
    /// Rotation σ (rad per axis of a small rotation).
    pub rotation: f64,
}

/// Which part of the tracker noise ([`TrackerNoise`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseAxis {
    /// The position σ.
    Position,
    /// The rotation σ.
    Rotation,
}

impl fmt::Display for NoiseAxis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            NoiseAxis::Position => "position",
            NoiseAxis::Rotation => "rotation",
        })
    }
}

/// A tracker noise σ that is negative or not finite.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("tracker noise {axis} σ {value}: a standard deviation must be ≥ 0")]
pub struct BadNoise {
    /// Which σ.
    pub axis: NoiseAxis,
    /// Its value.
    pub value: f64,
}

impl TrackerNoise {
    /// The noise of a position σ and a rotation σ: `None` when both are 0; an error naming
    /// the σ when one is negative or not finite.
    pub fn new(position: f64, rotation: f64) -> Result<Option<TrackerNoise>, BadNoise> {
        for (axis, value) in [
            (NoiseAxis::Position, position),
            (NoiseAxis::Rotation, rotation),
        ] {
            if !value.is_finite() || value < 0.0 {
                return Err(BadNoise { axis, value });
            }
        }
        Ok((position > 0.0 || rotation > 0.0).then_some(TrackerNoise { position, rotation }))
    }
}

/// How to open a hand besides its kind and scene.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HandOptions {
    /// Tracker noise (`None`: the exact pose).
    pub noise: Option<TrackerNoise>,
    /// Seed of the tracker noise (an episode's own seed).
    pub seed: u64,
}

/// Opens a fresh hand at the task's start state. Shared by worker threads (`dips eval
/// --jobs`): each thread opens its own hands.
pub trait Hands: Sync {
    /// Whether this factory can open `kind`.
    fn has(&self, kind: HandKind) -> bool;
    /// A fresh hand of `kind` for `scene`.
    fn open(
        &self,
        kind: HandKind,
        scene: SceneKind,
        options: &HandOptions,
    ) -> Result<Box<dyn Hand>, HandError>;
}

/// Our world only: the factory of the `dips` binary.
#[derive(Debug, Clone, Copy, Default)]
pub struct WorldHands;

/// Open our world; the error for tracker noise, which only a simulated tracker has.
pub fn open_world(scene: SceneKind, options: &HandOptions) -> Result<Box<dyn Hand>, HandError> {
    if options.noise.is_some() {
        return Err(HandError::NoTracker {
            hand: HandKind::World,
        });
    }
    Ok(Box::new(World::new(scene)))
}

impl Hands for WorldHands {
    fn has(&self, kind: HandKind) -> bool {
        kind == HandKind::World
    }

    fn open(
        &self,
        kind: HandKind,
        scene: SceneKind,
        options: &HandOptions,
    ) -> Result<Box<dyn Hand>, HandError> {
        match kind {
            HandKind::World => open_world(scene, options),
            other => Err(HandError::NotInBinary { kind: other }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_ones_list_the_allowed() {
        for k in HandKind::ALL {
            assert_eq!(k.name().parse::<HandKind>(), Ok(k));
            assert_eq!(k.to_string(), k.name());
            let json = serde_json::to_string(&k).unwrap();
            assert_eq!(json, format!("\"{}\"", k.name()));
            assert_eq!(serde_json::from_str::<HandKind>(&json).unwrap(), k);
        }
        let e = "isaac".parse::<HandKind>().unwrap_err().to_string();
        assert_eq!(e, "unknown hand `isaac` (allowed: world, mujoco)");
        let e = "host/data/allegro_v4.json"
            .parse::<HandKind>()
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "`host/data/allegro_v4.json` is not a hand (allowed: world, mujoco); a hand \
             description file is the hand model"
        );
    }

    #[test]
    fn the_world_factory_opens_our_world_only() {
        let h = WorldHands
            .open(HandKind::World, SceneKind::Card, &HandOptions::default())
            .unwrap();
        assert_eq!(h.name(), "world");
        assert!(WorldHands.has(HandKind::World) && !WorldHands.has(HandKind::Mujoco));
        assert!(
            WorldHands
                .open(HandKind::Mujoco, SceneKind::Card, &HandOptions::default())
                .is_err()
        );
        let noisy = HandOptions {
            noise: TrackerNoise::new(0.001, 0.0).unwrap(),
            seed: 1,
        };
        let e = WorldHands
            .open(HandKind::World, SceneKind::Card, &noisy)
            .err()
            .unwrap();
        assert!(
            matches!(
                e,
                HandError::NoTracker {
                    hand: HandKind::World
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("tracker noise"), "{e}");
        assert_eq!(
            TrackerNoise::new(-1.0, 0.0),
            Err(BadNoise {
                axis: NoiseAxis::Position,
                value: -1.0
            })
        );
        assert_eq!(TrackerNoise::new(0.0, 0.0), Ok(None));
    }
}
