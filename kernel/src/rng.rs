//! The kernel's seeded pseudo-random numbers.
//!
//! Xoshiro256++ (from `rand_xoshiro`) seeded through SplitMix64, with the few draws the
//! planner needs written on top using `libm` only, so the same seed gives the same numbers
//! bit for bit on the host and on the controller.

use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// A seeded generator. Cloning it forks an identical stream.
#[derive(Debug, Clone)]
pub struct KernelRng {
    inner: Xoshiro256PlusPlus,
    /// The second Box–Muller value, kept for the next normal draw.
    spare_normal: Option<f32>,
}

impl KernelRng {
    /// A generator whose whole stream is determined by `seed`.
    pub fn seed_from_u64(seed: u64) -> Self {
        Self {
            inner: Xoshiro256PlusPlus::seed_from_u64(seed),
            spare_normal: None,
        }
    }

    /// 64 uniformly random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.inner.next_u64()
    }

    /// Uniform in `[0, 1)` with 24 bits of resolution.
    pub fn uniform_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform in `[0, 1)` with 53 bits of resolution.
    pub fn uniform_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform integer in `[0, n)`; `n` must be positive (returns 0 for `n == 0`).
    pub fn below(&mut self, n: u32) -> u32 {
        if n == 0 {
            return 0;
        }
        // Lemire's multiply-shift; the bias is below 2^-32 and irrelevant here, and it keeps
        // the number of draws per call fixed, which keeps streams aligned across platforms.
        ((u64::from(self.next_u64() as u32) * u64::from(n)) >> 32) as u32
    }

    /// A standard normal draw (Box–Muller on `libm`).
    pub fn normal_f32(&mut self) -> f32 {
        if let Some(z) = self.spare_normal.take() {
            return z;
        }
        // u1 in (0, 1] so the logarithm is finite.
        let u1 = 1.0 - self.uniform_f64();
        let u2 = self.uniform_f64();
        let r = libm::sqrt(-2.0 * libm::log(u1));
        let (s, c) = libm::sincos(core::f64::consts::TAU * u2);
        self.spare_normal = Some((r * s) as f32);
        (r * c) as f32
    }

    /// Fill `out` with independent standard normal draws.
    pub fn fill_normal(&mut self, out: &mut [f32]) {
        for v in out {
            *v = self.normal_f32();
        }
    }

    /// Draw an index with probability proportional to `weights[i]` (inverse CDF).
    ///
    /// Negative and non-finite weights count as zero. Returns `None` when no weight is
    /// positive.
    pub fn weighted_index(&mut self, weights: &[f32]) -> Option<usize> {
        let total: f64 = weights
            .iter()
            .map(|&w| {
                if w.is_finite() && w > 0.0 {
                    f64::from(w)
                } else {
                    0.0
                }
            })
            .sum();
        if total <= 0.0 || !total.is_finite() {
            return None;
        }
        let target = self.uniform_f64() * total;
        let mut acc = 0.0f64;
        let mut last_positive = None;
        for (i, &w) in weights.iter().enumerate() {
            if w.is_finite() && w > 0.0 {
                acc += f64::from(w);
                last_positive = Some(i);
                if target < acc {
                    return Some(i);
                }
            }
        }
        // Rounding can leave `target` a hair above the sum: take the last positive weight.
        last_positive
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_stream() {
        let mut a = KernelRng::seed_from_u64(7);
        let mut b = KernelRng::seed_from_u64(7);
        for _ in 0..100 {
            assert_eq!(a.normal_f32().to_bits(), b.normal_f32().to_bits());
        }
        assert_ne!(
            KernelRng::seed_from_u64(7).next_u64(),
            KernelRng::seed_from_u64(8).next_u64()
        );
    }

    #[test]
    fn normal_moments() {
        let mut r = KernelRng::seed_from_u64(1);
        let n = 20_000;
        let (mut m, mut v) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let z = f64::from(r.normal_f32());
            m += z;
            v += z * z;
        }
        m /= n as f64;
        v = v / n as f64 - m * m;
        assert!(m.abs() < 0.03, "mean {m}");
        assert!((v - 1.0).abs() < 0.05, "variance {v}");
    }

    #[test]
    fn weighted_index_follows_weights() {
        let mut r = KernelRng::seed_from_u64(3);
        let w = [0.0, 1.0, 3.0, -2.0, f32::NAN];
        let mut counts = [0u32; 5];
        for _ in 0..8000 {
            counts[r.weighted_index(&w).unwrap_or(99)] += 1;
        }
        assert_eq!(counts[0] + counts[3] + counts[4], 0);
        let frac = f64::from(counts[2]) / 8000.0;
        assert!((frac - 0.75).abs() < 0.03, "{frac}");
        assert_eq!(r.weighted_index(&[0.0, -1.0]), None);
    }

    #[test]
    fn below_stays_in_range() {
        let mut r = KernelRng::seed_from_u64(5);
        for n in 1..50 {
            assert!(r.below(n) < n);
        }
        assert_eq!(r.below(0), 0);
    }
}
