//! Model swap: engines take model paths at run time; two models load one after the other in
//! one process and each gives its own outputs; a model for the wrong task, role or contract
//! is refused with a message naming the mismatch.

mod common;

use common::{assert_agree, fixture, tiled};
use dips_kernel::engine::{DenoiserEngine, DiscriminatorEngine};
use dips_kernel::nn::engine::KernelEngine;
use dips_onnx::io_json::TensorFile;
use dips_onnx::{Expectation, KernelHostEngine, ModelError, Role, TractEngine, lower_file};

fn io(dir: &str, role: &str) -> TensorFile {
    TensorFile::read(&fixture(dir, &format!("{role}.io.json"))).unwrap()
}

#[test]
fn two_denoisers_in_one_process_each_give_their_own_outputs() {
    for dir in [
        "torch-screwdriver-legacy",
        "torch-card-dynamo",
        "torch-screwdriver-legacy",
    ] {
        let path = fixture(dir, "denoiser.onnx");
        let task = if dir.contains("card") {
            "card"
        } else {
            "screwdriver"
        };
        let expected = Expectation::new(Role::Denoiser, task);
        let f = io(dir, "denoiser");
        let mut tract = TractEngine::load(&path, &expected).unwrap();
        let mut kernel = KernelHostEngine::load_onnx(&path, &expected).unwrap();
        let (batch, ins, want) = tiled(tract.contract(), &f, 1);
        let mut out = vec![0.0; want.len()];
        tract
            .predict_eps(batch, &ins[0], &ins[1], &ins[2], &ins[3], &mut out)
            .unwrap();
        assert_agree(&out, &want, &format!("tract {dir}"));
        kernel
            .predict_eps(batch, &ins[0], &ins[1], &ins[2], &ins[3], &mut out)
            .unwrap();
        assert_agree(&out, &want, &format!("kernel {dir}"));
        assert_eq!(
            DenoiserEngine::dims(&kernel).horizon,
            if task == "card" { 9 } else { 13 }
        );
    }
}

#[test]
fn no_std_kernel_engine_swaps_blobs_in_caller_memory() {
    let mut mem = vec![0.0f32; 1 << 20];
    for dir in ["torch-card-dynamo", "torch-screwdriver-legacy"] {
        let lowered =
            lower_file(&fixture(dir, "discriminator.onnx"), &Expectation::default()).unwrap();
        let f = io(dir, "discriminator");
        let (batch, ins, want) = tiled(&lowered.contract, &f, 1);
        let mut e = KernelEngine::new(&lowered.blob, &mut mem).unwrap();
        assert!(DiscriminatorEngine::max_batch(&e) >= 3);
        assert_eq!(
            DiscriminatorEngine::normalization(&e).mean,
            lowered.contract.norm_mean.as_slice()
        );
        let mut out = vec![0.0; want.len()];
        e.p_real(batch, &ins[0], &ins[1], &mut out).unwrap();
        assert_agree(&out, &want, &format!("no_std kernel engine {dir}"));
        let mut eps = vec![0.0; 3 * 13 * 37];
        assert!(
            e.predict_eps(3, &ins[0], &[0.0; 3], &ins[1], &[1.0; 3], &mut eps)
                .is_err(),
            "role is checked"
        );
    }
}

#[test]
fn a_written_blob_carries_its_contract_and_is_refused_for_another_task() {
    let lowered = lower_file(
        &fixture("torch-screwdriver-legacy", "denoiser.onnx"),
        &Expectation::default(),
    )
    .unwrap();
    assert_eq!(
        dips_onnx::Contract::from_blob(&lowered.blob).unwrap(),
        lowered.contract
    );
    let dir = std::env::temp_dir().join(format!("dips-onnx-swap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("screwdriver-denoiser.dipsm");
    lowered.write(&path).unwrap();
    let mut e =
        KernelHostEngine::load(&path, &Expectation::new(Role::Denoiser, "screwdriver")).unwrap();
    let f = io("torch-screwdriver-legacy", "denoiser");
    let (batch, ins, want) = tiled(e.contract(), &f, 1);
    let mut out = vec![0.0; want.len()];
    e.predict_eps(batch, &ins[0], &ins[1], &ins[2], &ins[3], &mut out)
        .unwrap();
    assert_agree(&out, &want, "kernel from .dipsm");
    let err = KernelHostEngine::load(&path, &Expectation::new(Role::Denoiser, "card")).unwrap_err();
    assert!(matches!(err, ModelError::Mismatch(_)), "{err}");
}

#[test]
fn wrong_task_or_role_is_refused_with_the_mismatch_named() {
    let card = fixture("torch-card-dynamo", "denoiser.onnx");
    let want_screw = Expectation::new(Role::Denoiser, "screwdriver");
    for err in [
        TractEngine::load(&card, &want_screw).unwrap_err(),
        KernelHostEngine::load_onnx(&card, &want_screw).unwrap_err(),
    ] {
        assert!(matches!(err, ModelError::Mismatch(_)), "{err}");
        let msg = err.to_string();
        assert!(msg.contains("screwdriver") && msg.contains("card"), "{msg}");
    }
    let err = TractEngine::load(&card, &Expectation::new(Role::Discriminator, "card")).unwrap_err();
    assert!(
        err.to_string().contains("discriminator") && err.to_string().contains("denoiser"),
        "{err}"
    );
}

#[test]
fn a_batch_split_over_threads_gives_the_same_bits() {
    for dir in ["torch-card-dynamo", "torch-screwdriver-legacy"] {
        for role in ["denoiser", "discriminator"] {
            let path = fixture(dir, &format!("{role}.onnx"));
            let mut e = KernelHostEngine::load_onnx(&path, &Expectation::default()).unwrap();
            let f = io(dir, role);
            // Enough samples for three threads, and a batch that does not divide evenly.
            let (batch, ins, want) = tiled(e.contract(), &f, 7);
            assert!(batch >= 12, "batch {batch}");
            let refs: Vec<&[f32]> = ins.iter().map(Vec::as_slice).collect();
            let mut one = vec![0.0; want.len()];
            e.run(batch, &refs, &mut one).unwrap();
            assert_agree(&one, &want, &format!("{dir} {role}, one thread"));
            for threads in [2, 3, 64] {
                e.set_threads(threads);
                let mut many = vec![f32::NAN; want.len()];
                e.run(batch, &refs, &mut many).unwrap();
                assert!(
                    one.iter()
                        .zip(&many)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{dir} {role}: {threads} threads differ from one"
                );
            }
        }
    }
}
