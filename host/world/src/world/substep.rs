//! One sub-step's contact program: the object's mass block, the contact candidates, the
//! second-order cone program of either friction form (the Anitescu cone for the screwdriver;
//! non-penetration plus a maximum-dissipation cone with a normal-force fixed point for the
//! card) and applying its solution.

use clarabel::solver::SolverStatus;
use nalgebra::{DMatrix, Matrix3, Point3, Rotation3, Vector3};

use super::{
    ConeActivation, ContactKey, ContactReport, FrictionModel, ObjectState, World, WorldError,
    contacts, socp,
};
use crate::kinematics::FingerFrames;
use crate::scenes::{card, screwdriver};

impl World {
    /// Object block of P (regularised mass plus damping over h) and the gravity force term.
    fn object_block(&self) -> (DMatrix<f64>, Vec<f64>) {
        let p = &self.params;
        let h = p.h();
        let g = p.gravity;
        match &self.object {
            ObjectState::Screwdriver { orientation, .. } => {
                let r = orientation.to_rotation_matrix();
                let i_body = Matrix3::from_diagonal(&Vector3::from(screwdriver::INERTIA_PIVOT));
                let max_i = screwdriver::INERTIA_PIVOT
                    .iter()
                    .copied()
                    .fold(0.0, f64::max);
                let eps = regulariser(p.kp, p.mass_scale, max_i);
                let m_world = r.matrix() * i_body * r.matrix().transpose() * eps;
                // Joint-space damping D on (roll, pitch, yaw) mapped to ω: ω = E θ̇, so the
                // damping quadratic form is E⁻ᵀ D E⁻¹.
                let [roll, pitch, _] = self.object.coords();
                let e = Matrix3::from_columns(&[
                    Vector3::x(),
                    Rotation3::from_axis_angle(&Vector3::x_axis(), roll) * Vector3::y(),
                    (Rotation3::from_axis_angle(&Vector3::x_axis(), roll)
                        * Rotation3::from_axis_angle(&Vector3::y_axis(), pitch))
                        * Vector3::z(),
                ]);
                let e_inv = e.try_inverse().unwrap_or_else(Matrix3::identity);
                let d = Matrix3::from_diagonal(&Vector3::from(p.damping));
                let damp = e_inv.transpose() * d * e_inv / h;
                let block = m_world + damp + Matrix3::identity() * 1e-9;
                let com = r * Vector3::new(0.0, 0.0, screwdriver::COM_HEIGHT);
                let torque = com.cross(&Vector3::new(0.0, 0.0, -screwdriver::MASS * g));
                (
                    DMatrix::from_iterator(3, 3, block.iter().copied()),
                    torque.iter().copied().collect(),
                )
            }
            ObjectState::Card { pose, .. } => {
                let inertia = card::inertia();
                let max_m = card::MASS.max(inertia.iter().copied().fold(0.0, f64::max));
                let eps = regulariser(p.kp, p.mass_scale, max_m);
                let rot = pose.rotation.to_rotation_matrix();
                let i_world = rot.matrix()
                    * Matrix3::from_diagonal(&Vector3::from(inertia))
                    * rot.matrix().transpose();
                let mut block = DMatrix::zeros(6, 6);
                for i in 0..3 {
                    block[(i, i)] = eps * card::MASS + p.damping[0] / h + 1e-9;
                    for j in 0..3 {
                        block[(3 + i, 3 + j)] = eps * i_world[(i, j)];
                    }
                    block[(3 + i, 3 + i)] += p.damping[0] / h + 1e-9;
                }
                (block, vec![0.0, 0.0, -card::MASS * g, 0.0, 0.0, 0.0])
            }
        }
    }

