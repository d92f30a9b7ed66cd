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
#[derive(Debug)]
pub struct KernelHostEngine {
    contract: Contract,
    blob: Vec<u8>,
    info: ModelInfo,
    mem: Vec<f32>,
}

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
            mem,
        })
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
        if batch > self.info.max_batch(self.mem.len()) {
            self.mem = memory(&self.info, batch)?;
            install(&self.info, &self.blob, &mut self.mem)?;
        }
        run(&self.info, &self.blob, &mut self.mem, batch, inputs, output)?;
        Ok(())
    }
}

crate::engine::impl_engine_traits!(KernelHostEngine);
