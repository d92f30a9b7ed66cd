//! The networks: every layer has its burn forward pass and its ONNX emission side by side,
//! so the exported graph is the trained function op for op.
//!
//! Denoiser (spec §4.1, scaled by [`NetSettings`]): `x [B,T,D]` → channels first → zero-pad the
//! time axis to a multiple of `2^(stages−1)` → down stages (2 residual blocks, then a stride-2
//! Conv1d(k3, p1) except at the last stage) → middle blocks → up stages (concatenate the skip
//! of that resolution, 2 residual blocks, ConvTranspose1d(k4, s2, p1)) → concatenate the
//! full-resolution skip, 2 residual blocks → Conv1d(k3)+GroupNorm+Mish → Conv1d(k1) → crop →
//! `eps [B,T,D]`. Unlike Diffuser, the first stage's skip is used: without it every row's
//! noise must pass a stride-2 bottleneck, and the held-out loss stalls (`docs/training.md`). The conditioning embedding is
//! `Mish(Linear([SinPos(t) ; cond_mask·Mish(Linear(c))]))`, read by every residual block
//! through its own `Linear(E→out)`. With `net.start_embed_dim` > 0 the embedding also reads
//! the start row's state columns, `[… ; Mish(Linear(x[:, 0, :S]))]` (row 0 is the inpainted
//! start whenever the planner samples), so the start state reaches every block directly
//! instead of only through the convolutions.
//!
//! Discriminator (§4.5): the same down stages and middle blocks (no time padding, no skips),
//! the conditioning `Mish(Linear(Mish(Linear(c))))`, global average pooling over time,
//! `Linear(w→1)`; the exported graph ends in a Sigmoid, training uses the logit.

use burn::tensor::activation::mish;
use burn::tensor::module::{conv_transpose1d, conv1d, linear};
use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};
use burn::tensor::{Device, Tensor, TensorData};
use dips_kernel::rng::KernelRng;

use crate::graph::{Attr, Graph};
use crate::params::ParamStore;
use crate::settings::NetSettings;

/// GroupNorm ε (PyTorch's default, written into the ONNX node).
pub const GN_EPS: f32 = 1e-5;

type P<'a> = &'a [Tensor<1>];

fn param<const D: usize>(p: P<'_>, i: usize, shape: [usize; D]) -> Tensor<D> {
    p[i].clone().reshape(shape)
}

/// `Linear(i→o)`, weight `[i, o]` (ONNX Gemm without transB).
#[derive(Debug, Clone)]
pub(crate) struct Linear {
    w: usize,
    b: usize,
    i: usize,
    o: usize,
}

impl Linear {
    fn new(ps: &mut ParamStore, name: &str, i: usize, o: usize, rng: &mut KernelRng) -> Self {
        let bound = 1.0 / (i as f32).sqrt();
        let w = ps.uniform(format!("{name}.weight"), vec![i, o], bound, rng);
        let b = ps.uniform(format!("{name}.bias"), vec![o], bound, rng);
        Self { w, b, i, o }
    }

    fn fwd(&self, p: P<'_>, x: Tensor<2>) -> Tensor<2> {
        linear(
            x,
            param(p, self.w, [self.i, self.o]),
            Some(p[self.b].clone()),
        )
    }

    fn emit(&self, g: &mut Graph, ps: &ParamStore, x: &str) -> String {
        let w = g.f32(&ps.names[self.w], &[self.i, self.o], &ps.data[self.w]);
        let b = g.f32(&ps.names[self.b], &[self.o], &ps.data[self.b]);
        g.node("Gemm", &[x, &w, &b], vec![])
    }
}

/// `Conv1d(cin→cout, k, stride, pad)`, weight `[cout, cin, k]`.
#[derive(Debug, Clone)]
pub(crate) struct Conv {
    w: usize,
    b: usize,
    cin: usize,
    cout: usize,
    k: usize,
    stride: usize,
    pad: usize,
}

impl Conv {
    #[allow(clippy::too_many_arguments)]
    fn new(
        ps: &mut ParamStore,
        name: &str,
        cin: usize,
        cout: usize,
        k: usize,
        stride: usize,
        pad: usize,
        rng: &mut KernelRng,
    ) -> Self {
        let bound = 1.0 / ((cin * k) as f32).sqrt();
        let w = ps.uniform(format!("{name}.weight"), vec![cout, cin, k], bound, rng);
        let b = ps.uniform(format!("{name}.bias"), vec![cout], bound, rng);
        Self {
            w,
            b,
            cin,
            cout,
            k,
            stride,
            pad,
        }
    }

