//! Pre-registration (`dips_eval::protocol`): a protocol round-trips, a run that differs from
//! it in a setting or a model file is refused with what differs, an uncommitted protocol is
//! refused, a committed registration spends its range, and a rerun never writes into the
//! registered run's directory. No episode runs here (`host/cli/tests/protocol_cli.rs` runs one).

use std::path::{Path, PathBuf};
use std::process::Command;

use dips_batch::{ProgressMode, Shard};
use dips_eval::EvalSettings;
use dips_eval::protocol::{
    Protocol, ProtocolError, ProtocolFile, REGISTRATION_FILE, RegistrationStatus,
    claim_registration, sha256_bytes,
};
use dips_eval::settings::claim_dir;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::search::SearchOverrides;
use dips_onnx::EngineKind;
use dips_planning::online::{Method, OnlineSettings};
use dips_world::hand::{HandKind, TrackerNoise};
use dips_world::scenes::SceneKind;

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dips-protocol-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A models directory of stand-in files (only their bytes are hashed here).
fn fake_models(dir: &Path) -> PathBuf {
    let m = dir.join("models");
    std::fs::create_dir_all(m.join("policy")).unwrap();
    for (f, bytes) in [
        ("denoiser.onnx", "denoiser"),
        ("discriminator.onnx", "discriminator"),
        ("prior.json", "{}"),
        ("policy/denoiser.onnx", "policy"),
    ] {
        std::fs::write(m.join(f), bytes).unwrap();
    }
    m
}

fn settings(models: &Path, methods: Vec<Method>, first_seed: u64) -> EvalSettings {
    EvalSettings {
        task: SceneKind::Card,
        methods,
        trials: 3,
        first_seed,
        shard: Shard::ALL,
        jobs: 1,
        model_threads: 1,
        online: OnlineSettings {
            time_budget_s: 60.0,
            search: SearchOverrides {
                node_budget: Some(3),
                ..SearchOverrides::default()
            },
            sampler: "ddim:8".parse::<SamplerConfig>().unwrap(),
            sequence: None,
            max_modes: Some(1),
            search_depth: None,
            stop_rule: Default::default(),
            first_mode: Default::default(),
            planner_size: Default::default(),
        },
        models: models.to_path_buf(),
        engine: EngineKind::Kernel,
        progress: ProgressMode::Hidden,
        stop_after: None,
        kernel: dips_link::KernelTarget::InProcess,
        hand: Default::default(),
        tracker_noise: None,
        registration: None,
        card_goals: Default::default(),
        exec_profile: Default::default(),
        pose_estimate: Default::default(),
        regrasp_guard: Default::default(),
        press: Default::default(),
    }
}

/// `git ARGS` in `dir`, which must succeed.
fn git(dir: &Path, args: &[&str]) {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args([
            "-c",
            "user.name=dips test",
            "-c",
            "user.email=test@example.invalid",
            "-c",
            "commit.gpgsign=false",
        ])
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "git {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn repo(name: &str) -> PathBuf {
    let dir = scratch(name);
    git(&dir, &["init", "-q", "."]);
    dir
}

fn commit_all(dir: &Path, message: &str) {
    git(dir, &["add", "-A", "."]);
    git(dir, &["commit", "-q", "-m", message]);
}

#[test]
fn a_protocol_round_trips() {
    let dir = scratch("round-trip");
    let models = fake_models(&dir);
    let s = settings(&models, vec![Method::Dips, Method::DiffusionPolicy], 10000);
    let protocol = Protocol::new("card-10000", &s).unwrap();
    let keys: Vec<&str> = protocol.models.keys().map(String::as_str).collect();
    assert_eq!(
        keys,
        [
            "denoiser.onnx",
            "discriminator.onnx",
            "policy/denoiser.onnx",
            "prior.json"
        ]
    );
    assert_eq!(protocol.models["denoiser.onnx"], sha256_bytes(b"denoiser"));
    assert_eq!(protocol.eval, {
        let mut e = s.eval_file();
        e.episode.models = protocol.eval.episode.models.clone();
        e
    });

    let path = dir.join("protocols/card-10000.json");
    protocol.write(&path).unwrap();
    let read = ProtocolFile::read(&path).unwrap();
    assert_eq!(read.protocol, protocol);
    assert_eq!(read.sha256, sha256_bytes(&std::fs::read(&path).unwrap()));
    read.protocol.check_settings(&s).unwrap();
    read.protocol.check_models(&s).unwrap();
    assert!(matches!(
        protocol.write(&path),
        Err(ProtocolError::Exists(_))
    ));
    // Without models, nothing is hashed.
    let csvto = Protocol::new("c", &settings(&models, vec![Method::CsvtoSampled], 10000)).unwrap();
    assert!(csvto.models.is_empty());
}

