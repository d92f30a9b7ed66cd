//! The command line's words for the libraries' typed errors. A library names the value that is
//! wrong, the setting it belongs to and what is allowed, never a flag; here each setting that a
//! flag sets is named by its flag (`the method list is empty` → `--methods is empty`), and the
//! fixes that are flags or commands are spelled out. [`crate::output::causes`] reads every
//! cause of an error through [`of`], so every command prints these words.

use std::error::Error;

use dips_batch::{ShardEnvError, ShardError};
use dips_datagen::{DatagenError, Remedy};
use dips_eval::merge::MergeError;
use dips_eval::protocol::ProtocolError;
use dips_eval::run::RunError;
use dips_eval::settings::{EvalFileError, SettingsError};
use dips_eval::summary::{Shortfall, SummaryError};
use dips_link::{LinkError, NoFirmware, RemoteError};
use dips_planning::ModelsError;
use dips_planning::online::{OnlineError, TimeBudgetError};
use dips_world::hand::{BadNoise, HandError, UnknownHand};

/// The command line's words for `e` (one cause of an error, without its own causes), or
/// `None` where the library's message is already the command line's.
pub fn of(e: &(dyn Error + 'static)) -> Option<String> {
    if let Some(e) = e.downcast_ref::<ModelsError>() {
        models(e)
    } else if let Some(e) = e.downcast_ref::<TimeBudgetError>() {
        Some(time_budget(e))
    } else if let Some(e) = e.downcast_ref::<OnlineError>() {
        online(e)
    } else if let Some(e) = e.downcast_ref::<SettingsError>() {
        Some(eval_settings(e))
    } else if let Some(e) = e.downcast_ref::<EvalFileError>() {
        eval_file(e)
    } else if let Some(e) = e.downcast_ref::<ProtocolError>() {
        protocol(e)
    } else if let Some(e) = e.downcast_ref::<RunError>() {
        run(e)
    } else if let Some(e) = e.downcast_ref::<MergeError>() {
        merge(e)
    } else if let Some(e) = e.downcast_ref::<SummaryError>() {
        match e {
            SummaryError::EvalFile(e) => eval_file(e),
            SummaryError::Protocol(e) => protocol(e),
            _ => None,
        }
    } else if let Some(e) = e.downcast_ref::<DatagenError>() {
        datagen(e)
    } else if let Some(e) = e.downcast_ref::<HandError>() {
        hand(e)
    } else if let Some(e) = e.downcast_ref::<BadNoise>() {
        Some(noise(e))
    } else if let Some(e) = e.downcast_ref::<ShardEnvError>() {
        Some(shard_env(e))
    } else if let Some(e) = e.downcast_ref::<ShardError>() {
        Some(shard(e))
    } else if let Some(e) = e.downcast_ref::<NoFirmware>() {
        no_firmware(e)
    } else if let Some(e) = e.downcast_ref::<LinkError>() {
        link(e)
    } else if let Some(e) = e.downcast_ref::<RemoteError>() {
        match e {
            RemoteError::Link(e) => link(e),
            _ => None,
        }
    } else {
        None
    }
}

/// The flag that sets a field of `eval.json` (`episode.time_budget_s` → `--time-budget-s`,
/// `first_seed` → `--first-seed`).
pub fn flag_of(field: &str) -> String {
    let last = field.rsplit('.').next().unwrap_or(field);
    format!("--{}", last.replace('_', "-"))
}

/// How `dips train --policy` makes the model a message says is missing.
const TRAIN_POLICY: &str = "(train it with `dips train --policy`)";

fn models(e: &ModelsError) -> Option<String> {
    Some(match e {
        ModelsError::NotFound { task, tried } => format!(
            "no {task} models found (tried {}); pass --models DIR or set ${}",
            tried
                .iter()
                .map(|d| d.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
            dips_planning::MODELS_ENV
        ),
        ModelsError::TooManySteps { .. } => format!("--{e}"),
        ModelsError::Psi { dir, mismatch } if !mismatch.usable.is_empty() => format!(
            "the discriminator in {}: {}; plan with --sampler {}, or {}",
            dir.display(),
            mismatch.what(),
            mismatch.usable.join(" or --sampler "),
            mismatch.retrain()
        ),
        ModelsError::Policy { .. } => format!("{e} {TRAIN_POLICY}"),
        _ => return None,
    })
}

fn no_firmware(e: &NoFirmware) -> Option<String> {
    match e {
        NoFirmware::NotFound { .. } => e
            .to_string()
            .strip_suffix("give the kernel target spawn:PATH")
            .map(|start| format!("{start}pass --kernel spawn:PATH")),
        NoFirmware::EnvNotAFile { .. } => None,
    }
}

fn link(e: &LinkError) -> Option<String> {
    match e {
        LinkError::NoFirmware(e) => no_firmware(e),
        _ => None,
    }
}

fn time_budget(e: &TimeBudgetError) -> String {
    format!(
        "--time-budget-s {}: expected a finite number of seconds ≥ 0 (0: no budget)",
        e.seconds
    )
}

fn online(e: &OnlineError) -> Option<String> {
    Some(match e {
        OnlineError::PolicyWithModes => "method `diffusion-policy` has no contact modes; --modes \
                                         is for dips-sampled and csvto-sampled"
            .into(),
        OnlineError::SearchWithModes { method } => format!(
            "method `{method}` plans its own modes; --modes is for dips-sampled and csvto-sampled"
        ),
        OnlineError::NoPolicyModel { .. } => format!("{e} {TRAIN_POLICY}"),
        _ => return None,
    })
}

fn eval_settings(e: &SettingsError) -> String {
    match e {
        SettingsError::NoMethods => format!(
            "--methods is empty; available: {}",
            dips_planning::online::Method::NAMES.join(", ")
        ),
        SettingsError::MethodTwice(m) => format!("--methods names {m} twice"),
        SettingsError::NoTrials => "--trials must be at least 1".into(),
        SettingsError::NoJobs => "--jobs must be at least 1".into(),
        SettingsError::NoModelThreads => "--model-threads must be at least 1".into(),
        SettingsError::SeedOverflow { first_seed, trials } => {
            format!("--first-seed {first_seed} + --trials {trials} overflows the seed range")
        }
        SettingsError::TimeBudget(e) => time_budget(e),
        SettingsError::NoModes => "--max-modes must be at least 1".into(),
        SettingsError::TcpJobs { kernel, .. } => format!(
            "--kernel {kernel}: a TCP kernel serves one connection at a time; use --jobs 1, or \
             --kernel spawn (one firmware per episode)"
        ),
        SettingsError::Profile(e) => format!("--exec-profile {}: {e}", e.profile),
    }
}

fn eval_file(e: &EvalFileError) -> Option<String> {
    Some(match e {
        EvalFileError::OtherSettings {
            file,
            field,
            there,
            here,
        } => format!(
            "{} holds an evaluation with other settings: {} is {there} there and {here} here; \
             use another --out, or the same task, sampler, budgets, mode limit, cost-to-come, \
             search depth, models, engine, hand, tracker noise, card goals and CSVTO profile",
            file.display(),
            flag_of(field),
        ),
        EvalFileError::OtherFirstSeed { file, there, here } => format!(
            "{} was started with --first-seed {there}; this run asks for {here}",
            file.display()
        ),
        EvalFileError::Protocol(e) => return protocol(e),
        _ => return None,
    })
}

fn protocol(e: &ProtocolError) -> Option<String> {
    Some(match e {
        ProtocolError::MissingField { .. } => {
            format!("{e} (write protocols with `dips eval --write-protocol`)")
        }
        ProtocolError::Differs {
            setting,
            protocol,
            run,
        } => format!(
            "{} is {protocol} in the protocol and {run} in this run",
            flag_of(setting)
        ),
        ProtocolError::NotCommitted { path, why } => format!(
            "{} {why}: commit it before the run (`git add {} && git commit`), or pass \
             --protocol-uncommitted to label the results unregistered",
            path.display(),
            path.display()
        ),
        ProtocolError::Unregistered {
            dir,
            holds,
            protocol,
        } => format!(
            "{} {holds}; a run without --protocol would mix into them (resume with --protocol \
             {protocol}): use another --out",
            dir.display()
        ),
        ProtocolError::Directory { dir, holds, why } => {
            format!("{} {holds}; {why}: use another --out", dir.display())
        }
        _ => return None,
    })
}

fn run(e: &RunError) -> Option<String> {
    match e {
        RunError::Settings(e) => Some(eval_settings(e)),
        RunError::Hand { hand, .. } => Some(format!("--hand {hand}")),
        RunError::Dir(e) => eval_file(e),
        RunError::Sampler(e) => models(e),
        _ => None,
    }
}

fn merge(e: &MergeError) -> Option<String> {
    match e {
        MergeError::OtherFirstSeed { file, there, here } => Some(format!(
            "{} starts at --first-seed {there}, the evaluation being merged at {here}",
            file.display()
        )),
        MergeError::Missing { .. } => e
            .to_string()
            .strip_suffix("merge allowing missing episodes to summarise what is there")
            .map(|start| format!("{start}merge with --allow-missing to summarise what is there")),
        MergeError::EvalFile(e) => eval_file(e),
        MergeError::Protocol(e) => protocol(e),
        _ => None,
    }
}

/// The flag of a `datagen.json` field where one sets it.
fn datagen_field(field: &str) -> String {
    match field {
        "task" | "sequences" => format!("--{field}"),
        other => other.to_string(),
    }
}

fn remedy(r: Remedy) -> &'static str {
    match r {
        Remedy::OtherSeedsOrDirectory => "give other seeds (--first-seed) or another --out",
        Remedy::OtherDirectory => "give another --out",
        Remedy::OneTask => "merge datasets of one task",
    }
}

fn datagen(e: &DatagenError) -> Option<String> {
    Some(match e {
        DatagenError::NoDemos => "invalid datagen settings: --demos must be at least 1".into(),
        DatagenError::NoJobs => "invalid datagen settings: --jobs must be at least 1".into(),
        DatagenError::SeedOverflow { first_seed, demos } => format!(
            "invalid datagen settings: --first-seed {first_seed} + --demos {demos} overflows \
             the seed range"
        ),
        DatagenError::OtherSequences { path, made, asked } => format!(
            "{} was made with --sequences {made}, this run asks for {asked}; {}",
            path.display(),
            remedy(Remedy::OtherSeedsOrDirectory)
        ),
        DatagenError::OtherSettings {
            path,
            field,
            theirs,
            ours,
            remedy: r,
        } => format!(
            "{} was made with {} {theirs}, this run asks for {ours}; {}",
            path.display(),
            datagen_field(field),
            remedy(*r)
        ),
        DatagenError::NoSettingsFile { dir } => format!(
            "{} has no datagen.json: not a dips datagen output (or made before it was \
             recorded; copy its demos/ by hand and run `dips datagen index`)",
            dir.display()
        ),
        _ => return None,
    })
}

/// `--hand`'s words for a name that is not a hand (a hand description file is `--hand-model`).
pub fn unknown_hand(e: &UnknownHand) -> String {
    match e {
        UnknownHand::Name(_) | UnknownHand::Allegro(_) => e.to_string(),
        UnknownHand::File(name) => format!(
            "`{name}` is not a hand (allowed: {}); a hand description file is `--hand-model \
             FILE`",
            dips_world::hand::HandKind::NAMES.join(", ")
        ),
    }
}

fn hand(e: &HandError) -> Option<String> {
    Some(match e {
        HandError::NoTracker { .. } => "world hand: our world reports the exact object pose; \
                                        tracker noise (--noise-position, --noise-rotation) \
                                        needs --hand mujoco"
            .into(),
        HandError::NotInBinary { kind } => format!(
            "world hand: --hand {kind} is not in this binary (it has our world only); run it \
             through dips-mujoco"
        ),
        _ => return None,
    })
}

/// `--noise-position` / `--noise-rotation`'s words for a σ below 0.
pub fn noise(e: &BadNoise) -> String {
    format!(
        "--noise-{} {}: a standard deviation must be ≥ 0",
        e.axis, e.value
    )
}

/// `--shard`'s words for a shard that does not read.
pub fn shard(e: &ShardError) -> String {
    format!(
        "--shard {:?}: {}; write I/N with 0 ≤ I < N (e.g. 0/4), auto (Slurm's \
         SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT) or auto/N (the index from Slurm or \
         JOB_COMPLETION_INDEX)",
        e.given, e.reason
    )
}

fn shard_env(e: &ShardEnvError) -> String {
    match e {
        ShardEnvError::NoScheduler => "--shard auto: no job array here (neither \
                                       SLURM_ARRAY_TASK_ID nor JOB_COMPLETION_INDEX is set); \
                                       submit it as an array (sbatch --array=0-3) or give \
                                       --shard I/N"
            .into(),
        ShardEnvError::Missing(name) => {
            format!("--shard auto: {name} is not set; give the count with --shard auto/N")
        }
        ShardEnvError::CountNeeded => "--shard auto: JOB_COMPLETION_INDEX gives the index only; \
                                       give the count with --shard auto/N (the Job's \
                                       completions)"
            .into(),
        ShardEnvError::NotANumber { name, value } => {
            format!("--shard auto: {name}={value:?} is not a whole number")
        }
        ShardEnvError::CountDiffers { given, slurm } => {
            format!("--shard auto: --shard auto/{given} but SLURM_ARRAY_TASK_COUNT={slurm}")
        }
        ShardEnvError::Inconsistent(why) => format!("--shard auto: {why}"),
    }
}

/// What a summary lacks, in the command line's words (`--trials`, `--summarize-only`).
pub fn shortfall(s: &Shortfall) -> String {
    match s {
        Shortfall::MoreAsked { asked, recorded } => format!(
            "--trials {asked}: this evaluation was asked for {recorded} trials per method \
             (eval.json); the summary covers those (run without --summarize-only to add the rest)"
        ),
        Shortfall::Unfinished { .. } => s.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use dips_planning::PsiMismatch;

    use super::*;

    #[test]
    fn flags_are_named_from_fields() {
        assert_eq!(flag_of(".episode.time_budget_s"), "--time-budget-s");
        assert_eq!(flag_of("episode.sampler"), "--sampler");
        assert_eq!(flag_of("first_seed"), "--first-seed");
        assert_eq!(flag_of("methods"), "--methods");
        assert_eq!(flag_of("card_goals"), "--card-goals");
    }

    #[test]
    fn psi_mismatch_names_the_samplers_by_their_flag() {
        let e = ModelsError::Psi {
            dir: PathBuf::from("/m"),
            mismatch: PsiMismatch {
                negatives: vec!["ddpm".into(), "ddim:8".into(), "ddpm:16+anchor".into()],
                planner: "ddpm:16".into(),
                usable: vec!["ddpm".into(), "ddim:8".into()],
                planner_steps: Some(16),
            },
        };
        let w = of(&e).unwrap();
        assert!(w.contains("--sampler ddpm or --sampler ddim:8"), "{w}");
        assert!(w.contains("never saw the planner's ddpm:16"), "{w}");
        assert!(w.contains("planner_fakes = [16]"), "{w}");
    }

    #[test]
    fn datagen_refusals_name_the_flags() {
        let e = DatagenError::OtherSequences {
            path: PathBuf::from("/d/demos/x.safetensors"),
            made: "markov".into(),
            asked: "pattern",
        };
        let w = of(&e).unwrap();
        assert!(
            w.contains("made with --sequences markov") && w.contains("--first-seed"),
            "{w}"
        );
        let e = DatagenError::OtherSettings {
            path: PathBuf::from("/d/datagen.json"),
            field: "sequences".into(),
            theirs: "markov".into(),
            ours: "pattern".into(),
            remedy: Remedy::OtherSeedsOrDirectory,
        };
        let w = of(&e).unwrap();
        assert!(
            w.contains("made with --sequences markov") && w.contains("--first-seed"),
            "{w}"
        );
        let e = DatagenError::OtherSettings {
            path: PathBuf::from("/d/datagen.json"),
            field: "task".into(),
            theirs: "card".into(),
            ours: "screwdriver".into(),
            remedy: Remedy::OtherDirectory,
        };
        assert_eq!(
            of(&e).unwrap(),
            "/d/datagen.json was made with --task card, this run asks for screwdriver; give \
             another --out"
        );
    }

    #[test]
    fn a_run_without_a_protocol_is_told_the_flag() {
        let e = EvalFileError::Protocol(ProtocolError::Unregistered {
            dir: PathBuf::from("/r"),
            holds: "holds the registered results of protocol p".into(),
            protocol: "p.json".into(),
        });
        let w = of(&e).unwrap();
        assert!(w.contains("without --protocol"), "{w}");
        assert!(w.contains("resume with --protocol p.json"), "{w}");
        assert!(w.ends_with("use another --out"), "{w}");
    }

    #[test]
    fn a_merge_with_missing_episodes_names_allow_missing() {
        let e = MergeError::Missing {
            out: PathBuf::from("/o"),
            missing: vec!["dips seed 3 (shard 1/2)".into()],
            total: 4,
            unfinished: vec!["1/2".into()],
        };
        let w = of(&e).unwrap();
        assert!(
            w.starts_with("/o: 1 of 4 episodes are missing: dips seed 3"),
            "{w}"
        );
        assert!(
            w.ends_with("merge with --allow-missing to summarise what is there"),
            "{w}"
        );
    }

    #[test]
    fn a_setting_that_differs_from_the_protocol_is_named_by_its_flag() {
        let differs = |setting: &str, protocol: &str, run: &str| {
            of(&ProtocolError::Differs {
                setting: setting.into(),
                protocol: protocol.into(),
                run: run.into(),
            })
            .unwrap()
        };
        assert_eq!(
            differs("episode.sampler", "\"ddim:8\"", "\"ddpm:16\""),
            "--sampler is \"ddim:8\" in the protocol and \"ddpm:16\" in this run"
        );
        assert_eq!(
            differs("episode.node_budget", "3", "4"),
            "--node-budget is 3 in the protocol and 4 in this run"
        );
        assert!(differs("first_seed", "10000", "10001").starts_with("--first-seed is 10000"));
        assert!(differs("methods", "[\"dips\"]", "[]").starts_with("--methods is [\"dips\"]"));
        assert!(differs("trials", "3", "4").starts_with("--trials is 3"));
    }

    #[test]
    fn a_missing_firmware_names_the_kernel_flag() {
        let e = LinkError::NoFirmware(NoFirmware::NotFound {
            name: "dips-firmware-sim".into(),
            tried: vec!["/x".into()],
        });
        let w = of(&e).unwrap();
        assert!(
            w.starts_with("no dips-firmware-sim found (tried /x)"),
            "{w}"
        );
        assert!(w.ends_with("or pass --kernel spawn:PATH"), "{w}");
    }

    #[test]
    fn every_eval_setting_is_named_by_its_flag() {
        use SettingsError as S;
        let all = [
            S::NoMethods,
            S::MethodTwice(dips_planning::online::Method::Dips),
            S::NoTrials,
            S::NoJobs,
            S::NoModelThreads,
            S::SeedOverflow {
                first_seed: u64::MAX,
                trials: 2,
            },
            S::TimeBudget(TimeBudgetError { seconds: -1.0 }),
            S::NoModes,
            S::TcpJobs {
                kernel: dips_link::KernelTarget::Tcp("h:1".into()),
                jobs: 2,
            },
        ];
        for e in all {
            let w = of(&e).unwrap();
            assert!(w.starts_with("--"), "{w}");
        }
    }

    #[test]
    fn hand_refusals_name_the_hand_flags() {
        use dips_world::hand::{HandKind, NoiseAxis, TrackerNoise};
        let e = "host/data/allegro_v4.json".parse::<HandKind>().unwrap_err();
        let w = unknown_hand(&e);
        assert!(w.contains("--hand-model FILE"), "{w}");
        assert!(w.contains("(allowed: world, mujoco, allegro:IFACE)"), "{w}");
        let e = "isaac".parse::<HandKind>().unwrap_err();
        assert_eq!(
            unknown_hand(&e),
            "unknown hand `isaac` (allowed: world, mujoco, allegro:IFACE)"
        );
        let w = of(&HandError::NoTracker {
            hand: HandKind::World,
        })
        .unwrap();
        assert!(
            w.contains("tracker noise (--noise-position, --noise-rotation)")
                && w.ends_with("needs --hand mujoco"),
            "{w}"
        );
        let w = of(&HandError::NotInBinary {
            kind: HandKind::Mujoco,
        })
        .unwrap();
        assert!(w.contains("--hand mujoco is not in this binary"), "{w}");
        let e = TrackerNoise::new(0.0, -1.0).unwrap_err();
        assert_eq!(e.axis, NoiseAxis::Rotation);
        assert_eq!(
            of(&e).unwrap(),
            "--noise-rotation -1: a standard deviation must be ≥ 0"
        );
        let e = TrackerNoise::new(f64::NAN, 0.0).unwrap_err();
        assert!(of(&e).unwrap().starts_with("--noise-position NaN"));
    }

    #[test]
    fn shard_refusals_name_the_shard_flag() {
        use dips_batch::ShardSpec;
        for bad in ["5/5", "1", "a/2", "0/0", "-1/3", "auto/0", "auto/x"] {
            let e = bad.parse::<ShardSpec>().unwrap_err();
            let w = of(&e).unwrap();
            assert!(
                w.starts_with(&format!("--shard {bad:?}: ")) && w.contains("I/N"),
                "{bad}: {w}"
            );
        }
        let auto = |count, vars: &[(&str, &str)]| {
            let e = ShardSpec::Auto { count }
                .resolve(&|name| {
                    vars.iter()
                        .find(|(k, _)| *k == name)
                        .map(|(_, v)| v.to_string())
                })
                .unwrap_err();
            of(&e).unwrap()
        };
        assert!(auto(None, &[]).ends_with("or give --shard I/N"));
        assert_eq!(
            auto(None, &[("SLURM_ARRAY_TASK_ID", "0")]),
            "--shard auto: SLURM_ARRAY_TASK_COUNT is not set; give the count with --shard auto/N"
        );
        assert!(
            auto(None, &[("JOB_COMPLETION_INDEX", "0")])
                .contains("give the count with --shard auto/N")
        );
        assert_eq!(
            auto(
                Some(2),
                &[
                    ("SLURM_ARRAY_TASK_ID", "1"),
                    ("SLURM_ARRAY_TASK_COUNT", "4")
                ]
            ),
            "--shard auto: --shard auto/2 but SLURM_ARRAY_TASK_COUNT=4"
        );
        assert!(
            auto(
                None,
                &[
                    ("SLURM_ARRAY_TASK_ID", "4"),
                    ("SLURM_ARRAY_TASK_COUNT", "4")
                ]
            )
            .starts_with("--shard auto: SLURM_ARRAY_TASK_ID=4 gives index 4")
        );
    }
}
