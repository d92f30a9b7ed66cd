//! Contact modes and the two tasks (`docs/contracts.md` §2).
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

/// A set of a task's modes, one bit per [`ModeId`] (bit `i` = mode `i`): which modes the
/// search may execute first ([`crate::search::Problem::first_modes`]). The empty set and bits
/// beyond a task's table are representable; [`ModeSet::valid_for`] says whether a set names at
/// least one of a task's modes and nothing else.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ModeSet(pub u8);

const _: () = assert!(MAX_MODES <= 8, "ModeSet holds one bit per mode in a u8");

impl ModeSet {
    /// No mode.
    pub const EMPTY: Self = Self(0);

    /// Every mode of `task`.
    pub const fn all(task: Task) -> Self {
        Self(((1u16 << task.mode_count()) - 1) as u8)
    }

    /// Whether `id` is in the set.
    pub const fn contains(self, id: ModeId) -> bool {
        id.index() < 8 && self.0 & (1 << id.0) != 0
    }

    /// The set with `id` added (ids beyond the bits are ignored).
    pub const fn with(self, id: ModeId) -> Self {
        if id.index() < 8 {
            Self(self.0 | (1 << id.0))
        } else {
            self
        }
    }

    /// Whether the set holds no mode.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Whether the set names at least one of `task`'s modes and no mode beyond its table.
    pub const fn valid_for(self, task: Task) -> bool {
        !self.is_empty() && self.0 & !Self::all(task).0 == 0
    }
}

/// A named mode of a task.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModeSpec {
    /// The name used on the command line and in results.
    pub name: &'static str,
    /// Its contact vector.
    pub mode: ContactMode,
    /// The typed name of the mode.
    pub named: TaskMode,
}

const fn spec(named: TaskMode, name: &'static str, contact: u8, fingers: u8) -> ModeSpec {
    ModeSpec {
        name,
        mode: ContactMode { contact, fingers },
        named,
    }
}

/// Screwdriver modes, fingers (index, middle, thumb) at bits 0, 1, 2. The table is the one
/// definition of the modes: names, contact vectors and order ([`ModeId`] indexes it).
const SCREWDRIVER_MODES: [ModeSpec; 3] = [
    spec(TaskMode::Turn, "turn", 0b111, 3),
    spec(TaskMode::IndexRegrasp, "index-regrasp", 0b110, 3),
    spec(
        TaskMode::ThumbMiddleRegrasp,
        "thumb-middle-regrasp",
        0b001,
        3,
    ),
];

/// Card modes, fingers (index, middle) at bits 0, 1.
const CARD_MODES: [ModeSpec; 4] = [
    spec(TaskMode::CardIndex, "index", 0b01, 2),
    spec(TaskMode::CardMiddle, "middle", 0b10, 2),
    spec(TaskMode::CardBoth, "both", 0b11, 2),
    spec(TaskMode::CardRegrasp, "regrasp", 0b00, 2),
];

/// Every named mode of both tasks, as a type (the host's CSVTO problems match on it). Its
/// facts come from the task's mode table ([`Task::modes`]): [`TaskMode::id`] is the only
/// mapping, and `names_round_trip` checks it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TaskMode {
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

impl TaskMode {
    /// The task the mode belongs to.
    pub const fn task(self) -> Task {
        match self {
            TaskMode::Turn | TaskMode::IndexRegrasp | TaskMode::ThumbMiddleRegrasp => {
                Task::Screwdriver
            }
            _ => Task::Card,
        }
    }

    /// Its index in the task's mode table.
    pub const fn id(self) -> ModeId {
        ModeId(match self {
            TaskMode::Turn | TaskMode::CardIndex => 0,
            TaskMode::IndexRegrasp | TaskMode::CardMiddle => 1,
            TaskMode::ThumbMiddleRegrasp | TaskMode::CardBoth => 2,
            TaskMode::CardRegrasp => 3,
        })
    }

    /// The mode's table entry.
    pub const fn spec(self) -> &'static ModeSpec {
        &self.task().modes()[self.id().index()]
    }

    /// The `docs/contracts.md` §2 name.
    pub const fn name(self) -> &'static str {
        self.spec().name
    }

    /// The contact vector.
    pub const fn contact_mode(self) -> ContactMode {
        self.spec().mode
    }

    /// Whether task finger `i` is in contact.
    pub const fn in_contact(self, i: usize) -> bool {
        self.contact_mode().in_contact(i)
    }

    /// Whether the mode moves the object toward the task goal (turn, the card's pushes):
    /// the mode's object goal ([`crate::task::mode_goal`]) moves it.
    pub const fn moves_object(self) -> bool {
        matches!(
            self,
            TaskMode::Turn | TaskMode::CardIndex | TaskMode::CardMiddle | TaskMode::CardBoth
        )
    }

    /// The mode of `task` with table index `id`.
    pub fn from_id(task: Task, id: ModeId) -> Option<Self> {
        task.modes().get(id.index()).map(|s| s.named)
    }

    /// The mode of `task` named `name`.
    pub fn from_name(task: Task, name: &str) -> Result<Self, UnknownName> {
        Self::from_id(task, task.mode_by_name(name)?).ok_or(UnknownName)
    }
}