#[test]
fn a_differing_setting_is_refused_with_its_name() {
    let dir = scratch("differs");
    let models = fake_models(&dir);
    let s = settings(&models, vec![Method::Dips], 10000);
    let protocol = Protocol::new("p", &s).unwrap();

    let mut other = settings(&models, vec![Method::Dips], 10000);
    other.online.sampler = "ddpm:16".parse::<SamplerConfig>().unwrap();
    let err = protocol.check_settings(&other).unwrap_err();
    assert!(
        matches!(&err, ProtocolError::Differs { setting, protocol, run }
            if setting == "episode.sampler" && protocol == "\"ddim:8\"" && run == "\"ddpm:16\""),
        "{err}"
    );
    assert_eq!(
        err.to_string(),
        "episode.sampler is \"ddim:8\" in the protocol and \"ddpm:16\" in this run"
    );

    let mut other = settings(&models, vec![Method::Dips], 10000);
    other.online.search.node_budget = Some(4);
    let err = protocol.check_settings(&other).unwrap_err().to_string();
    assert_eq!(
        err,
        "episode.node_budget is 3 in the protocol and 4 in this run"
    );

    let other = settings(&models, vec![Method::Dips], 10001);
    let err = protocol.check_settings(&other).unwrap_err().to_string();
    assert!(err.starts_with("first_seed is 10000"), "{err}");

    let other = settings(&models, vec![Method::Dips, Method::DipsK1], 10000);
    let err = protocol.check_settings(&other).unwrap_err().to_string();
    assert!(err.starts_with("methods is [\"dips\"]"), "{err}");

    let mut other = settings(&models, vec![Method::Dips], 10000);
    other.trials = 4;
    let err = protocol.check_settings(&other).unwrap_err().to_string();
    assert!(err.starts_with("trials is 3"), "{err}");

    // The same models elsewhere: the path is not a setting, the hashes are.
    let moved = scratch("differs-moved");
    let elsewhere = fake_models(&moved);
    let s2 = settings(&elsewhere, vec![Method::Dips], 10000);
    protocol.check_settings(&s2).unwrap();
    protocol.check_models(&s2).unwrap();
}

#[test]
fn a_model_hash_mismatch_is_refused_naming_the_file() {
    let dir = scratch("hash");
    let models = fake_models(&dir);
    let s = settings(&models, vec![Method::Dips], 10000);
    let protocol = Protocol::new("p", &s).unwrap();
    let expected = sha256_bytes(b"discriminator");

    std::fs::write(models.join("discriminator.onnx"), "retrained").unwrap();
    let err = protocol.check_models(&s).unwrap_err();
    match &err {
        ProtocolError::ModelHash {
            file,
            expected: e,
            found,
        } => {
            assert_eq!(file, &models.join("discriminator.onnx"));
            assert_eq!(e, &expected);
            assert_eq!(found, &sha256_bytes(b"retrained"));
        }
        other => panic!("expected a hash mismatch, got {other}"),
    }
    let text = err.to_string();
    assert!(text.contains("discriminator.onnx"), "{text}");
    assert!(text.contains(&expected), "{text}");
    assert!(text.contains(&sha256_bytes(b"retrained")), "{text}");

    std::fs::write(models.join("discriminator.onnx"), "discriminator").unwrap();
    protocol.check_models(&s).unwrap();
    std::fs::remove_file(models.join("prior.json")).unwrap();
    let err = protocol.check_models(&s).unwrap_err();
    assert!(
        matches!(&err, ProtocolError::ModelMissing { file, .. } if file.ends_with("prior.json")),
        "{err}"
    );
    // A protocol written without a prior refuses a run that reads one.
    let without = Protocol::new("p", &s).unwrap();
    std::fs::write(models.join("prior.json"), "{}").unwrap();
    let err = without.check_models(&s).unwrap_err();
    assert!(
        matches!(&err, ProtocolError::ModelNotInProtocol { file, .. } if file.ends_with("prior.json")),
        "{err}"
    );
}

