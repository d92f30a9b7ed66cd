//! Emission of the compute ops: Gemm, strided copies, broadcast binaries, convolutions and
//! GroupNormalization.

use dips_kernel::nn::format::{BinaryFn, ConvGeom, Op, Operand, RANK};
use dips_kernel::nn::ops::conv::{self, padded_channels};

use super::super::attrs::{Attrs, broadcast_dims};
use super::super::copyplan::{CopyPlan, strides};
use super::super::tensors::Const;
use super::{ActErr, ActResult, Builder, Ins, Val, pad4, u32s};
use tract_onnx::pb;

impl Builder {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn gemm(
        &mut self,
        st: usize,
        ps: &[usize],
        w: &[f32],
        bias: &[f32],
        k: usize,
        n: usize,
        out: Vec<usize>,
        key: String,
    ) -> ActResult<Val> {
        let rows = ps.iter().product::<usize>() / k;
        let w = self.weight(Some(format!("{key}:w")), w);
        let b = self.weight(Some(format!("{key}:b")), bias);
        let (v, y) = self.out(out)?;
        let (a, y) = (self.buf(st), self.buf(y));
        let [rows, k, n] = [rows, k, n].map(|v| v as u32);
        self.push(Op::Gemm {
            a,
            y,
            w,
            b,
            rows,
            k,
            n,
        });
        Ok(v)
    }

    pub(super) fn copy(&mut self, x: Operand, y: usize, plan: &CopyPlan) -> ActResult<()> {
        let dims = pad4(&u32s(&plan.dims)?, 1)?;
        let xs = pad4(
            &plan
                .xs
                .iter()
                .map(|s| i32::try_from(*s).map_err(|_| ActErr::from("stride exceeds i32")))
                .collect::<ActResult<Vec<_>>>()?,
            0,
        )?;
        let ys = pad4(&u32s(&plan.ys)?, 0)?;
        let x_off = u32::try_from(plan.x_off).map_err(|_| ActErr::from("negative copy offset"))?;
        let y_off = plan.y_off as u32;
        let yb = self.buf(y);
        self.push(Op::Copy {
            x,
            y: yb,
            dims,
            x_off,
            xs,
            y_off,
            ys,
        });
        Ok(())
    }

    /// Broadcast binary op with at least one activation.
    pub(super) fn binary(
        &mut self,
        f: BinaryFn,
        a: &Option<Val>,
        b: &Option<Val>,
    ) -> ActResult<Val> {
        let full = |v: &Option<Val>| -> ActResult<Vec<usize>> {
            Ok(match v {
                Some(Val::Act { ps, .. }) => {
                    let mut d = vec![self.batch];
                    d.extend(ps);
                    d
                }
                Some(Val::Const(c)) => c.dims.clone(),
                None => return Err("missing operand".into()),
            })
        };
        let (fa, fb) = (full(a)?, full(b)?);
        let out = broadcast_dims(&fa, &fb)
            .ok_or_else(|| format!("shapes {fa:?} and {fb:?} do not broadcast"))?;
        let r = out.len();
        let ops_ = out[1..].to_vec();
        let mut operand = |v: &Option<Val>, fd: &[usize]| -> ActResult<(Operand, [u32; RANK])> {
            // Per-sample dims of the operand aligned to the output's per-sample rank.
            let aligned: Vec<usize> = (0..r)
                .map(|i| {
                    if i + fd.len() >= r {
                        fd[i + fd.len() - r]
                    } else {
                        1
                    }
                })
                .collect();
            let per = &aligned[1..];
            let st = strides(per);
            let strides_: Vec<u32> = per
                .iter()
                .zip(&st)
                .zip(&ops_)
                .map(|((d, s), o)| if *d == 1 && *o != 1 { 0 } else { *s as u32 })
                .collect();
            let s4 = pad4(&strides_, 0)?;
            match v {
                Some(Val::Act { st, .. }) => {
                    if fd.len() != r {
                        return Err("an activation broadcast along the batch axis".into());
                    }
                    Ok((Operand::Act(self.buf(*st)), s4))
                }
                Some(Val::Const(c)) => {
                    if aligned[0] != 1 {
                        return Err("a constant varies along the batch axis".into());
                    }
                    let w = self.weight(None, &c.floats());
                    Ok((Operand::Weight(w), s4))
                }
                None => Err("missing operand".into()),
            }
        };
        let (oa, sa) = operand(a, &fa)?;
        let (ob, sb) = operand(b, &fb)?;
        if out[0] != self.batch {
            return Err("result does not keep the batch axis".into());
        }
        let dims = pad4(&u32s(&ops_)?, 1)?;
        let (v, y) = self.out(ops_)?;
        let yb = self.buf(y);
        self.push(Op::Binary {
            a: oa,
            b: ob,
            y: yb,
            f,
            dims,
            sa,
            sb,
        });
        Ok(v)
    }