    /// Contact candidates at a trial configuration (the start of the sub-step plus `guess`),
    /// with φ shifted so the rows constrain the increment measured from the sub-step start:
    /// `φ(trial) + nᵀJ (δq − guess) ≥ 0`.
    fn candidates_at(&self, guess: &[f64]) -> Vec<contacts::Candidate> {
        let fingers = self.scene.task_fingers();
        let mut joints = self.joints;
        for (k, f) in fingers.iter().enumerate() {
            for j in 0..4 {
                joints[f.index()][j] += guess[4 * k + j];
            }
        }
        let mut object = self.object.clone();
        object.apply(&guess[4 * fingers.len()..]);
        let frames: Vec<FingerFrames> = fingers
            .iter()
            .map(|f| self.hand.finger_frames(&self.base, *f, &joints[f.index()]))
            .collect();
        let names: Vec<&'static str> = fingers.iter().map(|f| f.name()).collect();
        let pose = object.pose();
        let dofs = match object {
            ObjectState::Screwdriver { .. } => contacts::ObjectDofs::Pivot {
                pivot: screwdriver::pivot(),
            },
            ObjectState::Card { pose, .. } => contacts::ObjectDofs::Free {
                origin: Point3::from(pose.translation.vector),
            },
        };
        let mut cands = contacts::candidates(&contacts::ContactInputs {
            scene: self.scene,
            hand: &self.hand,
            frames: &frames,
            finger_names: &names,
            object: &self.object_body,
            object_pose: &pose,
            dofs,
            table: self.table.as_ref(),
            margin: self.params.contact_margin,
            table_margin: 0.25 * self.params.contact_margin,
            finger_friction: self.params.finger_friction,
            finger_table_friction: self.params.finger_table_friction,
            table_friction: self.params.table_friction,
        });
        if guess.iter().any(|g| *g != 0.0) {
            let g = nalgebra::DVector::from_column_slice(guess);
            for cand in &mut cands {
                let moved = (cand.row.normal.transpose() * (&cand.row.jac * &g))[0];
                cand.row.phi -= moved;
            }
        }
        cands
    }

