//! The tasks a model can be trained for and their trajectory layout (`docs/contracts.md` §2): the
//! kernel's [`Task`] sizes and column names, as owned strings for the contract checks.

use dips_kernel::mode::Task;

/// Layout of one task's trajectory rows, as the contract fixes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskLayout {
    /// Task name (`dips.task`).
    pub name: &'static str,
    /// Rows per segment, `T = H + 1`.
    pub horizon: usize,
    /// Fingers in the contact-mode vector.
    pub fingers: usize,
    /// State column names.
    pub state_columns: Vec<String>,
    /// Action column names.
    pub action_columns: Vec<String>,
}

impl TaskLayout {
    /// All `D` column names, state first.
    pub fn columns(&self) -> Vec<String> {
        self.state_columns
            .iter()
            .chain(&self.action_columns)
            .cloned()
            .collect()
    }

    /// The layout of `task`.
    pub fn of(task: Task) -> Self {
        let dims = task.dims();
        let owned = |c: &[&str]| c.iter().map(|s| (*s).to_string()).collect();
        Self {
            name: task.name(),
            horizon: dims.horizon,
            fingers: dims.fingers,
            state_columns: owned(task.state_columns()),
            action_columns: owned(task.action_columns()),
        }
    }
}

/// The layout of a known task, `None` for a name the contract does not define.
pub fn task_layout(name: &str) -> Option<TaskLayout> {
    name.parse::<Task>().ok().map(TaskLayout::of)
}

/// Names of the tasks the contract defines.
pub const KNOWN_TASKS: [&str; 2] = [Task::ALL[0].name(), Task::ALL[1].name()];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_match_contract_table() {
        let s = task_layout("screwdriver").unwrap();
        assert_eq!((s.state_columns.len(), s.action_columns.len()), (16, 21));
        assert_eq!(s.columns()[14], "cos_yaw");
        assert_eq!(s.action_columns[12], "f_index_x");
        let c = task_layout("card").unwrap();
        assert_eq!((c.state_columns.len(), c.action_columns.len()), (12, 17));
        assert_eq!(c.action_columns[16], "f_env_z");
        assert!(task_layout("door").is_none());
    }
}
