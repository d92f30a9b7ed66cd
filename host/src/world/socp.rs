//! Assembly of one contact sub-step as a Clarabel second-order cone program (spec §1.2):
//!
//! ```text
//! minimise ½ xᵀ P x + cᵀ x   subject to   [φᵢ/μᵢ + nᵢᵀJᵢx/μᵢ ; t1ᵢᵀJᵢx ; t2ᵢᵀJᵢx] ∈ SOC₃  (each contact)
//!                                         lo ≤ x_a ≤ hi                              (joint limits)
//! ```
//!
//! with `x = [δq_a ; δq_u]`. The duals of the cones are the contact forces.

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
}

/// Solution of one program.
#[derive(Debug, Clone)]
pub(crate) struct Solution {
    /// Primal increments.
    pub x: Vec<f64>,
    /// Force on body A of each contact (world frame, N).
    pub forces_on_a: Vec<Vector3<f64>>,
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

/// Build and solve the program. Errors only for malformed data (a defect); solver statuses
/// other than `Solved` are returned in [`Solution::status`] for the caller to judge.
pub(crate) fn solve(prog: &Program<'_>) -> Result<Solution, String> {
    let n = prog.c.len();
    let m_cone = 3 * prog.cones.len();
    let m = m_cone + 2 * prog.bounds.len();
    let mut a = DMatrix::<f64>::zeros(m.max(1), n);
    let mut b = vec![0.0; m.max(1)];
    let mut cone_spec: Vec<SupportedConeT<f64>> = Vec::with_capacity(prog.cones.len() + 1);
    let mut tangent_frames = Vec::with_capacity(prog.cones.len());
    for (k, cone) in prog.cones.iter().enumerate() {
        let (t1, t2) = tangents(&cone.normal);
        let r = 3 * k;
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
        tangent_frames.push((t1, t2));
    }
    if !prog.bounds.is_empty() {
        for (i, &(lo, hi)) in prog.bounds.iter().enumerate() {
            // x_i ≤ hi  →  s = hi − x_i ≥ 0;   −x_i ≤ −lo  →  s = x_i − lo ≥ 0.
            a[(m_cone + 2 * i, i)] = 1.0;
            b[m_cone + 2 * i] = hi;
            a[(m_cone + 2 * i + 1, i)] = -1.0;
            b[m_cone + 2 * i + 1] = -lo;
        }
        cone_spec.push(SupportedConeT::NonnegativeConeT(2 * prog.bounds.len()));
    }
    if m == 0 {
        // A single trivially satisfied row keeps Clarabel's dimensions non-empty.
        b[0] = 1.0;
        cone_spec.push(SupportedConeT::NonnegativeConeT(1));
    }
    let p = to_csc(prog.p, true);
    let a = to_csc(&a, false);
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .max_iter(100)
        .build()
        .map_err(|e| format!("settings: {e:?}"))?;
    let mut solver = DefaultSolver::new(&p, prog.c, &a, &b, &cone_spec, settings)
        .map_err(|e| format!("setup: {e:?}"))?;
    solver.solve();
    let sol = &solver.solution;
    let forces_on_a = prog
        .cones
        .iter()
        .zip(&tangent_frames)
        .enumerate()
        .map(|(k, (cone, (t1, t2)))| {
            let z = &sol.z[3 * k..3 * k + 3];
            cone.normal * (z[0] / cone.mu) + t1 * z[1] + t2 * z[2]
        })
        .collect();
    Ok(Solution {
        x: sol.x.clone(),
        forces_on_a,
        status: sol.status,
        iterations: sol.iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point pushed into a floor (1-D spring toward z = −0.01) stops at the floor and the dual
    /// equals the spring force; a tangential command slides it with Coulomb friction.
    #[test]
    fn point_on_floor_matches_hand_solution() {
        // x = (dx, dy, dz) of a point at height 0 with stiffness k toward (0.004, 0, −0.01).
        let k = 100.0;
        let p = DMatrix::identity(3, 3) * k;
        let c = [-k * 0.004, 0.0, k * 0.01];
        let mut jac = Matrix3xX::zeros(3);
        jac.fill_with_identity();
        let cone = ConeRow {
            phi: 0.0,
            mu: 0.5,
            normal: Vector3::z(),
            jac,
        };
        let sol = solve(&Program {
            p: &p,
            c: &c,
            cones: &[cone],
            bounds: &[],
        })
        .unwrap();
        assert_eq!(sol.status, SolverStatus::Solved);
        // Normal force k·0.01 = 1 N on the point (+z); the tangential pull k·0.004 = 0.4 N is
        // inside the friction limit 0.5 N, so the point sticks and friction carries all of it.
        let f = sol.forces_on_a[0];
        assert!((f.z - 1.0).abs() < 1e-5, "{f:?}");
        assert!((f.x + 0.4).abs() < 1e-5, "{f:?}");
        assert!(sol.x.iter().all(|v| v.abs() < 1e-6), "{:?}", sol.x);
        // Pull harder (1 N tangential > 0.5 N limit): it slides and lifts by μ·|slip| (Anitescu).
        let c = [-k * 0.01, 0.0, k * 0.01];
        let mut jac = Matrix3xX::zeros(3);
        jac.fill_with_identity();
        let cone = ConeRow {
            phi: 0.0,
            mu: 0.5,
            normal: Vector3::z(),
            jac,
        };
        let sol = solve(&Program {
            p: &p,
            c: &c,
            cones: &[cone],
            bounds: &[],
        })
        .unwrap();
        assert!(sol.x[0] > 1e-3, "{:?}", sol.x);
        assert!((sol.x[2] - 0.5 * sol.x[0]).abs() < 1e-6, "{:?}", sol.x);
        let f = sol.forces_on_a[0];
        assert!((f.xy().norm() - 0.5 * f.z).abs() < 1e-5, "{f:?}");
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
