//! Filling one step's constraint rows, in the order [`StepRows`] counts them.

// Index loops over small fixed-size arrays mirror the maths (rows, joints, faces).
#![allow(clippy::needless_range_loop)]

use std::f64::consts::PI;

use super::geometry::{Lifted, object_pose, seed, tangents};
use super::rows::{CONTACT_EQ_ROWS, FREE_MOTION_ROWS, LIFT_OFF_ROWS};
use super::{
    AllegroProblem, CLEARANCE_MARGIN, PLANNER_FRICTION, PYRAMID_FACES, REGRASP_CLEARANCE, StepRows,
};
use crate::problems::dual::{Dual, V3};
use dips_csvto::{Problem, StepConstraints};
use dips_world::scenes::{self, SceneKind};

/// Terms of a contact finger at `s_{t+1}`, over `[q_{t+1}, o_{t+1}, f]`.
struct NextTerms {
    sdf: Dual<10>,
    /// `−J_cᵀf − K_p q_{t+1}`; the caller adds `K_p(q_t + Δq_t)`.
    balance: [Dual<10>; 4],
    wrench: [Dual<10>; 3],
    friction: [Dual<10>; PYRAMID_FACES],
    /// `f_min + n·f` (≤ 0: the finger presses with at least `f_min`).
    min_normal: Dual<10>,
}

