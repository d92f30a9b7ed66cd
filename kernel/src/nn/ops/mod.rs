//! Op kernels: free functions over slices, one sample (or a flat batch) at a time.
//!
//! Each returns [`OpSizeError`] instead of indexing out of range when its slices do not fit
//! the geometry, so a hostile blob cannot make the interpreter panic.

pub mod conv;
pub mod cpu;
pub mod elementwise;
pub mod gemm;
pub mod layout;
pub mod norm;

/// The slices handed to an op do not match its geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OpSizeError;

/// `Ok(())` when `cond` holds.
#[inline]
pub(crate) fn ensure(cond: bool) -> Result<(), OpSizeError> {
    if cond { Ok(()) } else { Err(OpSizeError) }
}

/// `a · b` as `usize`, or an error on overflow.
#[inline]
pub(crate) fn mul(a: usize, b: usize) -> Result<usize, OpSizeError> {
    a.checked_mul(b).ok_or(OpSizeError)
}

#[cfg(test)]
pub(crate) mod testutil {
    /// Deterministic pseudo-random floats in [-1, 1).
    pub(crate) fn rand_vec(n: usize, seed: u64) -> std::vec::Vec<f32> {
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(1);
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                ((s >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
            })
            .collect()
    }

    pub(crate) fn assert_close(a: &[f32], b: &[f32], tol: f32) {
        assert_eq!(a.len(), b.len());
        for (i, (x, y)) in a.iter().zip(b).enumerate() {
            assert!((x - y).abs() <= tol * (1.0 + y.abs()), "at {i}: {x} vs {y}");
        }
    }
}
