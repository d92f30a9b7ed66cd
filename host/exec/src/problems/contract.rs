//! Conversion between the problem's rows and the `docs/contracts.md` §2 trajectory layout used by
//! datasets, diffusion and the search.
//!
//! Contract: `T = H + 1` rows `[s_t, u_t]`, row 0 holding the start state, the last row's
//! action zero, angles as `(cos, sin)`, one force triple per task finger (zero for regrasping
//! fingers) and the card's table force. Problem: `H` rows `[s_{t+1}, u_t]`, angles as angles,
//! force triples of the contact fingers only, the object in problem units.

use super::allegro::AllegroProblem;
use dips_csvto::Problem;
use dips_world::scenes::SceneKind;

/// A contract trajectory that does not fit the problem.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LayoutError {
    /// Wrong number of values.
    #[error("contract trajectory has {got} values, expected {rows} rows × {cols} columns")]
    Length {
        /// Values given.
        got: usize,
        /// Rows expected (`H + 1`).
        rows: usize,
        /// Columns expected (`D`).
        cols: usize,
    },
    /// A value is NaN or infinite.
    #[error("contract trajectory value at row {row}, column {col} is not finite")]
    NotFinite {
        /// Row.
        row: usize,
        /// Column.
        col: usize,
    },
}

/// Columns `(state, action)` of a contract row for `task` (the kernel's layout).
pub fn contract_dims(task: SceneKind) -> (usize, usize) {
    let d = task.task().dims();
    (d.state_dim, d.action_dim)
}

/// Column of the first force column of task finger `i` in a contract row (`i = nf`: the
/// table force).
fn contract_force_col(task: SceneKind, _nf: usize, i: usize) -> usize {
    task.task().layout().force_col(i)
}

/// A task state `[q (4·nf), o (3)]` (metres and radians) in the contract layout: the joints,
/// the first two object coordinates, then `cos` and `sin` of the third (yaw or heading).
pub fn contract_state(state: &[f64]) -> Vec<f64> {
    let n = state.len();
    let mut out = Vec::with_capacity(n + 1);
    out.extend_from_slice(&state[..n.saturating_sub(1)]);
    if let Some(&angle) = state.last() {
        out.push(angle.cos());
        out.push(angle.sin());
    }
    out
}

/// The problem trajectory `x` (with the problem's start state) in the contract layout,
/// `(H + 1) × D` values row-major.
pub fn to_contract(problem: &AllegroProblem, x: &[f64]) -> Vec<f64> {
    let task = problem.task();
    let (dsc, duc) = contract_dims(task);
    let d = dsc + duc;
    let (h, n, ds) = (problem.horizon(), problem.row_dim(), problem.state_dim());
    let nf = problem.fingers();
    let nq = 4 * nf;
    let mut out = vec![0.0; (h + 1) * d];
    for t in 0..=h {
        let state = if t == 0 {
            problem.to_world_units(problem.start_state())
        } else {
            problem.to_world_units(&x[(t - 1) * n..(t - 1) * n + ds])
        };
        let row = &mut out[t * d..(t + 1) * d];
        row[..dsc].copy_from_slice(&contract_state(&state));
        if t < h {
            let pr = &x[t * n..(t + 1) * n];
            for c in 0..nq {
                row[dsc + c] = pr[problem.dq_col(c / 4, c % 4)];
            }
            for i in 0..nf {
                if let Some(s) = problem.contact_slot(i) {
                    for k in 0..3 {
                        row[contract_force_col(task, nf, i) + k] = pr[problem.force_col(s, k)];
                    }
                }
            }
            if problem.has_env_force() {
                for k in 0..3 {
                    row[contract_force_col(task, nf, nf) + k] = pr[problem.env_col(k)];
                }
            }
        }
    }
    out
}

