//! Element-wise ops: unary functions and broadcast binary functions.

use super::{OpSizeError, ensure, mul};
use crate::nn::format::{BinaryFn, RANK, UnaryFn};

/// `eˣ` in `f32`, branch-free so loops over it vectorize: range reduction by `ln 2` (split
/// in two parts), a degree-6 polynomial on `[-ln2/2, ln2/2]` (Cephes `expf`) and the power of
/// two built in the exponent bits. Relative error ≤ 2e-7 on `[-87, 88]` (tested against
/// `libm::expf`); inputs outside are clamped (`e⁻⁸⁷ ≈ 1.6e-38`, `e⁸⁸ ≈ 1.7e38`).
#[inline(always)]
pub fn exp_fast(x: f32) -> f32 {
    const LOG2E: f32 = core::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_359_4;
    const LN2_LO: f32 = -2.121_944_4e-4;
    // Adding and subtracting 1.5·2²³ rounds to the nearest integer without a branch.
    const ROUND: f32 = 12_582_912.0;
    let x = x.clamp(-87.0, 88.0);
    let t = x * LOG2E + ROUND;
    let n = t - ROUND;
    let r = x - n * LN2_HI - n * LN2_LO;
    let p = 1.987_569_1e-4_f32;
    let p = p * r + 1.398_199_9e-3;
    let p = p * r + 8.333_452e-3;
    let p = p * r + 4.166_579_6e-2;
    let p = p * r + 1.666_666_5e-1;
    let p = p * r + 5e-1;
    let e = p * r * r + r + 1.0;
    // `t`'s low mantissa bits hold `n` (|n| ≤ 127 < 2²²): integer maths only, no
    // saturating float-to-int conversion, so the loop stays vectorized.
    let n_int = t.to_bits().wrapping_sub(ROUND.to_bits());
    e * f32::from_bits(n_int.wrapping_add(127) << 23)
}

/// `ln(1 + eˣ)` without overflow for large `x`.
#[inline]
pub fn softplus(x: f32) -> f32 {
    if x > 20.0 {
        x
    } else {
        libm::log1pf(exp_fast(x))
    }
}

/// `x·tanh(ln(1 + eˣ))`, computed with one exponential:
/// with `n = eˣ(eˣ + 2)`, `tanh(softplus(x)) = n / (n + 2)`. Branch-free (vectorizes).
#[inline(always)]
pub fn mish(x: f32) -> f32 {
    let e = exp_fast(x.min(20.0));
    let n = e * (e + 2.0);
    let m = x * n / (n + 2.0);
    if x > 20.0 { x } else { m }
}

/// [`mish`] over a slice, in place (inlined, so the AVX2 copy of its caller vectorizes it).
#[inline(always)]
pub fn mish_in_place(y: &mut [f32]) {
    for v in y.iter_mut() {
        *v = mish(*v);
    }
}

/// `1 / (1 + e⁻ˣ)`.
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    let e = exp_fast(-x.abs());
    let p = 1.0 / (1.0 + e);
    if x >= 0.0 { p } else { e * p }
}

/// Apply one unary function.
#[inline]
pub fn apply_unary(f: UnaryFn, x: f32) -> f32 {
    match f {
        UnaryFn::Mish => mish(x),
        UnaryFn::Softplus => softplus(x),
        UnaryFn::Tanh => libm::tanhf(x),
        UnaryFn::Sigmoid => sigmoid(x),
        UnaryFn::Sin => libm::sinf(x),
        UnaryFn::Cos => libm::cosf(x),
        UnaryFn::Exp => libm::expf(x),
        UnaryFn::Relu => x.max(0.0),
        UnaryFn::Neg => -x,
        UnaryFn::Sqrt => libm::sqrtf(x),
        UnaryFn::Reciprocal => 1.0 / x,
        UnaryFn::Abs => libm::fabsf(x),
        UnaryFn::Log => libm::logf(x),
    }
}

/// `y = f(x)` element-wise; `x` and `y` have the same length.
pub fn unary(f: UnaryFn, x: &[f32], y: &mut [f32]) -> Result<(), OpSizeError> {
    ensure(x.len() == y.len())?;
    match f {
        // The common activations get their own loops so each is a tight loop.
        UnaryFn::Mish => y.iter_mut().zip(x).for_each(|(o, v)| *o = mish(*v)),
        UnaryFn::Tanh => y.iter_mut().zip(x).for_each(|(o, v)| *o = libm::tanhf(*v)),
        _ => y
            .iter_mut()
            .zip(x)
            .for_each(|(o, v)| *o = apply_unary(f, *v)),
    }
    Ok(())
}