impl AllegroProblem {
    /// Write step `t`'s rows (from `prev` through `row`) into `out`, block by block as
    /// [`Self::step_rows`] lays them out.
    pub(super) fn fill_step(&self, t: usize, prev: &[f64], row: &[f64], out: &mut StepConstraints) {
        let ds = self.state_dim();
        let width = ds + self.row_dim();
        let nf = self.nf;
        let rows: StepRows = self.step_rows(t);
        let mut e = 0; // equality row
        let mut q = 0; // inequality row
        // The object rows collect the contact fingers' wrenches as they are filled.
        let obj_row = rows.object;
        let mut wrench_rows = [0.0f64; 3];
        for i in 0..nf {
            let Some(s) = self.slot[i] else { continue };
            // Columns: q_{t+1}, o_{t+1}, f (row).
            let mut map10 = [0usize; 10];
            for k in 0..4 {
                map10[k] = ds + 4 * i + k;
            }
            for k in 0..3 {
                map10[4 + k] = ds + 4 * nf + k;
                map10[7 + k] = ds + self.force_col(s, k);
            }
            let v10: [f64; 10] = std::array::from_fn(|k| step_value(prev, row, ds, map10[k]));
            let next = self.next_terms(i, &v10);
            let put =
                |out: &mut StepConstraints, r: usize, value: f64, map: &[usize], d: &[f64]| {
                    out.eq[r] = value;
                    scatter(&mut out.jac_eq[r * width..(r + 1) * width], map, d, 1.0);
                };
            put(out, e, next.sdf.v, &map10, &next.sdf.d);
            self.rolling_rows(i, prev, row, e + 1, out);
            for k in 0..4 {
                let r = e + 3 + k;
                let (qc, dqc) = (4 * i + k, ds + self.dq_col(i, k));
                put(
                    out,
                    r,
                    next.balance[k].v + self.kp * (prev[qc] + row[dqc - ds]),
                    &map10,
                    &next.balance[k].d,
                );
                out.jac_eq[r * width + qc] += self.kp;
                out.jac_eq[r * width + dqc] += self.kp;
            }
            e += CONTACT_EQ_ROWS;
            for k in 0..3 {
                let r = obj_row + k;
                wrench_rows[k] += next.wrench[k].v;
                scatter(
                    &mut out.jac_eq[r * width..(r + 1) * width],
                    &map10,
                    &next.wrench[k].d,
                    1.0,
                );
            }
            for term in next.friction.iter().chain([&next.min_normal]) {
                out.ineq[q] = term.v;
                scatter(
                    &mut out.jac_ineq[q * width..(q + 1) * width],
                    &map10,
                    &term.d,
                    1.0,
                );
                q += 1;
            }
        }
        debug_assert_eq!((e, q), (rows.object, rows.clearance));
        // Object rows.
        let on = [row[4 * nf], row[4 * nf + 1], row[4 * nf + 2]];
        if self.nc > 0 {
            match self.task {
                SceneKind::Screwdriver => {
                    // Gravity torque about the pivot: (R·r_com) × (0, 0, −m g).
                    let od: [Dual<3>; 3] = seed(&on);
                    let (r, _) = object_pose(self.task, &self.units, &od);
                    let com = r.mul_v(&V3::cst([0.0, 0.0, scenes::screwdriver::COM_HEIGHT]));
                    let g = V3::cst([0.0, 0.0, -scenes::screwdriver::MASS * scenes::GRAVITY]);
                    let tg = com.cross(&g);
                    for k in 0..3 {
                        let rr = obj_row + k;
                        out.eq[rr] = wrench_rows[k] + tg.0[k].v;
                        for j in 0..3 {
                            out.jac_eq[rr * width + ds + 4 * nf + j] += tg.0[k].d[j];
                        }
                    }
                    if self.pinned > 0 {
                        self.hold_rows(obj_row + 3, 3 - self.pinned, prev, &on, width, out);
                    }
                }
                SceneKind::Card => {
                    let fe = [
                        row[self.env_col(0)],
                        row[self.env_col(1)],
                        row[self.env_col(2)],
                    ];
                    let weight = [0.0, 0.0, -scenes::card::MASS * scenes::GRAVITY];
                    for k in 0..3 {
                        let rr = obj_row + k;
                        out.eq[rr] = wrench_rows[k] + fe[k] + weight[k];
                        out.jac_eq[rr * width + ds + self.env_col(k)] += 1.0;
                    }
                    // Sliding friction of the table (spec §2.2): ‖f_xy‖ − μ f_z = 0. Its
                    // direction is left free: rows tying it to the displacement Δ are
                    // degenerate at Δ = 0 and pin the card in the tangent space (see
                    // docs/csvto.md).
                    let rr = obj_row + 3;
                    let nxy = (fe[0] * fe[0] + fe[1] * fe[1] + 1e-12).sqrt();
                    let mu = scenes::card::TABLE_FRICTION;
                    out.eq[rr] = nxy - mu * fe[2];
                    out.jac_eq[rr * width + ds + self.env_col(0)] = fe[0] / nxy;
                    out.jac_eq[rr * width + ds + self.env_col(1)] = fe[1] / nxy;
                    out.jac_eq[rr * width + ds + self.env_col(2)] = -mu;
                }
            }
        } else {
            // No finger in contact: the object holds still.
            self.hold_rows(obj_row, 0, prev, &on, width, out);
            if self.task == SceneKind::Card {
                let weight = scenes::card::MASS * scenes::GRAVITY;
                for k in 0..3 {
                    let rr = obj_row + 3 + k;
                    out.eq[rr] = row[self.env_col(k)] - if k == 2 { weight } else { 0.0 };
                    out.jac_eq[rr * width + ds + self.env_col(k)] = 1.0;
                }
            }
        }
        e = rows.free_motion;
        // Regrasping fingers: free motion, clearance, terminal contact.
        let last = t + 1 == self.horizon;
        for i in 0..nf {
            if self.slot[i].is_some() {
                continue;
            }
            for k in 0..4 {
                let r = e + k;
                out.eq[r] = row[4 * i + k] - prev[4 * i + k] - row[self.dq_col(i, k)];
                let jr = &mut out.jac_eq[r * width..(r + 1) * width];
                jr[ds + 4 * i + k] = 1.0;
                jr[4 * i + k] = -1.0;
                jr[ds + self.dq_col(i, k)] = -1.0;
            }
            e += FREE_MOTION_ROWS;
        }
        debug_assert_eq!(e, rows.lift_off);
        if t == 0 {
            // Lift-off along the normal: the finger's contact point has no tangential motion
            // relative to the object in the first step (the rolling rows of a contact finger).
            for i in (0..nf).filter(|&i| self.lift_off[i]) {
                self.rolling_rows(i, prev, row, e, out);
                e += LIFT_OFF_ROWS;
            }
        }
        debug_assert_eq!(e, rows.terminal);
        for i in 0..nf {
            if self.slot[i].is_some() {
                continue;
            }
            let qn = &row[4 * i..4 * i + 4];
            let (qcol, ocol) = (ds + 4 * i, ds + 4 * nf);
            if last {
                let (sdf, map) = self.regrasp_sdf(i, qn, &on, qcol, ocol);
                out.eq[e] = sdf.v;
                scatter(
                    &mut out.jac_eq[e * width..(e + 1) * width],
                    &map,
                    &sdf.d,
                    1.0,
                );
                e += 1;
            } else {
                // Clearance to the object where the step leaves it and where it found it (see
                // [`REGRASP_CLEARANCE`]).
                let before = [prev[4 * nf], prev[4 * nf + 1], prev[4 * nf + 2]];
                for (o, ocol) in [(&on, ocol), (&before, 4 * nf)] {
                    let (sdf, map) = self.regrasp_sdf(i, qn, o, qcol, ocol);
                    out.ineq[q] = REGRASP_CLEARANCE + CLEARANCE_MARGIN - sdf.v;
                    scatter(
                        &mut out.jac_ineq[q * width..(q + 1) * width],
                        &map,
                        &sdf.d,
                        -1.0,
                    );
                    q += 1;
                }
            }
        }
        debug_assert_eq!((e, q), (rows.eq, rows.ineq));
        debug_assert_eq!((e, q), (out.eq.len(), out.ineq.len()));
    }