    fn fwd(&self, p: P<'_>, x: Tensor<3>) -> Tensor<3> {
        conv1d(
            x,
            param(p, self.w, [self.cout, self.cin, self.k]),
            Some(p[self.b].clone()),
            ConvOptions::new([self.stride], [self.pad], [1], 1),
        )
    }

    fn emit(&self, g: &mut Graph, ps: &ParamStore, x: &str) -> String {
        let w = g.f32(
            &ps.names[self.w],
            &[self.cout, self.cin, self.k],
            &ps.data[self.w],
        );
        let b = g.f32(&ps.names[self.b], &[self.cout], &ps.data[self.b]);
        g.node(
            "Conv",
            &[x, &w, &b],
            vec![
                Attr::Ints("kernel_shape", vec![self.k as i64]),
                Attr::Ints("strides", vec![self.stride as i64]),
                Attr::Ints("pads", vec![self.pad as i64, self.pad as i64]),
                Attr::Ints("dilations", vec![1]),
                Attr::Int("group", 1),
            ],
        )
    }
}

/// `ConvTranspose1d(c→c, k4, s2, p1)`: exactly doubles the length. Weight `[c, c, 4]`.
#[derive(Debug, Clone)]
pub(crate) struct Upsample {
    w: usize,
    b: usize,
    c: usize,
}

impl Upsample {
    fn new(ps: &mut ParamStore, name: &str, c: usize, rng: &mut KernelRng) -> Self {
        let bound = 1.0 / ((c * 4) as f32).sqrt();
        let w = ps.uniform(format!("{name}.weight"), vec![c, c, 4], bound, rng);
        let b = ps.uniform(format!("{name}.bias"), vec![c], bound, rng);
        Self { w, b, c }
    }

    fn fwd(&self, p: P<'_>, x: Tensor<3>) -> Tensor<3> {
        conv_transpose1d(
            x,
            param(p, self.w, [self.c, self.c, 4]),
            Some(p[self.b].clone()),
            ConvTransposeOptions::new([2], [1], [0], [1], 1),
        )
    }

    fn emit(&self, g: &mut Graph, ps: &ParamStore, x: &str) -> String {
        let w = g.f32(&ps.names[self.w], &[self.c, self.c, 4], &ps.data[self.w]);
        let b = g.f32(&ps.names[self.b], &[self.c], &ps.data[self.b]);
        g.node(
            "ConvTranspose",
            &[x, &w, &b],
            vec![
                Attr::Ints("kernel_shape", vec![4]),
                Attr::Ints("strides", vec![2]),
                Attr::Ints("pads", vec![1, 1]),
                Attr::Ints("dilations", vec![1]),
                Attr::Int("group", 1),
            ],
        )
    }
}

/// GroupNorm with per-channel affine (ONNX GroupNormalization at opset 21).
#[derive(Debug, Clone)]
pub(crate) struct GroupNorm {
    scale: usize,
    bias: usize,
    c: usize,
    groups: usize,
}

impl GroupNorm {
    fn new(ps: &mut ParamStore, name: &str, c: usize, groups: usize) -> Self {
        let scale = ps.constant(format!("{name}.scale"), vec![c], 1.0);
        let bias = ps.constant(format!("{name}.bias"), vec![c], 0.0);
        Self {
            scale,
            bias,
            c,
            groups,
        }
    }

    fn fwd(&self, p: P<'_>, x: Tensor<3>) -> Tensor<3> {
        let [b, c, l] = x.dims();
        let g = x.reshape([b, self.groups, (c / self.groups) * l]);
        let mean = g.clone().mean_dim(2);
        let d = g - mean;
        let var = d.clone().powi_scalar(2).mean_dim(2);
        let y = (d / (var + GN_EPS).sqrt()).reshape([b, c, l]);
        y * param(p, self.scale, [1, self.c, 1]) + param(p, self.bias, [1, self.c, 1])
    }

