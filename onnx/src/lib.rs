//! `dips-onnx`: the DIPS model contract v1 (`docs/contracts.md` §3), the two engines that run such
//! models (tract on the host, the `dips-kernel` interpreter on a lowered blob) and the lowering
//! from ONNX to the kernel blob.

pub mod contract;
pub mod engine;
pub mod error;
pub mod io_json;
pub mod kernel_engine;
pub mod lower;
pub mod tasks;
pub mod tract_engine;

pub use contract::{Contract, Expectation, Role};
pub use engine::{AnyEngine, EngineKind};
pub use error::{ModelError, Result};
pub use kernel_engine::KernelHostEngine;
pub use lower::{LoweredModel, lower_file, lower_proto};
pub use tract_engine::TractEngine;