    /// Rolling rows of contact finger `i` over `[q_t (4), o_t (3), q_{t+1} (4), o_{t+1} (3)]`:
    /// the finger's contact point moves with the object's material point (tangentially).
    fn rolling_terms(&self, i: usize, vals: &[f64; 14]) -> [Dual<14>; 2] {
        let v: [Dual<14>; 14] = seed(vals);
        let qt = [v[0], v[1], v[2], v[3]];
        let ot = [v[4], v[5], v[6]];
        let qn = [v[7], v[8], v[9], v[10]];
        let on = [v[11], v[12], v[13]];
        let at_t: [f64; 7] = std::array::from_fn(|k| vals[k]);
        let ct: Lifted<Dual<14>> = self.lifted_contact(i, &at_t, 0, 4);
        let mut dfinger = V3::zero();
        for k in 0..4 {
            dfinger = dfinger.add(&ct.jac[k].scale(qn[k] - qt[k]));
        }
        let rel = dfinger.sub(&self.object_motion(&ot, &on, &ct.surface));
        let (t1, t2) = tangents(&ct.normal);
        [t1.dot(&rel), t2.dot(&rel)]
    }

    /// Write finger `i`'s two rolling rows ([`Self::rolling_terms`]) of the step from `prev`
    /// through `row` into equality rows `e` and `e + 1`.
    fn rolling_rows(
        &self,
        i: usize,
        prev: &[f64],
        row: &[f64],
        e: usize,
        out: &mut StepConstraints,
    ) {
        let (ds, nf) = (self.state_dim(), self.nf);
        let width = ds + self.row_dim();
        // Columns: q_t, o_t (previous state), q_{t+1}, o_{t+1} (row).
        let map: [usize; 14] = std::array::from_fn(|k| match k {
            0..4 => 4 * i + k,
            4..7 => 4 * nf + k - 4,
            7..11 => ds + 4 * i + k - 7,
            _ => ds + 4 * nf + k - 11,
        });
        let vals: [f64; 14] = std::array::from_fn(|k| step_value(prev, row, ds, map[k]));
        for (r, term) in self.rolling_terms(i, &vals).iter().enumerate() {
            out.eq[e + r] = term.v;
            scatter(
                &mut out.jac_eq[(e + r) * width..(e + r + 1) * width],
                &map,
                &term.d,
                1.0,
            );
        }
    }

    /// Terms of contact finger `i` at `s_{t+1}` over `[q_{t+1} (4), o_{t+1} (3), f (3)]`.
    fn next_terms(&self, i: usize, vals: &[f64; 10]) -> NextTerms {
        let v: [Dual<10>; 10] = seed(vals);
        let qn = [v[0], v[1], v[2], v[3]];
        let f = V3([v[7], v[8], v[9]]);
        let at_n: [f64; 7] = std::array::from_fn(|k| vals[k]);
        let cn: Lifted<Dual<10>> = self.lifted_contact(i, &at_n, 0, 4);
        // Joint impedance balance without its `K_p(q_t + Δq_t)` part (added by the caller).
        let balance = std::array::from_fn(|k| -cn.jac[k].dot(&f) - qn[k] * self.kp);
        let wrench = match self.task {
            SceneKind::Screwdriver => {
                cn.surface
                    .sub(&V3::cst(scenes::screwdriver::PIVOT))
                    .cross(&f)
                    .0
            }
            SceneKind::Card => f.0,
        };
        let (n1, n2) = tangents(&cn.normal);
        let (a, b, c) = (n1.dot(&f), n2.dot(&f), cn.normal.dot(&f));
        let friction = std::array::from_fn(|j| {
            let th = 2.0 * PI * j as f64 / PYRAMID_FACES as f64;
            a * th.cos() + b * th.sin() + c * PLANNER_FRICTION
        });
        NextTerms {
            sdf: cn.sdf,
            balance,
            wrench,
            friction,
            min_normal: c + self.min_normal_force,
        }
    }

    /// The rows `o_{t+1,k} − o_{t,k} = 0` for object coordinates `k ≥ first`, from equality
    /// row `r`.
    fn hold_rows(
        &self,
        r: usize,
        first: usize,
        prev: &[f64],
        on: &[f64; 3],
        width: usize,
        out: &mut StepConstraints,
    ) {
        let ds = self.state_dim();
        let oc = 4 * self.nf;
        for k in first..3 {
            let rr = r + k - first;
            out.eq[rr] = on[k] - prev[oc + k];
            out.jac_eq[rr * width + ds + oc + k] = 1.0;
            out.jac_eq[rr * width + oc + k] = -1.0;
        }
    }
}

/// The value of step column `c` (the previous state's `ds` columns, then the row's).
fn step_value(prev: &[f64], row: &[f64], ds: usize, c: usize) -> f64 {
    if c < ds { prev[c] } else { row[c - ds] }
}

/// Add `w·d[j]` to `row[map[j]]`.
fn scatter(row: &mut [f64], map: &[usize], d: &[f64], w: f64) {
    for (&c, &v) in map.iter().zip(d) {
        row[c] += w * v;
    }
}
