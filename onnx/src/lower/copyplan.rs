//! Strided-copy plans for layout ops (Slice, Transpose, Pad, Concat), shared by constant
//! folding (any rank) and kernel emission (padded to the kernel's rank).

use super::tensors::Const;

/// Copy `dims` elements: source `x_off + Σ iₖ·xsₖ`, destination `y_off + Σ iₖ·ysₖ`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CopyPlan {
    /// Index space.
    pub dims: Vec<usize>,
    /// Source start.
    pub x_off: isize,
    /// Source strides.
    pub xs: Vec<isize>,
    /// Destination start.
    pub y_off: usize,
    /// Destination strides.
    pub ys: Vec<usize>,
}

/// Row-major strides of `dims`.
pub fn strides(dims: &[usize]) -> Vec<usize> {
    let mut s = vec![1; dims.len()];
    for i in (0..dims.len().saturating_sub(1)).rev() {
        s[i] = s[i + 1] * dims[i + 1];
    }
    s
}

/// ONNX Slice on `dims`: returns the output dims and the plan (contiguous destination).
/// `starts/ends/steps` are per axis in `axes` (already normalized to non-negative axes).
pub fn slice_plan(
    dims: &[usize],
    axes: &[usize],
    starts: &[i64],
    ends: &[i64],
    steps: &[i64],
) -> Option<(Vec<usize>, CopyPlan)> {
    let st = strides(dims);
    let mut out = dims.to_vec();
    let mut x_off = 0isize;
    let mut xs: Vec<isize> = st.iter().map(|v| *v as isize).collect();
    for (i, &ax) in axes.iter().enumerate() {
        let d = *dims.get(ax)? as i64;
        let step = *steps.get(i)?;
        if step == 0 {
            return None;
        }
        let norm = |v: i64| if v < 0 { v + d } else { v };
        let (s, e) = (norm(*starts.get(i)?), norm(*ends.get(i)?));
        let (s, e) = if step > 0 {
            (s.clamp(0, d), e.clamp(0, d))
        } else {
            (s.clamp(0, d - 1), e.clamp(-1, d - 1))
        };
        let n = if step > 0 {
            (e - s + step - 1).max(0) / step
        } else {
            (s - e - step - 1).max(0) / -step
        };
        out[ax] = n as usize;
        x_off += s as isize * st[ax] as isize;
        xs[ax] = step as isize * st[ax] as isize;
    }
    let ys = strides(&out);
    Some((
        out.clone(),
        CopyPlan {
            dims: out,
            x_off,
            xs,
            y_off: 0,
            ys,
        },
    ))
}

/// ONNX Transpose: output dims and plan.
pub fn transpose_plan(dims: &[usize], perm: &[usize]) -> Option<(Vec<usize>, CopyPlan)> {
    let st = strides(dims);
    let out: Vec<usize> = perm
        .iter()
        .map(|p| dims.get(*p).copied())
        .collect::<Option<_>>()?;
    let xs = perm.iter().map(|p| st[*p] as isize).collect();
    let ys = strides(&out);
    Some((
        out.clone(),
        CopyPlan {
            dims: out,
            x_off: 0,
            xs,
            y_off: 0,
            ys,
        },
    ))
}

/// ONNX constant Pad: output dims and the plan that copies the kept input into the output
/// (the rest of the output is the pad value). `pads` is `[begin..., end...]`, may be negative.
pub fn pad_plan(dims: &[usize], pads: &[i64]) -> Option<(Vec<usize>, CopyPlan)> {
    let r = dims.len();
    if pads.len() != 2 * r {
        return None;
    }
    let out: Vec<usize> = (0..r)
        .map(|i| usize::try_from(dims[i] as i64 + pads[i] + pads[r + i]).ok())
        .collect::<Option<_>>()?;
    let (sx, sy) = (strides(dims), strides(&out));
    let mut x_off = 0isize;
    let mut y_off = 0usize;
    let mut cnt = vec![0; r];
    for i in 0..r {
        let src0 = (-pads[i]).max(0) as usize;
        let dst0 = pads[i].max(0) as usize;
        cnt[i] = dims[i]
            .saturating_sub(src0)
            .min(out[i].saturating_sub(dst0));
        x_off += (src0 * sx[i]) as isize;
        y_off += dst0 * sy[i];
    }
    Some((
        out,
        CopyPlan {
            dims: cnt,
            x_off,
            xs: sx.iter().map(|v| *v as isize).collect(),
            y_off,
            ys: sy,
        },
    ))
}

