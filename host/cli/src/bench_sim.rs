//! `dips bench sim --json`: time of one action (all sub-steps) in each scene. With
//! `--hand mujoco` (through `dips-mujoco`): one 1 s action on the MuJoCo hand beside our
//! world, both hands running the same closed-loop scripts from their own measured states.

use std::time::Instant;

use anyhow::Context;
use clap::{Args, ValueEnum};
use serde::Serialize;

use dips_exec::hand_state;
use dips_world::hand::{Hand, HandError, HandKind, HandOptions, Hands, add_task_deltas};
use dips_world::kinematics::HandJoints;
use dips_world::scenes::SceneKind;
use dips_world::world::World;
use dips_world::world::bench::{self, ContactModel};
use dips_world::world::scripted;

/// The contact model to time.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ContactModelArg {
    /// The world's defaults.
    Default,
    /// The model before issue 10 (friction cone on every candidate, step command), for
    /// comparison.
    PlainCone,
}

/// `dips bench sim` arguments.
#[derive(Debug, Args)]
pub struct BenchSimArgs {
    /// Print JSON instead of readable `key: value` lines.
    #[arg(long)]
    pub json: bool,
    /// Actions timed per scenario.
    #[arg(long, default_value_t = 24)]
    pub actions: usize,
    /// Contact model to time (our world).
    #[arg(long, value_enum, default_value = "default")]
    pub contact_model: ContactModelArg,
    /// `world`: our world's figures; `mujoco`: one action on the MuJoCo hand beside our
    /// world's (through the dips-mujoco binary).
    #[arg(
        long,
        value_name = "HAND",
        default_value_t = HandKind::World,
        value_parser = crate::hands::parse_hand
    )]
    pub hand: HandKind,
}

/// Run the benchmark and print its figures.
pub fn main(args: BenchSimArgs, hands: &dyn Hands) -> anyhow::Result<()> {
    if args.hand != HandKind::World {
        let timings = compare(&args.hand, args.actions.max(1), hands)?;
        let value = serde_json::json!({
            "bench": "sim",
            "hand": args.hand,
            "actions": args.actions.max(1),
            "scenarios": timings,
        });
        return crate::output::figures(args.json, &value);
    }
    let model = match args.contact_model {
        ContactModelArg::Default => ContactModel::Default,
        ContactModelArg::PlainCone => ContactModel::PlainCone,
    };
    let report = bench::run(args.actions.max(1), model)?;
    crate::output::figures(args.json, &serde_json::to_value(&report)?)?;
    Ok(())
}

/// Timing of one scenario on one hand.
#[derive(Debug, Clone, Serialize)]
pub struct HandTiming {
    /// Scene name.
    pub scene: &'static str,
    /// `hold` (targets = measured joints) or `manipulate` (pinch-and-turn / press-and-slide).
    pub scenario: &'static str,
    /// The hand.
    pub hand: HandKind,
    /// Actions timed.
    pub actions: usize,
    /// Median wall time of one action (ms).
    pub median_ms: f64,
    /// 90th percentile (ms).
    pub p90_ms: f64,
    /// Mean (ms).
    pub mean_ms: f64,
    /// Slowest action (ms).
    pub max_ms: f64,
    /// Mean change of the task coordinate (screwdriver yaw, rad; card y, m) over each run of
    /// six actions.
    pub mean_task_change: f64,
}

/// The targets of action `k` of a scripted scenario, planned as a controller would: a
/// planning world is put at the hand's measured state and the script's joint deltas are added
/// to the measured joints. `hold` sends the measured joints; `manipulate` is the pinch-and-turn
/// (squeeze 4 mm, turn 6 mm) or the card's 3 mm press then 8 mm pushes along −y.
pub fn scripted_targets(
    plan: &mut World,
    hand: &dyn Hand,
    manipulate: bool,
    k: usize,
) -> Result<HandJoints, HandError> {
    let scene = hand.scene();
    let q = hand.joint_positions();
    if !manipulate {
        return Ok(q);
    }
    plan.set_state(&hand_state(hand))?;
    let dq = match scene {
        SceneKind::Screwdriver => scripted::pinch_turn_action(plan, 0.004, 0.006),
        SceneKind::Card if k == 0 => scripted::card_push_action(plan, 0.0, 0.003),
        SceneKind::Card => scripted::card_push_action(plan, -0.008, 0.0),
    };
    Ok(add_task_deltas(scene, q, &dq))
}

/// Time `actions` actions (in runs of six from the start state) of each scene and scenario on
/// `kind` and on our world.
pub fn compare(
    kind: &HandKind,
    actions: usize,
    hands: &dyn Hands,
) -> anyhow::Result<Vec<HandTiming>> {
    let mut out = Vec::new();
    for scene in SceneKind::ALL {
        for manipulate in [false, true] {
            for k in [kind, &HandKind::World] {
                let mut times = Vec::new();
                let mut changes = Vec::new();
                while times.len() < actions {
                    let mut hand = hands
                        .open(k, scene, &HandOptions::default())
                        .with_context(|| format!("--hand {k}"))?;
                    let mut plan = World::new(scene);
                    let c0 = hand.object_pose().coords;
                    for a in 0..6 {
                        if times.len() == actions {
                            break;
                        }
                        let targets = scripted_targets(&mut plan, &*hand, manipulate, a)?;
                        let start = Instant::now();
                        hand.command(&targets)?;
                        times.push(start.elapsed().as_secs_f64() * 1e3);
                    }
                    let c = hand.object_pose().coords;
                    changes.push(match scene {
                        SceneKind::Screwdriver => c[2] - c0[2],
                        SceneKind::Card => c[1] - c0[1],
                    });
                }
                let mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
                times.sort_by(f64::total_cmp);
                let at = |q: f64| {
                    let i = ((times.len() as f64 * q).ceil() as usize).clamp(1, times.len()) - 1;
                    times[i]
                };
                out.push(HandTiming {
                    scene: scene.name(),
                    scenario: if manipulate { "manipulate" } else { "hold" },
                    hand: k.clone(),
                    actions: times.len(),
                    median_ms: times[times.len() / 2],
                    p90_ms: at(0.9),
                    mean_ms: mean,
                    max_ms: times[times.len() - 1],
                    mean_task_change: changes.iter().sum::<f64>() / changes.len().max(1) as f64,
                });
            }
        }
    }
    Ok(out)
}
