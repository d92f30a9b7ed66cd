//! Normalization and reductions.

use super::{OpSizeError, ensure, mul};

/// `Σ f(xᵢ)` with eight interleaved partial sums, so the loop vectorizes.
#[inline(always)]
fn sum_by(x: &[f32], f: impl Fn(f32) -> f32) -> f32 {
    let mut acc = [0.0f32; 8];
    let chunks = x.chunks_exact(8);
    let tail = chunks.remainder();
    for c in chunks {
        for (a, v) in acc.iter_mut().zip(c) {
            *a += f(*v);
        }
    }
    let mut s = acc.iter().sum::<f32>();
    for v in tail {
        s += f(*v);
    }
    s
}

/// One sample of instance normalization over rows: each of the `channels` rows of `len`
/// elements is normalized to zero mean and unit variance (biased), then scaled and shifted
/// per row: `y = (x − μ)/√(σ² + ε)·scale + bias`.
pub fn instance_norm(
    x: &[f32],
    y: &mut [f32],
    len: usize,
    eps: f32,
    scale: &[f32],
    bias: &[f32],
) -> Result<(), OpSizeError> {
    ensure(len > 0 && x.len() == y.len() && x.len().is_multiple_of(len))?;
    let channels = x.len() / len;
    ensure(scale.len() == channels && bias.len() == channels)?;
    let inv_len = 1.0 / len as f32;
    for (c, (xr, yr)) in x.chunks_exact(len).zip(y.chunks_exact_mut(len)).enumerate() {
        let mean = sum_by(xr, |v| v) * inv_len;
        let var = sum_by(xr, |v| (v - mean) * (v - mean)) * inv_len;
        let k = scale[c] / libm::sqrtf(var + eps);
        let sh = bias[c] - mean * k;
        for (o, v) in yr.iter_mut().zip(xr) {
            *o = v * k + sh;
        }
    }
    Ok(())
}

