//! Contact modes and the two tasks (`CONTRACTS.md` §2).
//!
//! A contact mode holds one sign per finger: `+1` in contact, `-1` regrasping. A [`Task`]
//! fixes the finger order, the named modes and the trajectory sizes. Modes are referred to
//! by [`ModeId`], their index in the task's mode table, so the search and the prior never
//! compare vectors.

use core::fmt;

/// The most fingers a contact mode can describe.
pub const MAX_FINGERS: usize = 8;

/// The most modes a task defines (and the most the search expands from one node).
pub const MAX_MODES: usize = 4;

/// The most state columns a task may have (the screwdriver's 16; the card has 12).
pub const MAX_STATE_DIM: usize = 16;

/// One sign per finger: bit `i` of `contact` set means finger `i` is in contact (`+1`),
/// clear means it regrasps (`-1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ContactMode {
    contact: u8,
    fingers: u8,
}

impl ContactMode {
    /// A placeholder for unused buffer entries: zero fingers.
    pub(crate) const PLACEHOLDER: ContactMode = ContactMode {
        contact: 0,
        fingers: 0,
    };

    /// A mode from its signs (`> 0` is contact, anything else regrasp). `None` when there are
    /// no fingers or more than [`MAX_FINGERS`].
    pub fn from_signs(signs: &[i8]) -> Option<Self> {
        if signs.is_empty() || signs.len() > MAX_FINGERS {
            return None;
        }
        let mut contact = 0u8;
        for (i, &s) in signs.iter().enumerate() {
            if s > 0 {
                contact |= 1 << i;
            }
        }
        Some(Self {
            contact,
            fingers: signs.len() as u8,
        })
    }

    /// Number of fingers the mode describes.
    pub const fn fingers(&self) -> usize {
        self.fingers as usize
    }

    /// Whether finger `i` is in contact (`false` past the last finger).
    pub const fn in_contact(&self, i: usize) -> bool {
        i < self.fingers as usize && self.contact & (1 << i) != 0
    }

    /// Number of fingers in contact.
    pub const fn contact_count(&self) -> u32 {
        self.contact.count_ones()
    }

    /// The sign of finger `i`: `+1`, `-1`, or `0` past the last finger.
    pub const fn sign(&self, i: usize) -> i8 {
        if i >= self.fingers as usize {
            0
        } else if self.contact & (1 << i) != 0 {
            1
        } else {
            -1
        }
    }

    /// Write the signs as `±1.0` (the model contract's `context` row) into `out[..fingers]`.
    /// Returns the number written (fewer when `out` is short).
    pub fn write_signs(&self, out: &mut [f32]) -> usize {
        let n = self.fingers().min(out.len());
        for (i, v) in out[..n].iter_mut().enumerate() {
            *v = f32::from(self.sign(i));
        }
        n
    }
}

/// A mode's index in its task's mode table ([`Task::modes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ModeId(pub u8);

impl ModeId {
    /// The index as `usize`.
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

/// A named mode of a task.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModeSpec {
    /// The name used on the command line and in results.
    pub name: &'static str,
    /// Its contact vector.
    pub mode: ContactMode,
}

const fn spec(name: &'static str, contact: u8, fingers: u8) -> ModeSpec {
    ModeSpec {
        name,
        mode: ContactMode { contact, fingers },
    }
}

/// Screwdriver modes, fingers (index, middle, thumb) at bits 0, 1, 2.
const SCREWDRIVER_MODES: [ModeSpec; 3] = [
    spec("turn", 0b111, 3),
    spec("index-regrasp", 0b110, 3),
    spec("thumb-middle-regrasp", 0b001, 3),
];

/// Card modes, fingers (index, middle) at bits 0, 1.
const CARD_MODES: [ModeSpec; 4] = [
    spec("index", 0b01, 2),
    spec("middle", 0b10, 2),
    spec("both", 0b11, 2),
    spec("regrasp", 0b00, 2),
];

/// Sizes of one trajectory segment (`CONTRACTS.md` §2), run-time values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SegmentDims {
    /// Rows per segment, `T = H + 1`.
    pub horizon: usize,
    /// State columns (`cos`/`sin` pairs count twice).
    pub state_dim: usize,
    /// Action columns.
    pub action_dim: usize,
    /// Fingers in a contact mode.
    pub fingers: usize,
}

impl SegmentDims {
    /// Columns per row, `D`.
    pub const fn dim(&self) -> usize {
        self.state_dim + self.action_dim
    }

    /// Floats per segment, `T * D`.
    pub const fn floats(&self) -> usize {
        self.horizon * self.dim()
    }
}

/// The manipulation tasks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Task {
    /// Turning a screwdriver with index, middle and thumb.
    Screwdriver,
    /// Sliding a card with index and middle.
    Card,
}

/// A task or mode name that is not known.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnknownName;

impl fmt::Display for UnknownName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("unknown name")
    }
}

impl core::error::Error for UnknownName {}

impl Task {
    /// Every task.
    pub const ALL: [Task; 2] = [Task::Screwdriver, Task::Card];

