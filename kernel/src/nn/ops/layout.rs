//! Layout ops: strided copies (Transpose, Slice, Concat parts, Pad interiors) and fills.

use super::{OpSizeError, ensure, mul};
use crate::nn::format::RANK;

/// Highest and lowest source offsets of a strided walk, or `None` when `dims` is empty.
fn source_range(
    dims: &[u32; RANK],
    off: usize,
    xs: &[i32; RANK],
) -> Result<Option<(usize, usize)>, OpSizeError> {
    let (mut lo, mut hi) = (off as i128, off as i128);
    for (d, s) in dims.iter().zip(xs) {
        if *d == 0 {
            return Ok(None);
        }
        let span = (*d as i128 - 1) * *s as i128;
        if span < 0 { lo += span } else { hi += span }
    }
    if lo < 0 || hi > usize::MAX as i128 {
        return Err(OpSizeError);
    }
    Ok(Some((lo as usize, hi as usize)))
}

/// One sample of `y[y_off + i·ys] = x[x_off + i·xs]` for every index `i` of `dims`.
pub fn strided_copy(
    x: &[f32],
    y: &mut [f32],
    dims: &[u32; RANK],
    x_off: usize,
    xs: &[i32; RANK],
    y_off: usize,
    ys: &[u32; RANK],
) -> Result<(), OpSizeError> {
    let Some((_, hi)) = source_range(dims, x_off, xs)? else {
        return Ok(());
    };
    ensure(hi < x.len())?;
    let ymax = super::elementwise::max_offset(dims, ys)?.ok_or(OpSizeError)?;
    ensure(y_off.checked_add(ymax).is_some_and(|m| m < y.len()))?;
    let [d0, d1, d2, d3] = dims.map(|d| d as usize);
    let [x0, x1, x2, x3] = xs.map(|s| s as isize);
    let [y0, y1, y2, y3] = ys.map(|s| s as usize);
    for i0 in 0..d0 {
        for i1 in 0..d1 {
            for i2 in 0..d2 {
                let xb = x_off as isize + i0 as isize * x0 + i1 as isize * x1 + i2 as isize * x2;
                let yb = y_off + i0 * y0 + i1 * y1 + i2 * y2;
                if x3 == 1 && y3 == 1 {
                    let xb = xb as usize;
                    y[yb..yb + d3].copy_from_slice(&x[xb..xb + d3]);
                } else {
                    for i3 in 0..d3 {
                        y[yb + i3 * y3] = x[(xb + i3 as isize * x3) as usize];
                    }
                }
            }
        }
    }
    Ok(())
}

/// Number of elements of `dims`.
pub fn volume(dims: &[u32; RANK]) -> Result<usize, OpSizeError> {
    dims.iter().try_fold(1usize, |acc, d| mul(acc, *d as usize))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    #[test]
    fn transpose_and_reversed_slice() {
        // [3,4] -> transpose [4,3]
        let x: Vec<f32> = (0..12).map(|v| v as f32).collect();
        let mut y = vec![0.0; 12];
        strided_copy(
            &x,
            &mut y,
            &[1, 1, 4, 3],
            0,
            &[0, 0, 1, 4],
            0,
            &[0, 0, 3, 1],
        )
        .unwrap();
        for r in 0..4 {
            for c in 0..3 {
                assert_eq!(y[r * 3 + c], x[c * 4 + r]);
            }
        }
        // reverse the last axis of row 1: x[1, 3..=0]
        let mut z = vec![0.0; 4];
        strided_copy(
            &x,
            &mut z,
            &[1, 1, 1, 4],
            7,
            &[0, 0, 0, -1],
            0,
            &[0, 0, 0, 1],
        )
        .unwrap();
        assert_eq!(z, vec![7.0, 6.0, 5.0, 4.0]);
        // out of range source or destination
        assert!(
            strided_copy(
                &x,
                &mut z,
                &[1, 1, 1, 4],
                9,
                &[0, 0, 0, 1],
                0,
                &[0, 0, 0, 1]
            )
            .is_err()
        );
        assert!(
            strided_copy(
                &x,
                &mut z,
                &[1, 1, 1, 4],
                3,
                &[0, 0, 0, -1],
                1,
                &[0, 0, 0, 1]
            )
            .is_err()
        );
        assert!(
            strided_copy(
                &x,
                &mut z,
                &[1, 1, 1, 4],
                2,
                &[0, 0, 0, -1],
                0,
                &[0, 0, 0, 1]
            )
            .is_err()
        );
    }
}