    pub(super) fn solve_substep(
        &self,
        setpoint: &[f64],
        substep: usize,
    ) -> Result<SubstepResult, WorldError> {
        let fingers = self.scene.task_fingers();
        let n_a = 4 * fingers.len();
        let n_u = match self.object {
            ObjectState::Screwdriver { .. } => 3,
            ObjectState::Card { .. } => 6,
        };
        let n = n_a + n_u;
        let (block, force_u) = self.object_block();
        let mut p = DMatrix::zeros(n, n);
        let mut c = vec![0.0; n];
        let q_now = self.task_joints();
        for i in 0..n_a {
            p[(i, i)] = self.params.kp + self.params.joint_damping / self.params.h();
            c[i] = -self.params.kp * (setpoint[i] - q_now[i]);
        }
        p.view_mut((n_a, n_a), (n_u, n_u)).copy_from(&block);
        for (i, f) in force_u.iter().enumerate() {
            c[n_a + i] = -f;
        }
        let bounds: Vec<(f64, f64)> = if self.params.enforce_joint_limits {
            fingers
                .iter()
                .enumerate()
                .flat_map(|(k, f)| {
                    let lim = self.hand.joint_limits(*f);
                    let q = &q_now;
                    (0..4).map(move |j| (lim[j].0 - q[4 * k + j], lim[j].1 - q[4 * k + j]))
                })
                .map(|(lo, hi)| (lo.min(0.0), hi.max(0.0)))
                .collect()
        } else {
            Vec::new()
        };
        let check = |sol: &socp::Solution| -> Result<(), WorldError> {
            match sol.status {
                SolverStatus::Solved | SolverStatus::AlmostSolved => {}
                other => {
                    return Err(WorldError::Solver {
                        substep,
                        status: format!("{other:?}"),
                    });
                }
            }
            if sol
                .x
                .iter()
                .chain(sol.normal_forces.iter())
                .any(|v| !v.is_finite())
            {
                return Err(WorldError::Solver {
                    substep,
                    status: "non-finite solution".into(),
                });
            }
            Ok(())
        };
        let mut iters = 0;
        let mut solves = 0;
        let mut unconverged = None;
        let mut worst_status = SolverStatus::Solved;
        // The Anitescu solve, with the number of solves it took.
        type AnitescuResult = (socp::Solution, Vec<contacts::Candidate>, u32);
        let anitescu = || -> Result<AnitescuResult, WorldError> {
            let cands = self.candidates_at(&vec![0.0; n]);
            let rows: Vec<socp::ConeRow> = cands.iter().map(|c| c.row.clone()).collect();
            let solve_with = |cone: &[bool]| -> Result<socp::Solution, WorldError> {
                let sol = socp::solve(&socp::Program {
                    p: &p,
                    c: &c,
                    cones: &rows,
                    bounds: &bounds,
                    max_iter: self.params.solver_max_iter,
                    friction: socp::FrictionForm::Anitescu { cone },
                })
                .map_err(WorldError::Setup)?;
                check(&sol)?;
                Ok(sol)
            };
            match self.params.cone_activation {
                ConeActivation::All => Ok((solve_with(&vec![true; rows.len()])?, cands, 1)),
                ConeActivation::Pressing => {
                    let probe = solve_with(&vec![false; rows.len()])?;
                    // Pressing in the frictionless probe, or pressed at the end of the
                    // previous sub-step: a pressed contact that slid ends its sub-step lifted
                    // by μ·slip and keeps its friction while it is held against the object.
                    let cone: Vec<bool> = probe
                        .normal_forces
                        .iter()
                        .zip(&cands)
                        .map(|(f, cand)| {
                            *f > PRESSING_FORCE
                                || self
                                    .normal_memory
                                    .iter()
                                    .any(|(k, m)| *k == cand.key && *m > PRESSING_FORCE)
                        })
                        .collect();
                    if !cone.contains(&true) {
                        return Ok((probe, cands, 1));
                    }
                    let sol = solve_with(&cone)?;
                    Ok((
                        socp::Solution {
                            iterations: sol.iterations + probe.iterations,
                            ..sol
                        },
                        cands,
                        2,
                    ))
                }
            }
        };
        let mut fell_back = false;
        let (sol, cands) = match self.params.friction_model {
            FrictionModel::Anitescu => {
                let (sol, cands, n_solves) = anitescu()?;
                iters += sol.iterations;
                solves += n_solves;
                worst_status = sol.status;
                (sol, cands)
            }
            FrictionModel::Staggered => {
                // Two coupled fixed points, iterated together:
                // - the contact geometry is re-linearised at the latest predicted configuration
                //   (sequential convex programming on φ(q + δq) ≥ 0), and
                // - the friction bounds μN use the latest normal forces N (staggered
                //   projections), relaxed with Aitken's dynamic factor: the plain iteration
                //   alternates (ratio ≈ −0.5) on the card and creeps (≈ +0.3) on the screwdriver.
                let mut cands = self.candidates_at(&vec![0.0; n]);
                let mut known: Vec<(ContactKey, f64)> = self.normal_memory.clone();
                let mut omega: f64 = 1.0;
                let mut prev: Option<(Vec<ContactKey>, Vec<f64>)> = None;
                let mut last = None;
                for _ in 0..self.params.staggered_iterations {
                    let keys: Vec<ContactKey> = cands.iter().map(|c| c.key).collect();
                    let normals: Vec<f64> = keys
                        .iter()
                        .map(|key| {
                            known
                                .iter()
                                .find(|(k, _)| k == key)
                                .map_or(0.0, |(_, f)| *f)
                        })
                        .collect();
                    let rows: Vec<socp::ConeRow> = cands.iter().map(|c| c.row.clone()).collect();
                    let prog = socp::Program {
                        p: &p,
                        c: &c,
                        cones: &rows,
                        bounds: &bounds,
                        max_iter: self.params.solver_max_iter,
                        friction: socp::FrictionForm::Lagged(&normals),
                    };
                    let sol = socp::solve(&prog).map_err(WorldError::Setup)?;
                    check(&sol)?;
                    iters += sol.iterations;
                    solves += 1;
                    if sol.status == SolverStatus::AlmostSolved {
                        worst_status = SolverStatus::AlmostSolved;
                    }
                    let residual: Vec<f64> = sol
                        .normal_forces
                        .iter()
                        .zip(&normals)
                        .map(|(g, n)| g.max(0.0) - n)
                        .collect();
                    let change = residual.iter().fold(0.0, |m: f64, r| m.max(r.abs()));
                    let largest = sol.normal_forces.iter().copied().fold(0.0, f64::max);
                    let tol = self.params.staggered_tolerance
                        + self.params.staggered_relative_tolerance * largest;
                    // Geometry: does the linearisation predict the true signed distances at the
                    // solution? (New penetrating contacts count as errors.)
                    let next = self.candidates_at(&sol.x);
                    let xv = nalgebra::DVector::from_column_slice(&sol.x);
                    let mut geom: f64 = 0.0;
                    for nc in &next {
                        match cands.iter().find(|c| c.key == nc.key) {
                            Some(c) => {
                                let predicted =
                                    c.row.phi + (c.row.normal.transpose() * (&c.row.jac * &xv))[0];
                                geom = geom.max((nc.phi_at_trial - predicted).abs());
                            }
                            None => geom = geom.max(-nc.phi_at_trial),
                        }
                    }
                    let converged = change <= tol && geom <= self.params.geometry_tolerance;
                    unconverged = (!converged).then_some(change.max(geom));
                    last = Some((sol, std::mem::replace(&mut cands, next)));
                    if converged {
                        break;
                    }
                    match &prev {
                        Some((prev_keys, prev_res)) if *prev_keys == keys => {
                            let dr: Vec<f64> =
                                residual.iter().zip(prev_res).map(|(a, b)| a - b).collect();
                            let denom: f64 = dr.iter().map(|d| d * d).sum();
                            if denom > 0.0 {
                                let num: f64 = prev_res.iter().zip(&dr).map(|(a, b)| a * b).sum();
                                omega = (-omega * num / denom).clamp(0.4, 1.5);
                            }
                        }
                        _ => omega = 1.0,
                    }
                    known = keys
                        .iter()
                        .zip(normals.iter().zip(&residual))
                        .map(|(k, (n, r))| (*k, (n + omega * r).max(0.0)))
                        .collect();
                    prev = Some((keys, residual));
                }
                let result =
                    last.ok_or_else(|| WorldError::Setup("no staggered iteration ran".into()))?;
                if unconverged.is_some() && self.params.staggered_fallback {
                    // No fixed point (e.g. wedging at high μ): take the convex cone model's
                    // answer for this sub-step and say so.
                    let (sol, cands, n_solves) = anitescu()?;
                    iters += sol.iterations;
                    solves += n_solves;
                    if sol.status == SolverStatus::AlmostSolved {
                        worst_status = SolverStatus::AlmostSolved;
                    }
                    fell_back = true;
                    (sol, cands)
                } else {
                    result
                }
            }
        };
        let memory = cands
            .iter()
            .zip(&sol.normal_forces)
            .map(|(cand, f)| (cand.key, f.max(0.0)))
            .collect();
        let reports = cands
            .iter()
            .zip(&sol.forces_on_a)
            .map(|(cand, f_a)| {
                // Force exerted by A (finger or card) on B (the part) is −(force on A).
                let f = -f_a;
                ContactReport {
                    finger: cand.finger.to_string(),
                    part: cand.part.to_string(),
                    point: [cand.point.x, cand.point.y, cand.point.z],
                    normal: [cand.row.normal.x, cand.row.normal.y, cand.row.normal.z],
                    force: [f.x, f.y, f.z],
                    phi: cand.row.phi,
                }
            })
            .collect();
        Ok(SubstepResult {
            dx: sol.x,
            contacts: reports,
            iters,
            solves,
            status: worst_status,
            unconverged,
            fell_back,
            memory,
        })
    }

