//! `dips eval`'s runner and summary on short card episodes (one mode each): every method
//! runs, a killed evaluation resumes without redoing finished episodes, and a directory of
//! other settings is refused.

use std::path::PathBuf;

use dips_batch::{ProgressMode, Shard};
use dips_eval::report::{EpisodeReports, ReportOptions, median_trial, write_report};
use dips_eval::{EvalSettings, run_eval, summarize};
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::Task;
use dips_kernel::search::{CostToCome, SearchConfig, SearchOverrides};
use dips_onnx::EngineKind;
use dips_planning::default_models_dir;
use dips_planning::online::{Method, OnlineSettings, SearchDepth};
use dips_world::scenes::SceneKind;

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dips-eval-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn settings(methods: Vec<Method>, trials: usize) -> EvalSettings {
    EvalSettings {
        task: SceneKind::Card,
        methods,
        trials,
        first_seed: 1000,
        shard: Shard::ALL,
        jobs: 2,
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
        models: default_models_dir(Task::Card).unwrap(),
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

#[test]
fn a_killed_eval_resumes_without_redoing_episodes() {
    let dir = scratch("resume");
    let mut s = settings(vec![Method::CsvtoSampled], 3);
    s.stop_after = Some(1);
    let first = run_eval(&s, &dir).unwrap();
    assert_eq!((first.ran, first.skipped), (1, 0));
    let done = dir.join("episodes/csvto-sampled/seed-1000/result.json");
    let before = std::fs::read(&done).unwrap();
    let stamp = std::fs::metadata(&done).unwrap().modified().unwrap();
    // An episode killed midway leaves a result without its wall.json: it is run again.
    let partial = dir.join("episodes/csvto-sampled/seed-1001");
    std::fs::create_dir_all(&partial).unwrap();
    std::fs::write(partial.join("result.json"), b"{\"cut off").unwrap();

    s.stop_after = None;
    let second = run_eval(&s, &dir).unwrap();
    assert_eq!((second.ran, second.skipped), (2, 1));
    assert_eq!(std::fs::read(&done).unwrap(), before);
    assert_eq!(std::fs::metadata(&done).unwrap().modified().unwrap(), stamp);

    let summary = summarize(&dir).unwrap();
    assert_eq!(summary.methods.len(), 1);
    assert_eq!(summary.methods[0].trials, 3);
    assert_eq!(summary.trials.len(), 3);
    let seeds: Vec<u64> = summary.trials.iter().map(|t| t.seed).collect();
    assert_eq!(seeds, [1000, 1001, 1002]);
    for f in ["results.json", "results.md", "outcome.svg", "outcome.png"] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let md = std::fs::read_to_string(dir.join("results.md")).unwrap();
    assert!(md.contains("| csvto-sampled | 3 |"), "{md}");

    // The report: summary, box plots, one section per method with its median trial animated,
    // every trial's own report linked; every file it references exists beside it.
    let options = ReportOptions {
        episodes: EpisodeReports::All,
        animate: vec![Method::CsvtoSampled],
    };
    let mut calls = 0;
    write_report(&dir, &summary, &options, &mut |_, _| calls += 1).unwrap();
    assert_eq!(calls, 3);
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    for part in [
        "<h2 id=\"summary\">",
        "<h2 id=\"method-csvto-sampled\">",
        "outcome.svg",
        "episode.gif",
    ] {
        assert!(html.contains(part), "report lacks {part}");
    }
    let median = median_trial(&summary, Method::CsvtoSampled).unwrap().seed;
    let files = dips_report::html::referenced_files(&html);
    assert!(files.contains(&format!("episodes/csvto-sampled/seed-{median}/episode.gif")));
    for seed in [1000, 1001, 1002] {
        assert!(files.contains(&format!("episodes/csvto-sampled/seed-{seed}/report.html")));
    }
    for f in files.iter().filter(|f| !f.starts_with('#')) {
        assert!(dir.join(f).is_file(), "report.html references missing {f}");
        if f.ends_with("report.html") {
            let page = std::fs::read_to_string(dir.join(f)).unwrap();
            let base = dir.join(f).parent().unwrap().to_path_buf();
            for g in dips_report::html::referenced_files(&page) {
                assert!(base.join(&g).is_file(), "{f} references missing {g}");
            }
        }
    }

    // A third run finds nothing to do.
    let third = run_eval(&s, &dir).unwrap();
    assert_eq!((third.ran, third.skipped), (0, 3));

    // Other settings in the same directory are refused, naming eval.json.
    let mut other = settings(vec![Method::CsvtoSampled], 3);
    other.online.sampler = "ddpm".parse::<SamplerConfig>().unwrap();
    let err = run_eval(&other, &dir).unwrap_err().to_string();
    assert!(err.contains("eval.json"), "{err}");
    // So is the other form of the search's cost-to-come than the task's.
    let mut other = settings(vec![Method::CsvtoSampled], 3);
    let task_form = SearchConfig::for_task(Task::Card).cost_to_come;
    other.online.search.cost_to_come = CostToCome::ALL.into_iter().find(|&c| c != task_form);
    let err = run_eval(&other, &dir).unwrap_err().to_string();
    assert!(err.contains("eval.json"), "{err}");
    // And the other search depth rule.
    let mut other = settings(vec![Method::CsvtoSampled], 3);
    let task_rule = SearchDepth::for_task(SceneKind::Card);
    other.online.search_depth = SearchDepth::ALL.into_iter().find(|&d| d != task_rule);
    let err = run_eval(&other, &dir).unwrap_err().to_string();
    assert!(err.contains("eval.json"), "{err}");

    // An eval.json written before the depth rule was recorded reads as the rule of then (the
    // card's modes left), so its evaluation still resumes.
    let path = dir.join("eval.json");
    let mut old: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(old["episode"]["search_depth"], "modes-left");
    old["episode"]
        .as_object_mut()
        .unwrap()
        .remove("search_depth");
    std::fs::write(&path, serde_json::to_string(&old).unwrap()).unwrap();
    let fourth = run_eval(&s, &dir).unwrap();
    assert_eq!((fourth.ran, fourth.skipped), (0, 3));
    // And so does one that recorded it as "".
    old["episode"]["search_depth"] = "".into();
    std::fs::write(&path, serde_json::to_string(&old).unwrap()).unwrap();
    let fifth = run_eval(&s, &dir).unwrap();
    assert_eq!((fifth.ran, fifth.skipped), (0, 3));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_method_runs_one_mode() {
    let dir = scratch("methods");
    let s = settings(Method::ALL.to_vec(), 1);
    let report = run_eval(&s, &dir).unwrap();
    assert_eq!(report.ran, Method::ALL.len());
    assert_eq!(report.errors, 0);
    let summary = summarize(&dir).unwrap();
    for (m, row) in Method::ALL.iter().zip(&summary.methods) {
        assert_eq!(row.method, *m);
        assert_eq!(row.trials, 1);
        let trial = summary.trials.iter().find(|t| t.method == *m).unwrap();
        assert_eq!(trial.modes.len(), 1, "{}: {:?}", m.name(), trial.modes);
        assert!(trial.outcome.is_some_and(f64::is_finite), "{}", m.name());
        // Searching methods plan once before their mode; fixed sequences never plan.
        assert_eq!(
            trial.planning_s.len(),
            usize::from(m.searches()),
            "{}",
            m.name()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Two shards in two directories merge into the evaluation one process makes: the same
/// episodes, a shard record each; before the second shard has run, the merge names its
/// episodes and shard instead of dropping them, and a shard of other settings is refused.
#[test]
fn shards_in_two_directories_merge_into_one_evaluation() {
    let root = scratch("merge");
    let parts: Vec<PathBuf> = (0..2).map(|i| root.join(format!("part{i}"))).collect();
    let shard = |index| {
        let mut s = settings(vec![Method::CsvtoSampled], 2);
        s.shard = Shard { index, count: 2 };
        s
    };
    run_eval(&shard(0), &parts[0]).unwrap();
    let merged = root.join("merged");
    let e = dips_eval::merge::merge(&merged, &parts[..1], false)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("1 of 2 episodes are missing")
            && e.contains("csvto-sampled seed 1001 (shard 1/2)"),
        "{e}"
    );
    run_eval(&shard(1), &parts[1]).unwrap();
    let report = dips_eval::merge::merge(&merged, &parts, false).unwrap();
    assert_eq!(
        (report.copied, report.already_there, report.shards),
        (1, 1, 2)
    );
    assert!(report.missing.is_empty());
    let single = root.join("single");
    run_eval(&settings(vec![Method::CsvtoSampled], 2), &single).unwrap();
    for seed in [1000, 1001] {
        let result = |dir: &PathBuf| {
            let path = dir.join(format!("episodes/csvto-sampled/seed-{seed}/result.json"));
            let v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
            (
                v["final_distance_m"].clone(),
                v["modes"].clone(),
                v["valid"].clone(),
            )
        };
        assert_eq!(result(&single), result(&merged), "seed {seed}");
    }
    assert_eq!(summarize(&merged).unwrap().trials.len(), 2);
    // A shard run with another sampler is named, with the setting that differs.
    let mut other = settings(vec![Method::CsvtoSampled], 2);
    other.online.sampler = "ddim:4".parse::<SamplerConfig>().unwrap();
    other.stop_after = Some(0); // its eval.json is all the merge reads first
    let odd = root.join("odd");
    run_eval(&other, &odd).unwrap();
    let e = dips_eval::merge::merge(&merged, &[odd], false)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("settings.sampler") && e.contains("ddim:4"),
        "{e}"
    );
    std::fs::remove_dir_all(&root).ok();
}
