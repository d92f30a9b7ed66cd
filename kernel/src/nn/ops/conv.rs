//! 1-D convolution and transposed convolution, channels-first `[c, l]` per sample.
//!
//! A convolution is a GEMM over `p = (input channel, tap)`. The input is first copied into a
//! zero-padded row per channel, so nothing below tests an edge. For a block of output
//! positions, every block of [`CO_BLOCK`] output channels accumulates `positions × CO_BLOCK`
//! sums in registers, walking the kernel (packed `[cout/CO_BLOCK][cin·k][CO_BLOCK]`)
//! contiguously. With stride 1 and dilation 1 (all but a U-Net's down-sampling convolutions)
//! the inputs of `p` for the block are a window of the padded row and are read in place;
//! otherwise they are first gathered into a small tile (`cin·k × T_BLOCK`, never a full im2col
//! matrix). Block sizes, measured (`conv1d_throughput`, on the shipped denoisers' shapes):
//! the SSE2 baseline runs 3 positions × 8 channels (4 × 8 vectorizes across positions, 3 × 16
//! spills); the AVX2 copy ([`super::cpu`]) runs 4 × 16 where 4 divides the output length
//! (the screwdriver's 16/8/4), 3 × 16 otherwise, at 25–32 GMAC/s on one core of this
//! project's EPYC VM (the gathered tile and 3 × 16 everywhere ran 12–20; 6 × 16 spills).
//! The blocking never changes a sum's order, so it never changes a result.

use super::{OpSizeError, ensure, mul};
use crate::nn::format::ConvGeom;

/// Output channels computed together (the packing width of conv kernels).
pub const CO_BLOCK: usize = 8;
/// Output positions computed together.
pub const T_BLOCK: usize = 3;

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