    fn emit(&self, g: &mut Graph, ps: &ParamStore, x: &str) -> String {
        let s = g.f32(&ps.names[self.scale], &[self.c], &ps.data[self.scale]);
        let b = g.f32(&ps.names[self.bias], &[self.c], &ps.data[self.bias]);
        g.node(
            "GroupNormalization",
            &[x, &s, &b],
            vec![
                Attr::Float("epsilon", GN_EPS),
                Attr::Int("num_groups", self.groups as i64),
            ],
        )
    }
}

/// ResidualTemporalBlock: `h = Mish(GN(Conv(x))) + Linear(emb)`, `h = Mish(GN(Conv(h)))`,
/// `out = h + skip(x)` (skip = Conv1x1 when the width changes, else identity).
#[derive(Debug, Clone)]
pub(crate) struct ResBlock {
    c1: Conv,
    n1: GroupNorm,
    mlp: Linear,
    c2: Conv,
    n2: GroupNorm,
    skip: Option<Conv>,
}

impl ResBlock {
    fn new(
        ps: &mut ParamStore,
        name: &str,
        cin: usize,
        cout: usize,
        net: &NetSettings,
        rng: &mut KernelRng,
    ) -> Self {
        let g = net.groups;
        Self {
            c1: Conv::new(ps, &format!("{name}.conv1"), cin, cout, 3, 1, 1, rng),
            n1: GroupNorm::new(ps, &format!("{name}.norm1"), cout, g),
            mlp: Linear::new(ps, &format!("{name}.emb"), net.embed_dim, cout, rng),
            c2: Conv::new(ps, &format!("{name}.conv2"), cout, cout, 3, 1, 1, rng),
            n2: GroupNorm::new(ps, &format!("{name}.norm2"), cout, g),
            skip: (cin != cout)
                .then(|| Conv::new(ps, &format!("{name}.skip"), cin, cout, 1, 1, 0, rng)),
        }
    }

    fn fwd(&self, p: P<'_>, x: Tensor<3>, emb: &Tensor<2>) -> Tensor<3> {
        let h = mish(self.n1.fwd(p, self.c1.fwd(p, x.clone())));
        let h = h + self.mlp.fwd(p, emb.clone()).unsqueeze_dim::<3>(2);
        let h = mish(self.n2.fwd(p, self.c2.fwd(p, h)));
        match &self.skip {
            Some(s) => h + s.fwd(p, x),
            None => h + x,
        }
    }

    fn emit(&self, g: &mut Graph, ps: &ParamStore, x: &str, emb: &str) -> String {
        let h = self.c1.emit(g, ps, x);
        let h = self.n1.emit(g, ps, &h);
        let h = g.node("Mish", &[&h], vec![]);
        let e = self.mlp.emit(g, ps, emb);
        let e = g.unsqueeze(&e, &[2]);
        let h = g.node("Add", &[&h, &e], vec![]);
        let h = self.c2.emit(g, ps, &h);
        let h = self.n2.emit(g, ps, &h);
        let h = g.node("Mish", &[&h], vec![]);
        let s = match &self.skip {
            Some(s) => s.emit(g, ps, x),
            None => x.to_string(),
        };
        g.node("Add", &[&h, &s], vec![])
    }
}

/// The down path and middle blocks (shared by both networks).
#[derive(Debug, Clone)]
pub(crate) struct Encoder {
    downs: Vec<(ResBlock, ResBlock, Option<Conv>)>,
    mids: Vec<ResBlock>,
}

impl Encoder {
    fn new(ps: &mut ParamStore, d: usize, net: &NetSettings, rng: &mut KernelRng) -> Self {
        let mut downs = Vec::new();
        let mut cin = d;
        let k = net.stages();
        for (i, &w) in net.widths.iter().enumerate() {
            let r1 = ResBlock::new(ps, &format!("down{i}.res1"), cin, w, net, rng);
            let r2 = ResBlock::new(ps, &format!("down{i}.res2"), w, w, net, rng);
            let down =
                (i + 1 < k).then(|| Conv::new(ps, &format!("down{i}.down"), w, w, 3, 2, 1, rng));
            downs.push((r1, r2, down));
            cin = w;
        }
        let mids = (0..net.mid_blocks)
            .map(|i| ResBlock::new(ps, &format!("mid{i}"), cin, cin, net, rng))
            .collect();
        Self { downs, mids }
    }

