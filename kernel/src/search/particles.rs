//! The particle arithmetic of Algorithm 1 (`propagate_variability`) as free functions over
//! slices, so each step is testable on its own.

use crate::rng::KernelRng;

/// `S'_j = discount · Ψ_j + S_parent_j` for every `j` (Algorithm 1, line 4), where
/// `discount = γ^d`. Entries with `valid[j] == false` (a non-finite segment) get score 0 so
/// they can never be drawn. `Ψ` is clamped to `[0, 1]`; a non-finite `Ψ` counts as 0.
/// Returns `Σ S'`.
pub fn accumulate_scores(
    parent: &[f32],
    psi: &[f32],
    valid: &[bool],
    discount: f32,
    out: &mut [f32],
) -> f32 {
    let mut total = 0.0f32;
    for (((o, &p), &s), &ok) in out.iter_mut().zip(psi).zip(parent).zip(valid) {
        let psi = if p.is_finite() {
            p.clamp(0.0, 1.0)
        } else {
            0.0
        };
        *o = if ok { discount * psi + s } else { 0.0 };
        total += *o;
    }
    total
}

/// Draw `out.len()` indices with replacement, index `j` with probability
/// `scores[j] / Σ scores` (Algorithm 1, lines 5–6). Returns `false` (and leaves `out`
/// unspecified) when no score is positive.
pub fn resample(scores: &[f32], rng: &mut KernelRng, out: &mut [u16]) -> bool {
    for o in out.iter_mut() {
        match rng.weighted_index(scores) {
            Some(i) => *o = i as u16,
            None => return false,
        }
    }
    true
}

/// The normalised weights `w_i = S_i / Σ S`, written to `out`; uniform when `Σ S` is not
/// positive (the root, whose scores are all zero).
pub fn normalized_weights(scores: &[f32], out: &mut [f32]) {
    let total: f32 = scores.iter().sum();
    let n = scores.len().min(out.len());
    if total > 0.0 && total.is_finite() {
        for (o, &s) in out.iter_mut().zip(scores) {
            *o = s / total;
        }
    } else if n > 0 {
        out[..n].fill(1.0 / n as f32);
    }
}

/// `Σ w_i · v_i`.
pub fn weighted_sum(weights: &[f32], values: impl IntoIterator<Item = f32>) -> f32 {
    weights.iter().zip(values).map(|(&w, v)| w * v).sum()
}

/// Index of the largest score (the first on ties); `None` when none is positive.
pub fn argmax_positive(scores: &[f32]) -> Option<usize> {
    let mut best: Option<(usize, f32)> = None;
    for (i, &s) in scores.iter().enumerate() {
        if s > 0.0 && best.is_none_or(|(_, b)| s > b) {
            best = Some((i, s));
        }
    }
    best.map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scores_accumulate_with_discount() {
        let mut out = [0.0; 4];
        let total = accumulate_scores(
            &[0.5, 0.25, 1.0, 0.1],
            &[0.2, 0.4, f32::NAN, 0.3],
            &[true, true, true, false],
            0.81,
            &mut out,
        );
        assert_eq!(out, [0.81 * 0.2 + 0.5, 0.81 * 0.4 + 0.25, 1.0, 0.0]);
        assert!((total - out.iter().sum::<f32>()).abs() < 1e-7);
    }

    #[test]
    fn weights_and_argmax() {
        let mut w = [0.0; 3];
        normalized_weights(&[1.0, 1.0, 2.0], &mut w);
        assert_eq!(w, [0.25, 0.25, 0.5]);
        normalized_weights(&[0.0, 0.0, 0.0], &mut w);
        assert_eq!(w, [1.0 / 3.0; 3]);
        assert_eq!(weighted_sum(&[0.25, 0.75], [4.0, 8.0]), 7.0);
        assert_eq!(argmax_positive(&[0.1, 0.3, 0.3]), Some(1));
        assert_eq!(argmax_positive(&[0.0, -1.0]), None);
    }

    #[test]
    fn resample_never_draws_zero_scores() {
        let mut rng = KernelRng::seed_from_u64(9);
        let mut idx = [0u16; 64];
        assert!(resample(&[0.0, 2.0, 0.0, 1.0], &mut rng, &mut idx));
        assert!(idx.iter().all(|&i| i == 1 || i == 3));
        assert!(!resample(&[0.0, 0.0], &mut rng, &mut idx));
    }
}