/// Scratch floats [`conv1d`] needs: the padded input rows and one input tile.
pub fn conv1d_temp_len(g: &ConvGeom) -> Result<usize, OpSizeError> {
    let tile = mul(mul(g.cin as usize, g.k as usize)?, T_BLOCK)?;
    mul(g.cin as usize, conv_row_len(g)?)?
        .checked_add(tile)
        .ok_or(OpSizeError)
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

/// Where a micro-kernel reads its inputs from.
#[derive(Clone, Copy)]
enum Inputs<'a> {
    /// A gathered tile, `[cin·k][TB]`: `tile[p·TB + j]` is the input that `p` multiplies for
    /// position `t0 + j`.
    Tile(&'a [f32]),
    /// The zero-padded rows themselves (stride 1, dilation 1): for `p = (ci, tap)` the `TB`
    /// inputs are `xp[ci][t0 + tap ..][..TB]`, a window of the row, so nothing is gathered.
    Rows {
        /// The padded rows, `[cin][lp]`.
        xp: &'a [f32],
        /// Length of one padded row.
        lp: usize,
        /// Taps per input channel.
        k: usize,
    },
}

/// `acc[i][j][c] += a[j] · w_i[c]` for the `CB` channel blocks (`w1` unread when `CB = 1`).
#[inline(always)]
fn mac<const TB: usize, const CB: usize>(
    acc: &mut [[[f32; CO_BLOCK]; TB]; CB],
    a: &[f32],
    wv0: &[f32],
    wv1: &[f32],
) {
    let (Ok(a), Ok(wv0), Ok(wv1)) = (
        <&[f32; TB]>::try_from(a),
        <&[f32; CO_BLOCK]>::try_from(wv0),
        <&[f32; CO_BLOCK]>::try_from(wv1),
    ) else {
        return;
    };
    for j in 0..TB {
        for c in 0..CO_BLOCK {
            acc[0][j][c] += a[j] * wv0[c];
        }
    }
    if CB == 2 {
        for j in 0..TB {
            for c in 0..CO_BLOCK {
                acc[CB - 1][j][c] += a[j] * wv1[c];
            }
        }
    }
}

/// `TB` output positions × `CB`·[`CO_BLOCK`] output channels starting at channel block `cb0`:
/// a GEMM micro-kernel over `p = (ci, tap)`, reading the `TB` inputs of each `p` from
/// `inputs`; `w` is the packed kernel, `[cout_padded / CO_BLOCK][cin·k][CO_BLOCK]`, of `p`
/// rows. Every sum starts at the bias and adds `p` in order, whatever `TB`, `CB` and the input
/// source are, so neither the blocking nor the source ever changes a result.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn tile_block<const TB: usize, const CB: usize>(
    inputs: Inputs<'_>,
    p: usize,
    w: &[f32],
    b: &[f32],
    y: &mut [f32],
    cout: usize,
    lout: usize,
    t0: usize,
    cb0: usize,
) {
    let mut acc = [[[0.0f32; CO_BLOCK]; TB]; CB];
    for (i, blk) in acc.iter_mut().enumerate() {
        let co = (cb0 + i) * CO_BLOCK;
        for row in blk.iter_mut() {
            row.copy_from_slice(&b[co..co + CO_BLOCK]);
        }
    }
    let w0 = &w[cb0 * p * CO_BLOCK..(cb0 + 1) * p * CO_BLOCK];
    // The second block (CB = 2) walks beside the first; with CB = 1 it is never read.
    let w1 = if CB == 2 {
        &w[(cb0 + 1) * p * CO_BLOCK..(cb0 + 2) * p * CO_BLOCK]
    } else {
        w0
    };
    match inputs {
        Inputs::Tile(tile) => {
            for ((a, wv0), wv1) in tile
                .chunks_exact(TB)
                .zip(w0.chunks_exact(CO_BLOCK))
                .zip(w1.chunks_exact(CO_BLOCK))
            {
                mac::<TB, CB>(&mut acc, a, wv0, wv1);
            }
        }
        Inputs::Rows { xp, lp, k } => {
            let per_channel = k * CO_BLOCK;
            for ((row, w0c), w1c) in xp
                .chunks_exact(lp)
                .zip(w0.chunks_exact(per_channel))
                .zip(w1.chunks_exact(per_channel))
            {
                let Some(window) = row.get(t0..t0 + k + TB - 1) else {
                    continue;
                };
                for ((a, wv0), wv1) in window
                    .windows(TB)
                    .zip(w0c.chunks_exact(CO_BLOCK))
                    .zip(w1c.chunks_exact(CO_BLOCK))
                {
                    mac::<TB, CB>(&mut acc, a, wv0, wv1);
                }
            }
        }
    }
    for (i, blk) in acc.iter().enumerate() {
        let co0 = (cb0 + i) * CO_BLOCK;
        for c in 0..CO_BLOCK.min(cout.saturating_sub(co0)) {
            let out = &mut y[(co0 + c) * lout + t0..(co0 + c) * lout + t0 + TB];
            for (j, o) in out.iter_mut().enumerate() {
                *o = blk[j][c];
            }
        }
    }
}

/// Every channel block for `TB` positions, `CB` blocks at a time (the rest one at a time).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn tile_blocks<const TB: usize, const CB: usize>(
    inputs: Inputs<'_>,
    p: usize,
    w: &[f32],
    b: &[f32],
    y: &mut [f32],
    cout: usize,
    lout: usize,
    t0: usize,
) {
    let blocks = cout.div_ceil(CO_BLOCK);
    let mut cb = 0;
    while cb + CB <= blocks {
        tile_block::<TB, CB>(inputs, p, w, b, y, cout, lout, t0, cb);
        cb += CB;
    }
    while cb < blocks {
        tile_block::<TB, 1>(inputs, p, w, b, y, cout, lout, t0, cb);
        cb += 1;
    }
}

super::cpu::wide! {
    /// One sample of a 1-D convolution (groups 1), kernel packed by [`pack_conv_kernel`].
    /// `temp` holds at least [`conv1d_temp_len`].
    pub fn conv1d(
        g: &ConvGeom,
        x: &[f32],
        y: &mut [f32],
        w: &[f32],
        b: &[f32],
        temp: &mut [f32],
    ) -> Result<(), OpSizeError> = conv1d_body::<1> | conv1d_body::<2>;
}

