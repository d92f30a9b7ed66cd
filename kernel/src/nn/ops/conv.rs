//! 1-D convolution and transposed convolution, channels-first `[c, l]` per sample.
//!
//! The kernel is packed `[cin][k][cout_padded]` so the innermost loop runs over a block of
//! [`CO_BLOCK`] contiguous output channels for [`T_BLOCK`] output positions at once: a
//! register-blocked outer product that the compiler turns into vector multiply-adds, with no
//! im2col buffer. The input is first copied into a zero-padded row per channel so the hot
//! loop has no edge tests.

use super::{OpSizeError, ensure, mul};
use crate::nn::format::ConvGeom;

/// Output channels computed together (the packing width of conv kernels).
pub const CO_BLOCK: usize = 8;
/// Output positions computed together.
pub const T_BLOCK: usize = 4;

fn geom(g: &ConvGeom) -> [usize; 9] {
    [
        g.cin as usize,
        g.cout as usize,
        g.cout_padded as usize,
        g.lin as usize,
        g.lout as usize,
        g.k as usize,
        g.stride as usize,
        g.dilation as usize,
        g.pad_begin as usize,
    ]
}

/// Length of the padded input row of [`conv1d`].
fn conv_row_len(g: &ConvGeom) -> Result<usize, OpSizeError> {
    let [_, _, _, lin, lout, k, s, d, pad] = geom(g);
    let blocks = lout.div_ceil(T_BLOCK);
    let reach = mul(mul(blocks, T_BLOCK)?.saturating_sub(1), s)?
        .checked_add(mul(k.saturating_sub(1), d)?)
        .and_then(|v| v.checked_add(1))
        .ok_or(OpSizeError)?;
    Ok(reach.max(pad.checked_add(lin).ok_or(OpSizeError)?))
}

/// Scratch floats [`conv1d`] needs.
pub fn conv1d_temp_len(g: &ConvGeom) -> Result<usize, OpSizeError> {
    mul(g.cin as usize, conv_row_len(g)?)
}

/// Length of the full (uncropped) output of [`conv_transpose1d`].
fn convt_full_len(g: &ConvGeom) -> Result<usize, OpSizeError> {
    let [_, _, _, lin, lout, k, s, d, pad] = geom(g);
    let full = mul(lin.saturating_sub(1), s)?
        .checked_add(mul(k.saturating_sub(1), d)?)
        .and_then(|v| v.checked_add(1))
        .ok_or(OpSizeError)?;
    Ok(full.max(pad.checked_add(lout).ok_or(OpSizeError)?))
}

/// Scratch floats [`conv_transpose1d`] needs.
pub fn conv_transpose1d_temp_len(g: &ConvGeom) -> Result<usize, OpSizeError> {
    mul(convt_full_len(g)?, g.cout_padded as usize)
}

fn check_common(
    g: &ConvGeom,
    x: &[f32],
    y: &[f32],
    w: &[f32],
    b: &[f32],
) -> Result<(), OpSizeError> {
    let [cin, cout, coutp, lin, lout, k, s, d, _] = geom(g);
    ensure(cin > 0 && cout > 0 && k > 0 && s > 0 && d > 0 && lout > 0)?;
    ensure(coutp == padded_channels(cout))?;
    ensure(x.len() == mul(cin, lin)?)?;
    ensure(y.len() == mul(cout, lout)?)?;
    ensure(w.len() == mul(mul(cin, k)?, coutp)?)?;
    ensure(b.len() == coutp)
}