    /// Returns the middle output and the skips (output of each stage before downsampling).
    fn fwd(&self, p: P<'_>, mut x: Tensor<3>, emb: &Tensor<2>) -> (Tensor<3>, Vec<Tensor<3>>) {
        let mut skips = Vec::new();
        for (r1, r2, down) in &self.downs {
            x = r2.fwd(p, r1.fwd(p, x, emb), emb);
            skips.push(x.clone());
            if let Some(d) = down {
                x = d.fwd(p, x);
            }
        }
        for m in &self.mids {
            x = m.fwd(p, x, emb);
        }
        (x, skips)
    }

    fn emit(&self, g: &mut Graph, ps: &ParamStore, x: &str, emb: &str) -> (String, Vec<String>) {
        let mut x = x.to_string();
        let mut skips = Vec::new();
        for (r1, r2, down) in &self.downs {
            let h = r1.emit(g, ps, &x, emb);
            x = r2.emit(g, ps, &h, emb);
            skips.push(x.clone());
            if let Some(d) = down {
                x = d.emit(g, ps, &x);
            }
        }
        for m in &self.mids {
            x = m.emit(g, ps, &x, emb);
        }
        (x, skips)
    }
}

/// Sizes of a task's trajectories as the networks see them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NetDims {
    /// Rows `T`.
    pub horizon: usize,
    /// Columns `D`.
    pub dim: usize,
    /// State columns (the first of each row).
    pub state_dim: usize,
    /// Fingers `F`.
    pub fingers: usize,
}

/// The ε-predicting temporal U-Net.
#[derive(Debug, Clone)]
pub struct Denoiser {
    dims: NetDims,
    padded: usize,
    freqs: Vec<f32>,
    ctx: Linear,
    start: Option<Linear>,
    emb: Linear,
    enc: Encoder,
    ups: Vec<(ResBlock, ResBlock, Upsample)>,
    top: (ResBlock, ResBlock),
    final_conv: Conv,
    final_norm: GroupNorm,
    out: Conv,
}

/// Frequencies of the sinusoidal step embedding of width `dim`:
/// `exp(−ln(10000)·i/(dim/2 − 1))`, `i < dim/2` (Diffuser's `SinusoidalPosEmb`).
pub fn sin_freqs(dim: usize) -> Vec<f32> {
    let half = dim / 2;
    let scale = (10000f64).ln() / (half as f64 - 1.0).max(1.0);
    (0..half)
        .map(|i| (-(i as f64) * scale).exp() as f32)
        .collect()
}

impl Denoiser {
    /// Register the parameters in `ps` (initialised from `rng`) and build the network.
    pub fn new(ps: &mut ParamStore, dims: NetDims, net: &NetSettings, rng: &mut KernelRng) -> Self {
        let c = net.context_embed_dim;
        let ctx = Linear::new(ps, "context", dims.fingers, c, rng);
        let se = net.start_embed_dim;
        let start = (se > 0).then(|| Linear::new(ps, "start", dims.state_dim, se, rng));
        let emb = Linear::new(ps, "embed", net.time_embed_dim + c + se, net.embed_dim, rng);
        let enc = Encoder::new(ps, dims.dim, net, rng);
        let mut ups = Vec::new();
        for i in (1..net.stages()).rev() {
            let (wi, wo) = (net.widths[i], net.widths[i - 1]);
            let r1 = ResBlock::new(ps, &format!("up{i}.res1"), 2 * wi, wo, net, rng);
            let r2 = ResBlock::new(ps, &format!("up{i}.res2"), wo, wo, net, rng);
            let up = Upsample::new(ps, &format!("up{i}.up"), wo, rng);
            ups.push((r1, r2, up));
        }
        let w0 = net.widths[0];
        let top = (
            ResBlock::new(ps, "top.res1", 2 * w0, w0, net, rng),
            ResBlock::new(ps, "top.res2", w0, w0, net, rng),
        );
        let final_conv = Conv::new(ps, "final.conv", w0, w0, 3, 1, 1, rng);
        let final_norm = GroupNorm::new(ps, "final.norm", w0, net.groups);
        let out = Conv::new(ps, "final.out", w0, dims.dim, 1, 1, 0, rng);
        let m = 1usize << (net.stages() - 1);
        Self {
            dims,
            padded: dims.horizon.div_ceil(m) * m,
            freqs: sin_freqs(net.time_embed_dim),
            ctx,
            start,
            emb,
            enc,
            ups,
            top,
            final_conv,
            final_norm,
            out,
        }
    }

