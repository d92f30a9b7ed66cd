//! Block-tridiagonal Cholesky factorisation for `∇C ∇Cᵀ + λI`.
//!
//! CSVTO's constraints at step `t` only touch rows `t − 1` (through the state part) and `t`
//! of the trajectory, so `∇C ∇Cᵀ` is block tridiagonal with one block per time step. The
//! factorisation `L Lᵀ` keeps that structure: a diagonal Cholesky factor `L_t` per step and a
//! sub-diagonal coupling block `C_t = A_{t,t−1} L_{t−1}⁻ᵀ`. Factoring and solving cost
//! `O(H·m³)` and `O(H·m²)` per right-hand side, where `m` is the number of constraints in one
//! step, instead of `O((H·m)³)` for a dense factorisation.
//!
//! Matrices are row-major `Vec<f64>`. Right-hand sides are stored "constraint-major": `k`
//! vectors side by side, so row `i` of the batch is `rhs[i*k..(i+1)*k]`; the inner loops run
//! over the `k` vectors and vectorise.

// Index loops over the fixed-width right-hand-side rows vectorise best as written.
#![allow(clippy::needless_range_loop)]

/// Dot product with eight independent accumulators, so it vectorises (a plain fold must
/// keep the sequential rounding order and does not).
#[inline]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let mut ca = a.chunks_exact(8);
    let mut cb = b.chunks_exact(8);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    let mut s = (acc[0] + acc[4]) + (acc[1] + acc[5]) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        s += x * y;
    }
    s
}

/// Smallest pivot accepted during a dense Cholesky; smaller pivots are raised to it.
const MIN_PIVOT: f64 = 1e-12;

/// In-place dense Cholesky of the `m×m` row-major SPD matrix `a` (lower triangle used and
/// overwritten with `L`; the strict upper triangle is zeroed). Non-positive pivots (from
/// round-off on a nearly singular matrix) are raised to `MIN_PIVOT` (1e-12), so the factor always
/// exists; the returned count says how many pivots were raised.
pub fn cholesky_in_place(a: &mut [f64], m: usize) -> usize {
    debug_assert_eq!(a.len(), m * m);
    let mut raised = 0;
    for j in 0..m {
        let rj = &a[j * m..j * m + j];
        let mut d = a[j * m + j] - dot(rj, rj);
        // Also catches NaN.
        if d.is_nan() || d <= MIN_PIVOT {
            d = MIN_PIVOT;
            raised += 1;
        }
        let d = d.sqrt();
        a[j * m + j] = d;
        let inv = 1.0 / d;
        for i in j + 1..m {
            let s = a[i * m + j] - dot(&a[i * m..i * m + j], &a[j * m..j * m + j]);
            a[i * m + j] = s * inv;
        }
        for k in j + 1..m {
            a[j * m + k] = 0.0;
        }
    }
    raised
}

/// Solve `L Y = B` in place for lower-triangular `L` (`m×m`) and `k` right-hand sides stored
/// constraint-major in `b` (`m×k`).
pub fn forward_sub(l: &[f64], m: usize, b: &mut [f64], k: usize) {
    match k {
        16 => forward_sub_k::<16>(l, m, b),
        8 => forward_sub_k::<8>(l, m, b),
        1 => forward_sub_k::<1>(l, m, b),
        _ => forward_sub_dyn(l, m, b, k),
    }
}

fn forward_sub_dyn(l: &[f64], m: usize, b: &mut [f64], k: usize) {
    for i in 0..m {
        let (head, tail) = b.split_at_mut(i * k);
        let bi = &mut tail[..k];
        for (j, bj) in head.chunks_exact(k).enumerate() {
            let lij = l[i * m + j];
            for (x, y) in bi.iter_mut().zip(bj) {
                *x -= lij * y;
            }
        }
        let inv = 1.0 / l[i * m + i];
        for v in bi.iter_mut() {
            *v *= inv;
        }
    }
}

