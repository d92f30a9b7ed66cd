//! A DIPS episode executed on the MuJoCo hand (release; scripts/mujoco-test.sh): the planner,
//! the shipped models and CSVTO are `dips episode`'s, the hand is MuJoCo's, and `result.json`
//! says so in its `hand` field; `dips-mujoco eval` resumes.

use dips_host::online::{Method, OnlineSettings};
use dips_host::planning::parse_sampler;
use dips_mujoco::episode::{
    EpisodeSpec, episode_dir, finished, run_episode, run_eval, write_episode,
};
use dips_mujoco::run::HandKind;
use dips_world::scenes::SceneKind;

/// One card mode, a two-node search, DDIM-8: a few seconds.
fn short_card(hand: HandKind) -> EpisodeSpec {
    EpisodeSpec {
        task: SceneKind::Card,
        method: Method::Dips,
        seed: 500,
        hand,
        noise: None,
        models: None,
        threads: 1,
        online: OnlineSettings {
            time_budget_s: 60.0,
            node_budget: Some(2),
            sampler: parse_sampler("ddim:8").expect("sampler"),
            max_modes: Some(1),
            ..OnlineSettings::default()
        },
    }
}

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("dips-mujoco-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn dips_card_episode_on_the_mujoco_hand_records_its_hand() {
    let dir = scratch("episode");
    let result =
        run_episode(&short_card(HandKind::Mujoco), &mut |l| eprintln!("{l}")).expect("episode");
    assert_eq!(result.hand, "mujoco");
    assert_eq!(result.modes.len(), 1, "one mode");
    assert_eq!(result.plans.len(), 1, "one planning call");
    write_episode(&dir, &result, false).expect("write");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("result.json")).expect("read"))
            .expect("JSON");
    assert_eq!(json["hand"], "mujoco");
    assert_eq!(json["method"], "dips");
    assert!(
        json["final_distance_m"]
            .as_f64()
            .is_some_and(f64::is_finite)
    );
    assert!(dir.join("report.html").is_file(), "the report is written");
    eprintln!(
        "card dips seed 500 on MuJoCo: {:?}, dy {:.2} cm, valid {}",
        result.modes,
        100.0 * result.final_dy_m.unwrap_or(f64::NAN),
        result.valid
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn eval_on_our_world_records_world_and_resumes() {
    let dir = scratch("eval");
    let mut base = short_card(HandKind::World);
    base.online.sequence = None;
    let seeds = [500];
    let first = run_eval(&base, &[Method::Dips], &seeds, &dir, &mut |_| {}).expect("eval");
    assert_eq!(first.len(), 1);
    assert_eq!(first[0].hand, "world");
    assert!(first[0].error.is_none(), "{:?}", first[0].error);
    let ep = episode_dir(&dir, Method::Dips, 500);
    assert!(finished(&ep));
    let stamp = std::fs::metadata(ep.join("result.json"))
        .and_then(|m| m.modified())
        .expect("stamp");
    let mut lines = Vec::new();
    let again = run_eval(&base, &[Method::Dips], &seeds, &dir, &mut |l| {
        lines.push(l.to_string())
    })
    .expect("resume");
    assert_eq!(again.len(), 1);
    assert!(
        lines.iter().any(|l| l.contains("finished already")),
        "{lines:?}"
    );
    let stamp2 = std::fs::metadata(ep.join("result.json"))
        .and_then(|m| m.modified())
        .expect("stamp");
    assert_eq!(stamp, stamp2, "a finished episode is not run again");
    let _ = std::fs::remove_dir_all(&dir);
}
