//! The cost `J` of a whole trajectory and its gradient, with the kernel's named weights
//! ([`CostWeights`]): the host's CSVTO and the search's `J` share every term but the regrasp
//! target (which needs the hand's kinematics).

use super::AllegroProblem;
use super::geometry::seed;
use crate::problems::dual::Dual;
use dips_csvto::Problem;
use dips_kernel::task::CostWeights;
use dips_world::scenes::SceneKind;

/// The kernel's [`CostWeights`] of a task in `f64` (exact: every weight is an integer).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Weights {
    scale: f64,
    joint_step: f64,
    joint_delta: f64,
    object_step: f64,
    contact_force: f64,
    upright: f64,
    regrasp_target: f64,
}

impl Weights {
    pub(super) fn of(task: SceneKind) -> Self {
        let w = CostWeights::of(task.task());
        Self {
            scale: f64::from(w.scale),
            joint_step: f64::from(w.joint_step),
            joint_delta: f64::from(w.joint_delta),
            object_step: f64::from(w.object_step),
            contact_force: f64::from(w.contact_force),
            upright: f64::from(w.upright),
            regrasp_target: f64::from(w.regrasp_target),
        }
    }
}

impl AllegroProblem {
    /// `J(x)`, adding its gradient into `grad`.
    pub(super) fn cost_and_gradient(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        let n = self.row_dim();
        let nf = self.nf;
        let nq = 4 * nf;
        let h = self.horizon;
        let mut j = 0.0;
        let (wt, wr) = self.goal_weights;
        let w = self.weights;
        for t in 0..h {
            let row = &x[t * n..(t + 1) * n];
            let prev: &[f64] = if t == 0 {
                &self.start
            } else {
                &x[(t - 1) * n..t * n]
            };
            // Smoothness on q_t − q_{t−1} and on Δq; object smoothness and goal.
            let w_goal = if t + 1 == h { wt } else { wr };
            let mut dprev = [0.0; 15];
            {
                let g = &mut grad[t * n..(t + 1) * n];
                let (ws, wd, wo) = (w.joint_step, w.joint_delta, w.object_step);
                for k in 0..nq {
                    let d = row[k] - prev[k];
                    j += ws * d * d;
                    g[k] += 2.0 * ws * d;
                    dprev[k] = -2.0 * ws * d;
                    let dq = row[nq + 3 + k];
                    j += wd * dq * dq;
                    g[nq + 3 + k] += 2.0 * wd * dq;
                }
                for k in 0..3 {
                    let u2 = self.units[k] * self.units[k];
                    let d = row[nq + k] - prev[nq + k];
                    j += wo * u2 * d * d;
                    g[nq + k] += 2.0 * wo * u2 * d;
                    dprev[nq + k] = -2.0 * wo * u2 * d;
                    let e = row[nq + k] - self.goal[k];
                    j += u2 * w_goal * e * e;
                    g[nq + k] += 2.0 * u2 * w_goal * e;
                }
            }
            if t > 0 {
                for k in 0..nq + 3 {
                    grad[(t - 1) * n + k] += dprev[k];
                }
            }
            let g = &mut grad[t * n..(t + 1) * n];
            if w.upright != 0.0 {
                for k in 0..2 {
                    let u2 = self.units[k] * self.units[k];
                    let a = row[nq + k];
                    j += w.upright * u2 * a * a;
                    g[nq + k] += 2.0 * w.upright * u2 * a;
                }
            }
            // Finger forces.
            for s in 0..self.nc {
                for k in 0..3 {
                    let f = row[self.force_col(s, k)];
                    j += w.contact_force * f * f;
                    g[self.force_col(s, k)] += 2.0 * w.contact_force * f;
                }
            }
            // Regrasp targets.
            for i in 0..nf {
                if self.slot[i].is_some() {
                    continue;
                }
                let mut vals = [0.0; 7];
                vals[..4].copy_from_slice(&row[4 * i..4 * i + 4]);
                vals[4..].copy_from_slice(&row[nq..nq + 3]);
                let v: [Dual<7>; 7] = seed(&vals);
                let err = self.target_error(i, &[v[0], v[1], v[2], v[3]], &[v[4], v[5], v[6]]);
                j += w.regrasp_target * err.v;
                for k in 0..4 {
                    g[4 * i + k] += w.regrasp_target * err.d[k];
                }
                for k in 0..3 {
                    g[nq + k] += w.regrasp_target * err.d[4 + k];
                }
            }
        }
        for v in grad.iter_mut() {
            *v *= w.scale;
        }
        w.scale * j
    }
}
