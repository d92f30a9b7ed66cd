//! Closed-loop episodes: a contact sequence executed mode by mode, and its result
//! (`docs/contracts.md` §5).

use std::collections::BTreeMap;
use std::path::Path;

use dips_kernel::rng::KernelRng;
use dips_kernel::search::ParticleDiagnostics;
use dips_kernel::task::CardGoals;
use serde::Serialize;

use super::mode_run::{ExecError, ModeRun, StepParticles, run_mode_observed, true_hand_state};
use super::settings::{ExecProfile, ExecSettings};
use crate::pose_estimate::PoseEstimate;
use crate::press::Press;
use crate::problems::Mode;
use crate::regrasp_guard::RegraspGuard;
use dips_world::hand::Hand;
use dips_world::kinematics::HandModel;
use dips_world::scenes::{SceneKind, card};
use dips_world::world::World;

/// Modes per screwdriver episode (sim).
pub const SCREWDRIVER_MODES: usize = 7;
/// Modes per card episode.
pub const CARD_MODES: usize = 5;

/// The screwdriver's two regrasps in random order (one draw of `rng`).
fn both_regrasps(rng: &mut KernelRng) -> [Mode; 2] {
    if rng.below(2) == 0 {
        [Mode::IndexRegrasp, Mode::ThumbMiddleRegrasp]
    } else {
        [Mode::ThumbMiddleRegrasp, Mode::IndexRegrasp]
    }
}

/// Draw a contact sequence from the task's data-generation prior (spec §4.3): screwdriver
/// "turn, then both regrasps in random order, repeated" (7 modes); card uniform (5 modes).
pub fn sample_prior_sequence(task: SceneKind, rng: &mut KernelRng) -> Vec<Mode> {
    match task {
        SceneKind::Screwdriver => {
            let mut seq = Vec::with_capacity(SCREWDRIVER_MODES);
            while seq.len() < SCREWDRIVER_MODES {
                seq.push(Mode::Turn);
                for m in both_regrasps(rng) {
                    if seq.len() < SCREWDRIVER_MODES {
                        seq.push(m);
                    }
                }
            }
            seq
        }
        SceneKind::Card => {
            let all = task.modes();
            (0..CARD_MODES)
                .map(|_| all[rng.below(all.len() as u32) as usize])
                .collect()
        }
    }
}

/// Where a demo's contact sequence comes from (`dips datagen --sequences`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SequenceSource {
    /// The paper's data-generation sequences ([`sample_prior_sequence`]): the screwdriver's
    /// "turn, then both regrasps in random order, repeated", which never holds two turns in a
    /// row or a turn after a single regrasp; the card's uniform modes.
    #[default]
    Pattern,
    /// Chains drawn from the paper's Markov prior p(C) (`MarkovPrior::paper`: screwdriver
    /// p(turn) = 0.8 first, the same mode again 0.1, each other 0.45; card uniform), the
    /// prior the search plans with, so the demos hold every transition a plan can choose.
    Markov,
    /// Runs of consecutive turns, as the planner executes them ([`sample_turn_run_sequence`]):
    /// the screwdriver's turn runs of 2–5 separated by one or both regrasps, so the demos hold
    /// late turns after turns, the ones that turn short or tip; card uniform.
    TurnRuns,
}

impl SequenceSource {
    /// Parse one of `dips_dataset::SEQUENCE_SOURCES`: `pattern`, `markov` or `turn-runs`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "pattern" => Some(Self::Pattern),
            "markov" => Some(Self::Markov),
            "turn-runs" => Some(Self::TurnRuns),
            _ => None,
        }
    }

    /// The name [`Self::from_name`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Self::Pattern => "pattern",
            Self::Markov => "markov",
            Self::TurnRuns => "turn-runs",
        }
    }
}

/// Shortest and longest run of consecutive screwdriver turns in a
/// [`SequenceSource::TurnRuns`] sequence.
pub const TURN_RUN_LENGTHS: (u32, u32) = (2, 5);