/// One sample of a 1-D convolution (groups 1). `temp` holds at least [`conv1d_temp_len`].
pub fn conv1d(
    g: &ConvGeom,
    x: &[f32],
    y: &mut [f32],
    w: &[f32],
    b: &[f32],
    temp: &mut [f32],
) -> Result<(), OpSizeError> {
    check_common(g, x, y, w, b)?;
    let [cin, cout, coutp, lin, lout, k, s, d, pad] = geom(g);
    let lp = conv_row_len(g)?;
    let xp = temp.get_mut(..mul(cin, lp)?).ok_or(OpSizeError)?;
    xp.fill(0.0);
    for ci in 0..cin {
        xp[ci * lp + pad..ci * lp + pad + lin].copy_from_slice(&x[ci * lin..(ci + 1) * lin]);
    }
    let xp = &*xp;
    let blocks = lout.div_ceil(T_BLOCK);
    // Positions read by one block of T_BLOCK outputs for one kernel tap.
    let span = (T_BLOCK - 1) * s + 1;
    for cb in 0..coutp / CO_BLOCK {
        let co0 = cb * CO_BLOCK;
        let mut bias = [0.0f32; CO_BLOCK];
        bias.copy_from_slice(&b[co0..co0 + CO_BLOCK]);
        for tb in 0..blocks {
            let t0 = tb * T_BLOCK;
            let mut acc = [bias; T_BLOCK];
            for ci in 0..cin {
                let row = &xp[ci * lp..(ci + 1) * lp];
                let wrow = &w[ci * k * coutp..(ci + 1) * k * coutp];
                for kk in 0..k {
                    let mut wv = [0.0f32; CO_BLOCK];
                    wv.copy_from_slice(&wrow[kk * coutp + co0..kk * coutp + co0 + CO_BLOCK]);
                    let base = t0 * s + kk * d;
                    let xs = &row[base..base + span];
                    if s == 1 {
                        let mut xv = [0.0f32; T_BLOCK];
                        xv.copy_from_slice(&xs[..T_BLOCK]);
                        for j in 0..T_BLOCK {
                            for c in 0..CO_BLOCK {
                                acc[j][c] += xv[j] * wv[c];
                            }
                        }
                    } else {
                        for (j, a) in acc.iter_mut().enumerate() {
                            let xv = xs[j * s];
                            for c in 0..CO_BLOCK {
                                a[c] += xv * wv[c];
                            }
                        }
                    }
                }
            }
            let tn = T_BLOCK.min(lout - t0);
            for c in 0..CO_BLOCK.min(cout - co0) {
                let out = &mut y[(co0 + c) * lout + t0..(co0 + c) * lout + t0 + tn];
                for (j, o) in out.iter_mut().enumerate() {
                    *o = acc[j][c];
                }
            }
        }
    }
    Ok(())
}

/// One sample of a 1-D transposed convolution (groups 1, no output padding beyond `lout`).
/// `temp` holds at least [`conv_transpose1d_temp_len`].
pub fn conv_transpose1d(
    g: &ConvGeom,
    x: &[f32],
    y: &mut [f32],
    w: &[f32],
    b: &[f32],
    temp: &mut [f32],
) -> Result<(), OpSizeError> {
    check_common(g, x, y, w, b)?;
    let [cin, cout, coutp, lin, lout, k, s, d, pad] = geom(g);
    let full = convt_full_len(g)?;
    let acc = temp.get_mut(..mul(full, coutp)?).ok_or(OpSizeError)?;
    acc.fill(0.0);
    for ci in 0..cin {
        let xrow = &x[ci * lin..(ci + 1) * lin];
        let wrow = &w[ci * k * coutp..(ci + 1) * k * coutp];
        for (i, &xv) in xrow.iter().enumerate() {
            for kk in 0..k {
                let t = i * s + kk * d;
                let dst = &mut acc[t * coutp..(t + 1) * coutp];
                let src = &wrow[kk * coutp..(kk + 1) * coutp];
                for (o, wv) in dst.iter_mut().zip(src) {
                    *o += xv * wv;
                }
            }
        }
    }
    for co in 0..cout {
        let out = &mut y[co * lout..(co + 1) * lout];
        for (t, o) in out.iter_mut().enumerate() {
            *o = b[co] + acc[(t + pad) * coutp + co];
        }
    }
    Ok(())
}