    /// `eps [B,T,D]` from `x [B,T,D]`, `t [B]`, `context [B,F]`, `cond_mask [B]`.
    pub fn fwd(
        &self,
        p: P<'_>,
        x: Tensor<3>,
        t: Tensor<1>,
        context: Tensor<2>,
        cond_mask: Tensor<1>,
    ) -> Tensor<3> {
        let [b, tt, d] = x.dims();
        let dev = x.device();
        let freqs = Tensor::<2>::from_data(
            TensorData::new(self.freqs.clone(), [1, self.freqs.len()]),
            &dev,
        );
        let arg = t.reshape([b, 1]) * freqs;
        let temb = Tensor::cat(vec![arg.clone().sin(), arg.cos()], 1);
        let c = mish(self.ctx.fwd(p, context)) * cond_mask.reshape([b, 1]);
        let mut parts = vec![temb, c];
        if let Some(start) = &self.start {
            let sd = self.dims.state_dim;
            let s0 = x.clone().narrow(1, 0, 1).narrow(2, 0, sd).reshape([b, sd]);
            parts.push(mish(start.fwd(p, s0)));
        }
        let emb = mish(self.emb.fwd(p, Tensor::cat(parts, 1)));

        let mut h = x.swap_dims(1, 2);
        if self.padded > tt {
            let z = Tensor::<3>::zeros([b, d, self.padded - tt], &dev);
            h = Tensor::cat(vec![h, z], 2);
        }
        let (mut h, skips) = self.enc.fwd(p, h, &emb);
        for (j, (r1, r2, up)) in self.ups.iter().enumerate() {
            let skip = skips[skips.len() - 1 - j].clone();
            h = Tensor::cat(vec![h, skip], 1);
            h = r2.fwd(p, r1.fwd(p, h, &emb), &emb);
            h = up.fwd(p, h);
        }
        let h = Tensor::cat(vec![h, skips[0].clone()], 1);
        let h = self.top.1.fwd(p, self.top.0.fwd(p, h, &emb), &emb);
        let h = mish(self.final_norm.fwd(p, self.final_conv.fwd(p, h)));
        let h = self.out.fwd(p, h);
        h.narrow(2, 0, tt).swap_dims(1, 2)
    }

    /// Emit the graph from inputs `x, t, context, cond_mask` to the output `eps`.
    pub(crate) fn emit(&self, g: &mut Graph, ps: &ParamStore) {
        let freqs = g.f32("time_freqs", &[1, self.freqs.len()], &self.freqs);
        let t1 = g.unsqueeze("t", &[1]);
        let arg = g.node("Mul", &[&t1, &freqs], vec![]);
        let s = g.node("Sin", &[&arg], vec![]);
        let c = g.node("Cos", &[&arg], vec![]);
        let temb = g.node("Concat", &[&s, &c], vec![Attr::Int("axis", 1)]);
        let ce = self.ctx.emit(g, ps, "context");
        let ce = g.node("Mish", &[&ce], vec![]);
        let m1 = g.unsqueeze("cond_mask", &[1]);
        let ce = g.node("Mul", &[&ce, &m1], vec![]);
        let mut parts = vec![temb, ce];
        if let Some(start) = &self.start {
            let (st, en) = (g.i64(&[0, 0]), g.i64(&[1, self.dims.state_dim as i64]));
            let ax = g.i64(&[1, 2]);
            let s0 = g.node("Slice", &["x", &st, &en, &ax], vec![]);
            let s0 = g.node("Flatten", &[&s0], vec![Attr::Int("axis", 1)]);
            let se = start.emit(g, ps, &s0);
            parts.push(g.node("Mish", &[&se], vec![]));
        }
        let refs: Vec<&str> = parts.iter().map(String::as_str).collect();
        let cat = g.node("Concat", &refs, vec![Attr::Int("axis", 1)]);
        let emb = self.emb.emit(g, ps, &cat);
        let emb = g.node("Mish", &[&emb], vec![]);

        let tt = self.dims.horizon;
        let mut h = g.node("Transpose", &["x"], vec![Attr::Ints("perm", vec![0, 2, 1])]);
        if self.padded > tt {
            let pads = g.i64(&[0, 0, 0, 0, 0, (self.padded - tt) as i64]);
            h = g.node("Pad", &[&h, &pads], vec![]);
        }
        let (mut h, skips) = self.enc.emit(g, ps, &h, &emb);
        for (j, (r1, r2, up)) in self.ups.iter().enumerate() {
            let skip = &skips[skips.len() - 1 - j];
            let cat = g.node("Concat", &[&h, skip], vec![Attr::Int("axis", 1)]);
            let r = r1.emit(g, ps, &cat, &emb);
            let r = r2.emit(g, ps, &r, &emb);
            h = up.emit(g, ps, &r);
        }
        let cat = g.node("Concat", &[&h, &skips[0]], vec![Attr::Int("axis", 1)]);
        let h = self.top.0.emit(g, ps, &cat, &emb);
        let h = self.top.1.emit(g, ps, &h, &emb);
        let h = self.final_conv.emit(g, ps, &h);
        let h = self.final_norm.emit(g, ps, &h);
        let h = g.node("Mish", &[&h], vec![]);
        let mut h = self.out.emit(g, ps, &h);
        if self.padded > tt {
            let (st, en, ax) = (g.i64(&[0]), g.i64(&[tt as i64]), g.i64(&[2]));
            h = g.node("Slice", &[&h, &st, &en, &ax], vec![]);
        }
        g.node_named(
            "Transpose",
            &[&h],
            vec![Attr::Ints("perm", vec![0, 2, 1])],
            "eps",
        );
    }

