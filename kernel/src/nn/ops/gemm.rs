//! Dense layers: `y = a·w + b` with `w` packed `[k][n]`.

use super::{OpSizeError, ensure, mul};

super::cpu::wide! {
    /// `y[r, :] = b + Σₖ a[r, k]·w[k, :]` for every row `r` of `a` (`[rows, k]`).
    pub fn gemm(
        a: &[f32],
        w: &[f32],
        b: &[f32],
        y: &mut [f32],
        k: usize,
        n: usize,
    ) -> Result<(), OpSizeError> = gemm_body;
}

#[inline(always)]
fn gemm_body(
    a: &[f32],
    w: &[f32],
    b: &[f32],
    y: &mut [f32],
    k: usize,
    n: usize,
) -> Result<(), OpSizeError> {
    ensure(k > 0 && n > 0)?;
    ensure(a.len().is_multiple_of(k))?;
    let rows = a.len() / k;
    ensure(y.len() == mul(rows, n)? && w.len() == mul(k, n)? && b.len() == n)?;
    for (arow, yrow) in a.chunks_exact(k).zip(y.chunks_exact_mut(n)) {
        yrow.copy_from_slice(b);
        for (av, wrow) in arow.iter().zip(w.chunks_exact(n)) {
            for (o, wv) in yrow.iter_mut().zip(wrow) {
                *o += av * wv;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::ops::testutil::{assert_close, rand_vec};
    use std::vec;

    #[test]
    fn gemm_matches_naive() {
        let (rows, k, n) = (5, 7, 11);
        let a = rand_vec(rows * k, 1);
        let w = rand_vec(k * n, 2);
        let b = rand_vec(n, 3);
        let mut want = vec![0.0; rows * n];
        for r in 0..rows {
            for j in 0..n {
                want[r * n + j] = b[j] + (0..k).map(|i| a[r * k + i] * w[i * n + j]).sum::<f32>();
            }
        }
        let mut y = vec![0.0; rows * n];
        gemm(&a, &w, &b, &mut y, k, n).unwrap();
        assert_close(&y, &want, 1e-6);
        assert!(gemm(&a, &w, &b, &mut y[1..], k, n).is_err());
    }
}