/// `docs/contracts.md` §2 column names (exactly these strings).
const SCREWDRIVER_STATE_COLUMNS: [&str; 16] = [
    "q_index_0",
    "q_index_1",
    "q_index_2",
    "q_index_3",
    "q_middle_0",
    "q_middle_1",
    "q_middle_2",
    "q_middle_3",
    "q_thumb_0",
    "q_thumb_1",
    "q_thumb_2",
    "q_thumb_3",
    "roll",
    "pitch",
    "cos_yaw",
    "sin_yaw",
];
const SCREWDRIVER_ACTION_COLUMNS: [&str; 21] = [
    "dq_index_0",
    "dq_index_1",
    "dq_index_2",
    "dq_index_3",
    "dq_middle_0",
    "dq_middle_1",
    "dq_middle_2",
    "dq_middle_3",
    "dq_thumb_0",
    "dq_thumb_1",
    "dq_thumb_2",
    "dq_thumb_3",
    "f_index_x",
    "f_index_y",
    "f_index_z",
    "f_middle_x",
    "f_middle_y",
    "f_middle_z",
    "f_thumb_x",
    "f_thumb_y",
    "f_thumb_z",
];
const CARD_STATE_COLUMNS: [&str; 12] = [
    "q_index_0",
    "q_index_1",
    "q_index_2",
    "q_index_3",
    "q_middle_0",
    "q_middle_1",
    "q_middle_2",
    "q_middle_3",
    "x",
    "y",
    "cos_theta",
    "sin_theta",
];
const CARD_ACTION_COLUMNS: [&str; 17] = [
    "dq_index_0",
    "dq_index_1",
    "dq_index_2",
    "dq_index_3",
    "dq_middle_0",
    "dq_middle_1",
    "dq_middle_2",
    "dq_middle_3",
    "f_index_x",
    "f_index_y",
    "f_index_z",
    "f_middle_x",
    "f_middle_y",
    "f_middle_z",
    "f_env_x",
    "f_env_y",
    "f_env_z",
];

/// Where things are in a task's `docs/contracts.md` §2 row `[s_t, u_t]`: finger joints, the object
/// pose (two plain coordinates, then the `(cos, sin)` of its angle), the joint deltas, one
/// force triple per finger and, for the card, the table force. The one definition of the
/// trajectory layout; sizes follow from the finger count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RowLayout {
    /// Task fingers (4 joints and one force triple each).
    pub fingers: usize,
    /// Whether the action ends with an environment (table) force triple.
    pub env_force: bool,
}

impl RowLayout {
    /// Joint columns `q` (`4·fingers`), from column 0.
    pub const fn joints(&self) -> usize {
        4 * self.fingers
    }

    /// First object column (roll/x); the object has [`Self::OBJECT_COLUMNS`] columns.
    pub const fn object(&self) -> usize {
        self.joints()
    }

    /// Object columns in the row: two plain coordinates, `cos` and `sin` of the angle.
    pub const OBJECT_COLUMNS: usize = 4;

    /// Column of the angle's `cos` (`sin` follows).
    pub const fn angle_cos(&self) -> usize {
        self.object() + 2
    }

    /// State columns.
    pub const fn state_dim(&self) -> usize {
        self.joints() + Self::OBJECT_COLUMNS
    }

    /// First action column (`Δq`, then the forces).
    pub const fn action(&self) -> usize {
        self.state_dim()
    }

    /// Action columns: `Δq`, a force triple per finger, the environment force.
    pub const fn action_dim(&self) -> usize {
        self.joints() + 3 * self.fingers + if self.env_force { 3 } else { 0 }
    }

    /// Column of `Δq` of finger `i`, joint `k`.
    pub const fn dq_col(&self, i: usize, k: usize) -> usize {
        self.action() + 4 * i + k
    }

    /// First column of finger `i`'s force triple; `i == fingers` is the environment force.
    pub const fn force_col(&self, i: usize) -> usize {
        self.action() + self.joints() + 3 * i
    }

    /// Object pose `(a, b, angle)` of a row: `(roll, pitch, yaw)` or `(x, y, θ)`, the angle
    /// from `atan2(sin, cos)`. `None` when the row is too short.
    pub fn pose(&self, row: &[f32]) -> Option<[f32; 3]> {
        let o = row.get(self.object()..self.object() + Self::OBJECT_COLUMNS)?;
        Some([o[0], o[1], libm::atan2f(o[3], o[2])])
    }
}

/// Sizes of one trajectory segment (`docs/contracts.md` §2), run-time values.
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

impl core::str::FromStr for Task {
    type Err = crate::name::UnknownValue;