    /// The network's trajectory sizes.
    pub fn dims(&self) -> NetDims {
        self.dims
    }
}

/// The discriminator Ψ (outputs the logit; the export appends a Sigmoid).
#[derive(Debug, Clone)]
pub struct Discriminator {
    dims: NetDims,
    ctx: Linear,
    emb: Linear,
    enc: Encoder,
    head: Linear,
    last: usize,
}

impl Discriminator {
    /// Register the parameters in `ps` (initialised from `rng`) and build the network.
    pub fn new(ps: &mut ParamStore, dims: NetDims, net: &NetSettings, rng: &mut KernelRng) -> Self {
        let c = net.context_embed_dim;
        let ctx = Linear::new(ps, "context", dims.fingers, c, rng);
        let emb = Linear::new(ps, "embed", c, net.embed_dim, rng);
        let enc = Encoder::new(ps, dims.dim, net, rng);
        let last = net.widths[net.stages() - 1];
        let head = Linear::new(ps, "head", last, 1, rng);
        Self {
            dims,
            ctx,
            emb,
            enc,
            head,
            last,
        }
    }

    /// The logit `[B,1]` of `x [B,T,D]` (normalised, clean) with `context [B,F]`.
    pub fn logit(&self, p: P<'_>, x: Tensor<3>, context: Tensor<2>) -> Tensor<2> {
        let [b, _, _] = x.dims();
        let e = mish(self.ctx.fwd(p, context));
        let emb = mish(self.emb.fwd(p, e));
        let (h, _) = self.enc.fwd(p, x.swap_dims(1, 2), &emb);
        let pooled = h.mean_dim(2).reshape([b, self.last]);
        self.head.fwd(p, pooled)
    }

    /// Emit the graph from inputs `x, context` to the output `p_real`.
    pub(crate) fn emit(&self, g: &mut Graph, ps: &ParamStore) {
        let e = self.ctx.emit(g, ps, "context");
        let e = g.node("Mish", &[&e], vec![]);
        let emb = self.emb.emit(g, ps, &e);
        let emb = g.node("Mish", &[&emb], vec![]);
        let h = g.node("Transpose", &["x"], vec![Attr::Ints("perm", vec![0, 2, 1])]);
        let (h, _) = self.enc.emit(g, ps, &h, &emb);
        let axes = g.i64(&[2]);
        let pooled = g.node("ReduceMean", &[&h, &axes], vec![Attr::Int("keepdims", 0)]);
        let z = self.head.emit(g, ps, &pooled);
        g.node_named("Sigmoid", &[&z], vec![], "p_real");
    }

    /// The network's trajectory sizes.
    pub fn dims(&self) -> NetDims {
        self.dims
    }
}

/// A device-independent helper: a `[n, ...]` float tensor from a flat vector.
pub(crate) fn tensor<const D: usize>(v: Vec<f32>, shape: [usize; D], dev: &Device) -> Tensor<D> {
    Tensor::<D>::from_data(TensorData::new(v, shape), dev)
}
