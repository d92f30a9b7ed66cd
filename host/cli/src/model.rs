//! `dips model check|run|lower`: validate, run and lower contract-v1 ONNX models.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::{Args, Subcommand, ValueEnum};
use dips_onnx::io_json::{JsonTensor, TensorFile};
use dips_onnx::{AnyEngine, EngineKind, Expectation, contract, lower_file};

/// Arguments of `dips model`.
#[derive(Debug, Args)]
pub struct ModelArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: ModelCommand,
}

/// `dips model` subcommands.
#[derive(Debug, Subcommand)]
pub enum ModelCommand {
    /// Validate the contract and print a JSON summary.
    Check {
        /// The `.onnx` file.
        file: PathBuf,
    },
    /// Run a model on inputs in the fixtures' JSON shape.
    Run {
        /// The `.onnx` file.
        file: PathBuf,
        /// `{"inputs": {name: {"shape": [..], "data": [..]}}}`.
        #[arg(long)]
        input: PathBuf,
        /// Where to write `{"outputs": {...}}`.
        #[arg(long)]
        output: PathBuf,
        /// Which engine runs it.
        #[arg(long, value_parser = crate::search_args::named::<EngineKind>(), default_value = "tract")]
        engine: EngineKind,
    },
    /// Measure trained models on their held-out demos: coherence of diffused trajectories
    /// beside real ones, open-loop executions; writes `quality.json` into the models directory.
    Quality(crate::model_quality::QualityArgs),
    /// Write `MODEL_CARD.md` from `train_report.json` and `quality.json`.
    Card(crate::model_quality::CardArgs),
    /// Lower to the kernel blob.
    Lower {
        /// The `.onnx` file.
        file: PathBuf,
        /// The `.dipsm` to write.
        #[arg(long)]
        out: PathBuf,
    },
}

/// Which copies of the kernel interpreter's op kernels run (`--simd`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum SimdArg {
    /// The AVX2 copies where the CPU has AVX2, the baseline copies elsewhere.
    #[default]
    Auto,
    /// The baseline copies (SSE2 on x86-64) only: to measure what AVX2 gains. The results
    /// are the same bit for bit.
    Baseline,
}

impl SimdArg {
    /// Set it for the whole process; the name of the copies in use (`avx2` or `baseline`).
    pub fn apply(self) -> &'static str {
        dips_kernel::nn::ops::cpu::allow_wide(self == SimdArg::Auto);
        if dips_kernel::nn::ops::cpu::wide_in_use() {
            "avx2"
        } else {
            "baseline"
        }
    }
}

/// The threads of a model call from `--threads` (default: every core); 0 is refused.
pub fn threads(given: Option<usize>) -> anyhow::Result<usize> {
    match given {
        Some(0) => anyhow::bail!("--threads must be at least 1"),
        Some(n) => Ok(n),
        None => Ok(dips_planning::default_threads()),
    }
}

/// Run `dips model`.
pub fn run(args: ModelArgs) -> anyhow::Result<()> {
    match args.command {
        ModelCommand::Quality(a) => crate::model_quality::run_quality(a)?,
        ModelCommand::Card(a) => crate::model_quality::run_card(a)?,
        ModelCommand::Check { file } => {
            let (proto, c) = contract::load_contract(&file)
                .with_context(|| format!("checking {}", file.display()))?;
            dips_onnx::lower::tensors::check_initializers_finite(&proto)?;
            let lowered = dips_onnx::lower_proto(&proto)
                .with_context(|| format!("lowering {}", file.display()))?;
            // What the trainer recorded beside the contract (absent: the model does not say).
            let trained = serde_json::json!({
                "card_goals": contract::card_goals(&proto)?,
                "psi_negatives": contract::psi_negatives(&proto)?,
            });
            let summary = serde_json::json!({
                "file": file.display().to_string(),
                "valid": true,
                "contract": c,
                "trained": trained,
                "inputs": c.role.input_names().iter().map(|n| {
                    let mut shape = vec![serde_json::json!("batch")];
                    shape.extend(c.input_shape(n).unwrap_or_default().into_iter().map(serde_json::Value::from));
                    (n.to_string(), serde_json::Value::from(shape))
                }).collect::<serde_json::Map<_, _>>(),
                "output": c.role.output_name(),
                "kernel": {
                    "ops": lowered.n_ops,
                    "weights": lowered.n_weights,
                    "arena_floats_per_sample": lowered.arena_per_sample,
                    "scratch_floats": lowered.temp_len,
                    "blob_bytes": lowered.blob.len(),
                },
            });
            crate::output::line(&serde_json::to_string_pretty(&summary)?)?;
        }
        ModelCommand::Run {
            file,
            input,
            output,
            engine,
        } => {
            let mut e = AnyEngine::load(engine, &file, &Expectation::default())
                .with_context(|| format!("loading {}", file.display()))?;
            let c = e.contract().clone();
            let io = TensorFile::read(&input)?;
            let (batch, ins) = io.contract_inputs(&c)?;
            let mut shape = vec![batch];
            shape.extend(c.output_shape());
            let mut out = vec![0.0; shape.iter().product()];
            e.run(batch, &ins, &mut out)?;
            let mut f = TensorFile::default();
            f.outputs.insert(
                c.role.output_name().to_string(),
                JsonTensor { shape, data: out },
            );
            f.write(&output)?;
            crate::note!("wrote {}", output.display());
        }
        ModelCommand::Lower { file, out } => {
            if out.extension().and_then(|e| e.to_str()) != Some("dipsm") {
                bail!(
                    "the kernel blob should be named *.dipsm, got {}",
                    out.display()
                );
            }
            let l = lower_file(&file, &Expectation::default())
                .with_context(|| format!("lowering {}", file.display()))?;
            l.write(&out)?;
            crate::output::line(&format!(
                "{}",
                serde_json::json!({"out": out.display().to_string(), "bytes": l.blob.len(), "ops": l.n_ops, "weights": l.n_weights})
            ))?;
        }
    }
    Ok(())
}