    /// A task by its name ([`Task::name`]); the error names the value and the tasks.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        crate::name::UnknownValue::find("task", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl fmt::Display for Task {
    /// The task's name ([`Task::name`]).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

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

    /// Every task's name, in [`Task::ALL`] order.
    pub const NAMES: [&'static str; 2] = [Task::Screwdriver.name(), Task::Card.name()];

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

    /// The task's modes as [`TaskMode`]s, in table order.
    pub const fn named_modes(self) -> &'static [TaskMode] {
        match self {
            Task::Screwdriver => &[
                TaskMode::Turn,
                TaskMode::IndexRegrasp,
                TaskMode::ThumbMiddleRegrasp,
            ],
            Task::Card => &[
                TaskMode::CardIndex,
                TaskMode::CardMiddle,
                TaskMode::CardBoth,
                TaskMode::CardRegrasp,
            ],
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

    /// The row layout of `docs/contracts.md` §2.
    pub const fn layout(self) -> RowLayout {
        match self {
            Task::Screwdriver => RowLayout {
                fingers: 3,
                env_force: false,
            },
            Task::Card => RowLayout {
                fingers: 2,
                env_force: true,
            },
        }
    }

    /// Planning steps per mode segment `H` (the segment has `H + 1` rows).
    pub const fn steps_per_mode(self) -> usize {
        match self {
            Task::Screwdriver => 12,
            Task::Card => 8,
        }
    }

    /// The segment sizes of `docs/contracts.md` §2.
    pub const fn dims(self) -> SegmentDims {
        let l = self.layout();
        SegmentDims {
            horizon: self.steps_per_mode() + 1,
            state_dim: l.state_dim(),
            action_dim: l.action_dim(),
            fingers: l.fingers,
        }
    }

    /// The state column names of `docs/contracts.md` §2.
    pub const fn state_columns(self) -> &'static [&'static str] {
        match self {
            Task::Screwdriver => &SCREWDRIVER_STATE_COLUMNS,
            Task::Card => &CARD_STATE_COLUMNS,
        }
    }

    /// The action column names of `docs/contracts.md` §2.
    pub const fn action_columns(self) -> &'static [&'static str] {
        match self {
            Task::Screwdriver => &SCREWDRIVER_ACTION_COLUMNS,
            Task::Card => &CARD_ACTION_COLUMNS,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for task in Task::ALL {
            assert_eq!(task.name().parse::<Task>(), Ok(task));
            for (i, m) in task.modes().iter().enumerate() {
                let id = task.mode_by_name(m.name).unwrap();
                assert_eq!(id.index(), i);
                assert_eq!(task.mode_name(id), Some(m.name));
                assert_eq!(task.mode_by_contact(m.mode), Some(id));
                assert_eq!(m.mode.fingers(), task.finger_names().len());
                let named = task.named_modes()[i];
                assert_eq!(named, m.named);
                assert_eq!((named.task(), named.id(), named.name()), (task, id, m.name));
                assert_eq!(TaskMode::from_name(task, m.name), Ok(named));
                assert_eq!(named.contact_mode(), m.mode);
            }
            assert_eq!(task.named_modes().len(), task.mode_count());
            assert!(task.mode_count() <= MAX_MODES);
            assert!(task.dims().state_dim <= MAX_STATE_DIM);
            assert_eq!(task.dims().fingers, task.finger_names().len());
        }
        assert_eq!(
            "valve".parse::<Task>(),
            Err(crate::name::UnknownValue::new(
                "task",
                "valve",
                &Task::NAMES
            ))
        );
        assert_eq!(Task::Card.mode_by_name("turn"), Err(UnknownName));
    }

    #[test]
    fn layout_sizes_and_column_names_agree() {
        use std::format;
        for task in Task::ALL {
            let (l, d) = (task.layout(), task.dims());
            assert_eq!(task.state_columns().len(), d.state_dim);
            assert_eq!(task.action_columns().len(), d.action_dim);
            let fingers = task.finger_names();
            for (i, f) in fingers.iter().enumerate() {
                for k in 0..4 {
                    assert_eq!(task.state_columns()[4 * i + k], format!("q_{f}_{k}"));
                    let dq = l.dq_col(i, k) - l.action();
                    assert_eq!(task.action_columns()[dq], format!("dq_{f}_{k}"));
                }
                let fc = l.force_col(i) - l.action();
                assert_eq!(task.action_columns()[fc], format!("f_{f}_x"));
            }
            let angle = if task == Task::Card { "theta" } else { "yaw" };
            assert_eq!(task.state_columns()[l.angle_cos()], format!("cos_{angle}"));
            if l.env_force {
                assert_eq!(
                    task.action_columns()[l.force_col(l.fingers) - l.action()],
                    "f_env_x"
                );
            }
        }
        assert_eq!(Task::Screwdriver.dims().horizon, 13);
        assert_eq!(Task::Card.dims().dim(), 29);
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