    pub(super) fn apply_increment(&mut self, dx: &[f64]) {
        let fingers = self.scene.task_fingers();
        for (k, f) in fingers.iter().enumerate() {
            for j in 0..4 {
                self.joints[f.index()][j] += dx[4 * k + j];
            }
        }
        self.object.apply(&dx[4 * fingers.len()..]);
    }
}

/// A candidate presses when its frictionless normal force (or its normal force at the end of
/// the previous sub-step) exceeds this (N); interior-point duals of separated candidates are
/// ≲ 1e-7 N.
const PRESSING_FORCE: f64 = 1e-5;

/// What one sub-step produced.
pub(super) struct SubstepResult {
    pub(super) dx: Vec<f64>,
    pub(super) contacts: Vec<ContactReport>,
    pub(super) iters: u32,
    pub(super) solves: u32,
    pub(super) status: SolverStatus,
    pub(super) unconverged: Option<f64>,
    pub(super) fell_back: bool,
    pub(super) memory: Vec<(ContactKey, f64)>,
}

/// qsim's mass scaling: `ε` such that the largest mass entry becomes `kp / s` (spec §1.1).
/// A non-positive or non-finite `s` means "use the true mass" (ε = 1).
fn regulariser(kp: f64, s: f64, max_mass: f64) -> f64 {
    if s.is_finite() && s > 0.0 && max_mass > 0.0 {
        kp / (s * max_mass)
    } else {
        1.0
    }
}