/// [`forward_sub`] with the number of right-hand sides fixed at compile time, so the inner
/// loop is fully unrolled and vectorised.
fn forward_sub_k<const K: usize>(l: &[f64], m: usize, b: &mut [f64]) {
    let (rows, _) = b.as_chunks_mut::<K>();
    for i in 0..m {
        let (head, tail) = rows.split_at_mut(i);
        let mut acc = tail[0];
        let li = &l[i * m..i * m + i];
        for (lij, bj) in li.iter().zip(head.iter()) {
            for c in 0..K {
                acc[c] -= lij * bj[c];
            }
        }
        let inv = 1.0 / l[i * m + i];
        for c in 0..K {
            tail[0][c] = acc[c] * inv;
        }
    }
}

/// Solve `Lᵀ Y = B` in place for lower-triangular `L` (`m×m`) and `k` right-hand sides.
pub fn backward_sub_transposed(l: &[f64], m: usize, b: &mut [f64], k: usize) {
    match k {
        16 => backward_sub_k::<16>(l, m, b),
        8 => backward_sub_k::<8>(l, m, b),
        1 => backward_sub_k::<1>(l, m, b),
        _ => backward_sub_dyn(l, m, b, k),
    }
}

fn backward_sub_dyn(l: &[f64], m: usize, b: &mut [f64], k: usize) {
    for i in (0..m).rev() {
        let (head, tail) = b.split_at_mut((i + 1) * k);
        let bi = &mut head[i * k..];
        for (q, bj) in tail.chunks_exact(k).enumerate() {
            let lji = l[(i + 1 + q) * m + i];
            for (x, y) in bi.iter_mut().zip(bj) {
                *x -= lji * y;
            }
        }
        let inv = 1.0 / l[i * m + i];
        for v in bi.iter_mut() {
            *v *= inv;
        }
    }
}

/// [`backward_sub_transposed`] with `K` right-hand sides fixed at compile time.
fn backward_sub_k<const K: usize>(l: &[f64], m: usize, b: &mut [f64]) {
    let (rows, _) = b.as_chunks_mut::<K>();
    for i in (0..m).rev() {
        let (head, tail) = rows.split_at_mut(i + 1);
        let mut acc = head[i];
        for (q, bj) in tail.iter().enumerate() {
            let lji = l[(i + 1 + q) * m + i];
            for c in 0..K {
                acc[c] -= lji * bj[c];
            }
        }
        let inv = 1.0 / l[i * m + i];
        for c in 0..K {
            head[i][c] = acc[c] * inv;
        }
    }
}

/// The factor of a block-tridiagonal SPD matrix.
#[derive(Debug, Clone, Default)]
pub struct BlockTriFactor {
    /// Block sizes `m_t`.
    sizes: Vec<usize>,
    /// Offsets of each block in a stacked vector.
    offsets: Vec<usize>,
    /// Diagonal Cholesky factors `L_t` (`m_t×m_t`).
    diag: Vec<Vec<f64>>,
    /// Coupling blocks `C_t = A_{t,t−1} L_{t−1}⁻ᵀ` (`m_t×m_{t−1}`); `C_0` is empty.
    sub: Vec<Vec<f64>>,
    /// Non-zero rows of each `C_t`.
    live: Vec<Vec<usize>>,
    /// How many pivots were raised to keep the factorisation defined.
    pub raised_pivots: usize,
}

impl BlockTriFactor {
    /// Factor the matrix with diagonal blocks `diag[t]` (`m_t×m_t`, row-major, SPD) and
    /// sub-diagonal blocks `sub[t] = A_{t,t−1}` (`m_t×m_{t−1}`; `sub[0]` is ignored). The
    /// blocks are consumed and overwritten.
    pub fn factor(sizes: Vec<usize>, mut diag: Vec<Vec<f64>>, mut sub: Vec<Vec<f64>>) -> Self {
        let h = sizes.len();
        let mut offsets = Vec::with_capacity(h + 1);
        let mut acc = 0;
        for &m in &sizes {
            offsets.push(acc);
            acc += m;
        }
        offsets.push(acc);
        let mut raised = 0;
        let mut lives = vec![Vec::new(); h];
        for t in 0..h {
            let m = sizes[t];
            if t > 0 {
                let mp = sizes[t - 1];
                // C_t = B_t L_{t−1}⁻ᵀ: each row c of C_t solves L_{t−1} cᵀ = (row of B_t)ᵀ.
                // Rows of B_t that are zero (constraints that do not see the previous
                // state) stay zero and are skipped here and in the Schur update.
                let lp = &diag[t - 1];
                let c = &mut sub[t];
                let live: Vec<usize> = (0..m)
                    .filter(|&r| c[r * mp..(r + 1) * mp].iter().any(|&v| v != 0.0))
                    .collect();
                for &r in &live {
                    let row = &mut c[r * mp..(r + 1) * mp];
                    for i in 0..mp {
                        let s = row[i] - dot(&lp[i * mp..i * mp + i], &row[..i]);
                        row[i] = s / lp[i * mp + i];
                    }
                }
                // S = D_t − C_t C_tᵀ (lower triangle).
                let d = &mut diag[t];
                for (a, &i) in live.iter().enumerate() {
                    let ci = &c[i * mp..(i + 1) * mp];
                    for &j in &live[..=a] {
                        let cj = &c[j * mp..(j + 1) * mp];
                        d[i * m + j] -= dot(ci, cj);
                    }
                }
                lives[t] = live;
            }
            raised += cholesky_in_place(&mut diag[t], m);
        }
        Self {
            sizes,
            offsets,
            diag,
            sub,
            live: lives,
            raised_pivots: raised,
        }
    }

