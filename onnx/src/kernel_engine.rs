//! The kernel engine on the host: a lowered blob run by the no_std interpreter of
//! `dips-kernel`, with memory grown to the largest batch asked for.

use std::path::Path;

use dips_kernel::nn::model::{ModelInfo, install, parse, run};

use crate::contract::{Contract, Expectation, Role};
use crate::error::{ModelError, Result};
use crate::lower::{LoweredModel, lower_file};
use crate::tract_engine::check_call;

/// The most memory (floats) a host kernel engine allocates: 1 GiB. A blob or a batch asking for
/// more is refused instead of aborting the process on a failed allocation.
pub const MAX_MEMORY_FLOATS: usize = 1 << 28;

fn memory(info: &ModelInfo, batch: usize) -> Result<Vec<f32>> {
    match info.memory_len(batch) {
        Some(len) if len <= MAX_MEMORY_FLOATS => Ok(vec![0.0; len]),
        _ => Err(ModelError::BadInput {
            name: "batch".into(),
            reason: format!(
                "batch {batch} needs more than {MAX_MEMORY_FLOATS} floats of kernel memory ({} per sample)",
                info.arena_per_sample
            ),
        }),
    }
}

/// A contract-v1 model run by the kernel interpreter.
///
/// With [`KernelHostEngine::set_threads`] above 1, a call's batch is split into that many
/// contiguous parts run side by side, each in its own memory. Every sample is computed by the
/// same instructions whatever its batch, so the outputs are the same bits as one thread's
/// (tested).
#[derive(Debug)]
pub struct KernelHostEngine {
    contract: Contract,
    blob: Vec<u8>,
    info: ModelInfo,
    /// One memory per thread (the first is the single-thread one).
    mems: Vec<Vec<f32>>,
    threads: usize,
}

/// The smallest number of samples a thread is given: below it, a thread's start costs more
/// than it saves.
const MIN_SAMPLES_PER_THREAD: usize = 4;

impl KernelHostEngine {
    /// Lower an `.onnx` file (validated against `expected`) and load the blob.
    pub fn load_onnx(path: &Path, expected: &Expectation) -> Result<Self> {
        Self::from_lowered(lower_file(path, expected)?)
    }

    /// Load a `.dipsm` blob (validated against `expected`).
    pub fn load_blob(path: &Path, expected: &Expectation) -> Result<Self> {
        let blob = std::fs::read(path).map_err(|source| ModelError::Io {
            action: "read kernel blob",
            path: path.to_path_buf(),
            cause: source,
        })?;
        let contract = Contract::from_blob(&blob)?;
        contract.expect(expected)?;
        Self::new(contract, blob)
    }

    /// Load a model file: a `.dipsm` blob as it is, anything else as ONNX to lower.
    pub fn load(path: &Path, expected: &Expectation) -> Result<Self> {
        if path.extension().is_some_and(|e| e == "dipsm") {
            Self::load_blob(path, expected)
        } else {
            Self::load_onnx(path, expected)
        }
    }

    /// Load a lowered model.
    pub fn from_lowered(l: LoweredModel) -> Result<Self> {
        Self::new(l.contract, l.blob)
    }

    /// Load blob bytes whose contract the caller already knows (checked against the blob).
    pub fn new(contract: Contract, blob: Vec<u8>) -> Result<Self> {
        let info = parse(&blob)?;
        if info.dims != contract.dims() || (info.role == 0) != (contract.role == Role::Denoiser) {
            return Err(ModelError::Mismatch(
                "the blob's metadata does not match the contract".into(),
            ));
        }
        let mut mem = memory(&info, 1)?;
        install(&info, &blob, &mut mem)?;
        Ok(KernelHostEngine {
            contract,
            blob,
            info,
            mems: vec![mem],
            threads: 1,
        })
    }

    /// Run each call on up to `threads` threads (at least 1; the default is 1).
    pub fn set_threads(&mut self, threads: usize) {
        self.threads = threads.max(1);
    }

    /// Threads a call may use.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// The model's contract.
    pub fn contract(&self) -> &Contract {
        &self.contract
    }

    /// Facts about the blob.
    pub fn info(&self) -> &ModelInfo {
        &self.info
    }

    /// Run on contract inputs in contract order.
    pub fn run(&mut self, batch: usize, inputs: &[&[f32]], output: &mut [f32]) -> Result<()> {
        check_call(&self.contract, batch, inputs, output)?;
        let parts = self.threads.min(batch / MIN_SAMPLES_PER_THREAD).max(1);
        let per = batch.div_ceil(parts);
        while self.mems.len() < parts {
            self.mems.push(Vec::new());
        }
        for mem in &mut self.mems[..parts] {
            if per > self.info.max_batch(mem.len()) {
                *mem = memory(&self.info, per)?;
                install(&self.info, &self.blob, mem)?;
            }
        }
        if parts == 1 {
            run(
                &self.info,
                &self.blob,
                &mut self.mems[0],
                batch,
                inputs,
                output,
            )?;
            return Ok(());
        }
        // Contiguous parts of `per` samples (the last one shorter); every input and the
        // output are `batch` equal rows.
        let (info, blob) = (&self.info, &self.blob[..]);
        let out_row = output.len() / batch;
        std::thread::scope(|scope| {
            let mut handles = Vec::with_capacity(parts);
            let mut out_rest = &mut output[..];
            for (p, mem) in self.mems[..parts].iter_mut().enumerate() {
                let lo = p * per;
                let n = per.min(batch - lo);
                let (out, rest) = out_rest.split_at_mut(n * out_row);
                out_rest = rest;
                let part: Vec<&[f32]> = inputs
                    .iter()
                    .map(|x| {
                        let row = x.len() / batch;
                        &x[lo * row..(lo + n) * row]
                    })
                    .collect();
                handles.push(scope.spawn(move || run(info, blob, mem, n, &part, out)));
            }
            handles.into_iter().try_for_each(|h| match h.join() {
                Ok(r) => r.map_err(ModelError::from),
                Err(_) => Err(ModelError::Mismatch(
                    "a kernel-engine thread panicked".into(),
                )),
            })
        })
    }
}

crate::engine::impl_engine_traits!(KernelHostEngine);