/// Pack an ONNX Conv kernel `[cout][cin][k]` into `[cin][k][cout_padded]`.
pub fn pack_conv_kernel(
    w: &[f32],
    cout: usize,
    cin: usize,
    k: usize,
    cout_padded: usize,
    out: &mut [f32],
) -> Result<(), OpSizeError> {
    ensure(w.len() == mul(mul(cout, cin)?, k)? && out.len() == mul(mul(cin, k)?, cout_padded)?)?;
    ensure(cout_padded >= cout)?;
    out.fill(0.0);
    for co in 0..cout {
        for ci in 0..cin {
            for kk in 0..k {
                out[(ci * k + kk) * cout_padded + co] = w[(co * cin + ci) * k + kk];
            }
        }
    }
    Ok(())
}

/// Pack an ONNX ConvTranspose kernel `[cin][cout][k]` into `[cin][k][cout_padded]`.
pub fn pack_conv_transpose_kernel(
    w: &[f32],
    cin: usize,
    cout: usize,
    k: usize,
    cout_padded: usize,
    out: &mut [f32],
) -> Result<(), OpSizeError> {
    ensure(w.len() == mul(mul(cout, cin)?, k)? && out.len() == mul(mul(cin, k)?, cout_padded)?)?;
    ensure(cout_padded >= cout)?;
    out.fill(0.0);
    for ci in 0..cin {
        for co in 0..cout {
            for kk in 0..k {
                out[(ci * k + kk) * cout_padded + co] = w[(ci * cout + co) * k + kk];
            }
        }
    }
    Ok(())
}

