//! Every settings file under `docs/results/` still reads, and what it reads as writes back
//! the same: `eval.json` and `registration.json` byte for byte (an `eval.json` written before
//! the search depth was recorded gains only the depth of then), protocols byte for byte (their
//! sha256 is their registration), and the settings, registration, task and methods of each
//! evaluation's `results.json` as they are.

use std::path::{Path, PathBuf};

use dips_eval::protocol::{ProtocolFile, Registration};
use dips_eval::settings::EvalFile;
use dips_planning::online::Method;
use dips_world::scenes::SceneKind;
use serde_json::Value;

fn results_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/results")
}

/// Every file under `dir` whose name `keep` accepts.
fn files(dir: &Path, keep: &dyn Fn(&Path) -> bool, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            files(&p, keep, out);
        } else if keep(&p) {
            out.push(p);
        }
    }
}

fn named(name: &'static str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    files(
        &results_dir(),
        &|p| p.file_name().is_some_and(|n| n == name),
        &mut out,
    );
    out
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The settings `eval` (an `eval.json`'s) as they read: with the task's search depth of
/// before it was recorded where they have none. `None` when they have one.
fn depth_filled_in(eval: &Value) -> Option<Value> {
    if eval["episode"].get("search_depth").is_some() {
        return None;
    }
    let depth = match eval["episode"]["task"].as_str() {
        Some("screwdriver") => "fixed",
        Some("card") => "modes-left",
        other => panic!("task {other:?}"),
    };
    let mut filled = eval.clone();
    filled["episode"]["search_depth"] = depth.into();
    Some(filled)
}

#[test]
fn every_committed_eval_file_writes_back_as_it_is() {
    let found = named("eval.json");
    assert!(found.len() >= 20, "{} eval.json files", found.len());
    let mut before_depth = 0;
    for path in found {
        let text = read(&path);
        let file: EvalFile = serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("{} does not read: {e}", path.display()));
        let written = serde_json::to_string_pretty(&file).unwrap();
        match depth_filled_in(&serde_json::from_str(&text).unwrap()) {
            Some(filled) => {
                before_depth += 1;
                let written: Value = serde_json::from_str(&written).unwrap();
                assert_eq!(written, filled, "{}", path.display());
            }
            None => assert_eq!(written, text, "{}", path.display()),
        }
    }
    assert!(
        before_depth > 0,
        "the files of before the depth was recorded"
    );
}

#[test]
fn every_committed_registration_writes_back_as_it_is() {
    let found = named("registration.json");
    assert!(found.len() >= 10, "{} registration.json files", found.len());
    for path in found {
        let text = read(&path);
        let r: Registration = serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("{} does not read: {e}", path.display()));
        assert_eq!(
            serde_json::to_string_pretty(&r).unwrap(),
            text,
            "{}",
            path.display()
        );
    }
}

#[test]
fn every_committed_protocol_reads_and_writes_back_as_it_is() {
    let mut found = Vec::new();
    files(
        &results_dir().join("protocols"),
        &|p| p.extension().is_some_and(|x| x == "json"),
        &mut found,
    );
    assert!(found.len() >= 10, "{} protocols", found.len());
    for path in found {
        let file = ProtocolFile::read(&path).unwrap_or_else(|e| panic!("{e}"));
        let mut written = serde_json::to_string_pretty(&file.protocol).unwrap();
        written.push('\n');
        assert_eq!(written, read(&path), "{}", path.display());
    }
}

#[test]
fn every_committed_summary_reads_as_it_is() {
    let found: Vec<(PathBuf, Value)> = named("results.json")
        .into_iter()
        .map(|p| {
            let v: Value = serde_json::from_str(&read(&p)).unwrap();
            (p, v)
        })
        // An evaluation's results (other commands write files of that name too).
        .filter(|(_, v)| v.get("eval").is_some() && v.get("trials").is_some())
        .collect();
    assert!(found.len() >= 20, "{} results.json files", found.len());
    for (path, v) in found {
        let at = path.display();
        let eval: EvalFile = serde_json::from_value(v["eval"].clone())
            .unwrap_or_else(|e| panic!("{at}: eval does not read: {e}"));
        let read = depth_filled_in(&v["eval"]).unwrap_or_else(|| v["eval"].clone());
        assert_eq!(serde_json::to_value(&eval).unwrap(), read, "{at}");
        if let Some(r) = v.get("registration") {
            let r: Registration = serde_json::from_value(r.clone())
                .unwrap_or_else(|e| panic!("{at}: registration does not read: {e}"));
            assert_eq!(serde_json::to_value(&r).unwrap(), v["registration"], "{at}");
        }
        let task: SceneKind = v["task"].as_str().unwrap().parse().unwrap();
        assert_eq!(task, eval.episode.task, "{at}");
        let methods = v["methods"].as_array().unwrap().iter();
        let trials = v["trials"].as_array().unwrap().iter();
        for m in methods.chain(trials) {
            let method: Method = m["method"].as_str().unwrap().parse().unwrap();
            assert!(eval.methods.contains(&method), "{at}: {method}");
        }
    }
}
