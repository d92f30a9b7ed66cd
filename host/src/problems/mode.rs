//! Tasks and contact modes (CONTRACTS §2).

use crate::scenes::SceneKind;

/// A contact mode: one entry per task finger, `true` = in contact, `false` = regrasping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Screwdriver, all three fingers turn it `(+1,+1,+1)`.
    Turn,
    /// Screwdriver, thumb and middle hold, index regrasps `(−1,+1,+1)`.
    IndexRegrasp,
    /// Screwdriver, index holds the cap, thumb and middle regrasp `(+1,−1,−1)`.
    ThumbMiddleRegrasp,
    /// Card, index pushes, middle regrasps `(+1,−1)`.
    CardIndex,
    /// Card, middle pushes, index regrasps `(−1,+1)`.
    CardMiddle,
    /// Card, both push `(+1,+1)`.
    CardBoth,
    /// Card, both regrasp `(−1,−1)`.
    CardRegrasp,
}

/// An unknown mode name for a task.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown contact mode `{name}` for task {task}; expected one of: {expected}")]
pub struct UnknownMode {
    /// The name given.
    pub name: String,
    /// The task.
    pub task: &'static str,
    /// The valid names.
    pub expected: String,
}

impl Mode {
    /// The modes of a task.
    pub fn all(task: SceneKind) -> &'static [Mode] {
        match task {
            SceneKind::Screwdriver => &[Mode::Turn, Mode::IndexRegrasp, Mode::ThumbMiddleRegrasp],
            SceneKind::Card => &[
                Mode::CardIndex,
                Mode::CardMiddle,
                Mode::CardBoth,
                Mode::CardRegrasp,
            ],
        }
    }

    /// The task a mode belongs to.
    pub fn task(self) -> SceneKind {
        match self {
            Mode::Turn | Mode::IndexRegrasp | Mode::ThumbMiddleRegrasp => SceneKind::Screwdriver,
            _ => SceneKind::Card,
        }
    }

    /// The CONTRACTS name.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Turn => "turn",
            Mode::IndexRegrasp => "index-regrasp",
            Mode::ThumbMiddleRegrasp => "thumb-middle-regrasp",
            Mode::CardIndex => "index",
            Mode::CardMiddle => "middle",
            Mode::CardBoth => "both",
            Mode::CardRegrasp => "regrasp",
        }
    }

    /// Parse a mode name of `task`.
    pub fn from_name(task: SceneKind, name: &str) -> Result<Mode, UnknownMode> {
        Mode::all(task)
            .iter()
            .copied()
            .find(|m| m.name() == name)
            .ok_or_else(|| UnknownMode {
                name: name.to_string(),
                task: task.name(),
                expected: Mode::all(task)
                    .iter()
                    .map(|m| m.name())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// Contact flags in task-finger order.
    pub fn contacts(self) -> &'static [bool] {
        match self {
            Mode::Turn => &[true, true, true],
            Mode::IndexRegrasp => &[false, true, true],
            Mode::ThumbMiddleRegrasp => &[true, false, false],
            Mode::CardIndex => &[true, false],
            Mode::CardMiddle => &[false, true],
            Mode::CardBoth => &[true, true],
            Mode::CardRegrasp => &[false, false],
        }
    }

    /// The ±1 contact vector.
    pub fn vector(self) -> Vec<f64> {
        self.contacts()
            .iter()
            .map(|&c| if c { 1.0 } else { -1.0 })
            .collect()
    }

    /// Whether this mode moves the object toward the task goal (turn, card pushes).
    pub fn moves_object(self) -> bool {
        matches!(
            self,
            Mode::Turn | Mode::CardIndex | Mode::CardMiddle | Mode::CardBoth
        )
    }
}
