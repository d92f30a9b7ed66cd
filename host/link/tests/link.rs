//! The link's failures name the request and never hang; a remote planner plans bit for bit as
//! the in-process session does and uploads only the models the kernel lacks.

use std::path::{Path, PathBuf};
use std::time::Duration;

use dips_exec::problems::contract::contract_state;
use dips_firmware_sim::{FirmwareMemory, serve};
use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::Task;
use dips_kernel::search::SearchConfig;
use dips_kernel::session::PlanSpec;
use dips_link::{Link, LinkError, RemotePlanner, Timeouts};
use dips_onnx::EngineKind;
use dips_planning::{Models, PaperSession, PlanOutcome, PlanService};
use dips_wire::{Hello, ToKernel};
use dips_world::scenes::SceneKind;
use dips_world::world::World;

fn models_dir(task: Task) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../onnx/models")
        .join(task.name())
}

fn short(reply: Duration) -> Timeouts {
    Timeouts {
        reply,
        ..Timeouts::default()
    }
}

#[test]
fn a_kernel_that_never_answers_is_a_timeout_naming_the_request() {
    let (reader, writer_kept) = std::io::pipe().unwrap();
    let mut link = Link::over("silent test peer", reader, std::io::sink());
    link.set_timeouts(short(Duration::from_millis(200)));
    let t0 = std::time::Instant::now();
    let err = link
        .request(&ToKernel::Hello(Hello::current()), link.timeouts().reply)
        .unwrap_err();
    assert!(t0.elapsed() < Duration::from_secs(5));
    assert!(matches!(err, LinkError::Timeout { id: 1, .. }), "{err}");
    let text = err.to_string();
    assert!(
        text.contains("Hello (request 1)") && text.contains("silent test peer"),
        "{text}"
    );
    drop(writer_kept);
}

#[test]
fn a_kernel_that_exits_is_a_closed_link_with_its_status_and_stderr() {
    let mut link = Link::spawn(
        Path::new("sh"),
        &[
            "-c".into(),
            "echo 'firmware: out of memory' >&2; exit 3".into(),
        ],
    )
    .unwrap();
    let err = link
        .request(&ToKernel::Status, Duration::from_secs(10))
        .unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, LinkError::Closed { .. }), "{text}");
    assert!(text.contains("Status (request 1)"), "{text}");
    assert!(text.contains("exit status: 3"), "{text}");
    assert!(text.contains("firmware: out of memory"), "{text}");
    // Every later request fails at once the same way.
    let again = link
        .request(&ToKernel::Cancel, Duration::from_secs(10))
        .unwrap_err();
    assert!(again.to_string().contains("Cancel (request 2)"), "{again}");
}

/// A card call from the task's start, fast settings, the shipped models' prior.
fn card_spec(models: &Models, seed: u64) -> PlanSpec {
    let task = Task::Card;
    let start: Vec<f32> = contract_state(&World::new(SceneKind::Card).state())
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let goal = PlanSpec::paper_goal(task, &start).unwrap();
    let mut spec = PlanSpec::new(task, &start, goal).unwrap();
    spec.search = SearchConfig {
        node_budget: 2,
        time_budget_ms: 0,
        seed,
        ..SearchConfig::for_task(task)
    };
    spec.sampler = "ddim:4:1".parse::<SamplerConfig>().unwrap();
    spec.prior = models.prior.expect("the shipped card models have a prior");
    spec.check().unwrap();
    spec
}

#[test]
fn a_remote_plan_is_the_in_process_plan_and_models_are_uploaded_once() {
    let dir = models_dir(Task::Card);
    let models = Models::load(EngineKind::Kernel, &dir, Task::Card).unwrap();
    let specs = [card_spec(&models, 4), card_spec(&models, 5)];
    let mut session = PaperSession::new(models);
    let local: Vec<PlanOutcome> = specs
        .iter()
        .map(|s| session.plan_call(s, &mut NoClock).unwrap())
        .collect();

    let mut memory = FirmwareMemory::planning(8 << 20, 8_000_000);
    let mut firmware = memory.firmware();
    // Two connections one after the other, as `--listen` serves them.
    for (round, spec) in specs.iter().enumerate() {
        let (to_kernel_r, to_kernel_w) = std::io::pipe().unwrap();
        let (from_kernel_r, from_kernel_w) = std::io::pipe().unwrap();
        std::thread::scope(|scope| {
            let fw = &mut firmware;
            let server = scope.spawn(move || {
                fw.reset_session();
                serve(fw, to_kernel_r, from_kernel_w).unwrap()
            });
            let link = Link::over("in-test firmware", from_kernel_r, to_kernel_w);
            let mut remote = RemotePlanner::new(link, &dir, Task::Card).unwrap();
            let got = remote.plan_call(spec, &mut NoClock).unwrap();
            assert_eq!(got, local[round], "round {round}");
            assert!(!got.modes.is_empty());
            // Uploaded on the first connection only: the firmware keeps its models.
            assert_eq!(remote.uploads(), if round == 0 { 2 } else { 0 });
            let status = remote.status().unwrap();
            assert_eq!(status.last_plan.unwrap().nodes_expanded, got.nodes_expanded);
            drop(remote);
            server.join().unwrap();
        });
    }
}
