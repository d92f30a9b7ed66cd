//! Constant folding: evaluate a node whose inputs are all constants.

use tract_onnx::pb;

use super::attrs::{Attrs, broadcast_dims, norm_axis};
use super::copyplan::{apply_const, pad_plan, slice_plan, strides, transpose_plan};
use super::tensors::{Const, decode_tensor};

/// Why a constant node could not be folded.
pub(super) type FoldResult = std::result::Result<Vec<Const>, String>;

fn unary(x: &Const, f: impl Fn(f64) -> f64) -> Const {
    let data = x.data.iter().map(|v| {
        let r = f(*v);
        if x.float { r as f32 as f64 } else { r }
    });
    Const {
        dims: x.dims.clone(),
        data: data.collect(),
        float: x.float,
    }
}

/// Broadcast `a ⊙ b` numpy-style.
pub(super) fn binary(
    a: &Const,
    b: &Const,
    float: bool,
    f: impl Fn(f64, f64) -> f64,
) -> std::result::Result<Const, String> {
    let out = broadcast_dims(&a.dims, &b.dims).ok_or("shapes do not broadcast")?;
    let r = out.len();
    let idx_of = |dims: &[usize], flat: usize| -> usize {
        let off = r - dims.len();
        let st = strides(dims);
        let ost = strides(&out);
        let mut rem = flat;
        let mut ix = 0;
        for k in 0..r {
            let i = rem / ost[k];
            rem %= ost[k];
            if k >= off && dims[k - off] != 1 {
                ix += i * st[k - off];
            }
        }
        ix
    };
    let n: usize = out.iter().product();
    let data = (0..n)
        .map(|i| {
            let v = f(a.data[idx_of(&a.dims, i)], b.data[idx_of(&b.dims, i)]);
            if float { v as f32 as f64 } else { v }
        })
        .collect();
    Ok(Const {
        dims: out,
        data,
        float,
    })
}

fn input(ins: &[Option<Const>], i: usize) -> std::result::Result<&Const, String> {
    ins.get(i)
        .and_then(Option::as_ref)
        .ok_or_else(|| format!("missing input {i}"))
}

/// Axes from the attribute (old opsets) or the second input (new opsets).
pub(super) fn axes_of(attrs: &Attrs, ins: &[Option<Const>], input_ix: usize) -> Option<Vec<i64>> {
    attrs
        .ints("axes")
        .or_else(|| ins.get(input_ix).and_then(Option::as_ref).map(Const::ints))
}

/// Output dims of Reshape.
pub(super) fn reshape_dims(
    input: &[usize],
    target: &[i64],
    allowzero: bool,
) -> std::result::Result<Vec<usize>, String> {
    let total: usize = input.iter().product();
    let mut out = Vec::with_capacity(target.len());
    let mut infer = None;
    for (i, t) in target.iter().enumerate() {
        match *t {
            -1 if infer.is_none() => {
                infer = Some(i);
                out.push(1);
            }
            0 if !allowzero => out.push(*input.get(i).ok_or("0 in reshape beyond the input rank")?),
            t if t >= 0 => out.push(t as usize),
            t => return Err(format!("bad reshape target {t}")),
        }
    }
    let known: usize = out.iter().product();
    if let Some(i) = infer {
        if known == 0 || !total.is_multiple_of(known) {
            return Err(format!("cannot infer -1 reshaping {input:?} to {target:?}"));
        }
        out[i] = total / known;
    }
    if out.iter().product::<usize>() != total {
        return Err(format!("cannot reshape {input:?} to {target:?}"));
    }
    Ok(out)
}

/// Unsqueeze dims.
pub(super) fn unsqueeze_dims(
    dims: &[usize],
    axes: &[i64],
) -> std::result::Result<Vec<usize>, String> {
    let r = dims.len() + axes.len();
    let mut ax: Vec<usize> = axes
        .iter()
        .map(|a| norm_axis(*a, r))
        .collect::<Option<_>>()
        .ok_or("bad axis")?;
    ax.sort_unstable();
    let mut out = Vec::with_capacity(r);
    let mut src = dims.iter();
    for i in 0..r {
        if ax.binary_search(&i).is_ok() {
            out.push(1);
        } else {
            out.push(*src.next().ok_or("bad unsqueeze axes")?);
        }
    }
    Ok(out)
}

