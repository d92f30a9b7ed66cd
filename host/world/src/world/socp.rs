//! Assembly of one contact sub-step as a Clarabel second-order cone program (spec §1.2):
//!
//! ```text
//! minimise ½ xᵀ P x + cᵀ x   subject to   [φᵢ/μᵢ + nᵢᵀJᵢx/μᵢ ; t1ᵢᵀJᵢx ; t2ᵢᵀJᵢx] ∈ SOC₃  (contacts with a cone)
//!                                         φᵢ + nᵢᵀJᵢx ≥ 0                            (the others)      
//!                                         lo ≤ x_a ≤ hi                              (joint limits)
//! ```
//!
//! with `x = [δq_a ; δq_u]`. The duals of the cones and rows are the contact forces. A contact
//! without a cone gets no friction: it can stop penetration but never push sideways.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::{DMatrix, Matrix3xX, Vector3};

/// One contact row block: relative-velocity Jacobian and contact frame.
#[derive(Debug, Clone)]
pub(crate) struct ConeRow {
    /// Signed distance (m).
    pub phi: f64,
    /// Friction coefficient.
    pub mu: f64,
    /// Unit normal pointing from body B toward body A.
    pub normal: Vector3<f64>,
    /// `J_A − J_B` at the contact (3 × n).
    pub jac: Matrix3xX<f64>,
}

/// How friction enters the program.
#[derive(Debug, Clone, Copy)]
pub(crate) enum FrictionForm<'a> {
    /// An Anitescu cone `[φ/μ + nᵀJx/μ ; TᵀJx] ∈ SOC₃` on each contact whose `cone` flag is
    /// set, a frictionless non-penetration row `φ + nᵀJx ≥ 0` on the others.
    Anitescu {
        /// Whether each contact gets the cone.
        cone: &'a [bool],
    },
    /// Non-penetration `φ + nᵀJx ≥ 0` per contact plus maximum dissipation with a fixed
    /// normal force: objective `+ μ N̂ τ` with `(τ, TᵀJx) ∈ SOC₃` (one cone per contact whose
    /// `μ N̂` is positive). `N̂` is given per contact.
    Lagged(&'a [f64]),
}

/// The program's data.
#[derive(Debug)]
pub(crate) struct Program<'a> {
    /// Full P (n × n, symmetric); only the upper triangle is passed on.
    pub p: &'a DMatrix<f64>,
    /// Linear term.
    pub c: &'a [f64],
    /// Contact cones.
    pub cones: &'a [ConeRow],
    /// `(lower, upper)` bounds on the first `bounds.len()` variables.
    pub bounds: &'a [(f64, f64)],
    /// Interior-point iteration limit.
    pub max_iter: u32,
    /// Friction formulation.
    pub friction: FrictionForm<'a>,
}

/// Solution of one program.
#[derive(Debug, Clone)]
pub(crate) struct Solution {
    /// Primal increments (without any friction epigraph variables).
    pub x: Vec<f64>,
    /// Force on body A of each contact (world frame, N).
    pub forces_on_a: Vec<Vector3<f64>>,
    /// Normal force magnitude of each contact (N).
    pub normal_forces: Vec<f64>,
    /// Solver status.
    pub status: SolverStatus,
    /// Interior-point iterations.
    pub iterations: u32,
}

/// An orthonormal tangent pair for a unit normal (deterministic).
pub(crate) fn tangents(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let a = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let t1 = n.cross(&a).normalize();
    let t2 = n.cross(&t1);
    (t1, t2)
}