/// Apply one binary function.
#[inline]
pub fn apply_binary(f: BinaryFn, a: f32, b: f32) -> f32 {
    match f {
        BinaryFn::Add => a + b,
        BinaryFn::Sub => a - b,
        BinaryFn::Mul => a * b,
        BinaryFn::Div => a / b,
        BinaryFn::Max => a.max(b),
        BinaryFn::Min => a.min(b),
        BinaryFn::Pow => libm::powf(a, b),
    }
}

/// Highest offset (inclusive) a strided loop over `dims` reads, or `None` when `dims` is empty.
pub fn max_offset(dims: &[u32; RANK], strides: &[u32; RANK]) -> Result<Option<usize>, OpSizeError> {
    let mut off = 0usize;
    for (d, s) in dims.iter().zip(strides) {
        if *d == 0 {
            return Ok(None);
        }
        off = off
            .checked_add(mul(*d as usize - 1, *s as usize)?)
            .ok_or(OpSizeError)?;
    }
    Ok(Some(off))
}

#[inline]
fn inner_loop(f: BinaryFn, a: &[f32], b: &[f32], y: &mut [f32], sa: usize, sb: usize) {
    macro_rules! lanes {
        ($op:expr) => {{
            let op = $op;
            match (sa, sb) {
                (1, 1) => y
                    .iter_mut()
                    .zip(a)
                    .zip(b)
                    .for_each(|((o, p), q)| *o = op(*p, *q)),
                (1, 0) => {
                    let q = b[0];
                    y.iter_mut().zip(a).for_each(|(o, p)| *o = op(*p, q))
                }
                (0, 1) => {
                    let p = a[0];
                    y.iter_mut().zip(b).for_each(|(o, q)| *o = op(p, *q))
                }
                _ => y
                    .iter_mut()
                    .enumerate()
                    .for_each(|(i, o)| *o = op(a[i * sa], b[i * sb])),
            }
        }};
    }
    match f {
        BinaryFn::Add => lanes!(|p: f32, q: f32| p + q),
        BinaryFn::Mul => lanes!(|p: f32, q: f32| p * q),
        BinaryFn::Sub => lanes!(|p: f32, q: f32| p - q),
        _ => lanes!(|p: f32, q: f32| apply_binary(f, p, q)),
    }
}

super::cpu::wide! {
    /// One sample of `y = f(a, b)` with broadcasting: `y` is `dims` row-major, `a` and `b` are
    /// read with `sa`/`sb` (0 on broadcast axes).
    pub fn binary(
        f: BinaryFn,
        a: &[f32],
        b: &[f32],
        y: &mut [f32],
        dims: &[u32; RANK],
        sa: &[u32; RANK],
        sb: &[u32; RANK],
    ) -> Result<(), OpSizeError> = binary_body;
}