    /// The task's name (`screwdriver`, `card`).
    pub const fn name(self) -> &'static str {
        match self {
            Task::Screwdriver => "screwdriver",
            Task::Card => "card",
        }
    }

    /// Parse a task name.
    pub fn from_name(name: &str) -> Result<Self, UnknownName> {
        Self::ALL
            .into_iter()
            .find(|t| t.name() == name)
            .ok_or(UnknownName)
    }

    /// Finger names in mode order.
    pub const fn finger_names(self) -> &'static [&'static str] {
        match self {
            Task::Screwdriver => &["index", "middle", "thumb"],
            Task::Card => &["index", "middle"],
        }
    }

    /// The task's mode table; a [`ModeId`] indexes it.
    pub const fn modes(self) -> &'static [ModeSpec] {
        match self {
            Task::Screwdriver => &SCREWDRIVER_MODES,
            Task::Card => &CARD_MODES,
        }
    }

    /// Number of modes in the table.
    pub const fn mode_count(self) -> usize {
        self.modes().len()
    }

    /// The modes the search appends to a node (screwdriver: its 3 modes, the pregrasp's
    /// all-regrasp is not in the table; card: all 4).
    pub fn candidate_modes(self) -> impl Iterator<Item = ModeId> {
        (0..self.mode_count() as u8).map(ModeId)
    }

    /// The contact vector of a mode, `None` when the id is not in the table.
    pub fn contact_mode(self, id: ModeId) -> Option<ContactMode> {
        self.modes().get(id.index()).map(|s| s.mode)
    }

    /// The name of a mode, `None` when the id is not in the table.
    pub fn mode_name(self, id: ModeId) -> Option<&'static str> {
        self.modes().get(id.index()).map(|s| s.name)
    }

    /// The id of a named mode.
    pub fn mode_by_name(self, name: &str) -> Result<ModeId, UnknownName> {
        self.modes()
            .iter()
            .position(|s| s.name == name)
            .map(|i| ModeId(i as u8))
            .ok_or(UnknownName)
    }

    /// The id of a contact vector.
    pub fn mode_by_contact(self, mode: ContactMode) -> Option<ModeId> {
        self.modes()
            .iter()
            .position(|s| s.mode == mode)
            .map(|i| ModeId(i as u8))
    }

    /// The segment sizes of `CONTRACTS.md` §2.
    pub const fn dims(self) -> SegmentDims {
        match self {
            Task::Screwdriver => SegmentDims {
                horizon: 13,
                state_dim: 16,
                action_dim: 21,
                fingers: 3,
            },
            Task::Card => SegmentDims {
                horizon: 9,
                state_dim: 12,
                action_dim: 17,
                fingers: 2,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for task in Task::ALL {
            assert_eq!(Task::from_name(task.name()), Ok(task));
            for (i, m) in task.modes().iter().enumerate() {
                let id = task.mode_by_name(m.name).unwrap();
                assert_eq!(id.index(), i);
                assert_eq!(task.mode_name(id), Some(m.name));
                assert_eq!(task.mode_by_contact(m.mode), Some(id));
                assert_eq!(m.mode.fingers(), task.finger_names().len());
            }
            assert!(task.mode_count() <= MAX_MODES);
            assert!(task.dims().state_dim <= MAX_STATE_DIM);
            assert_eq!(task.dims().fingers, task.finger_names().len());
        }
        assert_eq!(Task::from_name("valve"), Err(UnknownName));
        assert_eq!(Task::Card.mode_by_name("turn"), Err(UnknownName));
    }

    #[test]
    fn contract_vectors() {
        let sd = Task::Screwdriver;
        let sig = |name| {
            let m = sd.contact_mode(sd.mode_by_name(name).unwrap()).unwrap();
            [m.sign(0), m.sign(1), m.sign(2)]
        };
        assert_eq!(sig("turn"), [1, 1, 1]);
        assert_eq!(sig("index-regrasp"), [-1, 1, 1]);
        assert_eq!(sig("thumb-middle-regrasp"), [1, -1, -1]);
        let c = Task::Card;
        let sig = |name| {
            let m = c.contact_mode(c.mode_by_name(name).unwrap()).unwrap();
            [m.sign(0), m.sign(1)]
        };
        assert_eq!(sig("index"), [1, -1]);
        assert_eq!(sig("middle"), [-1, 1]);
        assert_eq!(sig("both"), [1, 1]);
        assert_eq!(sig("regrasp"), [-1, -1]);
        assert_eq!(sd.candidate_modes().count(), 3);
        assert_eq!(c.candidate_modes().count(), 4);
    }

    #[test]
    fn signs_and_bounds() {
        let m = ContactMode::from_signs(&[1, -1, 1, 1, -1, -1, 1, -1]).unwrap();
        assert_eq!(m.fingers(), 8);
        assert_eq!(m.contact_count(), 4);
        let mut out = [0.0f32; 10];
        assert_eq!(m.write_signs(&mut out), 8);
        assert_eq!(&out[..8], &[1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0, -1.0]);
        assert_eq!(m.sign(8), 0);
        assert!(!m.in_contact(9));
        assert!(ContactMode::from_signs(&[1; 9]).is_none());
        assert!(ContactMode::from_signs(&[]).is_none());
        let mut short = [0.0f32; 2];
        assert_eq!(m.write_signs(&mut short), 2);
    }
}