/// A contract trajectory (`(H + 1) × D` values) as problem rows. Row 0's state is ignored (the
/// problem starts from its own start state); angles are unwrapped from the start's angle,
/// each row taking the branch nearest the previous one; force columns of regrasping fingers
/// are dropped.
pub fn from_contract(problem: &AllegroProblem, rows: &[f64]) -> Result<Vec<f64>, LayoutError> {
    let task = problem.task();
    let (dsc, duc) = contract_dims(task);
    let d = dsc + duc;
    let (h, n) = (problem.horizon(), problem.row_dim());
    if rows.len() != (h + 1) * d {
        return Err(LayoutError::Length {
            got: rows.len(),
            rows: h + 1,
            cols: d,
        });
    }
    if let Some(i) = rows.iter().position(|v| !v.is_finite()) {
        return Err(LayoutError::NotFinite {
            row: i / d,
            col: i % d,
        });
    }
    let nf = problem.fingers();
    let nq = 4 * nf;
    let start = problem.to_world_units(problem.start_state());
    let mut angle = start[nq + 2];
    let mut x = vec![0.0; h * n];
    for t in 0..h {
        let next = &rows[(t + 1) * d..(t + 2) * d];
        let cur = &rows[t * d..(t + 1) * d];
        let raw = next[nq + 3].atan2(next[nq + 2]);
        let turns = ((angle - raw) / std::f64::consts::TAU).round();
        angle = raw + turns * std::f64::consts::TAU;
        let mut state = next[..nq + 2].to_vec();
        state.push(angle);
        let state = problem.to_problem_units(&state);
        let pr = &mut x[t * n..(t + 1) * n];
        pr[..nq + 3].copy_from_slice(&state);
        for c in 0..nq {
            pr[problem.dq_col(c / 4, c % 4)] = cur[dsc + c];
        }
        for i in 0..nf {
            if let Some(s) = problem.contact_slot(i) {
                for k in 0..3 {
                    pr[problem.force_col(s, k)] = cur[contract_force_col(task, nf, i) + k];
                }
            }
        }
        if problem.has_env_force() {
            for k in 0..3 {
                pr[problem.env_col(k)] = cur[contract_force_col(task, nf, nf) + k];
            }
        }
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::init::default_particles;
    use crate::problems::{Mode, ProblemSpec};
    use dips_kernel::rng::KernelRng;
    use dips_world::kinematics::HandModel;

    fn problem(mode: Mode, yaw: f64) -> AllegroProblem {
        let task = SceneKind::from(mode.task());
        let q = task.default_joints();
        let mut start = Vec::new();
        for f in task.task_fingers() {
            start.extend_from_slice(&q[f.index()]);
        }
        start.extend_from_slice(&[0.0, 0.0, yaw]);
        let spec = ProblemSpec {
            task,
            mode,
            horizon: 5,
            start,
            goal: [0.0, 0.0, yaw],
        };
        AllegroProblem::new(&HandModel::allegro_v4(), &spec).expect("valid spec")
    }

    #[test]
    fn round_trip_through_the_contract_layout() {
        for mode in [
            Mode::Turn,
            Mode::IndexRegrasp,
            Mode::CardMiddle,
            Mode::CardBoth,
        ] {
            // A start yaw near π so the unwrapping is exercised.
            let p = problem(mode, 3.1);
            let mut rng = KernelRng::seed_from_u64(2);
            let mut x = default_particles(&p, mode, 1, &mut rng).remove(0);
            let n = p.row_dim();
            let nq = 4 * p.fingers();
            for t in 0..5 {
                x[t * n + nq + 2] += 0.03 * (t as f64 + 1.0);
            }
            let c = to_contract(&p, &x);
            let (dsc, duc) = contract_dims(mode.task().into());
            assert_eq!(c.len(), 6 * (dsc + duc));
            // Last row's action is zero; regrasping fingers' force columns are zero.
            assert!(c[5 * (dsc + duc) + dsc..].iter().all(|&v| v == 0.0));
            if mode == Mode::IndexRegrasp {
                assert!(c[dsc + 12..dsc + 15].iter().all(|&v| v == 0.0));
            }
            let back = from_contract(&p, &c).expect("fits");
            for (a, b) in x.iter().zip(&back) {
                assert!((a - b).abs() < 1e-12, "{mode:?}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn wrong_sizes_and_nan_are_typed_errors() {
        let p = problem(Mode::Turn, 0.0);
        assert!(matches!(
            from_contract(&p, &[0.0; 10]),
            Err(LayoutError::Length {
                rows: 6,
                cols: 37,
                ..
            })
        ));
        let mut c = vec![0.0; 6 * 37];
        c[40] = f64::NAN;
        assert_eq!(
            from_contract(&p, &c),
            Err(LayoutError::NotFinite { row: 1, col: 3 })
        );
    }
}
