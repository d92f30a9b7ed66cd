//! The search flags shared by `dips plan`, `dips episode`, `dips eval` and `dips bench plan`:
//! one declaration, flattened into each command, so the four parse, check and document them
//! the same way.

use std::ffi::OsStr;
use std::fmt::Display;
use std::marker::PhantomData;
use std::str::FromStr;

use clap::Args;
use clap::builder::{PossibleValue, TypedValueParser};
use dips_exec::{ExecProfile, PoseEstimate, Press, RegraspGuard};
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::Task;
use dips_kernel::search::{CostToCome, SearchOverrides};
use dips_kernel::task::CardGoals;
use dips_onnx::EngineKind;
use dips_planning::first_mode::FirstModeRule;
use dips_planning::online::{Method, SearchDepth};
use dips_planning::sized::PlannerSize;
use dips_planning::stop_rule::StopRule;
use dips_world::scenes::SceneKind;

/// A domain value that the command line reads with its own `FromStr` (whose error names the
/// value and the allowed ones) and lists in `--help` by its names.
pub trait Named: FromStr<Err: Display> + Clone + Send + Sync + 'static {
    /// Every name `FromStr` reads.
    const NAMES: &'static [&'static str];
    /// What each name means, in [`Named::NAMES`] order, for `--help` (empty: none).
    const HELP: &'static [&'static str] = &[];
}

impl Named for Task {
    const NAMES: &'static [&'static str] = &Task::NAMES;
}

impl Named for SceneKind {
    const NAMES: &'static [&'static str] = &Task::NAMES;
}

impl Named for Method {
    const NAMES: &'static [&'static str] = &Method::NAMES;
}

impl Named for CostToCome {
    const NAMES: &'static [&'static str] = &CostToCome::NAMES;
    const HELP: &'static [&'static str] = &[
        "`g` = the sum of the expected segment costs along the sequence (the paper's equation)",
        "`g` = the expected cost of the last segment only (the authors' code)",
    ];
}

impl Named for CardGoals {
    const NAMES: &'static [&'static str] = &CardGoals::NAMES;
    const HELP: &'static [&'static str] = &[
        "Every push aims 2 cm on; the goal test is ȳ ≤ o_G (the paper's card)",
        "Pushes stop at o_G; the goal test passes within 1 mm of it (ours)",
    ];
}

/// `--card-goals` of `dips episode` and `dips eval`: where the card's pushes aim and when its
/// search goal is reached. Given or not, it must agree with the models' (`dips.card_goals`);
/// left out, the models' is used (ours without models).
#[derive(Debug, Clone, Copy, Default, Args)]
pub struct CardGoalsArgs {
    /// The card's goals: `paper` (every push aims 2 cm on, goal test ȳ ≤ o_G) or `capped`
    /// (ours: pushes stop at o_G, goal test within 1 mm). Default: the models' own
    /// (`dips.card_goals`), else `capped`. The card only.
    #[arg(long, value_parser = named::<CardGoals>())]
    pub card_goals: Option<CardGoals>,
}

impl CardGoalsArgs {
    /// The goals given, checked against the task: an error for the screwdriver, whose modes
    /// have no pushes.
    pub fn given(&self, task: Task) -> anyhow::Result<Option<CardGoals>> {
        match (self.card_goals, task) {
            (Some(g), Task::Screwdriver) => anyhow::bail!(
                "--card-goals {g}: the screwdriver has no pushes; --card-goals is for --task card"
            ),
            (given, _) => Ok(given),
        }
    }

    /// The card goals of the run: `--card-goals` (checked by [`Self::given`]), else `fallback`
    /// (a protocol's), resolved against the models' (`(directory, goals)`) by
    /// [`dips_planning::resolve_card_goals`]; a mismatch names the flag and the fix.
    pub fn resolve(
        &self,
        task: Task,
        fallback: Option<CardGoals>,
        models: Option<(&std::path::Path, CardGoals)>,
    ) -> anyhow::Result<CardGoals> {
        let given = self.given(task)?.or(fallback);
        dips_planning::resolve_card_goals(given, models).map_err(|e| {
            anyhow::anyhow!(
                "--card-goals {}: {e}; give --card-goals {}, or models trained with `dips \
                 datagen --card-goals {}`",
                e.given,
                e.trained,
                e.given
            )
        })
    }
}