/// Run a plan on constant data.
pub fn apply(plan: &CopyPlan, x: &[f64], y: &mut [f64]) -> Option<()> {
    let n: usize = plan.dims.iter().product();
    if n == 0 {
        return Some(());
    }
    let r = plan.dims.len();
    let mut idx = vec![0usize; r];
    for _ in 0..n {
        let xo = plan.x_off
            + idx
                .iter()
                .zip(&plan.xs)
                .map(|(i, s)| *i as isize * s)
                .sum::<isize>();
        let yo = plan.y_off + idx.iter().zip(&plan.ys).map(|(i, s)| i * s).sum::<usize>();
        *y.get_mut(yo)? = *x.get(usize::try_from(xo).ok()?)?;
        for k in (0..r).rev() {
            idx[k] += 1;
            if idx[k] < plan.dims[k] {
                break;
            }
            idx[k] = 0;
        }
    }
    Some(())
}

/// A constant produced by a plan into a fresh tensor of `out` dims filled with `fill`.
pub fn apply_const(plan: &CopyPlan, x: &Const, out: Vec<usize>, fill: f64) -> Option<Const> {
    let mut data = vec![fill; out.iter().product()];
    apply(plan, &x.data, &mut data)?;
    Some(Const {
        dims: out,
        data,
        float: x.float,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(dims: &[usize], plan: &CopyPlan, out: &[usize], fill: f64) -> Vec<f64> {
        let x = Const::float(
            dims.to_vec(),
            (0..dims.iter().product::<usize>())
                .map(|v| v as f64)
                .collect(),
        );
        apply_const(plan, &x, out.to_vec(), fill).unwrap().data
    }

    #[test]
    fn slice_with_negative_step_and_clamped_ends() {
        // x = [[0,1,2,3,4],[5,6,7,8,9]]; x[:, ::-2] = [[4,2,0],[9,7,5]]
        let (out, plan) = slice_plan(&[2, 5], &[1], &[-1], &[i64::MIN + 1], &[-2]).unwrap();
        assert_eq!(out, vec![2, 3]);
        assert_eq!(
            run(&[2, 5], &plan, &out, 0.0),
            vec![4.0, 2.0, 0.0, 9.0, 7.0, 5.0]
        );
        // x[1:, 1:100] = [[6,7,8,9]]
        let (out, plan) = slice_plan(&[2, 5], &[0, 1], &[1, 1], &[2, 100], &[1, 1]).unwrap();
        assert_eq!(run(&[2, 5], &plan, &out, 0.0), vec![6.0, 7.0, 8.0, 9.0]);
        assert!(slice_plan(&[2, 5], &[1], &[0], &[5], &[0]).is_none());
    }

    #[test]
    fn pad_with_positive_and_negative_amounts() {
        // [2,3] padded by (0,1) rows and cropped by 1 at the front of columns, 2 at the end added.
        let (out, plan) = pad_plan(&[2, 3], &[0, -1, 1, 2]).unwrap();
        assert_eq!(out, vec![3, 4]);
        let y = run(&[2, 3], &plan, &out, -1.0);
        assert_eq!(
            y,
            vec![
                1.0, 2.0, -1.0, -1.0, 4.0, 5.0, -1.0, -1.0, -1.0, -1.0, -1.0, -1.0
            ]
        );
        assert!(pad_plan(&[2, 3], &[0, -4, 0, 0]).is_none());
    }

    #[test]
    fn transpose_plan_permutes() {
        let (out, plan) = transpose_plan(&[2, 3], &[1, 0]).unwrap();
        assert_eq!(out, vec![3, 2]);
        assert_eq!(
            run(&[2, 3], &plan, &out, 0.0),
            vec![0.0, 3.0, 1.0, 4.0, 2.0, 5.0]
        );
    }
}
