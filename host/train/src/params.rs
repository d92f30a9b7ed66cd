//! Parameters live in host memory (`Vec<f32>` per tensor), outside burn: initialisation from
//! our own seeded generator, Adam and EMA in plain `f32` loops, and checkpoints as
//! safetensors. burn only sees them as leaf tensors for one forward/backward pass. This keeps
//! every bit of the training state in our hands: a resumed run equals an uninterrupted one.

use std::collections::HashMap;
use std::path::Path;

use burn::tensor::{Device, Tensor, TensorData};
use dips_kernel::rng::KernelRng;
use safetensors::{Dtype, SafeTensors, tensor::TensorView};

use crate::error::{Result, TrainError, io_err};

/// Named parameter tensors in registration order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParamStore {
    /// Names (unique).
    pub names: Vec<String>,
    /// Shapes.
    pub shapes: Vec<Vec<usize>>,
    /// Values, row-major.
    pub data: Vec<Vec<f32>>,
}

impl ParamStore {
    /// Register a tensor initialised uniformly in `[−bound, bound]`; returns its index.
    pub fn uniform(
        &mut self,
        name: String,
        shape: Vec<usize>,
        bound: f32,
        rng: &mut KernelRng,
    ) -> usize {
        let n = shape.iter().product();
        let v = (0..n)
            .map(|_| (rng.uniform_f32() * 2.0 - 1.0) * bound)
            .collect();
        self.push(name, shape, v)
    }

    /// Register a tensor filled with `value`; returns its index.
    pub fn constant(&mut self, name: String, shape: Vec<usize>, value: f32) -> usize {
        let n = shape.iter().product();
        self.push(name, shape, vec![value; n])
    }

    fn push(&mut self, name: String, shape: Vec<usize>, v: Vec<f32>) -> usize {
        self.names.push(name);
        self.shapes.push(shape);
        self.data.push(v);
        self.data.len() - 1
    }

    /// Total number of scalars.
    pub fn count(&self) -> usize {
        self.data.iter().map(Vec::len).sum()
    }

    /// The parameters as flat leaf tensors on `device` (with gradients when `grad`).
    pub fn tensors(&self, device: &Device, grad: bool) -> Vec<Tensor<1>> {
        self.data
            .iter()
            .map(|v| {
                let t = Tensor::<1>::from_data(TensorData::new(v.clone(), [v.len()]), device);
                if grad { t.require_grad() } else { t }
            })
            .collect()
    }
}

/// Read a burn tensor back as `f32`s.
pub fn to_vec<const D: usize>(t: Tensor<D>) -> Result<Vec<f32>> {
    t.into_data()
        .try_into_vec::<f32>()
        .map_err(|e| TrainError::Backend(format!("{e:?}")))
}

/// Adam (β₁ 0.9, β₂ 0.999, ε 1e-8, bias-corrected) over a [`ParamStore`], plus the EMA copy.
#[derive(Debug, Clone, PartialEq)]
pub struct OptimState {
    /// Optimiser steps taken.
    pub step: usize,
    /// First moments.
    pub m: Vec<Vec<f32>>,
    /// Second moments.
    pub v: Vec<Vec<f32>>,
    /// EMA of the parameters.
    pub ema: Vec<Vec<f32>>,
}

const BETA1: f32 = 0.9;
const BETA2: f32 = 0.999;
const ADAM_EPS: f32 = 1e-8;

impl OptimState {
    /// Fresh state for `params` (moments zero, EMA a copy).
    pub fn new(params: &ParamStore) -> Self {
        let zeros: Vec<Vec<f32>> = params.data.iter().map(|v| vec![0.0; v.len()]).collect();
        Self {
            step: 0,
            m: zeros.clone(),
            v: zeros,
            ema: params.data.clone(),
        }
    }

    /// One Adam step with learning rate `lr`; a missing gradient counts as zero.
    pub fn adam(&mut self, params: &mut ParamStore, grads: &[Option<Vec<f32>>], lr: f64) {
        self.step += 1;
        let t = self.step as i32;
        let bc1 = 1.0 - BETA1.powi(t);
        let bc2 = 1.0 - BETA2.powi(t);
        let lr = lr as f32;
        for (i, p) in params.data.iter_mut().enumerate() {
            let Some(g) = grads.get(i).and_then(Option::as_ref) else {
                continue;
            };
            let (m, v) = (&mut self.m[i], &mut self.v[i]);
            for j in 0..p.len() {
                let gj = g[j];
                m[j] = BETA1 * m[j] + (1.0 - BETA1) * gj;
                v[j] = BETA2 * v[j] + (1.0 - BETA2) * gj * gj;
                let mh = m[j] / bc1;
                let vh = v[j] / bc2;
                p[j] -= lr * mh / (vh.sqrt() + ADAM_EPS);
            }
        }
    }