impl Named for SearchDepth {
    const NAMES: &'static [&'static str] = &SearchDepth::NAMES;
    const HELP: &'static [&'static str] = &[
        "The task's mode limit on every call (the paper's screwdriver: 7 throughout)",
        "The modes the episode has left (the paper's card)",
    ];
}

impl Named for EngineKind {
    const NAMES: &'static [&'static str] = &EngineKind::NAMES;
    const HELP: &'static [&'static str] = &[
        "tract-onnx on the `.onnx` file",
        "The dips-kernel interpreter on the lowered blob",
    ];
}

impl Named for StopRule {
    const NAMES: &'static [&'static str] = &StopRule::NAMES;
    const HELP: &'static [&'static str] = &[
        "Stop when a plan holds no mode (the paper's)",
        "Also stop when the plan's expected end is no nearer the goal than here (ours)",
    ];
}

impl Named for FirstModeRule {
    const NAMES: &'static [&'static str] = &FirstModeRule::NAMES;
    const HELP: &'static [&'static str] = &[
        "Any of the task's modes (the paper's)",
        "Only modes whose contact fingers touch the object, within 4 mm (ours)",
    ];
}

impl Named for ExecProfile {
    const NAMES: &'static [&'static str] = &ExecProfile::NAMES;
    const HELP: &'static [&'static str] = &[
        "The paper's simulation settings",
        "The paper's hardware experiment's (§V-D): α_J 1e-2, 250/50 iterations, the thumb's \
         and middle finger's diffused turn forces redrawn; screwdriver only",
    ];
}

impl Named for PoseEstimate {
    const NAMES: &'static [&'static str] = &PoseEstimate::NAMES;
    const HELP: &'static [&'static str] = &[
        "The tracker's reading as it comes",
        "The tracker's reading fused with the mode's contacts (fingertips on the surface)",
    ];
}

impl Named for Press {
    const NAMES: &'static [&'static str] = &Press::NAMES;
    const HELP: &'static [&'static str] = &[
        "Contact fingers press with at least 0.05 N (the problems the data were made with)",
        "Contact fingers press with at least 0.3 N in the executed modes",
    ];
}

impl Named for RegraspGuard {
    const NAMES: &'static [&'static str] = &RegraspGuard::NAMES;
    const HELP: &'static [&'static str] = &[
        "Every command as CSVTO's plan gives it (the paper's execution)",
        "Regrasping fingers kept 7.5 mm clear of the object until their touch-down step",
    ];
}

/// `--exec-profile`, `--pose-estimate` and `--regrasp-guard` of `dips episode` and `dips
/// eval`: how the modes are executed (which of the paper's CSVTO settings, from which object
/// pose, with which guard on the commands). The planner and its models are the same under
/// all.
#[derive(Debug, Clone, Copy, Default, Args)]
pub struct ExecProfileArgs {
    /// The CSVTO settings that execute the modes: `simulation` (the default) or `hardware`
    /// (the paper's hardware experiment, §V-D: α_J 1e-2, 250/50 iterations, the thumb's and
    /// middle finger's diffused `turn` forces redrawn; the screwdriver only). `dips eval`
    /// resumes with the directory's.
    #[arg(long, value_parser = named::<ExecProfile>())]
    pub exec_profile: Option<ExecProfile>,
    /// The object pose each CSVTO solve starts from: `tracker` (the default: the hand's
    /// reading as it comes) or `contacts` (that reading fused with the mode's contacts, for
    /// a noisy tracker; docs/mujoco.md). `dips eval` resumes with the directory's.
    #[arg(long, value_parser = named::<PoseEstimate>())]
    pub pose_estimate: Option<PoseEstimate>,
    /// Whether the controller guards regrasping fingers' commands: `off` (the default: the
    /// paper's execution) or `clearance` (no regrasping finger is commanded closer than
    /// 7.5 mm to the object before its mode's last step; one that is closer is lifted away
    /// from the surface; docs/mujoco.md). `dips eval` resumes with the directory's.
    #[arg(long, value_parser = named::<RegraspGuard>())]
    pub regrasp_guard: Option<RegraspGuard>,
    /// How hard the contact fingers of executed modes press at least: `light` (the default,
    /// 0.05 N, the problems the data were generated with) or `firm` (0.3 N, for a hand with
    /// compliant contacts; docs/mujoco.md, "A firmer press"). Execution only: the planner and
    /// its models are unchanged. `dips eval` resumes with the directory's.
    #[arg(long, value_parser = named::<Press>())]
    pub press: Option<Press>,
}