/// Draw a sequence of runs of consecutive turns (7 screwdriver modes): a run of
/// [`TURN_RUN_LENGTHS`] turns (uniform), then a break of one regrasp (either finger group) or
/// both in random order (each break kind with probability 1/2), repeated. The planner executes
/// such runs (its plans hold up to seven turns in a row), while the paper's pattern never
/// holds two turns in a row and its Markov prior repeats a mode with probability 0.1, so late
/// turns after turns, which turn short or tip the screwdriver, are rare in both. The card's
/// modes are uniform, as in the other sources.
pub fn sample_turn_run_sequence(task: SceneKind, rng: &mut KernelRng) -> Vec<Mode> {
    let SceneKind::Screwdriver = task else {
        return sample_prior_sequence(task, rng);
    };
    let (lo, hi) = TURN_RUN_LENGTHS;
    let mut seq = Vec::with_capacity(SCREWDRIVER_MODES);
    while seq.len() < SCREWDRIVER_MODES {
        let run = lo + rng.below(hi - lo + 1);
        seq.extend(std::iter::repeat_n(Mode::Turn, run as usize));
        let regrasps = both_regrasps(rng);
        let count = if rng.below(2) == 0 { 1 } else { 2 };
        seq.extend_from_slice(&regrasps[..count]);
    }
    seq.truncate(SCREWDRIVER_MODES);
    seq
}

/// Draw a sequence of the task's length (7 screwdriver, 5 card modes) from the paper's Markov
/// prior p(C) (`MarkovPrior::paper` with the task's search `p_min`, as the planner uses it).
pub fn sample_markov_sequence(task: SceneKind, rng: &mut KernelRng) -> Vec<Mode> {
    use dips_kernel::mode::ModeId;
    let kt = task.task();
    let p_min = dips_kernel::search::SearchConfig::for_task(kt).p_min;
    let prior = dips_kernel::prior::MarkovPrior::paper(kt, p_min)
        .expect("the paper's prior is a valid table for every task");
    let n = prior.modes();
    let len = match task {
        SceneKind::Screwdriver => SCREWDRIVER_MODES,
        SceneKind::Card => CARD_MODES,
    };
    let mut prev: Option<ModeId> = None;
    let mut seq = Vec::with_capacity(len);
    for _ in 0..len {
        let w: Vec<f32> = (0..n)
            .map(|i| prior.probability(prev, ModeId(i as u8)))
            .collect();
        let id = ModeId(rng.weighted_index(&w).unwrap_or(0) as u8);
        let Some(mode) = Mode::from_id(kt, id) else {
            break;
        };
        seq.push(mode);
        prev = Some(id);
    }
    seq
}

/// The sequence of demo `seed` from `source`, drawn from the seed's own stream
/// ([`prior_sequence_for_seed`] is the [`SequenceSource::Pattern`] case).
pub fn sequence_for_seed(task: SceneKind, seed: u64, source: SequenceSource) -> Vec<Mode> {
    let mut rng = KernelRng::seed_from_u64(seed ^ 0x5eed_c0de);
    match source {
        SequenceSource::Pattern => sample_prior_sequence(task, &mut rng),
        SequenceSource::Markov => sample_markov_sequence(task, &mut rng),
        SequenceSource::TurnRuns => sample_turn_run_sequence(task, &mut rng),
    }
}

/// The prior sequence of episode `seed`: [`sample_prior_sequence`] with its own stream of the
/// seed, so that `dips episode --seed S` and demo `S` of `dips datagen` execute the same modes.
pub fn prior_sequence_for_seed(task: SceneKind, seed: u64) -> Vec<Mode> {
    sequence_for_seed(task, seed, SequenceSource::Pattern)
}

/// Screwdriver success: still valid and turned at least this far (rad, clockwise negative):
/// one planning goal's worth, `π/3`.
pub const SCREWDRIVER_SUCCESS_YAW: f64 = -std::f64::consts::FRAC_PI_3;

/// Card success: still valid and within this planar distance of its goal (m).
pub const CARD_SUCCESS_DISTANCE_M: f64 = 0.01;

