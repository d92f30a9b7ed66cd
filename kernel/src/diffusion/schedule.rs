//! The cosine β schedule (Nichol & Dhariwal), as the DIPS code builds it.
//!
//! `f(i) = cos²(((i/N + s)/(1 + s))·π/2)` for `i = 0..=N`, `β_i = 1 − f(i+1)/f(i)` clipped to
//! `[0, 0.999]`, with `s = 0.008`. The βs are computed in `f64` and stored as `f32`, and
//! `ᾱ_t = Π_{i≤t}(1 − β_i)` is accumulated in `f32`, as the reference (PyTorch float32
//! buffers) does.

/// The offset `s` of the cosine schedule.
pub const COSINE_S: f64 = 0.008;
/// Upper clip of every β.
pub const MAX_BETA: f32 = 0.999;

/// `β_i` of the cosine schedule with `steps` steps (`i < steps`).
pub fn cosine_beta(i: usize, steps: usize) -> f32 {
    let n = steps as f64;
    let f = |k: f64| {
        let c = libm::cos(((k / n + COSINE_S) / (1.0 + COSINE_S)) * core::f64::consts::FRAC_PI_2);
        c * c
    };
    let beta = 1.0 - f(i as f64 + 1.0) / f(i as f64);
    (beta.clamp(0.0, f64::from(MAX_BETA))) as f32
}

/// Fill `alpha_bar[..steps]` with the cumulative products `ᾱ_t` of the cosine schedule.
///
/// Returns `false` (and writes nothing) when `alpha_bar` is shorter than `steps`.
pub fn fill_alpha_bar(steps: usize, alpha_bar: &mut [f32]) -> bool {
    let Some(out) = alpha_bar.get_mut(..steps) else {
        return false;
    };
    let mut acc = 1.0f32;
    for (i, slot) in out.iter_mut().enumerate() {
        acc *= 1.0 - cosine_beta(i, steps);
        *slot = acc;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn betas_are_in_range_and_last_is_clipped() {
        let n = 256;
        for i in 0..n {
            let b = cosine_beta(i, n);
            assert!(b > 0.0 && b <= MAX_BETA, "beta {i} = {b}");
        }
        assert_eq!(cosine_beta(n - 1, n), MAX_BETA);
        // Reference values (float64 formula, cast to float32).
        assert!((cosine_beta(0, n) - 1.888_266_7e-4).abs() < 1e-10);
        assert!((cosine_beta(128, n) - 0.012_325_939).abs() < 1e-9);
    }

    #[test]
    fn alpha_bar_decreases_to_near_zero() {
        let mut ab = [0.0f32; 256];
        assert!(fill_alpha_bar(256, &mut ab));
        for w in ab.windows(2) {
            assert!(w[1] < w[0]);
        }
        assert!(ab[0] > 0.9998 && ab[255] < 1e-6 && ab[255] > 0.0);
        assert!(!fill_alpha_bar(257, &mut ab));
    }
}