impl Named for PlannerSize {
    const NAMES: &'static [&'static str] = &PlannerSize::NAMES;
    const HELP: &'static [&'static str] = &[
        "The firmware's PaperPlanner: 512 nodes, 256 open",
        "The host's: 4 096 nodes, 2 048 open",
    ];
}

/// clap's parser of a [`Named`] value (`value_parser = named::<SceneKind>()`): the value's
/// `FromStr`, its message as the error, its names as the possible values of `--help`.
#[derive(Debug)]
pub struct NamedParser<T>(PhantomData<fn() -> T>);

impl<T> Clone for NamedParser<T> {
    fn clone(&self) -> Self {
        Self(PhantomData)
    }
}

/// The parser of a [`Named`] value.
pub fn named<T: Named>() -> NamedParser<T> {
    NamedParser(PhantomData)
}

impl<T: Named> TypedValueParser for NamedParser<T> {
    type Value = T;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        _arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<T, clap::Error> {
        let text = value.to_string_lossy();
        text.trim().parse::<T>().map_err(|e| {
            clap::Error::raw(clap::error::ErrorKind::InvalidValue, format!("{e}\n")).with_cmd(cmd)
        })
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(T::NAMES.iter().enumerate().map(
            |(i, name)| match T::HELP.get(i) {
                Some(help) => PossibleValue::new(name).help(*help),
                None => PossibleValue::new(name),
            },
        )))
    }
}

/// The sampler of `dips episode`, `dips eval`, `dips plan` and `dips bench plan` when none
/// is given: the paper's ancestral DDPM (posterior noise × 0.5) over 16 strided steps, 16
/// times fewer denoiser calls than its DDPM-256 (`--sampler ddpm`). On the screwdriver it
/// planned as well as DDPM-256 where strided DDIM (`ddim:16:1`, the default until
/// 2026-11-26) did not; deterministic DDIM (η = 0) misplaces the object (`docs/online.md`,
/// "Sampler").
pub const DEFAULT_SAMPLER: &str = "ddpm:16";

/// A seed (`--seed`): a whole number from 0 to 2^64 − 1; the message says so.
pub fn parse_seed(s: &str) -> Result<u64, String> {
    s.trim().parse::<u64>().map_err(|_| {
        format!(
            "seeds are non-negative integers (0 to {}), got `{s}`",
            u64::MAX
        )
    })
}

/// A whole number ≥ `min` (`--max-modes`, `--threads`, `--calls`): the message names the
/// bound.
pub fn parse_count(s: &str, min: u64) -> Result<u64, String> {
    match s.trim().parse::<i128>() {
        Ok(v) if v >= i128::from(min) && v <= i128::from(u64::MAX) => Ok(v as u64),
        Ok(_) => Err(format!("must be a whole number ≥ {min}, got `{s}`")),
        Err(_) => Err(format!("must be a whole number ≥ {min}, got `{s}`")),
    }
}

/// A count of at least 1 (`--max-modes`, `--threads`).
pub fn parse_positive(s: &str) -> Result<usize, String> {
    parse_count(s, 1)
        .ok()
        .and_then(|v| usize::try_from(v).ok())
        .ok_or_else(|| format!("must be a whole number ≥ 1, got `{s}`"))
}

/// `--node-budget`: a whole number ≥ 0 (0: the planner's capacity).
pub fn parse_node_budget(s: &str) -> Result<u32, String> {
    parse_count(s, 0)
        .ok()
        .and_then(|v| u32::try_from(v).ok())
        .ok_or_else(|| {
            format!(
                "must be a whole number from 0 (the planner's capacity) to {}, got `{s}`",
                u32::MAX
            )
        })
}

/// `--time-budget-s`: seconds ≥ 0 (0: no budget), finite.
pub fn parse_budget_s(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!(
            "must be a finite number of seconds ≥ 0 (0: no budget), got `{s}`"
        )),
    }
}