/// The rule [`episode_success`] applies to `task`, in words (`result.json`'s `success_rule`).
pub fn success_rule(task: SceneKind) -> &'static str {
    match task {
        SceneKind::Screwdriver => "valid and final yaw <= -pi/3 rad (-1.047)",
        SceneKind::Card => "valid and final distance to the goal <= 1 cm",
    }
}

/// Whether an episode succeeded: the object stayed valid and the outcome passed the task's
/// threshold ([`SCREWDRIVER_SUCCESS_YAW`], [`CARD_SUCCESS_DISTANCE_M`]). Our definition; the
/// paper reports the outcomes themselves.
pub fn episode_success(
    task: SceneKind,
    valid: bool,
    final_yaw: Option<f64>,
    final_distance_m: Option<f64>,
) -> bool {
    valid
        && match task {
            SceneKind::Screwdriver => final_yaw.is_some_and(|y| y <= SCREWDRIVER_SUCCESS_YAW),
            SceneKind::Card => final_distance_m.is_some_and(|d| d <= CARD_SUCCESS_DISTANCE_M),
        }
}

/// Names of the raw state vectors of `result.json` (`start_state`, `end_state`, each step's
/// `state` and `planned_state`): the task fingers' joints `q_<finger>_<j>`, then the object's
/// coordinates (screwdriver roll, pitch, yaw in rad; card x, y in m and yaw in rad).
pub fn state_columns(task: SceneKind) -> Vec<String> {
    let mut names: Vec<String> = task
        .task_fingers()
        .iter()
        .flat_map(|f| (0..4).map(move |j| format!("q_{}_{j}", f.name())))
        .collect();
    let object: [&str; 3] = match task {
        SceneKind::Screwdriver => ["roll", "pitch", "yaw"],
        SceneKind::Card => ["card_x", "card_y", "card_yaw"],
    };
    names.extend(object.map(String::from));
    names
}

/// `result.json` of one episode.
#[derive(Debug, Clone, Serialize)]
pub struct EpisodeResult {
    /// Task name.
    pub task: &'static str,
    /// Method name.
    pub method: String,
    /// The hand that executed the episode ([`Hand::name`]):
    /// `"world"` (our quasi-static world) or `"mujoco"` (`host/mujoco`). A `result.json`
    /// written before the field existed ran on our world.
    pub hand: &'static str,
    /// Seed.
    pub seed: u64,
    /// Executed modes, by name.
    pub modes: Vec<&'static str>,
    /// Final yaw (screwdriver, rad, clockwise negative).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_yaw: Option<f64>,
    /// Final planar distance of the card to its goal (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_distance_m: Option<f64>,
    /// Final card displacement along y from its start (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_dy_m: Option<f64>,
    /// Whether the object stayed valid over the whole episode.
    pub valid: bool,
    /// Whether the episode succeeded ([`episode_success`]).
    pub success: bool,
    /// The rule behind `success`, in words.
    pub success_rule: &'static str,
    /// Names of the raw state vectors' entries ([`state_columns`]).
    pub state_columns: Vec<String>,
    /// Names of the entries of `plans[].expected_terminal_state` (the model contract's state
    /// columns: the yaw as its cosine and sine).
    pub plan_state_columns: &'static [&'static str],
    /// Planning time per mode (s); no search for csvto-sampled, so zeros.
    pub planning_s: Vec<f64>,
    /// CSVTO solve time per executed step (s).
    pub csvto_step_s: Vec<f64>,
    /// Per-mode details (start/end states, per-step logs, regrasp distances).
    pub mode_runs: Vec<ModeRun>,
    /// The world state the episode began in, written only when no mode ran (a first planning
    /// call that planned nothing): otherwise the first mode run's `start_state` holds it. It is
    /// what a report of such an episode draws.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_state: Option<Vec<f64>>,
    /// Every planning call of a searching method, in order (empty for fixed sequences).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub plans: Vec<PlanRecord>,
    /// The card's goals the episode's pushes (and its planner) aimed for
    /// ([`ExecSettings::card_goals`]); left out when ours, the default, as in files written
    /// before it was recorded.
    #[serde(skip_serializing_if = "CardGoals::is_capped")]
    pub card_goals: CardGoals,
    /// The CSVTO settings the modes were executed with ([`ExecSettings::profile`]); left out
    /// when the simulation's, as in files written before it was recorded.
    #[serde(skip_serializing_if = "ExecProfile::is_simulation")]
    pub exec_profile: ExecProfile,
    /// The object pose the modes' solves started from ([`ExecSettings::pose_estimate`]); left
    /// out when the tracker's, as in files written before it was recorded.
    #[serde(skip_serializing_if = "PoseEstimate::is_tracker")]
    pub pose_estimate: PoseEstimate,
    /// Whether regrasping fingers' commands were guarded ([`ExecSettings::regrasp_guard`]);
    /// left out when off, as in files written before the guard existed.
    #[serde(skip_serializing_if = "RegraspGuard::is_off")]
    pub regrasp_guard: RegraspGuard,
    /// How hard contact fingers pressed ([`ExecSettings::press`]); left out when light, as in
    /// files written before it was recorded.
    #[serde(skip_serializing_if = "Press::is_light")]
    pub press: Press,
    /// What the hand measured of itself over the episode ([`Hand::report`]): for the Allegro
    /// driver, its options, the loop's period statistics and the frames counted. Left out for
    /// simulated hands.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hand_report: Option<serde_json::Value>,
}

