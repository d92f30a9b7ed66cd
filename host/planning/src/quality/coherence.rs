//! Physical coherence of trajectories in the contract layout: do the joint deltas agree with
//! the next row's joints, are the joints within their limits, are the contact forces inside the
//! friction cone, and do regrasping fingers keep clear of the object.

use dips_kernel::mode::Task;
use serde::Serialize;

use dips_exec::problems::allegro::{PLANNER_FRICTION, REGRASP_CLEARANCE};
use dips_exec::problems::{AllegroProblem, Mode, ProblemSpec};
use dips_world::kinematics::HandModel;
use dips_world::scenes::SceneKind;

/// Summary of a distribution.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct Dist {
    /// Values summarised.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Median.
    pub p50: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Largest value.
    pub max: f64,
}

impl Dist {
    /// The summary of `v` (all zero when empty).
    pub fn of(mut v: Vec<f64>) -> Self {
        if v.is_empty() {
            return Self {
                n: 0,
                mean: 0.0,
                p50: 0.0,
                p90: 0.0,
                max: 0.0,
            };
        }
        v.sort_by(f64::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        Self {
            n: v.len(),
            mean: v.iter().sum::<f64>() / v.len() as f64,
            p50: q(0.5),
            p90: q(0.9),
            max: v[v.len() - 1],
        }
    }
}

/// Coherence figures of a set of trajectories.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct Coherence {
    /// `|q_{r+1} − (q_r + Δq_r)|` per joint entry, rows `0 … T−2` (rad).
    pub dq_residual_rad: Dist,
    /// Fraction of joint entries outside the hand's limits.
    pub joints_outside_limits: f64,
    /// Largest distance of a joint beyond its limit (rad).
    pub joint_limit_excess_max_rad: f64,
    /// Friction-cone excess `max(0, ‖f_t‖ − μ·(−n·f))` of every contact finger's force at rows
    /// `0 … T−2`, with the outward normal at the next row's state and the planner's μ (N).
    pub friction_excess_n: Dist,
    /// Fraction of those forces whose excess is above 0.05 N.
    pub friction_violations: f64,
    /// Regrasp modes only: signed distance of the lifted fingers at rows `1 … T−2` (m).
    pub lifted_sdf_m: Dist,
    /// Fraction of those rows with `sdf ≥ δ` (δ = 1.5 cm).
    pub lifted_clear: f64,
}

/// The world state `[q, a, b, angle]` of a contract row's state columns.
pub fn world_state(task: Task, row: &[f32]) -> Vec<f64> {
    let l = task.layout();
    let mut s: Vec<f64> = row[..l.joints()].iter().map(|&v| f64::from(v)).collect();
    if let Some(p) = l.pose(row) {
        s.extend(p.iter().map(|&v| f64::from(v)));
    }
    s
}