#[inline(always)]
fn binary_body(
    f: BinaryFn,
    a: &[f32],
    b: &[f32],
    y: &mut [f32],
    dims: &[u32; RANK],
    sa: &[u32; RANK],
    sb: &[u32; RANK],
) -> Result<(), OpSizeError> {
    let total = dims
        .iter()
        .try_fold(1usize, |acc, d| mul(acc, *d as usize))?;
    ensure(y.len() == total)?;
    if total == 0 {
        return Ok(());
    }
    ensure(max_offset(dims, sa)?.is_some_and(|m| m < a.len()))?;
    ensure(max_offset(dims, sb)?.is_some_and(|m| m < b.len()))?;
    let [d0, d1, d2, d3] = dims.map(|d| d as usize);
    let (sa3, sb3) = (sa[3] as usize, sb[3] as usize);
    let mut out = 0;
    for i0 in 0..d0 {
        for i1 in 0..d1 {
            for i2 in 0..d2 {
                let oa = i0 * sa[0] as usize + i1 * sa[1] as usize + i2 * sa[2] as usize;
                let ob = i0 * sb[0] as usize + i1 * sb[1] as usize + i2 * sb[2] as usize;
                let ya = &a[oa..oa + (d3 - 1) * sa3 + 1];
                let yb = &b[ob..ob + (d3 - 1) * sb3 + 1];
                inner_loop(f, ya, yb, &mut y[out..out + d3], sa3, sb3);
                out += d3;
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
    use std::vec::Vec;

    #[test]
    fn exp_fast_matches_libm() {
        let mut worst = 0.0f64;
        let mut x = -87.0f32;
        while x < 88.0 {
            let want = libm::exp(x as f64);
            let rel = ((exp_fast(x) as f64 - want) / want).abs();
            worst = worst.max(rel);
            x += 0.0137;
        }
        assert!(worst < 3e-7, "worst relative error {worst}");
        assert_eq!(exp_fast(0.0), 1.0);
        assert!(exp_fast(-1000.0) < 1e-37 && exp_fast(1000.0) > 1e38);
    }

    #[test]
    fn activations_match_reference_formulas() {
        for i in -400..400 {
            let x = i as f32 * 0.07;
            let sp = (1.0f64 + (x as f64).exp()).ln();
            let want = x as f64 * sp.tanh();
            assert!(
                (mish(x) as f64 - want).abs() <= 1e-6 * (1.0 + want.abs()),
                "mish({x})"
            );
            assert!(
                (softplus(x) as f64 - sp).abs() <= 1e-6 * (1.0 + sp),
                "softplus({x})"
            );
            let sg = 1.0 / (1.0 + (-(x as f64)).exp());
            assert!((sigmoid(x) as f64 - sg).abs() <= 1e-7, "sigmoid({x})");
        }
        assert_eq!(mish(100.0), 100.0);
        assert!(mish(-100.0).abs() < 1e-30);
    }

    #[test]
    fn unary_applies_each_function() {
        let x = rand_vec(33, 1);
        let mut y = vec![0.0; 33];
        unary(UnaryFn::Tanh, &x, &mut y).unwrap();
        let want: Vec<f32> = x.iter().map(|v| v.tanh()).collect();
        assert_close(&y, &want, 1e-6);
        assert!(unary(UnaryFn::Exp, &x, &mut [0.0; 3]).is_err());
    }

    fn naive_binary(
        a: &[f32],
        b: &[f32],
        dims: [usize; 4],
        sa: [usize; 4],
        sb: [usize; 4],
    ) -> Vec<f32> {
        let mut y = vec![];
        for i0 in 0..dims[0] {
            for i1 in 0..dims[1] {
                for i2 in 0..dims[2] {
                    for i3 in 0..dims[3] {
                        let ia = i0 * sa[0] + i1 * sa[1] + i2 * sa[2] + i3 * sa[3];
                        let ib = i0 * sb[0] + i1 * sb[1] + i2 * sb[2] + i3 * sb[3];
                        y.push(a[ia] - b[ib]);
                    }
                }
            }
        }
        y
    }

    #[test]
    fn binary_broadcasts_like_numpy() {
        // [2,3,5] - [3,1] ; [1,3,5] - [2,3,1] ; same shapes.
        type Case = ([usize; 4], [usize; 4], [usize; 4], usize, usize);
        let cases: [Case; 3] = [
            ([1, 2, 3, 5], [0, 15, 5, 1], [0, 0, 1, 0], 30, 3),
            ([1, 2, 3, 5], [0, 0, 5, 1], [0, 3, 1, 0], 15, 6),
            ([1, 1, 4, 7], [0, 0, 7, 1], [0, 0, 7, 1], 28, 28),
        ];
        for (i, (dims, sa, sb, na, nb)) in cases.into_iter().enumerate() {
            let a = rand_vec(na, i as u64);
            let b = rand_vec(nb, 9 + i as u64);
            let want = naive_binary(&a, &b, dims, sa, sb);
            let mut y = vec![0.0; want.len()];
            let u = |v: [usize; 4]| v.map(|d| d as u32);
            binary(BinaryFn::Sub, &a, &b, &mut y, &u(dims), &u(sa), &u(sb)).unwrap();
            assert_eq!(y, want);
        }
        let mut y = vec![0.0; 30];
        assert!(
            binary(
                BinaryFn::Add,
                &[0.0; 29],
                &[0.0; 3],
                &mut y,
                &[1, 2, 3, 5],
                &[0, 15, 5, 1],
                &[0, 0, 1, 0]
            )
            .is_err()
        );
    }
}