#[test]
fn malformed_protocols_are_errors_not_panics() {
    let dir = scratch("malformed");
    let models = fake_models(&dir);
    let good = serde_json::to_value(
        Protocol::new("p", &settings(&models, vec![Method::Dips], 10000)).unwrap(),
    )
    .unwrap();
    let path = dir.join("p.json");
    let parse = |text: &str| Protocol::parse(text, &path);

    assert!(parse(&good.to_string()).is_ok());
    assert!(matches!(
        parse("{\"format\": 1,"),
        Err(ProtocolError::Json { .. })
    ));
    assert!(matches!(parse("[]"), Err(ProtocolError::Json { .. })));

    let edit = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut v = good.clone();
        f(&mut v);
        parse(&v.to_string()).unwrap_err().to_string()
    };
    let err = edit(&|v| {
        v["eval"]["episode"]
            .as_object_mut()
            .unwrap()
            .remove("cost_to_come");
    });
    assert!(
        err.contains("missing field `eval.episode.cost_to_come`"),
        "{err}"
    );
    let err = edit(&|v| {
        v.as_object_mut().unwrap().remove("models");
    });
    assert!(err.contains("models"), "{err}");
    let err = edit(&|v| v["eval"]["episode"]["smapler"] = "ddpm".into());
    assert!(
        err.contains("unknown field `eval.episode.smapler`"),
        "{err}"
    );
    let err = edit(&|v| v["spent"] = true.into());
    assert!(err.contains("spent"), "{err}");
    let err = edit(&|v| v["eval"]["methods"] = serde_json::json!(["dips", "dipz"]));
    assert!(
        err.contains("unknown method `dipz` (expected dips, "),
        "{err}"
    );
    let err = edit(&|v| v["eval"]["methods"] = serde_json::json!([]));
    assert!(err.contains("`eval.methods` is empty"), "{err}");
    let err = edit(&|v| v["eval"]["episode"]["task"] = "spoon".into());
    assert!(
        err.contains("unknown task `spoon` (expected screwdriver or card)"),
        "{err}"
    );
    let err = edit(&|v| v["eval"]["episode"]["sampler"] = "ddim".into());
    assert!(
        err.contains("unknown sampler `ddim`: expected `ddpm`"),
        "{err}"
    );
    let err = edit(&|v| v["eval"]["trials"] = 0.into());
    assert!(err.contains("eval.trials"), "{err}");
    let err = edit(&|v| v["models"]["denoiser.onnx"] = "abc".into());
    assert!(err.contains("not a sha256"), "{err}");
    let err = edit(&|v| v["format"] = 2.into());
    assert!(err.contains("format"), "{err}");

    std::fs::write(&path, [0xff, 0xfe, 0x00]).unwrap();
    assert!(ProtocolFile::read(&path).is_err());
    assert!(ProtocolFile::read(&dir.join("absent.json")).is_err());
}

