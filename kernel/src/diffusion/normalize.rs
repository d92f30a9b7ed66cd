//! Column normalization of the model contract: `normalized = (raw − mean) / std`.

use crate::engine::Normalization;

/// Whether `norm` has `dim` finite means and finite positive stds.
pub fn is_valid(norm: &Normalization<'_>, dim: usize) -> bool {
    norm.mean.len() == dim
        && norm.std.len() == dim
        && norm.mean.iter().all(|m| m.is_finite())
        && norm.std.iter().all(|s| s.is_finite() && *s > 0.0)
}

/// Normalize rows of `D` columns in place (`data.len()` a multiple of `D`; a partial last row
/// is normalized as far as it goes).
pub fn normalize_in_place(norm: &Normalization<'_>, data: &mut [f32]) {
    let dim = norm.mean.len().min(norm.std.len());
    if dim == 0 {
        return;
    }
    for row in data.chunks_mut(dim) {
        for ((v, m), s) in row.iter_mut().zip(norm.mean).zip(norm.std) {
            *v = (*v - m) / s;
        }
    }
}

/// De-normalize rows of `D` columns in place: `raw = normalized · std + mean`.
pub fn denormalize_in_place(norm: &Normalization<'_>, data: &mut [f32]) {
    let dim = norm.mean.len().min(norm.std.len());
    if dim == 0 {
        return;
    }
    for row in data.chunks_mut(dim) {
        for ((v, m), s) in row.iter_mut().zip(norm.mean).zip(norm.std) {
            *v = *v * s + m;
        }
    }
}
