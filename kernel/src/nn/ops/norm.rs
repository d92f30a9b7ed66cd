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

/// Groups whose statistics [`group_norm`] computes together.
const STATS: usize = 8;

/// [`sum_by`] of each of the (at most [`STATS`]) consecutive `group_len`-long groups of `xb`,
/// `f` given the group's index: per group the same operations in the same order as `sum_by`
/// (so the same result bit for bit), the groups' accumulations interleaved so that their
/// chains of dependent adds overlap. Entries past the last group are 0.
#[inline(always)]
fn group_sums(xb: &[f32], group_len: usize, f: impl Fn(usize, f32) -> f32) -> [f32; STATS] {
    let n = (xb.len() / group_len).min(STATS);
    let full = group_len / 8;
    let mut acc = [[0.0f32; 8]; STATS];
    for i in 0..full {
        for (g, a) in acc.iter_mut().enumerate().take(n) {
            let start = g * group_len + 8 * i;
            let Some(c) = xb.get(start..start + 8) else {
                continue;
            };
            for (a, v) in a.iter_mut().zip(c) {
                *a += f(g, *v);
            }
        }
    }
    let mut out = [0.0f32; STATS];
    for (g, (o, a)) in out.iter_mut().zip(&acc).enumerate().take(n) {
        let mut s = a.iter().sum::<f32>();
        for v in xb
            .get(g * group_len + 8 * full..(g + 1) * group_len)
            .unwrap_or(&[])
        {
            s += f(g, *v);
        }
        *o = s;
    }
    out
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
        let k = scale[c] / super::cpu::sqrt(var + eps);
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
    // The statistics of up to STATS groups at a time, their reductions interleaved
    // ([`group_sums`]), then their normalization: a group's mean, variance, square root and
    // division are a chain of dependent operations a few hundred cycles long, and the groups'
    // chains now run side by side instead of one after another.
    for (block, (xb, yb)) in x
        .chunks(STATS * group_len)
        .zip(y.chunks_mut(STATS * group_len))
        .enumerate()
    {
        let sums = group_sums(xb, group_len, |_, v| v);
        let mean = sums.map(|s| s * inv_len);
        let sq = group_sums(xb, group_len, |g, v| (v - mean[g]) * (v - mean[g]));
        let rstd = sq.map(|s| 1.0 / super::cpu::sqrt(s * inv_len + eps));
        for (i, ((xg, yg), (mu, rs))) in xb
            .chunks_exact(group_len)
            .zip(yb.chunks_exact_mut(group_len))
            .zip(mean.iter().zip(&rstd))
            .enumerate()
        {
            let g = block * STATS + i;
            for (c, (xc, yc)) in xg
                .chunks_exact(channel_len)
                .zip(yg.chunks_exact_mut(channel_len))
                .enumerate()
            {
                let ch = g * per_group + c;
                let k = gamma[ch] * rs;
                let sh = beta[ch] - mu * k;
                for (o, v) in yc.iter_mut().zip(xc) {
                    *o = v * k + sh;
                }
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

    /// Group normalization one group at a time with [`sum_by`], as it was computed before
    /// the groups' statistics were interleaved.
    fn group_norm_one_group_at_a_time(x: &[f32], group_len: usize, eps: f32) -> Vec<f32> {
        let inv_len = 1.0 / group_len as f32;
        let mut y = Vec::new();
        for xg in x.chunks_exact(group_len) {
            let mean = sum_by(xg, |v| v) * inv_len;
            let var = sum_by(xg, |v| (v - mean) * (v - mean)) * inv_len;
            let rstd = 1.0 / libm::sqrtf(var + eps);
            y.extend(xg.iter().map(|v| v * rstd + (0.0 - mean * rstd)));
        }
        y
    }

    #[test]
    fn interleaved_group_statistics_change_no_bit() {
        // Groups of 6 × 13 (a tail of 6 after 9 full chunks), 8 × 16, 12 × 4, 3 × 3 (no full
        // chunk); 5, 8, 13 and 16 groups (blocks of 8 with and without a remainder).
        for (seed, &(groups, channels, len)) in [(5, 6, 13), (8, 8, 16), (13, 12, 4), (16, 3, 3)]
            .iter()
            .enumerate()
        {
            let group_len = channels * len;
            let x: Vec<f32> = rand_vec(groups * group_len, 30 + seed as u64)
                .iter()
                .map(|v| v * 4.0 - 1.0)
                .collect();
            let ones = vec![1.0; groups * channels];
            let zeros = vec![0.0; groups * channels];
            let mut y = vec![0.0; x.len()];
            group_norm(&x, &mut y, group_len, len, 1e-5, &ones, &zeros, false).unwrap();
            let want = group_norm_one_group_at_a_time(&x, group_len, 1e-5);
            let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&y), bits(&want), "case {seed}");
        }
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

#[cfg(test)]
mod throughput {
    use super::*;
    use crate::nn::ops::testutil::rand_vec;
    use std::vec;

    /// `cargo test -p dips-kernel --release -- --ignored --nocapture group_norm_throughput`
    #[test]
    #[ignore = "timing, run by hand"]
    fn group_norm_throughput() {
        // The shipped denoisers' shapes: 8 groups of 48/64/96 channels over 16/8/4 steps.
        for &(channels, len) in &[(48, 16), (64, 8), (96, 4), (48, 12), (96, 3)] {
            let group_len = channels / 8 * len;
            let x = rand_vec(channels * len, 1);
            let gamma = rand_vec(channels, 2);
            let beta = rand_vec(channels, 3);
            let mut y = vec![0.0; x.len()];
            let reps = 200_000;
            for mish in [false, true] {
                let mut best = f64::MAX;
                for _ in 0..5 {
                    let t = std::time::Instant::now();
                    for _ in 0..reps {
                        group_norm(&x, &mut y, group_len, len, 1e-5, &gamma, &beta, mish).unwrap();
                    }
                    best = best.min(t.elapsed().as_secs_f64());
                }
                std::println!(
                    "{channels} × {len}, mish {mish}: {:.2} ns per element",
                    best / (reps * x.len()) as f64 * 1e9
                );
            }
        }
    }
}