/// [`conv1d`] with `CB` channel blocks per micro-kernel: 1 for SSE2's 16 registers (2 spill),
/// 2 for AVX2's, where one block fills one register and 3 × 1 leaves the adds waiting.
#[inline(always)]
fn conv1d_body<const CB: usize>(
    g: &ConvGeom,
    x: &[f32],
    y: &mut [f32],
    w: &[f32],
    b: &[f32],
    temp: &mut [f32],
) -> Result<(), OpSizeError> {
    check_common(g, x, y, w, b)?;
    let [cin, cout, _, lin, lout, k, s, d, pad] = geom(g);
    let lp = conv_row_len(g)?;
    let (xp, rest) = temp
        .split_at_mut_checked(mul(cin, lp)?)
        .ok_or(OpSizeError)?;
    let tile = rest
        .get_mut(..mul(mul(cin, k)?, T_BLOCK)?)
        .ok_or(OpSizeError)?;
    xp.fill(0.0);
    for ci in 0..cin {
        xp[ci * lp + pad..ci * lp + pad + lin].copy_from_slice(&x[ci * lin..(ci + 1) * lin]);
    }
    let p = cin * k;
    // Stride 1 and dilation 1 (most of a U-Net's convolutions): the padded rows are read in
    // place. Otherwise each block's inputs are gathered into the tile first.
    let direct = s == 1 && d == 1;
    // With AVX2's registers (CB = 2), 4 positions × 16 channels when they tile the output
    // exactly (the screwdriver's 16/8/4), 3 × 16 otherwise.
    let block = if direct && CB == 2 && lout.is_multiple_of(4) {
        4
    } else {
        T_BLOCK
    };
    let mut t0 = 0;
    while t0 < lout {
        let tb = block.min(lout - t0);
        let inputs = if direct {
            Inputs::Rows { xp, lp, k }
        } else {
            // tile[(ci·k + tap)·tb + j] = xp[ci][(t0 + j)·s + tap·d].
            let tile = &mut tile[..p * tb];
            for (ci, row) in xp.chunks_exact(lp).enumerate() {
                for kk in 0..k {
                    let dst = &mut tile[(ci * k + kk) * tb..(ci * k + kk + 1) * tb];
                    for (j, v) in dst.iter_mut().enumerate() {
                        *v = row[(t0 + j) * s + kk * d];
                    }
                }
            }
            Inputs::Tile(tile)
        };
        match tb {
            4 => tile_blocks::<4, CB>(inputs, p, w, b, y, cout, lout, t0),
            3 => tile_blocks::<3, CB>(inputs, p, w, b, y, cout, lout, t0),
            2 => tile_blocks::<2, CB>(inputs, p, w, b, y, cout, lout, t0),
            _ => tile_blocks::<1, CB>(inputs, p, w, b, y, cout, lout, t0),
        }
        t0 += tb;
    }
    Ok(())
}

super::cpu::wide! {
    /// One sample of a 1-D transposed convolution (groups 1, no output padding beyond `lout`).
    /// `temp` holds at least [`conv_transpose1d_temp_len`].
    pub fn conv_transpose1d(
        g: &ConvGeom,
        x: &[f32],
        y: &mut [f32],
        w: &[f32],
        b: &[f32],
        temp: &mut [f32],
    ) -> Result<(), OpSizeError> = conv_transpose1d_body;
}