/// Measure `trajs` (`[n, T, D]` raw contract rows) with their contexts `[n, F]`.
pub fn measure(scene: SceneKind, hand: &HandModel, trajs: &[f32], contexts: &[f32]) -> Coherence {
    let task = scene.task();
    let dims = task.dims();
    let l = task.layout();
    let (t, d, f) = (dims.horizon, dims.dim(), dims.fingers);
    let fingers = scene.task_fingers();
    let mut dq_res = Vec::new();
    let (mut outside, mut joint_entries, mut excess_max) = (0usize, 0usize, 0f64);
    let mut friction = Vec::new();
    let mut lifted = Vec::new();
    for (traj, ctx) in trajs.chunks_exact(t * d).zip(contexts.chunks_exact(f)) {
        let rows: Vec<&[f32]> = traj.chunks_exact(d).collect();
        // Joints and limits.
        for row in &rows {
            for (i, fg) in fingers.iter().enumerate() {
                let lim = hand.joint_limits(*fg);
                for (k, (lo, hi)) in lim.iter().enumerate() {
                    let q = f64::from(row[4 * i + k]);
                    let ex = (lo - q).max(q - hi).max(0.0);
                    joint_entries += 1;
                    if ex > 0.0 {
                        outside += 1;
                        excess_max = excess_max.max(ex);
                    }
                }
            }
        }
        for r in 0..t - 1 {
            for i in 0..f {
                for k in 0..4 {
                    let q0 = f64::from(rows[r][4 * i + k]);
                    let q1 = f64::from(rows[r + 1][4 * i + k]);
                    let dq = f64::from(rows[r][l.dq_col(i, k)]);
                    dq_res.push((q1 - q0 - dq).abs());
                }
            }
        }
        // Geometry needs the mode's problem (normals, signed distances).
        let signs: Vec<i8> = ctx.iter().map(|&c| if c > 0.0 { 1 } else { -1 }).collect();
        let Some(mode) = task
            .modes()
            .iter()
            .find(|m| (0..f).all(|i| m.mode.in_contact(i) == (signs[i] > 0)))
            .map(|m| m.named)
        else {
            continue;
        };
        let Some(problem) = problem_for(scene, hand, mode, t - 1, &world_state(task, rows[0]))
        else {
            continue;
        };
        for r in 0..t - 1 {
            let next = world_state(task, rows[r + 1]);
            let o = problem.object_pose(&next);
            for (i, &sign) in signs.iter().enumerate() {
                let q = AllegroProblem::finger_joints(&next, i);
                if sign > 0 {
                    let n = problem.contact_normal(i, &q, &o);
                    let c = l.force_col(i);
                    let fv = [0, 1, 2].map(|k| f64::from(rows[r][c + k]));
                    let fn_ = -(n[0] * fv[0] + n[1] * fv[1] + n[2] * fv[2]);
                    let ft = [0, 1, 2].map(|k| fv[k] + fn_ * n[k]);
                    let ftn = (ft[0] * ft[0] + ft[1] * ft[1] + ft[2] * ft[2]).sqrt();
                    friction.push((ftn - PLANNER_FRICTION * fn_).max(0.0));
                } else if r + 1 < t - 1 {
                    lifted.push(problem.finger_sdf(i, &q, &o));
                }
            }
        }
    }
    let clear = if lifted.is_empty() {
        0.0
    } else {
        lifted.iter().filter(|&&s| s >= REGRASP_CLEARANCE).count() as f64 / lifted.len() as f64
    };
    let viol = if friction.is_empty() {
        0.0
    } else {
        friction.iter().filter(|&&e| e > 0.05).count() as f64 / friction.len() as f64
    };
    Coherence {
        dq_residual_rad: Dist::of(dq_res),
        joints_outside_limits: outside as f64 / joint_entries.max(1) as f64,
        joint_limit_excess_max_rad: excess_max,
        friction_excess_n: Dist::of(friction),
        friction_violations: viol,
        lifted_sdf_m: Dist::of(lifted),
        lifted_clear: clear,
    }
}

/// The CSVTO problem of `mode` from `start` (world units), for its geometry.
fn problem_for(
    scene: SceneKind,
    hand: &HandModel,
    mode: Mode,
    horizon: usize,
    start: &[f64],
) -> Option<AllegroProblem> {
    let goal = [
        start[start.len() - 3],
        start[start.len() - 2],
        start[start.len() - 1],
    ];
    AllegroProblem::new(
        hand,
        &ProblemSpec {
            task: scene,
            mode,
            horizon,
            start: start.to_vec(),
            goal,
        },
    )
    .ok()
}

/// The object's motion over one trajectory: the change of the task's progress coordinate from
/// row 0 to the last row (screwdriver yaw in rad, wrapped to ±π; card `y` in m).
pub fn progress_delta(task: Task, traj: &[f32]) -> f64 {
    let dims = task.dims();
    let (d, h) = (dims.dim(), dims.horizon - 1);
    let layout = task.layout();
    let col = match task {
        Task::Screwdriver => 2,
        Task::Card => 1,
    };
    let at = |r: usize| {
        layout
            .pose(&traj[r * d..(r + 1) * d])
            .map_or(f64::NAN, |p| f64::from(p[col]))
    };
    let v = at(h) - at(0);
    match task {
        Task::Screwdriver => {
            let tau = std::f64::consts::TAU;
            (v + std::f64::consts::PI).rem_euclid(tau) - std::f64::consts::PI
        }
        Task::Card => v,
    }
}