    pub(super) fn conv(&mut self, transposed: bool, attrs: &Attrs, ins: &Ins) -> ActResult<Val> {
        let (ps, st) = self.act(&ins[0])?;
        if ps.len() != 2 {
            return Err(format!(
                "only 1-D convolutions ([batch, channels, length]) are supported, input is {ps:?}"
            )
            .into());
        }
        if attrs.int("group").unwrap_or(1) != 1 {
            return Err("grouped convolutions are not supported".into());
        }
        let auto_pad = attrs.string("auto_pad").unwrap_or_default();
        if !(auto_pad.is_empty() || auto_pad == "NOTSET" || auto_pad == "VALID") {
            return Err(format!("auto_pad {auto_pad} is not supported").into());
        }
        if attrs.get("output_shape").is_some() {
            return Err("ConvTranspose output_shape is not supported".into());
        }
        let w = self.konst(&ins[1], "the kernel")?.clone();
        if w.dims.len() != 3 {
            return Err("the kernel must be 3-D".into());
        }
        let (cin, lin) = (ps[0], ps[1]);
        let (cout, k) = if transposed {
            (w.dims[1], w.dims[2])
        } else {
            (w.dims[0], w.dims[2])
        };
        let wcin = if transposed { w.dims[0] } else { w.dims[1] };
        if wcin != cin {
            return Err(
                format!("the kernel expects {wcin} input channels, the input has {cin}").into(),
            );
        }
        let one = |name: &str, default: i64| -> ActResult<i64> {
            match attrs.ints(name) {
                Some(v) if v.len() == 1 => Ok(v[0]),
                Some(v) => Err(format!("{name} {v:?} is not 1-D").into()),
                None => Ok(default),
            }
        };
        let s = one("strides", 1)?;
        let d = one("dilations", 1)?;
        let pads = attrs.ints("pads").unwrap_or_else(|| vec![0, 0]);
        if pads.len() != 2 || pads.iter().any(|p| *p < 0) || s < 1 || d < 1 {
            return Err(format!("pads {pads:?}, stride {s}, dilation {d} not supported").into());
        }
        if let Some(kk) = attrs.ints("kernel_shape")
            && kk != [k as i64]
        {
            return Err("kernel_shape disagrees with the kernel".into());
        }
        let (s, d, pb, pe) = (s as usize, d as usize, pads[0] as usize, pads[1] as usize);
        let lout = if transposed {
            let op = one("output_padding", 0)? as usize;
            ((lin - 1) * s + op + (k - 1) * d + 1).checked_sub(pb + pe)
        } else {
            (lin + pb + pe)
                .checked_sub(d * (k - 1) + 1)
                .map(|v| v / s + 1)
        }
        .filter(|v| *v > 0)
        .ok_or("the convolution output is empty")?;
        let coutp = padded_channels(cout);
        let wf = w.floats();
        let mut packed = vec![0.0f32; cin * k * coutp];
        let res = if transposed {
            conv::pack_conv_transpose_kernel(&wf, cin, cout, k, coutp, &mut packed)
        } else {
            conv::pack_conv_kernel(&wf, cout, cin, k, coutp, &mut packed)
        };
        res.map_err(|_| ActErr::from("kernel packing failed"))?;
        let mut bias = match ins.get(2).cloned().flatten() {
            None => vec![0.0; cout],
            Some(Val::Const(c)) if c.len() == cout => c.floats(),
            Some(_) => return Err("the bias must be a constant of cout entries".into()),
        };
        bias.resize(coutp, 0.0);
        let wk = self.weight(None, &packed);
        let bk = self.weight(None, &bias);
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
        let (v, y) = self.out(vec![cout, lout])?;
        let (x, y) = (self.buf(st), self.buf(y));
        self.push(if transposed {
            Op::ConvTranspose1d {
                x,
                y,
                w: wk,
                b: bk,
                g,
            }
        } else {
            Op::Conv1d {
                x,
                y,
                w: wk,
                b: bk,
                g,
            }
        });
        Ok(v)
    }

    /// ONNX GroupNormalization: normalize `num_groups` groups, then scale/shift per channel
    /// (opset ≥ 21) or per group (opset 18, as tract and the older spec read it).
    pub(super) fn group_norm(
        &mut self,
        node: &pb::NodeProto,
        attrs: &Attrs,
        ins: &Ins,
    ) -> ActResult<Val> {
        let (ps, st) = self.act(&ins[0])?;
        let groups = attrs
            .int("num_groups")
            .ok_or("GroupNormalization without num_groups")? as usize;
        if ps.is_empty() || groups == 0 || ps[0] % groups != 0 {
            return Err(format!("{groups} groups for shape {ps:?}").into());
        }
        let c = ps[0];
        let len: usize = ps.iter().product::<usize>() / groups;
        let eps = attrs.float("epsilon").unwrap_or(1e-5);
        let scale = self.konst(&ins[1], "scale")?.floats();
        let bias = self.konst(&ins[2], "bias")?.floats();
        let per_channel = self.opset >= 21;
        let want = if per_channel { c } else { groups };
        if scale.len() != want || bias.len() != want {
            return Err(format!("scale/bias need {want} entries").into());
        }
        let (ones, zeros) = (vec![1.0; groups], vec![0.0; groups]);
        let sc = self.weight(None, &ones);
        let bi = self.weight(None, &zeros);
        let (_, n) = self.out(ps.clone())?;
        let (xb, nb) = (self.buf(st), self.buf(n));
        self.push(Op::InstanceNorm {
            x: xb,
            y: nb,
            channels: groups as u32,
            len: len as u32,
            eps,
            scale: sc,
            bias: bi,
        });
        let expand = |v: &[f32]| -> Vec<f32> {
            (0..c)
                .map(|ch| {
                    if per_channel {
                        v[ch]
                    } else {
                        v[ch / (c / groups)]
                    }
                })
                .collect()
        };
        let mut cshape = vec![c];
        cshape.extend(std::iter::repeat_n(1, ps.len() - 1));
        let s_const = Some(Val::Const(Const::float(
            cshape.clone(),
            expand(&scale).iter().map(|v| *v as f64).collect(),
        )));
        let b_const = Some(Val::Const(Const::float(
            cshape,
            expand(&bias).iter().map(|v| *v as f64).collect(),
        )));
        let _ = node;
        let scaled = self.binary(
            BinaryFn::Mul,
            &Some(Val::Act {
                ps: ps.clone(),
                st: n,
            }),
            &s_const,
        )?;
        self.binary(BinaryFn::Add, &Some(scaled), &b_const)
    }
}