    /// Total dimension.
    pub fn dim(&self) -> usize {
        *self.offsets.last().unwrap_or(&0)
    }

    /// Solve `A X = B` in place for `k` right-hand sides stored constraint-major (`dim×k`).
    pub fn solve_in_place(&self, b: &mut [f64], k: usize) {
        debug_assert_eq!(b.len(), self.dim() * k);
        match k {
            16 => self.solve_k::<16>(b),
            8 => self.solve_k::<8>(b),
            1 => self.solve_k::<1>(b),
            _ => self.solve_dyn(b, k),
        }
    }

    /// [`Self::solve_in_place`] with `K` right-hand sides fixed at compile time.
    fn solve_k<const K: usize>(&self, b: &mut [f64]) {
        let h = self.sizes.len();
        let (rows, _) = b.as_chunks_mut::<K>();
        for t in 0..h {
            let (m, o) = (self.sizes[t], self.offsets[t]);
            if t > 0 {
                let (mp, op) = (self.sizes[t - 1], self.offsets[t - 1]);
                let (prev, cur) = rows.split_at_mut(o);
                let prev = &prev[op..op + mp];
                let c = &self.sub[t];
                for &r in &self.live[t] {
                    let mut acc = cur[r];
                    for (cq, pq) in c[r * mp..(r + 1) * mp].iter().zip(prev) {
                        for j in 0..K {
                            acc[j] -= cq * pq[j];
                        }
                    }
                    cur[r] = acc;
                }
            }
            forward_sub_k::<K>(&self.diag[t], m, rows[o..o + m].as_flattened_mut());
        }
        for t in (0..h).rev() {
            let (m, o) = (self.sizes[t], self.offsets[t]);
            if t + 1 < h {
                let on = self.offsets[t + 1];
                let (cur, next) = rows.split_at_mut(on);
                let cur = &mut cur[o..o + m];
                let c = &self.sub[t + 1];
                for &r in &self.live[t + 1] {
                    let nr = next[r];
                    for (cq, dst) in c[r * m..(r + 1) * m].iter().zip(cur.iter_mut()) {
                        for j in 0..K {
                            dst[j] -= cq * nr[j];
                        }
                    }
                }
            }
            backward_sub_k::<K>(&self.diag[t], m, rows[o..o + m].as_flattened_mut());
        }
    }