/// Dense to CSC, dropping exact zeros; `upper` keeps only the upper triangle.
fn to_csc(m: &DMatrix<f64>, upper: bool) -> CscMatrix<f64> {
    let (rows, cols) = m.shape();
    let mut colptr = Vec::with_capacity(cols + 1);
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    colptr.push(0);
    for j in 0..cols {
        let last = if upper { j + 1 } else { rows };
        for i in 0..last {
            let v = m[(i, j)];
            if v != 0.0 {
                rowval.push(i);
                nzval.push(v);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(rows, cols, colptr, rowval, nzval)
}

/// Below this `μ N̂` (N) a lagged contact gets no friction cone.
const MIN_FRICTION_BOUND: f64 = 1e-9;

/// Build and solve the program. Errors only for malformed data (a defect); solver statuses
/// other than `Solved` are returned in [`Solution::status`] for the caller to judge.
pub(crate) fn solve(prog: &Program<'_>) -> Result<Solution, String> {
    let n = prog.c.len();
    let k = prog.cones.len();
    let frames: Vec<(Vector3<f64>, Vector3<f64>)> =
        prog.cones.iter().map(|c| tangents(&c.normal)).collect();
    // Friction epigraph variables (lagged form): one per contact with a positive bound.
    let lagged_slot: Vec<Option<usize>> = match prog.friction {
        FrictionForm::Anitescu { .. } => vec![None; k],
        FrictionForm::Lagged(normals) => {
            let mut next = 0;
            prog.cones
                .iter()
                .zip(normals)
                .map(|(c, nf)| {
                    (c.mu * nf > MIN_FRICTION_BOUND).then(|| {
                        next += 1;
                        next - 1
                    })
                })
                .collect()
        }
    };
    let n_tau = lagged_slot.iter().flatten().count();
    let nv = n + n_tau;
    if let FrictionForm::Anitescu { cone } = prog.friction
        && cone.len() != k
    {
        return Err(format!("{} cone flags for {k} contacts", cone.len()));
    }
    // Rows of each contact: 3 (a cone) or 1 (a non-penetration row).
    let contact_rows: Vec<usize> = match prog.friction {
        FrictionForm::Anitescu { cone } => cone.iter().map(|c| if *c { 3 } else { 1 }).collect(),
        FrictionForm::Lagged(_) => vec![1; k],
    };
    let row_start: Vec<usize> = contact_rows
        .iter()
        .scan(0, |next, rows| {
            let start = *next;
            *next += rows;
            Some(start)
        })
        .collect();
    let n_contact_rows: usize = contact_rows.iter().sum();
    let n_soc = match prog.friction {
        FrictionForm::Anitescu { .. } => 0,
        FrictionForm::Lagged(_) => n_tau,
    };
    let m_bounds = 2 * prog.bounds.len();
    let m = n_contact_rows + 3 * n_soc + m_bounds;
    let rows_total = m.max(1);
    let mut a = DMatrix::<f64>::zeros(rows_total, nv);
    let mut b = vec![0.0; rows_total];
    let mut cone_spec: Vec<SupportedConeT<f64>> = Vec::with_capacity(n_soc + 3);
    let mut c_full = prog.c.to_vec();
    c_full.resize(nv, 0.0);
    match prog.friction {
        FrictionForm::Anitescu { cone: with_cone } => {
            for (i, (cone, (t1, t2))) in prog.cones.iter().zip(&frames).enumerate() {
                let r = row_start[i];
                if !with_cone[i] {
                    let jn = cone.normal.transpose() * &cone.jac;
                    for col in 0..n {
                        a[(r, col)] = -jn[col];
                    }
                    b[r] = cone.phi;
                    cone_spec.push(SupportedConeT::NonnegativeConeT(1));
                    continue;
                }
                let jn = cone.normal.transpose() * &cone.jac / cone.mu;
                let j1 = t1.transpose() * &cone.jac;
                let j2 = t2.transpose() * &cone.jac;
                for col in 0..n {
                    a[(r, col)] = -jn[col];
                    a[(r + 1, col)] = -j1[col];
                    a[(r + 2, col)] = -j2[col];
                }
                b[r] = cone.phi / cone.mu;
                cone_spec.push(SupportedConeT::SecondOrderConeT(3));
            }
        }
        FrictionForm::Lagged(normals) => {
            for (i, cone) in prog.cones.iter().enumerate() {
                let jn = cone.normal.transpose() * &cone.jac;
                for col in 0..n {
                    a[(i, col)] = -jn[col];
                }
                b[i] = cone.phi;
            }
            if k > 0 {
                cone_spec.push(SupportedConeT::NonnegativeConeT(k));
            }
            for (i, (cone, (t1, t2))) in prog.cones.iter().zip(&frames).enumerate() {
                let Some(slot) = lagged_slot[i] else { continue };
                let r = k + 3 * slot;
                let tau = n + slot;
                a[(r, tau)] = -1.0;
                let j1 = t1.transpose() * &cone.jac;
                let j2 = t2.transpose() * &cone.jac;
                for col in 0..n {
                    a[(r + 1, col)] = -j1[col];
                    a[(r + 2, col)] = -j2[col];
                }
                c_full[tau] = cone.mu * normals[i];
                cone_spec.push(SupportedConeT::SecondOrderConeT(3));
            }
        }
    }
    let r0 = n_contact_rows + 3 * n_soc;
    if !prog.bounds.is_empty() {
        for (i, &(lo, hi)) in prog.bounds.iter().enumerate() {
            // x_i ≤ hi  →  s = hi − x_i ≥ 0;   −x_i ≤ −lo  →  s = x_i − lo ≥ 0.
            a[(r0 + 2 * i, i)] = 1.0;
            b[r0 + 2 * i] = hi;
            a[(r0 + 2 * i + 1, i)] = -1.0;
            b[r0 + 2 * i + 1] = -lo;
        }
        cone_spec.push(SupportedConeT::NonnegativeConeT(m_bounds));
    }
    if m == 0 {
        // A single trivially satisfied row keeps Clarabel's dimensions non-empty.
        b[0] = 1.0;
        cone_spec.push(SupportedConeT::NonnegativeConeT(1));
    }
    let mut p_full = DMatrix::zeros(nv, nv);
    p_full.view_mut((0, 0), (n, n)).copy_from(prog.p);
    let p = to_csc(&p_full, true);
    let a = to_csc(&a, false);
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .max_iter(prog.max_iter)
        .build()
        .map_err(|e| format!("settings: {e:?}"))?;
    let mut solver = DefaultSolver::new(&p, &c_full, &a, &b, &cone_spec, settings)
        .map_err(|e| format!("setup: {e:?}"))?;
    solver.solve();
    let sol = &solver.solution;
    let mut forces_on_a = Vec::with_capacity(k);
    let mut normal_forces = Vec::with_capacity(k);
    for (i, (cone, (t1, t2))) in prog.cones.iter().zip(&frames).enumerate() {
        match prog.friction {
            FrictionForm::Anitescu { cone: with_cone } if !with_cone[i] => {
                let fn_ = sol.z[row_start[i]];
                normal_forces.push(fn_);
                forces_on_a.push(cone.normal * fn_);
            }
            FrictionForm::Anitescu { .. } => {
                let z = &sol.z[row_start[i]..row_start[i] + 3];
                let fn_ = z[0] / cone.mu;
                normal_forces.push(fn_);
                forces_on_a.push(cone.normal * fn_ + t1 * z[1] + t2 * z[2]);
            }
            FrictionForm::Lagged(_) => {
                let fn_ = sol.z[i];
                let mut f = cone.normal * fn_;
                if let Some(slot) = lagged_slot[i] {
                    let z = &sol.z[k + 3 * slot..k + 3 * slot + 3];
                    f += t1 * z[1] + t2 * z[2];
                }
                normal_forces.push(fn_);
                forces_on_a.push(f);
            }
        }
    }
    Ok(Solution {
        x: sol.x[..n].to_vec(),
        forces_on_a,
        normal_forces,
        status: sol.status,
        iterations: sol.iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point at height 0 on a floor with normal +z and μ = 0.5; its velocity Jacobian is the
    /// identity.
    fn floor_cone() -> ConeRow {
        let mut jac = Matrix3xX::zeros(3);
        jac.fill_with_identity();
        ConeRow {
            phi: 0.0,
            mu: 0.5,
            normal: Vector3::z(),
            jac,
        }
    }

    /// The point on [`floor_cone`] with stiffness `p` and linear term `c`, Anitescu friction.
    fn solve_on_floor(p: &DMatrix<f64>, c: &[f64]) -> Solution {
        solve(&Program {
            p,
            c,
            cones: &[floor_cone()],
            bounds: &[],
            max_iter: 100,
            friction: FrictionForm::Anitescu { cone: &[true] },
        })
        .unwrap()
    }

    /// A point pushed into a floor (1-D spring toward z = −0.01) stops at the floor and the dual
    /// equals the spring force; a tangential command slides it with Coulomb friction.
    #[test]
    fn point_on_floor_matches_hand_solution() {
        // x = (dx, dy, dz) of a point at height 0 with stiffness k toward (0.004, 0, −0.01).
        let k = 100.0;
        let p = DMatrix::identity(3, 3) * k;
        let c = [-k * 0.004, 0.0, k * 0.01];
        let sol = solve_on_floor(&p, &c);
        assert_eq!(sol.status, SolverStatus::Solved);
        // Normal force k·0.01 = 1 N on the point (+z); the tangential pull k·0.004 = 0.4 N is
        // inside the friction limit 0.5 N, so the point sticks and friction carries all of it.
        let f = sol.forces_on_a[0];
        assert!((f.z - 1.0).abs() < 1e-5, "{f:?}");
        assert!((f.x + 0.4).abs() < 1e-5, "{f:?}");
        assert!(sol.x.iter().all(|v| v.abs() < 1e-6), "{:?}", sol.x);
        // Pull harder (1 N tangential > 0.5 N limit): it slides and lifts by μ·|slip| (Anitescu).
        let c = [-k * 0.01, 0.0, k * 0.01];
        let sol = solve_on_floor(&p, &c);
        assert!(sol.x[0] > 1e-3, "{:?}", sol.x);
        assert!((sol.x[2] - 0.5 * sol.x[0]).abs() < 1e-6, "{:?}", sol.x);
        let f = sol.forces_on_a[0];
        assert!((f.xy().norm() - 0.5 * f.z).abs() < 1e-5, "{f:?}");
    }

    /// A separated contact under the Anitescu form gets only a non-penetration row: a point
    /// 1 mm above the floor slides freely and does not lift (the cone would lift it by μ·slip),
    /// and a point pressed into the floor from 1 mm above stops on it with the spring force as
    /// its normal force and no friction.
    #[test]
    fn separated_contacts_have_no_friction() {
        let k = 100.0;
        let p = DMatrix::identity(3, 3) * k;
        let mut cone = floor_cone();
        cone.phi = 0.001;
        let solve_with = |c: &[f64], touching: bool| {
            solve(&Program {
                p: &p,
                c,
                cones: std::slice::from_ref(&cone),
                bounds: &[],
                max_iter: 100,
                friction: FrictionForm::Anitescu { cone: &[touching] },
            })
            .unwrap()
        };
        let slide = [-k * 0.01, 0.0, 0.0];
        let sol = solve_with(&slide, false);
        assert_eq!(sol.status, SolverStatus::Solved);
        assert!(
            (sol.x[0] - 0.01).abs() < 1e-7 && sol.x[2].abs() < 1e-7,
            "{:?}",
            sol.x
        );
        assert!(sol.forces_on_a[0].norm() < 1e-6, "{:?}", sol.forces_on_a);
        // The cone on the same contact drags: it must lift μ·slip − φ to slide.
        let sol = solve_with(&slide, true);
        assert!(sol.x[0] < 0.0099 && sol.x[2] > 0.0, "{:?}", sol.x);
        // Pressed 1 cm down from 1 mm above: stops on the floor, normal force k·9 mm, no
        // tangential force even with a tangential pull.
        let press = [-k * 0.004, 0.0, k * 0.01];
        let sol = solve_with(&press, false);
        assert!((sol.x[2] + 0.001).abs() < 1e-7, "{:?}", sol.x);
        assert!((sol.x[0] - 0.004).abs() < 1e-7, "{:?}", sol.x);
        let f = sol.forces_on_a[0];
        assert!((f.z - 0.9).abs() < 1e-5 && f.xy().norm() < 1e-6, "{f:?}");
        assert!(
            solve(&Program {
                p: &p,
                c: &press,
                cones: std::slice::from_ref(&cone),
                bounds: &[],
                max_iter: 100,
                friction: FrictionForm::Anitescu { cone: &[] },
            })
            .is_err()
        );
    }

    /// Lagged form: no lift when sliding, friction bounded by μ N̂ and opposing the slip.
    #[test]
    fn lagged_friction_slides_without_lift() {
        let k = 100.0;
        let p = DMatrix::identity(3, 3) * k;
        let c = [-k * 0.01, 0.0, k * 0.01];
        let cone = floor_cone();
        let normals = [1.0];
        let prog = Program {
            p: &p,
            c: &c,
            cones: std::slice::from_ref(&cone),
            bounds: &[],
            max_iter: 100,
            friction: FrictionForm::Lagged(&normals),
        };
        let sol = solve(&prog).unwrap();
        assert_eq!(sol.status, SolverStatus::Solved);
        // Spring pulls 1 N tangentially, friction holds 0.5 N: slides by 0.5 N / k, no lift.
        assert!(
            (sol.x[0] - 0.005).abs() < 1e-6 && sol.x[2].abs() < 1e-7,
            "{:?}",
            sol.x
        );
        let f = sol.forces_on_a[0];
        assert!(
            (f.x + 0.5).abs() < 1e-5 && (f.z - 1.0).abs() < 1e-5,
            "{f:?}"
        );
        // With N̂ = 0 there is no friction at all.
        let zero = [0.0];
        let prog = Program {
            friction: FrictionForm::Lagged(&zero),
            ..prog
        };
        let sol = solve(&prog).unwrap();
        assert!((sol.x[0] - 0.01).abs() < 1e-6, "{:?}", sol.x);
    }

    #[test]
    fn bounds_are_respected() {
        let p = DMatrix::identity(2, 2);
        let c = [-1.0, 1.0];
        let sol = solve(&Program {
            p: &p,
            c: &c,
            cones: &[],
            bounds: &[(-0.5, 0.5), (-0.2, 0.2)],
            max_iter: 100,
            friction: FrictionForm::Anitescu { cone: &[] },
        })
        .unwrap();
        assert_eq!(sol.status, SolverStatus::Solved);
        assert!(
            (sol.x[0] - 0.5).abs() < 1e-6 && (sol.x[1] + 0.2).abs() < 1e-6,
            "{:?}",
            sol.x
        );
    }
}
