//! Which hand executes the actions ([`HandKind`]), and the factory that opens one
//! ([`Hands`]): `dips episode`, `dips eval`, `dips sim run` and `dips bench sim` take
//! `--hand world|mujoco|allegro:…` and open the hand through a [`Hands`]. [`WorldHands`] has
//! only our world; the `dips` binary adds the Allegro driver (`dips-allegro`), and
//! `dips-mujoco` (`host/mujoco`, a workspace of its own) is the same command line with the
//! MuJoCo hand registered (docs/mujoco.md).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::hand::allegro::{AllegroOptions, BadAllegro};
use crate::hand::{Hand, HandError};
use crate::scenes::SceneKind;
use crate::world::World;

/// Which hand executes the actions. The planner, the models and CSVTO's internal model are
/// the same for every kind: they model our world. Files write a hand as its command-line
/// form (`world`, `mujoco`, `allegro:emulated,gains=paper`).
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash)]
pub enum HandKind {
    /// Our quasi-static world ([`World`]).
    #[default]
    World,
    /// MuJoCo 3.17 with the 333 Hz host PD (`dips_mujoco::MujocoHand`).
    Mujoco,
    /// The Allegro Hand V4 through its CAN driver (`dips_allegro`): a real hand on a
    /// SocketCAN interface, or the emulated one (boxed: the options are large beside the
    /// other kinds).
    Allegro(Box<AllegroOptions>),
}

impl HandKind {
    /// Every kind's name, in the order the help lists them.
    pub const NAMES: [&'static str; 3] = ["world", "mujoco", "allegro:IFACE"];

    /// The kind's name (`world`, `mujoco`, `allegro`), as `result.json`'s `hand` records it.
    pub fn name(&self) -> &'static str {
        match self {
            HandKind::World => "world",
            HandKind::Mujoco => "mujoco",
            HandKind::Allegro(_) => "allegro",
        }
    }

    /// The Allegro hand's options, for that kind.
    pub fn allegro(&self) -> Option<&AllegroOptions> {
        match self {
            HandKind::Allegro(o) => Some(o),
            _ => None,
        }
    }
}

impl fmt::Display for HandKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HandKind::Allegro(o) => write!(f, "allegro:{o}"),
            other => f.write_str(other.name()),
        }
    }
}

impl Serialize for HandKind {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for HandKind {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<HandKind, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
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
    /// An `allegro:…` spec that does not parse.
    #[error("hand allegro: {0}")]
    Allegro(#[from] BadAllegro),
}

/// The hands' names, as the errors list them (`world, mujoco, allegro:IFACE`).
fn allowed_hands() -> String {
    HandKind::NAMES.join(", ")
}

impl FromStr for HandKind {
    type Err = UnknownHand;

    fn from_str(s: &str) -> Result<HandKind, UnknownHand> {
        match s {
            "world" => return Ok(HandKind::World),
            "mujoco" => return Ok(HandKind::Mujoco),
            "allegro" => return Err(BadAllegro::NoBus(s.to_string()).into()),
            _ => {}
        }
        if let Some(spec) = s.strip_prefix("allegro:") {
            return Ok(HandKind::Allegro(Box::new(AllegroOptions::parse(spec)?)));
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
    fn has(&self, kind: &HandKind) -> bool;
    /// A fresh hand of `kind` for `scene`.
    fn open(
        &self,
        kind: &HandKind,
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
    fn has(&self, kind: &HandKind) -> bool {
        *kind == HandKind::World
    }

    fn open(
        &self,
        kind: &HandKind,
        scene: SceneKind,
        options: &HandOptions,
    ) -> Result<Box<dyn Hand>, HandError> {
        match kind {
            HandKind::World => open_world(scene, options),
            other => Err(HandError::NotInBinary {
                kind: other.clone(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_ones_list_the_allowed() {
        for name in [
            "world",
            "mujoco",
            "allegro:emulated",
            "allegro:can0,pose=file:p.jsonl",
        ] {
            let k: HandKind = name.parse().unwrap();
            assert_eq!(k.to_string(), name);
            let json = serde_json::to_string(&k).unwrap();
            assert_eq!(json, format!("\"{name}\""));
            assert_eq!(serde_json::from_str::<HandKind>(&json).unwrap(), k);
        }
        assert_eq!(
            "allegro:emulated".parse::<HandKind>().unwrap().name(),
            "allegro"
        );
        let e = "isaac".parse::<HandKind>().unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown hand `isaac` (allowed: world, mujoco, allegro:IFACE)"
        );
        let e = "allegro".parse::<HandKind>().unwrap_err().to_string();
        assert!(
            e.starts_with("hand allegro: `allegro`: name the bus"),
            "{e}"
        );
        let e = "host/data/allegro_v4.json"
            .parse::<HandKind>()
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "`host/data/allegro_v4.json` is not a hand (allowed: world, mujoco, allegro:IFACE); \
             a hand description file is the hand model"
        );
    }

    #[test]
    fn the_world_factory_opens_our_world_only() {
        let h = WorldHands
            .open(&HandKind::World, SceneKind::Card, &HandOptions::default())
            .unwrap();
        assert_eq!(h.name(), "world");
        assert!(WorldHands.has(&HandKind::World) && !WorldHands.has(&HandKind::Mujoco));
        assert!(
            WorldHands
                .open(&HandKind::Mujoco, SceneKind::Card, &HandOptions::default())
                .is_err()
        );
        let noisy = HandOptions {
            noise: TrackerNoise::new(0.001, 0.0).unwrap(),
            seed: 1,
        };
        let e = WorldHands
            .open(&HandKind::World, SceneKind::Card, &noisy)
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