/// Squeeze dims.
pub(super) fn squeeze_dims(
    dims: &[usize],
    axes: Option<&[i64]>,
) -> std::result::Result<Vec<usize>, String> {
    match axes {
        None => Ok(dims.iter().copied().filter(|d| *d != 1).collect()),
        Some(axes) => {
            let ax: Vec<usize> = axes
                .iter()
                .map(|a| norm_axis(*a, dims.len()))
                .collect::<Option<_>>()
                .ok_or("bad axis")?;
            if ax.iter().any(|a| dims[*a] != 1) {
                return Err("squeezing an axis that is not 1".into());
            }
            Ok(dims
                .iter()
                .enumerate()
                .filter(|(i, _)| !ax.contains(i))
                .map(|(_, d)| *d)
                .collect())
        }
    }
}

/// Slice parameters: axes, starts, ends, steps.
pub(super) type SliceParams = (Vec<usize>, Vec<i64>, Vec<i64>, Vec<i64>);

/// Slice parameters from inputs (opset ≥ 10) or attributes (older).
pub(super) fn slice_params(
    attrs: &Attrs,
    ins: &[Option<Const>],
    rank: usize,
) -> std::result::Result<SliceParams, String> {
    let get = |i: usize, name: &str| -> Option<Vec<i64>> {
        ins.get(i)
            .and_then(Option::as_ref)
            .map(Const::ints)
            .or_else(|| attrs.ints(name))
    };
    let starts = get(1, "starts").ok_or("Slice without starts")?;
    let ends = get(2, "ends").ok_or("Slice without ends")?;
    let axes = get(3, "axes").unwrap_or_else(|| (0..starts.len() as i64).collect());
    let steps = ins
        .get(4)
        .and_then(Option::as_ref)
        .map(Const::ints)
        .unwrap_or_else(|| vec![1; starts.len()]);
    let axes: Vec<usize> = axes
        .iter()
        .map(|a| norm_axis(*a, rank))
        .collect::<Option<_>>()
        .ok_or("bad Slice axis")?;
    if starts.len() != axes.len() || ends.len() != axes.len() || steps.len() != axes.len() {
        return Err("Slice parameter lengths differ".into());
    }
    Ok((axes, starts, ends, steps))
}

/// Pad amounts `[begin..., end...]` for all axes (opset ≥ 11 input, older attribute).
pub(super) fn pad_params(
    attrs: &Attrs,
    ins: &[Option<Const>],
    rank: usize,
) -> std::result::Result<(Vec<i64>, f64), String> {
    let mode = attrs.string("mode").unwrap_or_else(|| "constant".into());
    if mode != "constant" {
        return Err(format!(
            "Pad mode {mode:?} is not supported (only constant)"
        ));
    }
    let raw = ins
        .get(1)
        .and_then(Option::as_ref)
        .map(Const::ints)
        .or_else(|| attrs.ints("pads"))
        .ok_or("Pad without pads")?;
    let value = ins
        .get(2)
        .and_then(Option::as_ref)
        .and_then(|c| c.data.first().copied())
        .or_else(|| attrs.float("value").map(f64::from))
        .unwrap_or(0.0);
    let pads = match ins.get(3).and_then(Option::as_ref) {
        Some(axes) => {
            let axes: Vec<usize> = axes
                .ints()
                .iter()
                .map(|a| norm_axis(*a, rank))
                .collect::<Option<_>>()
                .ok_or("bad Pad axis")?;
            let mut p = vec![0; 2 * rank];
            for (i, a) in axes.iter().enumerate() {
                p[*a] = raw[i];
                p[rank + *a] = raw[axes.len() + i];
            }
            p
        }
        None => raw,
    };
    if pads.len() != 2 * rank {
        return Err(format!("Pad has {} pads for rank {rank}", pads.len()));
    }
    Ok((pads, value))
}