/// One planning call of an online method (`result.json`'s `plans`).
#[derive(Debug, Clone, Serialize)]
pub struct PlanRecord {
    /// Modes executed before the call.
    pub executed: usize,
    /// The goal searched for (yaw in rad, or card y in m).
    pub goal: f32,
    /// The search depth: the most modes a plan may hold.
    pub depth: u8,
    /// The planned modes, by name (the first is executed next).
    pub modes: Vec<&'static str>,
    /// How the search ended (`Found`, `Approximate(..)`, ...).
    pub status: String,
    /// Expected terminal state of the plan (contract state columns; `null` where not finite).
    pub expected_terminal_state: Vec<Option<f32>>,
    /// Node expansions.
    pub nodes_expanded: u32,
    /// Diffused segments sampled over the call (`|modes| · k` per expansion; `|modes| · 16`
    /// for the max-likelihood variant, which keeps the best of each 16).
    pub segments_sampled: u32,
    /// Particles of the plan's result node (`k`; 1 for `dips-k1` and
    /// `dips-max-likelihood`).
    pub particles: u8,
    /// Effective particles of its normalised Ψ scores (`1 / Σ w²`).
    pub effective_particles: Option<f32>,
    /// Wall time of the call (s).
    pub seconds: f64,
    /// What the particles and Ψ did in the call (in-process planning only; a kernel over the
    /// wire keeps them to itself). `docs/particles.md`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub particles_diagnostics: Option<ParticleSummary>,
    /// The modes the plan could begin with, when fewer than the task's
    /// (`--first-mode touching` with a contact finger off the object). Written only then.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_modes: Option<Vec<&'static str>>,
    /// The episode stopped instead of executing this plan: its expected end was no nearer the
    /// goal than the state it started from (`--stop-rule no-gain`). Written only when true.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub stopped_no_gain: bool,
}

/// [`ParticleDiagnostics`] of one planning call as means, for `result.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParticleSummary {
    /// Children created over the call (one per mode per expansion).
    pub children: u32,
    /// Mean effective number of a child's accumulated scores before resampling (out of `k`).
    pub ess_scores_mean: f32,
    /// The smallest.
    pub ess_scores_min: f32,
    /// Mean effective number of Ψ alone over a child's `k` fresh samples (`k` when Ψ is flat).
    pub ess_psi_mean: f32,
    /// The smallest.
    pub ess_psi_min: f32,
    /// Mean distinct samples drawn by a child's resampling.
    pub distinct_mean: f32,
    /// Ψ over every sampled segment: mean and standard deviation.
    pub psi_mean: f32,
    /// Standard deviation of Ψ.
    pub psi_std: f32,
    /// Ψ histogram, 10 bins over `[0, 1]`.
    pub psi_histogram: Vec<u32>,
    /// Per mode (by name): mean standard deviation of a child's `k` samples' end progress
    /// (yaw in rad, card y in m).
    pub progress_spread: BTreeMap<String, f32>,
    /// Mean |weighted − plain mean| of a child's samples' end progress: how far the scores
    /// move the estimate (rad or m).
    pub weight_shift_mean: f32,
}

