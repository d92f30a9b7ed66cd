//! Data generation on tiny settings (4 particles, a few iterations): deterministic, resumable
//! after a kill without duplicate or missing demos, mergeable across shards, and each demo is
//! the `dips episode` of its seed.

use std::path::Path;

use dips_batch::{ProgressMode, Shard};
use dips_datagen::run::demo_path;
use dips_datagen::{DatagenError, DatagenSettings, generate, merge, record_demo};
use dips_dataset::{DemoRecord, read_demo};
use dips_exec::{
    ExecSettings, SequenceSource, prior_sequence_for_seed, run_episode, sequence_for_seed,
};
use dips_kernel::mode::Task;
use dips_world::scenes::SceneKind;

fn tiny(task: SceneKind, demos: usize) -> DatagenSettings {
    let mut exec = ExecSettings::for_task(task);
    exec.particles = 4;
    exec.warmup_iters = 8;
    exec.online_iters = 2;
    exec.warmup_retries = 0;
    DatagenSettings {
        task,
        demos,
        first_seed: 10,
        shard: Shard::ALL,
        jobs: 2,
        sequences: SequenceSource::Pattern,
        exec,
        progress: ProgressMode::Hidden,
        stop_after: None,
    }
}

fn demo(dir: &Path, seed: u64) -> DemoRecord {
    let mut d = read_demo(&demo_path(dir, SceneKind::Card, seed), Task::Card).unwrap();
    // Wall times differ between runs; everything else must not.
    d.metadata.remove("seconds");
    d.metadata.remove("csvto_seconds");
    d
}

#[test]
fn datagen_is_deterministic_resumable_and_shardable() {
    let root = tempdir();
    let (full, killed, shards) = (root.join("full"), root.join("killed"), root.join("shards"));
    let s = tiny(SceneKind::Card, 3);
    let report = generate(&s, &full).unwrap();
    assert_eq!((report.generated, report.skipped), (3, 0));
    assert_eq!(report.manifest.seeds, vec![10, 11, 12]);
    assert_eq!(report.manifest.shape, [9, 29]);
    // One demo, then a "kill"; the re-run finishes the other two and keeps the first.
    let first = generate(
        &DatagenSettings {
            stop_after: Some(1),
            ..s.clone()
        },
        &killed,
    )
    .unwrap();
    assert_eq!(first.manifest.seeds, vec![10]);
    let resumed = generate(&s, &killed).unwrap();
    assert_eq!((resumed.generated, resumed.skipped), (2, 1));
    assert_eq!(
        without_time(resumed.manifest),
        without_time(report.manifest.clone())
    );
    // Two shards in two directories, merged with `merge`; before the second has run, the merge
    // names its seed and shard instead of dropping it.
    let parts: Vec<_> = (0..2).map(|i| shards.join(format!("part{i}"))).collect();
    let run_shard = |i: usize| {
        let shard = Shard { index: i, count: 2 };
        let r = generate(&DatagenSettings { shard, ..s.clone() }, &parts[i]).unwrap();
        assert_eq!(r.generated, shard.seeds(10, 3).len());
    };
    run_shard(0);
    let e = merge(SceneKind::Card, &shards.join("merged"), &parts[..1], false)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("1 of 3 demos are missing") && e.contains("seeds 11") && e.contains("1/2"),
        "{e}"
    );
    run_shard(1);
    let r = merge(SceneKind::Card, &shards.join("merged"), &parts, false).unwrap();
    assert_eq!((r.copied, r.already_there, r.shards), (1, 2, 2));
    let merged = r.manifest;
    assert_eq!(merged.seeds, vec![10, 11, 12]);
    // A shard with other settings is refused by name.
    let mut other = s.clone();
    other.exec.particles = 5;
    let e = generate(&other, &parts[0]).unwrap_err().to_string();
    assert!(
        e.contains("exec.particles") && e.contains('4') && e.contains('5'),
        "{e}"
    );
    for seed in 10..13 {
        let a = demo(&full, seed);
        assert_eq!(a, demo(&killed, seed), "seed {seed}: resumed differs");
        assert_eq!(
            a,
            demo(&shards.join("merged"), seed),
            "seed {seed}: shard differs"
        );
    }
    // A corrupt (cut off) demo file is made again.
    let path = demo_path(&killed, SceneKind::Card, 11);
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let again = generate(&s, &killed).unwrap();
    assert_eq!((again.generated, again.skipped), (1, 2));
    assert_eq!(demo(&full, 11), demo(&killed, 11));
    std::fs::remove_dir_all(&root).ok();
}