/// Evaluate a node on constant inputs.
pub(super) fn eval(node: &pb::NodeProto, attrs: &Attrs, ins: &[Option<Const>]) -> FoldResult {
    let x = || input(ins, 0);
    let one = |c: Const| Ok(vec![c]);
    let op = node.op_type.as_str();
    let float_un = |f: fn(f64) -> f64| -> FoldResult { Ok(vec![unary(x()?, f)]) };
    match op {
        "Constant" => {
            if let Some(t) = attrs.tensor("value") {
                return one(decode_tensor(t).map_err(|e| e.to_string())?);
            }
            if let Some(v) = attrs.float("value_float") {
                return one(Const::float(vec![], vec![v as f64]));
            }
            if let Some(v) = attrs.int("value_int") {
                return one(Const::int(vec![], vec![v as f64]));
            }
            if let Some(v) = attrs.ints("value_ints") {
                return one(Const::int(
                    vec![v.len()],
                    v.iter().map(|v| *v as f64).collect(),
                ));
            }
            if let Some(v) = attrs.floats("value_floats") {
                return one(Const::float(
                    vec![v.len()],
                    v.iter().map(|v| *v as f64).collect(),
                ));
            }
            Err("Constant without a supported value attribute".into())
        }
        "Identity" | "Dropout" => one(x()?.clone()),
        "Cast" => {
            let to = attrs.int("to").ok_or("Cast without to")?;
            let float = matches!(to, 1 | 10 | 11 | 16);
            let c = x()?;
            let data = c
                .data
                .iter()
                .map(|v| {
                    if float {
                        *v as f32 as f64
                    } else if c.float {
                        v.trunc()
                    } else {
                        *v
                    }
                })
                .collect();
            one(Const {
                dims: c.dims.clone(),
                data,
                float,
            })
        }
        "Shape" => {
            let d = &x()?.dims;
            let r = d.len() as i64;
            let clampi = |v: i64| (if v < 0 { v + r } else { v }).clamp(0, r) as usize;
            let s = clampi(attrs.int("start").unwrap_or(0));
            let e = clampi(attrs.int("end").unwrap_or(r));
            let v: Vec<f64> = d[s..e.max(s)].iter().map(|v| *v as f64).collect();
            one(Const::int(vec![v.len()], v))
        }
        "Size" => one(Const::int(vec![], vec![x()?.len() as f64])),
        "Gather" => {
            let (data, idx) = (x()?, input(ins, 1)?);
            let axis = norm_axis(attrs.int("axis").unwrap_or(0), data.dims.len())
                .ok_or("bad Gather axis")?;
            let d = data.dims[axis];
            let outer: usize = data.dims[..axis].iter().product();
            let inner: usize = data.dims[axis + 1..].iter().product();
            let mut out = Vec::new();
            for o in 0..outer {
                for i in idx.ints() {
                    let i = if i < 0 { i + d as i64 } else { i };
                    if i < 0 || i as usize >= d {
                        return Err(format!("Gather index {i} out of range {d}"));
                    }
                    let base = (o * d + i as usize) * inner;
                    out.extend_from_slice(&data.data[base..base + inner]);
                }
            }
            let mut dims = data.dims[..axis].to_vec();
            dims.extend(&idx.dims);
            dims.extend(&data.dims[axis + 1..]);
            one(Const {
                dims,
                data: out,
                float: data.float,
            })
        }
        "Unsqueeze" => {
            let axes = axes_of(attrs, ins, 1).ok_or("Unsqueeze without axes")?;
            let c = x()?;
            one(Const {
                dims: unsqueeze_dims(&c.dims, &axes)?,
                ..c.clone()
            })
        }
        "Squeeze" => {
            let c = x()?;
            one(Const {
                dims: squeeze_dims(&c.dims, axes_of(attrs, ins, 1).as_deref())?,
                ..c.clone()
            })
        }
        "Reshape" => {
            let c = x()?;
            let target = input(ins, 1)?.ints();
            one(Const {
                dims: reshape_dims(&c.dims, &target, attrs.int("allowzero") == Some(1))?,
                ..c.clone()
            })
        }
        "Flatten" => {
            let c = x()?;
            let axis =
                norm_axis(attrs.int("axis").unwrap_or(1), c.dims.len() + 1).ok_or("bad axis")?;
            let dims = vec![
                c.dims[..axis].iter().product(),
                c.dims[axis..].iter().product(),
            ];
            one(Const { dims, ..c.clone() })
        }
        "Concat" => {
            let parts: Vec<&Const> = ins.iter().flatten().collect();
            let first = parts.first().ok_or("Concat without inputs")?;
            let r = first.dims.len();
            let axis =
                norm_axis(attrs.int("axis").ok_or("Concat without axis")?, r).ok_or("bad axis")?;
            let outer: usize = first.dims[..axis].iter().product();
            let mut dims = first.dims.clone();
            dims[axis] = parts
                .iter()
                .map(|p| p.dims.get(axis).copied().unwrap_or(0))
                .sum();
            let mut data = Vec::new();
            for o in 0..outer {
                for p in &parts {
                    if p.dims.len() != r {
                        return Err("Concat rank mismatch".into());
                    }
                    let blk: usize = p.dims[axis..].iter().product();
                    data.extend_from_slice(&p.data[o * blk..(o + 1) * blk]);
                }
            }
            one(Const {
                dims,
                data,
                float: parts.iter().any(|p| p.float),
            })
        }
        "ConstantOfShape" => {
            let dims: Vec<usize> = x()?.ints().iter().map(|v| *v as usize).collect();
            let (value, float) = match attrs.tensor("value") {
                Some(t) => {
                    let c = decode_tensor(t).map_err(|e| e.to_string())?;
                    (c.data.first().copied().unwrap_or(0.0), c.float)
                }
                None => (0.0, true),
            };
            let n = dims.iter().product();
            one(Const {
                dims,
                data: vec![value; n],
                float,
            })
        }
        "Range" => {
            let (s, l, d) = (input(ins, 0)?, input(ins, 1)?, input(ins, 2)?);
            let (s0, l0, d0) = (s.data[0], l.data[0], d.data[0]);
            if d0 == 0.0 {
                return Err("Range with delta 0".into());
            }
            let n = ((l0 - s0) / d0).ceil().max(0.0) as usize;
            one(Const {
                dims: vec![n],
                data: (0..n).map(|i| s0 + i as f64 * d0).collect(),
                float: s.float,
            })
        }
        "Expand" => {
            let c = x()?;
            let shape: Vec<usize> = input(ins, 1)?.ints().iter().map(|v| *v as usize).collect();
            let ones = Const {
                dims: shape,
                data: vec![],
                float: c.float,
            };
            let ones = Const {
                data: vec![0.0; ones.dims.iter().product()],
                ..ones
            };
            one(binary(c, &ones, c.float, |a, _| a)?)
        }
        "Where" => {
            let (c, a, b) = (input(ins, 0)?, input(ins, 1)?, input(ins, 2)?);
            let ab = binary(a, b, a.float, |_, _| 0.0)?;
            let pick_a = binary(c, &ab, true, |c, _| c)?;
            let av = binary(a, &ab, a.float, |a, _| a)?;
            let bv = binary(b, &ab, a.float, |b, _| b)?;
            let data = pick_a
                .data
                .iter()
                .zip(av.data.iter().zip(&bv.data))
                .map(|(c, (a, b))| if *c != 0.0 { *a } else { *b })
                .collect();
            one(Const {
                dims: ab.dims,
                data,
                float: a.float,
            })
        }
        "Slice" => {
            let c = x()?;
            let (axes, starts, ends, steps) = slice_params(attrs, ins, c.dims.len())?;
            let (out, plan) =
                slice_plan(&c.dims, &axes, &starts, &ends, &steps).ok_or("bad Slice")?;
            one(apply_const(&plan, c, out, 0.0).ok_or("bad Slice")?)
        }
        "Transpose" => {
            let c = x()?;
            let perm: Vec<usize> = attrs
                .ints("perm")
                .map(|p| p.iter().map(|v| *v as usize).collect())
                .unwrap_or_else(|| (0..c.dims.len()).rev().collect());
            let (out, plan) = transpose_plan(&c.dims, &perm).ok_or("bad perm")?;
            one(apply_const(&plan, c, out, 0.0).ok_or("bad Transpose")?)
        }
        "Pad" => {
            let c = x()?;
            let (pads, value) = pad_params(attrs, ins, c.dims.len())?;
            let (out, plan) = pad_plan(&c.dims, &pads).ok_or("bad pads")?;
            one(apply_const(&plan, c, out, value).ok_or("bad Pad")?)
        }
        "Add" | "Sub" | "Mul" | "Div" | "Pow" | "Max" | "Min" | "Equal" | "Less" | "Greater"
        | "And" | "Or" | "Mod" => {
            let (a, b) = (x()?, input(ins, 1)?);
            let float = a.float || b.float;
            let cmp = matches!(op, "Equal" | "Less" | "Greater" | "And" | "Or");
            let f: fn(f64, f64) -> f64 = match op {
                "Add" => |a, b| a + b,
                "Sub" => |a, b| a - b,
                "Mul" => |a, b| a * b,
                "Div" => |a, b| a / b,
                "Pow" => f64::powf,
                "Max" => f64::max,
                "Min" => f64::min,
                "Equal" => |a, b| f64::from(u8::from(a == b)),
                "Less" => |a, b| f64::from(u8::from(a < b)),
                "Greater" => |a, b| f64::from(u8::from(a > b)),
                "And" => |a, b| f64::from(u8::from(a != 0.0 && b != 0.0)),
                "Or" => |a, b| f64::from(u8::from(a != 0.0 || b != 0.0)),
                _ => |a, b| a.rem_euclid(b),
            };
            let mut r = binary(a, b, float && !cmp, f)?;
            if !float && op == "Div" {
                r.data.iter_mut().for_each(|v| *v = v.trunc());
            }
            one(r)
        }
        "Not" => one(unary(x()?, |v| f64::from(u8::from(v == 0.0)))),
        "Neg" => float_un(|v| -v),
        "Abs" => float_un(f64::abs),
        "Sqrt" => float_un(f64::sqrt),
        "Exp" => float_un(f64::exp),
        "Log" => float_un(f64::ln),
        "Sin" => float_un(f64::sin),
        "Cos" => float_un(f64::cos),
        "Tanh" => float_un(f64::tanh),
        "Floor" => float_un(f64::floor),
        "Ceil" => float_un(f64::ceil),
        "Reciprocal" => float_un(|v| 1.0 / v),
        "Relu" => float_un(|v| v.max(0.0)),
        "Sigmoid" => float_un(|v| 1.0 / (1.0 + (-v).exp())),
        "Softplus" => float_un(|v| v.exp().ln_1p()),
        "Mish" => float_un(|v| v * v.exp().ln_1p().tanh()),
        _ => Err(format!("no constant folding for {op}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reshape_and_broadcast_rules() {
        assert_eq!(
            reshape_dims(&[5, 16, 12], &[0, 8, -1], false).unwrap(),
            vec![5, 8, 24]
        );
        assert!(reshape_dims(&[5, 16, 12], &[0, 7, -1], false).is_err());
        assert_eq!(unsqueeze_dims(&[5, 16], &[2]).unwrap(), vec![5, 16, 1]);
        let a = Const::float(vec![2, 1], vec![1.0, 2.0]);
        let b = Const::float(vec![3], vec![10.0, 20.0, 30.0]);
        let c = binary(&a, &b, true, |x, y| x + y).unwrap();
        assert_eq!(c.dims, vec![2, 3]);
        assert_eq!(c.data, vec![11.0, 21.0, 31.0, 12.0, 22.0, 32.0]);
    }
}