impl ParticleSummary {
    /// The means of `d`; `mode_name(i)` names candidate mode `i`. `None` when the call created
    /// no child.
    pub fn of(
        d: &ParticleDiagnostics,
        mode_name: impl Fn(usize) -> Option<String>,
    ) -> Option<Self> {
        if d.children == 0 {
            return None;
        }
        let n = d.children as f32;
        let segments: u32 = d.psi_histogram.iter().sum();
        let (psi_mean, psi_std) = if segments > 0 {
            let m = d.psi_sum / segments as f32;
            (m, (d.psi_sq_sum / segments as f32 - m * m).max(0.0).sqrt())
        } else {
            (f32::NAN, f32::NAN)
        };
        let progress_spread = (0..d.mode_children.len())
            .filter(|&i| d.mode_children[i] > 0)
            .filter_map(|i| {
                mode_name(i)
                    .map(|name| (name, d.progress_spread_sum[i] / d.mode_children[i] as f32))
            })
            .collect();
        Some(Self {
            children: d.children,
            ess_scores_mean: d.ess_scores_sum / n,
            ess_scores_min: d.ess_scores_min,
            ess_psi_mean: d.ess_psi_sum / n,
            ess_psi_min: d.ess_psi_min,
            distinct_mean: d.distinct_sum as f32 / n,
            psi_mean,
            psi_std,
            psi_histogram: d.psi_histogram.to_vec(),
            progress_spread,
            weight_shift_mean: d.weight_shift_sum / n,
        })
    }
}

impl EpisodeResult {
    /// Write as pretty JSON to `dir/result.json` atomically (temporary file, then rename).
    pub fn write(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(dir)?;
        let text = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        dips_fs::write_atomic(&dir.join("result.json"), text.as_bytes())
    }
}

/// Run `modes` from the scene's initial state in a fresh world.
pub fn run_episode(
    task: SceneKind,
    method: &str,
    seed: u64,
    modes: &[Mode],
    settings: &ExecSettings,
    progress: &mut dyn FnMut(&str),
) -> Result<EpisodeResult, ExecError> {
    let mut world = World::new(task);
    run_episode_on(&mut world, method, seed, modes, settings, progress)
}

/// Run `modes` on `hand` from its current state.
pub fn run_episode_on<H: Hand + ?Sized>(
    hand: &mut H,
    method: &str,
    seed: u64,
    modes: &[Mode],
    settings: &ExecSettings,
    progress: &mut dyn FnMut(&str),
) -> Result<EpisodeResult, ExecError> {
    run_episode_observed(
        hand,
        method,
        seed,
        modes,
        settings,
        progress,
        &mut |_, _| {},
    )
}