#[test]
fn an_uncommitted_protocol_is_refused() {
    let dir = repo("uncommitted");
    let models = fake_models(&scratch("uncommitted-models"));
    let s = settings(&models, vec![Method::Dips], 10000);
    let path = dir.join("protocols/card.json");
    Protocol::new("card", &s).unwrap().write(&path).unwrap();
    let file = ProtocolFile::read(&path).unwrap();

    let refused = |why: &str| {
        let err = file.register(&s, false).unwrap_err();
        assert!(
            matches!(&err, ProtocolError::NotCommitted { why: w, .. } if w.contains(why)),
            "{err}"
        );
        assert!(err.to_string().contains("commit it"), "{err}");
    };
    refused("not tracked");
    git(&dir, &["add", "protocols/card.json"]);
    refused("not in HEAD");
    // The escape hatch labels the results.
    let r = file.register(&s, true).unwrap();
    assert_eq!(r.status, RegistrationStatus::Unregistered);

    git(&dir, &["commit", "-q", "-m", "register card"]);
    let r = file.register(&s, false).unwrap();
    assert_eq!(r.status, RegistrationStatus::Registered);
    assert_eq!(r.protocol_sha256, file.sha256);
    assert_eq!(r.stamp.dirty, Some(false));
    assert_eq!(r.stamp.commit.as_deref().map(str::len), Some(40));
    assert!(!r.stamp.cpu.is_empty());

    let mut text = std::fs::read_to_string(&path).unwrap();
    text.push('\n');
    std::fs::write(&path, &text).unwrap();
    let changed = ProtocolFile::read(&path).unwrap();
    let err = changed.register(&s, false).unwrap_err();
    assert!(err.to_string().contains("differs from HEAD"), "{err}");

    // Outside any repository.
    let loose = scratch("uncommitted-loose").join("p.json");
    Protocol::new("loose", &s).unwrap().write(&loose).unwrap();
    let err = ProtocolFile::read(&loose).unwrap().register(&s, false);
    // (The temporary directory may itself lie in a repository; then it is untracked.)
    let err = err.unwrap_err().to_string();
    assert!(
        err.contains("not inside a git repository") || err.contains("not tracked"),
        "{err}"
    );
}

#[test]
fn tuning_seeds_are_never_registered() {
    let dir = repo("tuning");
    let models = fake_models(&scratch("tuning-models"));
    let s = settings(&models, vec![Method::Dips], 500);
    let path = dir.join("tuning.json");
    Protocol::new("tuning", &s).unwrap().write(&path).unwrap();
    commit_all(&dir, "tuning protocol");
    let r = ProtocolFile::read(&path)
        .unwrap()
        .register(&s, false)
        .unwrap();
    assert_eq!(r.status, RegistrationStatus::Tuning);
}