    fn solve_dyn(&self, b: &mut [f64], k: usize) {
        let h = self.sizes.len();
        debug_assert_eq!(b.len(), self.dim() * k);
        // Forward: y_t = L_t⁻¹ (b_t − C_t y_{t−1}).
        for t in 0..h {
            let (m, o) = (self.sizes[t], self.offsets[t]);
            if t > 0 {
                let (mp, op) = (self.sizes[t - 1], self.offsets[t - 1]);
                let (prev, cur) = b.split_at_mut(o * k);
                let prev = &prev[op * k..];
                let c = &self.sub[t];
                for &r in &self.live[t] {
                    let br = &mut cur[r * k..(r + 1) * k];
                    for (q, pq) in prev[..mp * k].chunks_exact(k).enumerate() {
                        let v = c[r * mp + q];
                        for (x, y) in br.iter_mut().zip(pq) {
                            *x -= v * y;
                        }
                    }
                }
            }
            forward_sub(&self.diag[t], m, &mut b[o * k..(o + m) * k], k);
        }
        // Backward: x_t = L_t⁻ᵀ (y_t − C_{t+1}ᵀ x_{t+1}).
        for t in (0..h).rev() {
            let (m, o) = (self.sizes[t], self.offsets[t]);
            if t + 1 < h {
                let on = self.offsets[t + 1];
                let (cur, next) = b.split_at_mut(on * k);
                let cur = &mut cur[o * k..];
                let c = &self.sub[t + 1];
                for &r in &self.live[t + 1] {
                    let nr = &next[r * k..(r + 1) * k];
                    for (q, cq) in cur[..m * k].chunks_exact_mut(k).enumerate() {
                        let v = c[r * m + q];
                        for (x, y) in cq.iter_mut().zip(nr) {
                            *x -= v * y;
                        }
                    }
                }
            }
            backward_sub_transposed(&self.diag[t], m, &mut b[o * k..(o + m) * k], k);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random matrix entry.
    fn entry(seed: usize) -> f64 {
        let x = (seed as f64 * 12.9898).sin() * 43_758.545_3;
        x - x.floor() - 0.5
    }

    #[test]
    fn banded_solve_equals_dense_solve() {
        // A = J Jᵀ + 1e-3 I with J block-bidiagonal (each step's rows touch two column blocks).
        let sizes = vec![3usize, 5, 2, 4];
        let ncols_per = 4;
        let total: usize = sizes.iter().sum();
        let ncols = ncols_per * (sizes.len() + 1);
        let mut j = vec![0.0; total * ncols];
        let mut row = 0;
        for (t, &m) in sizes.iter().enumerate() {
            for _ in 0..m {
                for c in t * ncols_per..(t + 2) * ncols_per {
                    j[row * ncols + c] = entry(row * 131 + c * 7 + 1);
                }
                row += 1;
            }
        }
        let mut a = vec![0.0; total * total];
        for r in 0..total {
            for s in 0..total {
                let mut v = 0.0;
                for c in 0..ncols {
                    v += j[r * ncols + c] * j[s * ncols + c];
                }
                a[r * total + s] = v + if r == s { 1e-3 } else { 0.0 };
            }
        }
        // Extract blocks.
        let mut offs = vec![0];
        for &m in &sizes {
            offs.push(offs.last().unwrap() + m);
        }
        let mut diag = Vec::new();
        let mut sub = Vec::new();
        for t in 0..sizes.len() {
            let (m, o) = (sizes[t], offs[t]);
            let mut d = vec![0.0; m * m];
            for r in 0..m {
                for s in 0..m {
                    d[r * m + s] = a[(o + r) * total + o + s];
                }
            }
            diag.push(d);
            if t == 0 {
                sub.push(Vec::new());
            } else {
                let (mp, op) = (sizes[t - 1], offs[t - 1]);
                let mut b = vec![0.0; m * mp];
                for r in 0..m {
                    for s in 0..mp {
                        b[r * mp + s] = a[(o + r) * total + op + s];
                    }
                }
                sub.push(b);
            }
        }
        let f = BlockTriFactor::factor(sizes.clone(), diag, sub);
        assert_eq!(f.raised_pivots, 0);
        let k = 3;
        let rhs: Vec<f64> = (0..total * k).map(|i| entry(i + 999)).collect();
        let mut x = rhs.clone();
        f.solve_in_place(&mut x, k);
        // Dense reference: Cholesky of the full matrix.
        let mut l = a.clone();
        cholesky_in_place(&mut l, total);
        let mut y = rhs.clone();
        forward_sub(&l, total, &mut y, k);
        backward_sub_transposed(&l, total, &mut y, k);
        for i in 0..total * k {
            assert!(
                (x[i] - y[i]).abs() < 1e-9 * (1.0 + y[i].abs()),
                "{i}: {} vs {}",
                x[i],
                y[i]
            );
        }
        // And the residual A x − b is small.
        for r in 0..total {
            for c in 0..k {
                let mut s = 0.0;
                for q in 0..total {
                    s += a[r * total + q] * x[q * k + c];
                }
                assert!((s - rhs[r * k + c]).abs() < 1e-8);
            }
        }
    }
}