/// [`run_episode_on`] with an observer that sees every online step's solved particles, with
/// the index of the mode in `modes` (datasets record them).
pub fn run_episode_observed<H: Hand + ?Sized>(
    hand: &mut H,
    method: &str,
    seed: u64,
    modes: &[Mode],
    settings: &ExecSettings,
    progress: &mut dyn FnMut(&str),
    observe: &mut dyn FnMut(usize, StepParticles<'_>),
) -> Result<EpisodeResult, ExecError> {
    let task = hand.scene();
    let model = HandModel::allegro_v4();
    let mut rng = KernelRng::seed_from_u64(seed);
    let start = true_hand_state(hand);
    let mut runs = Vec::with_capacity(modes.len());
    let mut valid = hand.true_object_pose().valid(task);
    let mut step_s = Vec::new();
    for (i, &mode) in modes.iter().enumerate() {
        progress(&format!("mode {}/{}: {}", i + 1, modes.len(), mode.name()));
        let run = run_mode_observed(
            hand,
            &model,
            mode,
            settings,
            None,
            &mut rng,
            progress,
            &mut |step| observe(i, step),
        )?;
        valid &= run.steps.iter().all(|s| s.valid);
        step_s.extend(run.solve_times());
        runs.push(run);
    }
    let planning_s = vec![0.0; modes.len()];
    let end = true_hand_state(hand);
    let mut result = EpisodeResult::assemble(
        task, method, seed, &start, &end, runs, planning_s, step_s, valid,
    );
    result.record_execution(hand.name(), hand.report(), settings);
    Ok(result)
}

impl EpisodeResult {
    /// The result of `runs` executed from `start` to `end` (task states): the final yaw, or
    /// the card's distance to its goal and its displacement; no planning records.
    #[allow(clippy::too_many_arguments)]
    pub fn assemble(
        task: SceneKind,
        method: &str,
        seed: u64,
        start: &[f64],
        end: &[f64],
        runs: Vec<ModeRun>,
        planning_s: Vec<f64>,
        csvto_step_s: Vec<f64>,
        valid: bool,
    ) -> Self {
        let nq = end.len() - 3;
        let (final_yaw, final_distance_m, final_dy_m) = match task {
            SceneKind::Screwdriver => (Some(end[nq + 2]), None, None),
            SceneKind::Card => {
                let g = card::goal_from_start(start[nq], start[nq + 1]);
                let d = ((end[nq] - g[0]).powi(2) + (end[nq + 1] - g[1]).powi(2)).sqrt();
                (None, Some(d), Some(end[nq + 1] - start[nq + 1]))
            }
        };
        EpisodeResult {
            task: task.name(),
            method: method.to_string(),
            // Our world unless the caller says otherwise (`run_online` records its hand's).
            hand: "world",
            seed,
            modes: runs.iter().map(|r| r.mode).collect(),
            final_yaw,
            final_distance_m,
            final_dy_m,
            valid,
            success: episode_success(task, valid, final_yaw, final_distance_m),
            success_rule: success_rule(task),
            state_columns: state_columns(task),
            plan_state_columns: task.task().state_columns(),
            planning_s,
            csvto_step_s,
            start_state: runs.is_empty().then(|| start.to_vec()),
            mode_runs: runs,
            plans: Vec::new(),
            card_goals: CardGoals::default(),
            exec_profile: ExecProfile::Simulation,
            pose_estimate: PoseEstimate::Tracker,
            regrasp_guard: RegraspGuard::Off,
            press: Press::Light,
            hand_report: None,
        }
    }

    /// Record what executed the episode: the hand's name ([`Hand::name`]) and what it measured
    /// of itself ([`Hand::report`]: a driver's loop period and frame counts), and the execution
    /// settings that reach `result.json` (the card's goals, the CSVTO profile, the pose
    /// estimate, the regrasp guard, the press).
    pub fn record_execution(
        &mut self,
        hand: &'static str,
        hand_report: Option<serde_json::Value>,
        settings: &ExecSettings,
    ) {
        self.hand = hand;
        self.hand_report = hand_report;
        self.card_goals = settings.card_goals;
        self.exec_profile = settings.profile;
        self.pose_estimate = settings.pose_estimate;
        self.regrasp_guard = settings.regrasp_guard;
        self.press = settings.press;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Markov demo sequences follow the paper's prior: the screwdriver starts with a turn 80 %
    /// of the time and repeats a mode 10 % of the time; the card draws its four modes
    /// uniformly. Pattern sequences are unchanged by the option.
    #[test]
    fn markov_sequences_follow_the_papers_prior() {
        let n = 4000u64;
        let (mut first_turn, mut repeats, mut transitions) = (0, 0, 0);
        for seed in 0..n {
            let s = sequence_for_seed(SceneKind::Screwdriver, seed, SequenceSource::Markov);
            assert_eq!(s.len(), SCREWDRIVER_MODES);
            first_turn += usize::from(s[0] == Mode::Turn);
            repeats += s.windows(2).filter(|w| w[0] == w[1]).count();
            transitions += s.len() - 1;
        }
        let first = first_turn as f64 / n as f64;
        let repeat = repeats as f64 / transitions as f64;
        assert!((first - 0.8).abs() < 0.03, "p(turn first) {first}");
        assert!((repeat - 0.1).abs() < 0.02, "p(same mode again) {repeat}");
        let mut counts = [0usize; 4];
        for seed in 0..n {
            for m in sequence_for_seed(SceneKind::Card, seed, SequenceSource::Markov) {
                counts[SceneKind::Card
                    .modes()
                    .iter()
                    .position(|&c| c == m)
                    .unwrap()] += 1;
            }
        }
        for c in counts {
            let p = c as f64 / (n as usize * CARD_MODES) as f64;
            assert!((p - 0.25).abs() < 0.02, "card mode frequency {p}");
        }
        for seed in [0, 7, 41] {
            assert_eq!(
                sequence_for_seed(SceneKind::Screwdriver, seed, SequenceSource::Pattern),
                prior_sequence_for_seed(SceneKind::Screwdriver, seed)
            );
        }
    }

    /// Turn-run sequences start with two to five turns, break them with one or two distinct
    /// regrasps, never repeat a regrasp, and hold a turn right after a turn late in the
    /// episode (modes 4–6) in most demos; every run length and both break kinds occur.
    #[test]
    fn turn_run_sequences_hold_late_turns_after_turns() {
        let n = 2000u64;
        let (mut late_turn_after_turn, mut run_lengths, mut breaks) = (0, [0usize; 8], [0usize; 3]);
        for seed in 0..n {
            let s = sequence_for_seed(SceneKind::Screwdriver, seed, SequenceSource::TurnRuns);
            assert_eq!(s.len(), SCREWDRIVER_MODES);
            assert!(s[0] == Mode::Turn && s[1] == Mode::Turn, "{s:?}");
            assert!(
                s.windows(2).all(|w| w[0] == Mode::Turn || w[0] != w[1]),
                "a regrasp repeated: {s:?}"
            );
            late_turn_after_turn += usize::from(
                (4..SCREWDRIVER_MODES).any(|i| s[i] == Mode::Turn && s[i - 1] == Mode::Turn),
            );
            // Whole runs and breaks (the last of each may be cut at the 7th mode).
            let mut i = 0;
            while i < s.len() {
                let turn = s[i] == Mode::Turn;
                let j = (i..s.len())
                    .find(|&j| (s[j] == Mode::Turn) != turn)
                    .unwrap_or(s.len());
                let len = j - i;
                if j < s.len() {
                    if turn {
                        run_lengths[len] += 1;
                    } else {
                        breaks[len] += 1;
                    }
                }
                i = j;
            }
        }
        let (lo, hi) = TURN_RUN_LENGTHS;
        assert!(run_lengths[..lo as usize].iter().all(|&c| c == 0));
        assert!(
            run_lengths[lo as usize..=hi as usize]
                .iter()
                .all(|&c| c > 0)
        );
        assert!(run_lengths[hi as usize + 1..].iter().all(|&c| c == 0));
        assert!(breaks[1] > 0 && breaks[2] > 0 && breaks[0] == 0);
        assert!(
            late_turn_after_turn as f64 / n as f64 > 0.5,
            "late turn after turn in {late_turn_after_turn} of {n}"
        );
        // Every name the dataset format knows parses and round-trips, the default first.
        for name in dips_dataset::SEQUENCE_SOURCES {
            assert_eq!(
                SequenceSource::from_name(name).map(SequenceSource::name),
                Some(name)
            );
        }
        assert_eq!(
            SequenceSource::default().name(),
            dips_dataset::SEQUENCE_SOURCES[0]
        );
    }
}
