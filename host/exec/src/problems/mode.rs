//! Tasks and contact modes (docs/contracts.md §2): the kernel's [`TaskMode`](dips_kernel::mode::TaskMode) under the host's name,
//! and the parse error the command line reports.

pub use dips_kernel::mode::TaskMode as Mode;

use dips_world::scenes::SceneKind;

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

/// Parse a mode name of `task`, naming the valid ones on failure.
pub fn parse_mode(task: SceneKind, name: &str) -> Result<Mode, UnknownMode> {
    Mode::from_name(task.task(), name).map_err(|_| UnknownMode {
        name: name.to_string(),
        task: task.name(),
        expected: task
            .modes()
            .iter()
            .map(|m| m.name())
            .collect::<Vec<_>>()
            .join(", "),
    })
}