/// The manifest without the field that depends on wall time.
fn without_time(mut m: dips_datagen::Manifest) -> dips_datagen::Manifest {
    m.median_seconds_per_demo = None;
    m
}

#[test]
fn a_demo_is_the_episode_of_its_seed_with_every_particle() {
    let s = tiny(SceneKind::Card, 1);
    let (record, outcome) = record_demo(
        SceneKind::Card,
        3,
        dips_exec::SequenceSource::Pattern,
        &s.exec,
        &mut |_| {},
    )
    .unwrap();
    let modes = prior_sequence_for_seed(SceneKind::Card, 3);
    let episode = run_episode(
        SceneKind::Card,
        "csvto-sampled",
        3,
        &modes,
        &s.exec,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(outcome.final_distance_m, episode.final_distance_m);
    assert_eq!(outcome.valid, episode.valid);
    assert_eq!(
        record.modes,
        modes
            .iter()
            .map(|m| m.name().to_string())
            .collect::<Vec<_>>()
    );
    // Every mode, every online step (H = 8), every particle.
    let (h, d) = (8, 29);
    assert_eq!(record.len(), modes.len() * h * 4);
    for i in 0..record.len() {
        let traj = record.trajectory(i);
        let (m, k) = (record.mode_index[i] as usize, record.step[i] as usize);
        let run = &episode.mode_runs[m];
        // Row 0 holds the mode's measured start state (cos/sin of the heading).
        let s0 = &run.start_state;
        assert!((f64::from(traj[8]) - s0[8]).abs() < 1e-6, "x");
        assert!((f64::from(traj[9]) - s0[9]).abs() < 1e-6, "y");
        assert!((f64::from(traj[10]) - s0[10].cos()).abs() < 1e-6, "cos θ");
        // Row k holds the measured state the step planned from.
        if k > 0 {
            let sk = &run.steps[k - 1].state;
            for c in 0..8 {
                assert!(
                    (f64::from(traj[k * d + c]) - sk[c]).abs() < 1e-6,
                    "demo row {k} joint {c}"
                );
            }
            // The executed rows' joint deltas are the commanded ones.
            let dq = &run.steps[k - 1].dq;
            for c in 0..8 {
                assert!((f64::from(traj[(k - 1) * d + 12 + c]) - dq[c]).abs() < 1e-6);
            }
        }
        // The last row's control is zero.
        assert!(traj[(h * d + 12)..((h + 1) * d)].iter().all(|v| *v == 0.0));
    }
}

/// `--sequences markov` demos execute the seed's Markov chain and say so in their metadata; a
/// run never takes a demo made from other sequences for its own (it stops and names the file).
#[test]
fn markov_demos_are_their_chains_and_never_mixed_up_on_resume() {
    let dir = tempdir();
    let mut settings = tiny(SceneKind::Card, 1);
    settings.first_seed = 5;
    settings.sequences = SequenceSource::Markov;
    generate(&settings, &dir).unwrap();
    let d = demo(&dir, 5);
    let chain: Vec<String> = sequence_for_seed(SceneKind::Card, 5, SequenceSource::Markov)
        .iter()
        .map(|m| m.name().to_string())
        .collect();
    assert_eq!(d.modes, chain);
    assert_eq!(
        d.metadata.get("sequences").map(String::as_str),
        Some("markov")
    );
    settings.sequences = SequenceSource::Pattern;
    let err = generate(&settings, &dir).unwrap_err();
    assert!(
        matches!(
            &err,
            DatagenError::OtherSettings { field, theirs, ours, .. }
                if field == "sequences" && theirs == "markov" && ours == "pattern"
        ),
        "{err}"
    );
    let err = err.to_string();
    assert!(
        err.contains("made with sequences markov") && err.contains("give other seeds"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

fn tempdir() -> std::path::PathBuf {
    let p = std::env::temp_dir().join(format!(
        "dips-datagen-test-{}-{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos())
    ));
    std::fs::create_dir_all(&p).unwrap();
    p
}