/// The flags of an episode's planning beyond one call's search, for `dips episode` and
/// `dips eval` (a single planning call, `dips plan`, takes `--depth` instead).
#[derive(Debug, Clone, Args)]
pub struct OnlineArgs {
    /// How deep each planning call searches: `fixed` (the task's mode limit on every call,
    /// the paper's screwdriver) or `modes-left` (the modes the episode has left, the paper's
    /// card). Default: the task's (`docs/online.md`, "Search depth").
    #[arg(long, value_parser = named::<SearchDepth>())]
    pub search_depth: Option<SearchDepth>,
    /// When a searching method stops before the mode limit: `goal-reached` (a plan holds no
    /// mode; the paper's) or `no-gain` (also when the plan's expected end is no nearer the
    /// goal than here; ours, `docs/online.md`, "Stopping and the planner's size").
    #[arg(long, value_parser = named::<StopRule>(), default_value = "goal-reached")]
    pub stop_rule: StopRule,
    /// Which modes a plan may begin with: `any` (the paper's) or `touching` (only modes whose
    /// contact fingers are within 4 mm of the object at the measured state; ours,
    /// `docs/online.md`, "The first mode").
    #[arg(long, value_parser = named::<FirstModeRule>(), default_value = "any")]
    pub first_mode: FirstModeRule,
    /// The in-process planner's capacities: `paper` (the firmware's `PaperPlanner`, 512
    /// nodes, 256 open) or `host` (4 096 nodes, 2 048 open). A `--kernel` over the wire has
    /// its own.
    #[arg(long, value_parser = named::<PlannerSize>(), default_value = "paper")]
    pub planner_size: PlannerSize,
}

/// The flags that set how a planning call searches, beyond the task's own settings.
#[derive(Debug, Clone, Args)]
pub struct SearchArgs {
    /// Diffusion sampler of the search (and of CSVTO's initialisation in episodes): `ddpm`
    /// (the paper's 256 steps), `ddpm:STEPS` or `ddim:STEPS[:ETA]`.
    #[arg(long, default_value = DEFAULT_SAMPLER)]
    pub sampler: SamplerConfig,
    /// Wall-clock budget of each planning call in seconds (0: none; the paper's: 300).
    #[arg(
        long,
        default_value_t = 300.0,
        allow_negative_numbers = true,
        value_parser = parse_budget_s
    )]
    pub time_budget_s: f64,
    /// Most node expansions per planning call (0: the planner's capacity). Default: the
    /// task's (screwdriver 13, card 0; `docs/search.md`, "Node budget").
    #[arg(long, allow_negative_numbers = true, value_parser = parse_node_budget)]
    pub node_budget: Option<u32>,
    /// How the search forms the cost-to-come `g`: `cumulative` (the paper's equation) or
    /// `last-segment` (the authors' code). Default: the task's (`docs/search.md`).
    #[arg(long, value_parser = named::<CostToCome>())]
    pub cost_to_come: Option<CostToCome>,
    /// Weight α of the heuristic's terminal cost (≥ 0). Default: the task's, screwdriver 1e4
    /// (the paper's), card 1e5 (the authors' code's; the paper's is 1e4).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_weight)]
    pub alpha: Option<f32>,
    /// Weight β of the heuristic's prior term (≥ 0). Default: the task's, screwdriver 1e3
    /// (the paper's), card 0 (the authors' code's; the paper's is 1e3).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_weight)]
    pub beta: Option<f32>,
}

/// `--alpha`, `--beta`: a finite weight ≥ 0.
pub fn parse_weight(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("must be a finite number ≥ 0, got `{s}`")),
    }
}

impl SearchArgs {
    /// The search settings these flags give over the task's ([`SearchOverrides`]: the node
    /// budget, the cost-to-come, α and β; `None`: the task's), resolved by
    /// [`SearchOverrides::resolve`].
    pub fn overrides(&self) -> SearchOverrides {
        SearchOverrides {
            node_budget: self.node_budget,
            cost_to_come: self.cost_to_come,
            alpha: self.alpha,
            beta: self.beta,
            ..SearchOverrides::default()
        }
    }