#[test]
fn a_committed_registration_spends_its_range_and_is_never_overwritten() {
    let dir = repo("spent");
    let models = fake_models(&scratch("spent-models"));
    let s = settings(&models, vec![Method::Dips], 10000);
    let path = dir.join("protocols/card.json");
    Protocol::new("card", &s).unwrap().write(&path).unwrap();
    commit_all(&dir, "register card");
    let file = ProtocolFile::read(&path).unwrap();

    let first = file.register(&s, false).unwrap();
    assert_eq!(first.status, RegistrationStatus::Registered);
    let results = dir.join("results/card");
    let mut registered = s.clone();
    registered.registration = Some(first.clone());
    claim_dir(&results, &registered).unwrap();
    assert!(results.join(REGISTRATION_FILE).is_file());
    // A resume (or a shard) of the same registration may write there.
    claim_dir(&results, &registered).unwrap();
    // Not yet committed: the range is not spent yet.
    assert_eq!(
        file.register(&s, false).unwrap().status,
        RegistrationStatus::Registered
    );
    commit_all(&dir, "card results");

    // The registered run resumed in its own directory after a partial commit stays registered;
    // anywhere else it is a rerun.
    assert_eq!(
        file.register_in(&s, false, &results).unwrap().status,
        RegistrationStatus::Registered
    );
    assert_eq!(
        file.register_in(&s, false, &dir.join("results/elsewhere"))
            .unwrap()
            .status,
        RegistrationStatus::Rerun
    );
    let again = file.register(&s, false).unwrap();
    assert_eq!(again.status, RegistrationStatus::Rerun);
    assert!(
        again.spent_by[0].starts_with("results/card/registration.json"),
        "{:?}",
        again.spent_by
    );
    let mut rerun = s.clone();
    rerun.registration = Some(again.clone());
    let err = claim_dir(&results, &rerun).unwrap_err().to_string();
    assert!(err.contains("holds the registered results"), "{err}");
    assert!(err.contains("this run is rerun"), "{err}");
    let err = claim_dir(&results, &s).unwrap_err().to_string();
    assert!(
        err.contains("a run without a protocol would mix into them"),
        "{err}"
    );
    assert_eq!(
        dips_eval::protocol::read_registration(&results).unwrap(),
        Some(first)
    );
    claim_dir(&dir.join("results/card-rerun"), &rerun).unwrap();

    // Another protocol of the same task on an overlapping range is a rerun too; another task
    // or a disjoint range is not.
    let overlapping = settings(&models, vec![Method::DipsK1], 10002);
    let other_task = EvalSettings {
        task: SceneKind::Screwdriver,
        ..settings(&models, vec![Method::Dips], 10000)
    };
    let disjoint = settings(&models, vec![Method::Dips], 10003);
    for (name, s, status) in [
        ("disjoint", &disjoint, RegistrationStatus::Registered),
        ("overlapping", &overlapping, RegistrationStatus::Rerun),
        ("other-task", &other_task, RegistrationStatus::Registered),
    ] {
        let p = dir.join(format!("protocols/{name}.json"));
        Protocol::new(name, s).unwrap().write(&p).unwrap();
        commit_all(&dir, name);
        let r = ProtocolFile::read(&p).unwrap().register(s, false).unwrap();
        assert_eq!(r.status, status, "{name}");
    }

    // The arms of one experiment, registered in one commit before either ran (here the same
    // seeds on our world and on MuJoCo with tracker noise), share their seeds: the second is
    // registered after the first's results are committed. A protocol committed after those
    // results is a rerun, spent by the arm whose outcomes could be seen when it was written.
    let arm = |hand, tracker_noise| EvalSettings {
        hand,
        tracker_noise,
        ..settings(&models, vec![Method::Dips], 10100)
    };
    let noise = Some(TrackerNoise {
        position: 1e-3,
        rotation: 0.02,
    });
    let arms = [
        ("arm-world", arm(HandKind::World, None)),
        ("arm-mujoco-noisy", arm(HandKind::Mujoco, noise)),
    ];
    for (name, s) in &arms {
        Protocol::new(name, s)
            .unwrap()
            .write(&dir.join(format!("protocols/{name}.json")))
            .unwrap();
    }
    commit_all(&dir, "register both arms");
    let late = dir.join("protocols/arm-late.json");
    for (name, s) in &arms {
        let file = ProtocolFile::read(&dir.join(format!("protocols/{name}.json"))).unwrap();
        let r = file.register(s, false).unwrap();
        assert_eq!(r.status, RegistrationStatus::Registered, "{name}");
        let mut run = s.clone();
        run.registration = Some(r);
        claim_dir(&dir.join(format!("results/{name}")), &run).unwrap();
        commit_all(&dir, &format!("{name} results"));
        if *name == "arm-world" {
            Protocol::new("arm-late", &arms[1].1)
                .unwrap()
                .write(&late)
                .unwrap();
            commit_all(&dir, "a protocol registered after the first arm ran");
        }
    }
    let r = ProtocolFile::read(&late)
        .unwrap()
        .register(&arms[1].1, false)
        .unwrap();
    // Spent by the arm that ran before it was committed, not by the one that ran after.
    assert_eq!(r.status, RegistrationStatus::Rerun);
    assert_eq!(r.spent_by.len(), 1, "{:?}", r.spent_by);
    assert!(
        r.spent_by[0].starts_with("results/arm-world/"),
        "{:?}",
        r.spent_by
    );
}

#[test]
fn a_protocol_run_never_mixes_with_episodes_run_without_one() {
    let dir = repo("mix");
    let models = fake_models(&scratch("mix-models"));
    let s = settings(&models, vec![Method::Dips], 10000);
    let out = dir.join("out");
    claim_dir(&out, &s).unwrap();
    let path = dir.join("p.json");
    Protocol::new("p", &s).unwrap().write(&path).unwrap();
    commit_all(&dir, "p");
    let r = ProtocolFile::read(&path)
        .unwrap()
        .register(&s, false)
        .unwrap();
    let err = claim_registration(&out, Some(&r)).unwrap_err().to_string();
    assert!(err.contains("run without a protocol"), "{err}");
    assert!(!out.join(REGISTRATION_FILE).exists());
}