/// The output channels rounded up to the packing width.
pub const fn padded_channels(cout: usize) -> usize {
    cout.div_ceil(CO_BLOCK) * CO_BLOCK
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::ops::testutil::{assert_close, rand_vec};
    use std::vec;
    use std::vec::Vec;

    #[allow(clippy::too_many_arguments)]
    fn naive_conv(
        x: &[f32],
        w: &[f32],
        b: &[f32],
        cin: usize,
        cout: usize,
        lin: usize,
        k: usize,
        s: usize,
        d: usize,
        pb: usize,
        pe: usize,
    ) -> (Vec<f32>, usize) {
        let lout = (lin + pb + pe - d * (k - 1) - 1) / s + 1;
        let mut y = vec![0.0; cout * lout];
        for co in 0..cout {
            for t in 0..lout {
                let mut acc = b[co];
                for ci in 0..cin {
                    for kk in 0..k {
                        let pos = (t * s + kk * d) as isize - pb as isize;
                        if pos >= 0 && (pos as usize) < lin {
                            acc += w[(co * cin + ci) * k + kk] * x[ci * lin + pos as usize];
                        }
                    }
                }
                y[co * lout + t] = acc;
            }
        }
        (y, lout)
    }

    #[allow(clippy::too_many_arguments)]
    fn naive_convt(
        x: &[f32],
        w: &[f32],
        b: &[f32],
        cin: usize,
        cout: usize,
        lin: usize,
        k: usize,
        s: usize,
        d: usize,
        pb: usize,
        pe: usize,
    ) -> (Vec<f32>, usize) {
        let lout = (lin - 1) * s + d * (k - 1) + 1 - pb - pe;
        let mut y = vec![0.0; cout * lout];
        for co in 0..cout {
            for t in 0..lout {
                y[co * lout + t] = b[co];
            }
        }
        for ci in 0..cin {
            for i in 0..lin {
                for co in 0..cout {
                    for kk in 0..k {
                        let t = (i * s + kk * d) as isize - pb as isize;
                        if t >= 0 && (t as usize) < lout {
                            y[co * lout + t as usize] +=
                                x[ci * lin + i] * w[(ci * cout + co) * k + kk];
                        }
                    }
                }
            }
        }
        (y, lout)
    }

    #[test]
    fn conv1d_matches_naive_over_geometries() {
        let cases = [
            (3, 5, 7, 3, 1, 1, 1, 1),
            (37, 16, 16, 3, 1, 1, 1, 1),
            (16, 16, 16, 3, 2, 1, 1, 1),
            (29, 16, 9, 3, 1, 1, 1, 4),
            (29, 16, 9, 1, 1, 1, 0, 3),
            (8, 37, 13, 1, 1, 1, 0, 0),
            (4, 9, 11, 5, 3, 2, 2, 1),
            (2, 3, 3, 3, 1, 1, 0, 0),
        ];
        for (seed, &(cin, cout, lin, k, s, d, pb, pe)) in cases.iter().enumerate() {
            let x = rand_vec(cin * lin, seed as u64);
            let w = rand_vec(cout * cin * k, 100 + seed as u64);
            let b = rand_vec(cout, 200 + seed as u64);
            let (want, lout) = naive_conv(&x, &w, &b, cin, cout, lin, k, s, d, pb, pe);
            let coutp = padded_channels(cout);
            let g = ConvGeom {
                cin: cin as u32,
                cout: cout as u32,
                cout_padded: coutp as u32,
                lin: lin as u32,
                lout: lout as u32,
                k: k as u32,
                stride: s as u32,
                dilation: d as u32,
                pad_begin: pb as u32,
            };
            let mut wp = vec![0.0; cin * k * coutp];
            pack_conv_kernel(&w, cout, cin, k, coutp, &mut wp).unwrap();
            let mut bp = b.clone();
            bp.resize(coutp, 0.0);
            let mut temp = vec![f32::NAN; conv1d_temp_len(&g).unwrap()];
            let mut y = vec![0.0; cout * lout];
            conv1d(&g, &x, &mut y, &wp, &bp, &mut temp).unwrap();
            assert_close(&y, &want, 1e-5);
        }
    }

    #[test]
    fn conv_transpose1d_matches_naive() {
        for (seed, &(cin, cout, lin, k, s, d, pb, pe)) in [
            (16, 16, 4, 4, 2, 1, 1, 1),
            (32, 8, 3, 4, 2, 1, 1, 1),
            (3, 5, 6, 3, 1, 2, 0, 1),
        ]
        .iter()
        .enumerate()
        {
            let x = rand_vec(cin * lin, seed as u64);
            let w = rand_vec(cout * cin * k, 10 + seed as u64);
            let b = rand_vec(cout, 20 + seed as u64);
            let (want, lout) = naive_convt(&x, &w, &b, cin, cout, lin, k, s, d, pb, pe);
            let coutp = padded_channels(cout);
            let g = ConvGeom {
                cin: cin as u32,
                cout: cout as u32,
                cout_padded: coutp as u32,
                lin: lin as u32,
                lout: lout as u32,
                k: k as u32,
                stride: s as u32,
                dilation: d as u32,
                pad_begin: pb as u32,
            };
            let mut wp = vec![0.0; cin * k * coutp];
            pack_conv_transpose_kernel(&w, cin, cout, k, coutp, &mut wp).unwrap();
            let mut bp = b.clone();
            bp.resize(coutp, 0.0);
            let mut temp = vec![0.0; conv_transpose1d_temp_len(&g).unwrap()];
            let mut y = vec![0.0; cout * lout];
            conv_transpose1d(&g, &x, &mut y, &wp, &bp, &mut temp).unwrap();
            assert_close(&y, &want, 1e-5);
        }
    }

    #[test]
    fn wrong_sizes_are_errors() {
        let g = ConvGeom {
            cin: 2,
            cout: 3,
            cout_padded: 8,
            lin: 4,
            lout: 4,
            k: 3,
            stride: 1,
            dilation: 1,
            pad_begin: 1,
        };
        let mut y = vec![0.0; 12];
        let mut temp = vec![0.0; 64];
        assert!(conv1d(&g, &[0.0; 7], &mut y, &[0.0; 48], &[0.0; 8], &mut temp).is_err());
        assert!(conv1d(&g, &[0.0; 8], &mut y, &[0.0; 47], &[0.0; 8], &mut temp).is_err());
        assert!(conv1d(&g, &[0.0; 8], &mut y, &[0.0; 48], &[0.0; 8], &mut [0.0; 3]).is_err());
        let huge = ConvGeom {
            lin: u32::MAX,
            lout: u32::MAX,
            ..g
        };
        assert!(conv1d(&huge, &[0.0; 8], &mut y, &[0.0; 48], &[0.0; 8], &mut temp).is_err());
    }
}