    /// `--time-budget-s` as checked seconds ([`dips_planning::online::check_time_budget_s`]).
    pub fn time_budget_s(&self) -> anyhow::Result<f64> {
        Ok(dips_planning::online::check_time_budget_s(
            self.time_budget_s,
        )?)
    }

    /// `--time-budget-s` checked, in the kernel's milliseconds
    /// ([`dips_planning::online::time_budget_ms`]).
    pub fn time_budget_ms(&self) -> anyhow::Result<u32> {
        Ok(dips_planning::online::time_budget_ms(self.time_budget_s()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        search: SearchArgs,
    }

    fn parse(extra: &[&str]) -> Result<SearchArgs, clap::Error> {
        let mut argv = vec!["dips-x"];
        argv.extend_from_slice(extra);
        Cli::try_parse_from(argv).map(|c| c.search)
    }

    #[test]
    fn defaults_are_the_papers_budget_and_the_fast_sampler() {
        let a = parse(&[]).unwrap();
        assert_eq!(a.sampler.method.to_string(), DEFAULT_SAMPLER);
        assert_eq!(a.time_budget_ms().unwrap(), 300_000);
        assert_eq!(a.node_budget, None);
        let budget = |task| a.overrides().resolve(task, 0, 0).node_budget;
        assert_eq!(
            budget(Task::Screwdriver),
            13,
            "the screwdriver's own budget"
        );
        assert_eq!(budget(Task::Card), 0);
        assert_eq!(a.cost_to_come, None);
        assert_eq!(a.sampler, DEFAULT_SAMPLER.parse::<SamplerConfig>().unwrap());
    }

    #[test]
    fn flags_are_parsed_and_bad_values_named() {
        let a = parse(&[
            "--sampler",
            "ddim:8",
            "--time-budget-s",
            "0.25",
            "--node-budget",
            "7",
            "--cost-to-come",
            "last-segment",
        ])
        .unwrap();
        assert_eq!(a.time_budget_ms().unwrap(), 250);
        assert_eq!(a.node_budget, Some(7));
        let sd = |a: &SearchArgs| a.overrides().resolve(Task::Screwdriver, 0, 0);
        assert_eq!(sd(&a).node_budget, 7, "a given budget wins");
        let none = parse(&["--node-budget", "0"]).unwrap();
        assert_eq!(sd(&none).node_budget, 0, "0 lifts the task's budget");
        assert_eq!(a.cost_to_come, Some(CostToCome::LastSegment));
        assert_eq!(sd(&a).cost_to_come, CostToCome::LastSegment);
        assert_eq!(a.sampler, SamplerConfig::ddim(8));

        for bad in ["-1", "inf", "NaN"] {
            let e = parse(&["--time-budget-s", bad]).unwrap_err().to_string();
            assert!(e.contains("--time-budget-s") && e.contains("≥ 0"), "{e}");
        }
        let e = parse(&["--node-budget", "-1"]).unwrap_err().to_string();
        assert!(e.contains("--node-budget") && e.contains("from 0"), "{e}");
        let e = parse(&["--sampler", "ddim"]).unwrap_err().to_string();
        assert!(e.contains("--sampler"), "{e}");
        let e = parse(&["--cost-to-come", "sum"]).unwrap_err().to_string();
        assert!(
            e.contains("unknown cost-to-come `sum` (expected cumulative or last-segment)"),
            "{e}"
        );
    }

    #[derive(Debug, Parser)]
    struct DepthCli {
        #[command(flatten)]
        depth: OnlineArgs,
    }

    #[test]
    fn search_depth_defaults_to_the_tasks_and_names_its_values() {
        let depth = |extra: &[&str]| {
            let mut argv = vec!["dips-x"];
            argv.extend_from_slice(extra);
            DepthCli::try_parse_from(argv).map(|c| c.depth.search_depth)
        };
        assert_eq!(depth(&[]).unwrap(), None);
        assert_eq!(
            depth(&["--search-depth", "modes-left"]).unwrap(),
            Some(SearchDepth::ModesLeft)
        );
        assert_eq!(
            depth(&["--search-depth", "fixed"]).unwrap(),
            Some(SearchDepth::Fixed)
        );
        let e = depth(&["--search-depth", "7"]).unwrap_err().to_string();
        assert!(e.contains("fixed") && e.contains("modes-left"), "{e}");
    }
}