/// The object's motion in one contact mode: what the search reads from a diffused segment
/// (its progress and the per-mode goal cost come from the object's columns).
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct ModeMotion {
    /// The contact vector (±1 per finger).
    pub context: Vec<f32>,
    /// Trajectories.
    pub n: usize,
    /// Mean progress change (rad or m).
    pub mean: f64,
    /// Its standard deviation.
    pub std: f64,
    /// Mean `|Δ − Δ_real|` against the real trajectory from the same start (diffused sets).
    pub mean_abs_error: Option<f64>,
}

/// [`ModeMotion`] per contact vector of `trajs`; `real` (the same starts and contexts, in the
/// same order) gives the paired error.
pub fn object_motion(
    task: Task,
    trajs: &[f32],
    contexts: &[f32],
    real: Option<&[f32]>,
) -> Vec<ModeMotion> {
    let dims = task.dims();
    let (td, f) = (dims.floats(), dims.fingers);
    let mut groups: Vec<(Vec<f32>, Vec<f64>, Vec<f64>)> = Vec::new();
    for (i, (traj, ctx)) in trajs
        .chunks_exact(td)
        .zip(contexts.chunks_exact(f))
        .enumerate()
    {
        let delta = progress_delta(task, traj);
        let err = real.map(|r| (delta - progress_delta(task, &r[i * td..(i + 1) * td])).abs());
        let g = match groups.iter().position(|g| g.0 == ctx) {
            Some(p) => &mut groups[p],
            None => {
                groups.push((ctx.to_vec(), Vec::new(), Vec::new()));
                groups.last_mut().expect("just pushed")
            }
        };
        g.1.push(delta);
        g.2.extend(err);
    }
    groups.sort_by(|a, b| {
        a.0.iter()
            .map(|v| v.to_bits())
            .cmp(b.0.iter().map(|v| v.to_bits()))
    });
    groups
        .into_iter()
        .map(|(context, d, e)| {
            let n = d.len();
            let mean = d.iter().sum::<f64>() / n as f64;
            let std = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
            ModeMotion {
                context,
                n,
                mean,
                std,
                mean_abs_error: (!e.is_empty()).then(|| e.iter().sum::<f64>() / e.len() as f64),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A screwdriver trajectory whose yaw goes from `y0` by `dy` evenly over the rows.
    fn screwdriver(y0: f32, dy: f32) -> Vec<f32> {
        let dims = Task::Screwdriver.dims();
        let (t, d) = (dims.horizon, dims.dim());
        let c = Task::Screwdriver.layout().angle_cos();
        let mut v = vec![0.0; t * d];
        for r in 0..t {
            let y = y0 + dy * r as f32 / (t - 1) as f32;
            v[r * d + c] = y.cos();
            v[r * d + c + 1] = y.sin();
        }
        v
    }

    #[test]
    fn yaw_motion_wraps_and_pairs_with_the_real_one() {
        // Across the ±π seam: from 3.0 by −0.5 is −0.5, not 2π − 0.5.
        let a = screwdriver(3.0, 0.5);
        assert!((progress_delta(Task::Screwdriver, &a) - 0.5).abs() < 1e-5);
        let b = screwdriver(-3.0, -0.4);
        assert!((progress_delta(Task::Screwdriver, &b) + 0.4).abs() < 1e-5);
        let real: Vec<f32> = [screwdriver(0.0, -0.3), screwdriver(0.0, 0.0)].concat();
        let diffused: Vec<f32> = [screwdriver(0.0, -0.1), screwdriver(0.0, 0.2)].concat();
        let ctx = [1.0, 1.0, 1.0, 1.0, -1.0, -1.0];
        let m = object_motion(Task::Screwdriver, &diffused, &ctx, Some(&real));
        assert_eq!(m.len(), 2);
        let turn = m.iter().find(|g| g.context == [1.0, 1.0, 1.0]).unwrap();
        assert!((turn.mean + 0.1).abs() < 1e-5);
        assert!((turn.mean_abs_error.unwrap() - 0.2).abs() < 1e-5);
        let regrasp = m.iter().find(|g| g.context == [1.0, -1.0, -1.0]).unwrap();
        assert!((regrasp.mean_abs_error.unwrap() - 0.2).abs() < 1e-5);
        assert!(
            object_motion(Task::Screwdriver, &real, &ctx, None)[0]
                .mean_abs_error
                .is_none()
        );
    }
}