#[inline(always)]
fn conv_transpose1d_body(
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

/// Pack an ONNX Conv kernel `[cout][cin][k]` into channel blocks
/// `[cout_padded / CO_BLOCK][cin][k][CO_BLOCK]` (zeros for the padding channels).
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
                let (blk, c) = (co / CO_BLOCK, co % CO_BLOCK);
                out[((blk * cin + ci) * k + kk) * CO_BLOCK + c] = w[(co * cin + ci) * k + kk];
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

    /// The geometry of a test case (`cout_padded` from [`padded_channels`]).
    #[allow(clippy::too_many_arguments)]
    fn case_geom(
        cin: usize,
        cout: usize,
        lin: usize,
        lout: usize,
        k: usize,
        s: usize,
        d: usize,
        pb: usize,
    ) -> ConvGeom {
        ConvGeom {
            cin: cin as u32,
            cout: cout as u32,
            cout_padded: padded_channels(cout) as u32,
            lin: lin as u32,
            lout: lout as u32,
            k: k as u32,
            stride: s as u32,
            dilation: d as u32,
            pad_begin: pb as u32,
        }
    }

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
            (20, 24, 6, 3, 1, 1, 1, 1),
            (48, 48, 12, 3, 1, 1, 1, 1),
        ];
        for (seed, &(cin, cout, lin, k, s, d, pb, pe)) in cases.iter().enumerate() {
            let x = rand_vec(cin * lin, seed as u64);
            let w = rand_vec(cout * cin * k, 100 + seed as u64);
            let b = rand_vec(cout, 200 + seed as u64);
            let (want, lout) = naive_conv(&x, &w, &b, cin, cout, lin, k, s, d, pb, pe);
            let coutp = padded_channels(cout);
            let g = case_geom(cin, cout, lin, lout, k, s, d, pb);
            let mut wp = vec![0.0; cin * k * coutp];
            pack_conv_kernel(&w, cout, cin, k, coutp, &mut wp).unwrap();
            let mut bp = b.clone();
            bp.resize(coutp, 0.0);
            let mut temp = vec![f32::NAN; conv1d_temp_len(&g).unwrap()];
            let mut y = vec![0.0; cout * lout];
            conv1d(&g, &x, &mut y, &wp, &bp, &mut temp).unwrap();
            // Not merely close: every sum is the bias plus the products in `(ci, tap)` order,
            // as the naive loop adds them (a padding product adds ±0), whatever the blocking
            // and input source, so plans stay the same when either changes.
            assert_eq!(y, want, "case {seed}");
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
            let g = case_geom(cin, cout, lin, lout, k, s, d, pb);
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

#[cfg(test)]
mod throughput {
    use super::*;
    use crate::nn::ops::testutil::rand_vec;
    use std::vec;

    /// `cargo test -p dips-kernel --release -- --ignored --nocapture conv1d_throughput`
    #[test]
    #[ignore = "timing, run by hand"]
    fn conv1d_throughput() {
        // The shipped denoisers' shapes (widths 48/64/96, k = 3): the screwdriver's time
        // axis is 16/8/4 long, the card's 12/6/3; up stages read the skip beside their input.
        for &(cin, cout, lin, s) in &[
            (48, 48, 16, 1),
            (96, 48, 16, 1),
            (64, 64, 8, 1),
            (128, 64, 8, 1),
            (96, 96, 4, 1),
            (192, 96, 4, 1),
            (48, 48, 16, 2),
            (48, 48, 12, 1),
            (64, 64, 6, 1),
            (96, 96, 3, 1),
        ] {
            let k = 3;
            let lout = (lin + 2 - 3) / s + 1;
            let coutp = padded_channels(cout);
            let g = ConvGeom {
                cin: cin as u32,
                cout: cout as u32,
                cout_padded: coutp as u32,
                lin: lin as u32,
                lout: lout as u32,
                k: 3,
                stride: s as u32,
                dilation: 1,
                pad_begin: 1,
            };
            let x = rand_vec(cin * lin, 1);
            let w = rand_vec(cin * k * coutp, 2);
            let b = rand_vec(coutp, 3);
            let mut y = vec![0.0; cout * lout];
            let mut temp = vec![0.0; conv1d_temp_len(&g).unwrap()];
            let reps = 20000;
            let mut best = f64::MAX;
            for _ in 0..5 {
                let t = std::time::Instant::now();
                for _ in 0..reps {
                    conv1d(&g, &x, &mut y, &w, &b, &mut temp).unwrap();
                }
                best = best.min(t.elapsed().as_secs_f64());
            }
            let macs = (cin * k * cout * lout * reps) as f64;
            std::println!(
                "cin {cin} cout {cout} lout {lout} s {s}: {:.2} GMAC/s",
                macs / best / 1e9
            );
        }
    }
}
