//! Normalization and reductions.

use super::{OpSizeError, ensure, mul};

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
    ensure(len > 0 && x.len() == y.len() && x.len() % len == 0)?;
    let channels = x.len() / len;
    ensure(scale.len() == channels && bias.len() == channels)?;
    let inv_len = 1.0 / len as f32;
    for (c, (xr, yr)) in x.chunks_exact(len).zip(y.chunks_exact_mut(len)).enumerate() {
        let mean = xr.iter().sum::<f32>() * inv_len;
        let var = xr.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() * inv_len;
        let k = scale[c] / libm::sqrtf(var + eps);
        let sh = bias[c] - mean * k;
        for (o, v) in yr.iter_mut().zip(xr) {
            *o = v * k + sh;
        }
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