    /// The EMA rule of the DIPS code, called after every optimiser step: every `every` steps,
    /// copy the parameters while `step < warmup`, otherwise `ema ← decay·ema + (1−decay)·p`.
    pub fn ema_update(&mut self, params: &ParamStore, decay: f32, every: usize, warmup: usize) {
        if !self.step.is_multiple_of(every.max(1)) {
            return;
        }
        if self.step < warmup {
            self.ema.clone_from(&params.data);
            return;
        }
        for (e, p) in self.ema.iter_mut().zip(&params.data) {
            for (a, b) in e.iter_mut().zip(p) {
                *a = decay * *a + (1.0 - decay) * b;
            }
        }
    }
}

/// A checkpoint: parameters, optimiser state and the metadata needed to check that a resumed
/// run is the same run (`settings` JSON, data fingerprint). The random streams are functions of
/// `(seed, step)`, so the step is the whole generator state.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    /// Parameters.
    pub params: ParamStore,
    /// Optimiser and EMA.
    pub optim: OptimState,
    /// Free-form string metadata (settings, fingerprint, ...).
    pub meta: HashMap<String, String>,
}

impl Checkpoint {
    /// Write atomically to `path`.
    pub fn save(&self, path: &Path) -> Result<()> {
        let bytes: Vec<(String, Vec<usize>, Vec<u8>)> = self
            .params
            .names
            .iter()
            .enumerate()
            .flat_map(|(i, n)| {
                let s = &self.params.shapes[i];
                [
                    (
                        format!("param/{n}"),
                        s.clone(),
                        dips_dataset::f32_bytes(&self.params.data[i]),
                    ),
                    (
                        format!("adam_m/{n}"),
                        s.clone(),
                        dips_dataset::f32_bytes(&self.optim.m[i]),
                    ),
                    (
                        format!("adam_v/{n}"),
                        s.clone(),
                        dips_dataset::f32_bytes(&self.optim.v[i]),
                    ),
                    (
                        format!("ema/{n}"),
                        s.clone(),
                        dips_dataset::f32_bytes(&self.optim.ema[i]),
                    ),
                ]
            })
            .collect();
        let ck = |reason: String| TrainError::Checkpoint {
            path: path.to_path_buf(),
            reason,
        };
        let mut views = Vec::with_capacity(bytes.len());
        for (name, shape, b) in &bytes {
            let shape = if shape.is_empty() {
                vec![1]
            } else {
                shape.clone()
            };
            views.push((
                name.clone(),
                TensorView::new(Dtype::F32, shape, b).map_err(|e| ck(e.to_string()))?,
            ));
        }
        let mut meta = self.meta.clone();
        meta.insert("step".into(), self.optim.step.to_string());
        meta.insert(
            "param_names".into(),
            serde_json::to_string(&self.params.names).map_err(|e| ck(e.to_string()))?,
        );
        let buf = safetensors::serialize(views, Some(meta)).map_err(|e| ck(e.to_string()))?;
        dips_fs::write_atomic(path, &buf).map_err(io_err(path))
    }

    /// Read a checkpoint whose parameters must have the names and shapes of `template`.
    pub fn load(path: &Path, template: &ParamStore) -> Result<Self> {
        let ck = |reason: String| TrainError::Checkpoint {
            path: path.to_path_buf(),
            reason,
        };
        let buf = std::fs::read(path).map_err(io_err(path))?;
        let (_, md) = SafeTensors::read_metadata(&buf).map_err(|e| ck(e.to_string()))?;
        let st = SafeTensors::deserialize(&buf).map_err(|e| ck(e.to_string()))?;
        let meta = md.metadata().clone().unwrap_or_default();
        let step: usize = meta
            .get("step")
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| ck("no step in the metadata".into()))?;
        let read = |name: &str, len: usize| -> Result<Vec<f32>> {
            let v = st
                .tensor(name)
                .map_err(|_| ck(format!("tensor {name:?} is missing")))?;
            if v.dtype() != Dtype::F32 || v.data().len() != len * 4 {
                return Err(ck(format!(
                    "tensor {name:?} is not {len} float32s (the network differs)"
                )));
            }
            Ok(v.data()
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect())
        };
        let mut params = template.clone();
        let mut optim = OptimState::new(template);
        optim.step = step;
        for (i, n) in template.names.iter().enumerate() {
            let len = template.data[i].len();
            params.data[i] = read(&format!("param/{n}"), len)?;
            optim.m[i] = read(&format!("adam_m/{n}"), len)?;
            optim.v[i] = read(&format!("adam_v/{n}"), len)?;
            optim.ema[i] = read(&format!("ema/{n}"), len)?;
        }
        if st.len() != 4 * template.names.len() {
            return Err(ck(format!(
                "holds {} tensors, the network has {}",
                st.len(),
                4 * template.names.len()
            )));
        }
        Ok(Self {
            params,
            optim,
            meta,
        })
    }
}