super::cpu::wide! {
    /// One sample of group normalization with a per-channel affine map and optional Mish
    /// ([`crate::nn::format::Op::GroupNorm`]).
    #[allow(clippy::too_many_arguments)]
    pub fn group_norm(
        x: &[f32],
        y: &mut [f32],
        group_len: usize,
        channel_len: usize,
        eps: f32,
        gamma: &[f32],
        beta: &[f32],
        mish: bool,
    ) -> Result<(), OpSizeError> = group_norm_body;
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn group_norm_body(
    x: &[f32],
    y: &mut [f32],
    group_len: usize,
    channel_len: usize,
    eps: f32,
    gamma: &[f32],
    beta: &[f32],
    mish: bool,
) -> Result<(), OpSizeError> {
    ensure(group_len > 0 && channel_len > 0 && group_len.is_multiple_of(channel_len))?;
    ensure(x.len() == y.len() && x.len().is_multiple_of(group_len))?;
    ensure(gamma.len() == x.len() / channel_len && beta.len() == gamma.len())?;
    let inv_len = 1.0 / group_len as f32;
    let per_group = group_len / channel_len;
    for (g, (xg, yg)) in x
        .chunks_exact(group_len)
        .zip(y.chunks_exact_mut(group_len))
        .enumerate()
    {
        let mean = sum_by(xg, |v| v) * inv_len;
        let var = sum_by(xg, |v| (v - mean) * (v - mean)) * inv_len;
        let rstd = 1.0 / libm::sqrtf(var + eps);
        for (c, (xc, yc)) in xg
            .chunks_exact(channel_len)
            .zip(yg.chunks_exact_mut(channel_len))
            .enumerate()
        {
            let ch = g * per_group + c;
            let k = gamma[ch] * rstd;
            let sh = beta[ch] - mean * k;
            for (o, v) in yc.iter_mut().zip(xc) {
                *o = v * k + sh;
            }
        }
    }
    // One long pass over the sample vectorizes; per-channel rows are often only 3-16 long.
    if mish {
        super::elementwise::mish_in_place(y);
    }
    Ok(())
}

/// One sample of `y[o, i] = mean_l x[o, l, i]`.
pub fn reduce_mean(
    x: &[f32],
    y: &mut [f32],
    outer: usize,
    len: usize,
    inner: usize,
) -> Result<(), OpSizeError> {
    ensure(len > 0 && x.len() == mul(mul(outer, len)?, inner)? && y.len() == mul(outer, inner)?)?;
    let inv = 1.0 / len as f32;
    for o in 0..outer {
        let yr = &mut y[o * inner..(o + 1) * inner];
        yr.fill(0.0);
        for l in 0..len {
            let xr = &x[(o * len + l) * inner..(o * len + l + 1) * inner];
            for (a, v) in yr.iter_mut().zip(xr) {
                *a += v;
            }
        }
        yr.iter_mut().for_each(|a| *a *= inv);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::ops::testutil::{assert_close, rand_vec};
    use std::vec;
    use std::vec::Vec;

    #[test]
    fn instance_norm_matches_naive_f64() {
        let (c, l) = (8, 26);
        let x: Vec<f32> = rand_vec(c * l, 4).iter().map(|v| v * 3.0 + 1.5).collect();
        let scale = rand_vec(c, 5);
        let bias = rand_vec(c, 6);
        let mut want = vec![0.0; c * l];
        for ch in 0..c {
            let r = &x[ch * l..(ch + 1) * l];
            let m = r.iter().map(|v| *v as f64).sum::<f64>() / l as f64;
            let v = r.iter().map(|v| (*v as f64 - m).powi(2)).sum::<f64>() / l as f64;
            for t in 0..l {
                want[ch * l + t] = (((r[t] as f64 - m) / (v + 1e-5).sqrt()) * scale[ch] as f64
                    + bias[ch] as f64) as f32;
            }
        }
        let mut y = vec![0.0; c * l];
        instance_norm(&x, &mut y, l, 1e-5, &scale, &bias).unwrap();
        assert_close(&y, &want, 1e-5);
        assert!(instance_norm(&x, &mut y, l, 1e-5, &scale[1..], &bias).is_err());
    }

    #[test]
    fn group_norm_matches_instance_norm_then_affine_then_mish() {
        let (groups, cpg, l) = (4, 3, 10);
        let c = groups * cpg;
        let x: Vec<f32> = rand_vec(c * l, 11).iter().map(|v| v * 2.0 - 0.3).collect();
        let gamma = rand_vec(c, 12);
        let beta = rand_vec(c, 13);
        let mut n = vec![0.0; c * l];
        instance_norm(&x, &mut n, cpg * l, 1e-5, &[1.0; 4], &[0.0; 4]).unwrap();
        let want: Vec<f32> = n
            .iter()
            .enumerate()
            .map(|(i, v)| crate::nn::ops::elementwise::mish(v * gamma[i / l] + beta[i / l]))
            .collect();
        let mut y = vec![0.0; c * l];
        group_norm(&x, &mut y, cpg * l, l, 1e-5, &gamma, &beta, true).unwrap();
        assert_close(&y, &want, 1e-5);
        assert!(group_norm(&x, &mut y, cpg * l, 7, 1e-5, &gamma, &beta, true).is_err());
    }

    #[test]
    fn reduce_mean_matches_naive() {
        let (o, l, i) = (3, 5, 4);
        let x = rand_vec(o * l * i, 8);
        let mut y = vec![0.0; o * i];
        reduce_mean(&x, &mut y, o, l, i).unwrap();
        for a in 0..o {
            for b in 0..i {
                let m = (0..l).map(|k| x[(a * l + k) * i + b]).sum::<f32>() / l as f32;
                assert!((y[a * i + b] - m).abs() < 1e-6);
            }
        }
        assert!(reduce_mean(&x, &mut y, o, l + 1, i).is_err());
    }
}
