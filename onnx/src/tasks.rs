//! The tasks a model can be trained for and their trajectory layout (`CONTRACTS.md` §2).

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
}

fn joints(prefix: &str, fingers: &[&str]) -> Vec<String> {
    fingers
        .iter()
        .flat_map(|f| (0..4).map(move |j| format!("{prefix}_{f}_{j}")))
        .collect()
}

fn forces(names: &[&str]) -> Vec<String> {
    names
        .iter()
        .flat_map(|f| {
            ["x", "y", "z"]
                .into_iter()
                .map(move |a| format!("f_{f}_{a}"))
        })
        .collect()
}

/// The layout of a known task, `None` for a name the contract does not define.
pub fn task_layout(name: &str) -> Option<TaskLayout> {
    match name {
        "screwdriver" => {
            let fingers = ["index", "middle", "thumb"];
            let mut state = joints("q", &fingers);
            state.extend(["roll", "pitch", "cos_yaw", "sin_yaw"].map(String::from));
            let mut action = joints("dq", &fingers);
            action.extend(forces(&fingers));
            Some(TaskLayout {
                name: "screwdriver",
                horizon: 13,
                fingers: 3,
                state_columns: state,
                action_columns: action,
            })
        }
        "card" => {
            let fingers = ["index", "middle"];
            let mut state = joints("q", &fingers);
            state.extend(["x", "y", "cos_theta", "sin_theta"].map(String::from));
            let mut action = joints("dq", &fingers);
            action.extend(forces(&["index", "middle", "env"]));
            Some(TaskLayout {
                name: "card",
                horizon: 9,
                fingers: 2,
                state_columns: state,
                action_columns: action,
            })
        }
        _ => None,
    }
}

/// Names of the tasks the contract defines.
pub const KNOWN_TASKS: [&str; 2] = ["screwdriver", "card"];

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
