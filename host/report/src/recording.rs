//! What the pictures are drawn from: an episode's `result.json` or a `dips sim run`
//! trajectory, read into one list of world states with their contacts, labels and goals.

use std::path::Path;

use crate::render::Goal;
use dips_exec::problems::mode::parse_mode;
use dips_world::scenes::SceneKind;
use dips_world::world::ContactReport;
use serde::Deserialize;

use crate::ReportError;

/// One executed step of an episode (the fields of `result.json` the pictures use).
#[derive(Debug, Clone, Deserialize)]
pub struct StepView {
    /// CSVTO solve time before the step (s).
    pub solve_s: f64,
    /// World state after the step (`state_columns`).
    pub state: Vec<f64>,
    /// Signed distance of each task fingertip to the object after the step (m).
    pub tip_sdf: Vec<f64>,
    /// Whether the object was still valid.
    pub valid: bool,
    /// Contacts and forces after the step (absent in files written before they were logged).
    #[serde(default)]
    pub contacts: Vec<ContactReport>,
}

/// One executed mode.
#[derive(Debug, Clone, Deserialize)]
pub struct ModeRunView {
    /// Mode name.
    pub mode: String,
    /// The object goal of the mode (task coordinates).
    pub goal: [f64; 3],
    /// World state at the start of the mode.
    pub start_state: Vec<f64>,
    /// The steps.
    pub steps: Vec<StepView>,
}

/// One planning call.
#[derive(Debug, Clone, Deserialize)]
pub struct PlanView {
    /// Planned modes.
    pub modes: Vec<String>,
    /// Search status.
    pub status: String,
    /// Nodes expanded.
    pub nodes_expanded: u32,
    /// Seconds.
    pub seconds: f64,
}

impl PlanView {
    /// Whether the call found the episode already done: `Found` at the root with no mode
    /// planned and no node expanded (the last call of a card episode that reached its goal).
    /// It plans nothing, so it is listed but left out of planning-time statistics.
    pub fn finished(&self) -> bool {
        self.modes.is_empty() && self.nodes_expanded == 0 && self.status.starts_with("Found")
    }
}

/// An episode's `result.json` (`dips episode`, `dips eval`): the fields the pictures, the
/// reports and `dips eval`'s summary read.
#[derive(Debug, Clone, Deserialize)]
pub struct EpisodeFile {
    /// Task name.
    pub task: String,
    /// Method name.
    pub method: String,
    /// Seed.
    pub seed: u64,
    /// Executed modes.
    pub modes: Vec<String>,
    /// Final yaw (screwdriver, rad).
    #[serde(default)]
    pub final_yaw: Option<f64>,
    /// Final distance of the card to its goal (m).
    #[serde(default)]
    pub final_distance_m: Option<f64>,
    /// Whether the object stayed valid.
    pub valid: bool,
    /// Whether the episode succeeded.
    #[serde(default)]
    pub success: Option<bool>,
    /// The success rule in words.
    #[serde(default)]
    pub success_rule: Option<String>,
    /// Planning seconds per call.
    #[serde(default)]
    pub planning_s: Vec<f64>,
    /// CSVTO solve seconds per executed step.
    #[serde(default)]
    pub csvto_step_s: Vec<f64>,
    /// The executed modes in detail.
    pub mode_runs: Vec<ModeRunView>,
    /// The state the episode began in, present only when no mode ran.
    #[serde(default)]
    pub start_state: Option<Vec<f64>>,
    /// The planning calls.
    #[serde(default)]
    pub plans: Vec<PlanView>,
}

impl EpisodeFile {
    /// The planning-call times that count in statistics: [`EpisodeFile::planning_s`] without
    /// the calls that found the episode done ([`PlanView::finished`]).
    pub fn planning_times(&self) -> Vec<f64> {
        if self.plans.len() != self.planning_s.len() {
            return self.planning_s.clone();
        }
        self.planning_s
            .iter()
            .zip(&self.plans)
            .filter(|(_, p)| !p.finished())
            .map(|(&s, _)| s)
            .collect()
    }

    /// The task.
    pub fn scene(&self) -> Result<SceneKind, ReportError> {
        self.task.parse().map_err(|e| ReportError::Input {
            path: String::new(),
            reason: format!("{e}"),
        })
    }

    /// The outcome in words (final yaw or distance, validity, success).
    pub fn outcome(&self) -> String {
        let value = match (self.final_yaw, self.final_distance_m) {
            (Some(y), _) => format!("final yaw {y:.3} rad"),
            (_, Some(d)) => format!("final distance to the goal {} cm", fixed(100.0 * d, 2)),
            _ => "no outcome".to_string(),
        };
        let success = match self.success {
            Some(true) => ", success",
            Some(false) => ", no success",
            None => "",
        };
        format!(
            "{value}, {}{success}",
            if self.valid { "valid" } else { "INVALID" }
        )
    }
}

/// A `dips sim run` trajectory.
#[derive(Debug, Clone, Deserialize)]
struct SimTrajectory {
    scene: String,
    states: Vec<Vec<f64>>,
    #[serde(default)]
    valid: Vec<bool>,
    #[serde(default)]
    contacts: Vec<Vec<ContactReport>>,
}

/// One picture's worth of an episode: a world state and what to draw over it.
#[derive(Debug, Clone)]
pub struct Frame {
    /// World state (`state_columns`).
    pub state: Vec<f64>,
    /// Contacts with forces.
    pub contacts: Vec<ContactReport>,
    /// Goals to draw.
    pub goals: Vec<Goal>,
    /// The second heading line: mode, step, time, the object's coordinate against its goal.
    pub label: String,
    /// Seconds the frame is shown in an animation.
    pub hold_s: f64,
}

/// A sequence of frames of one task, with a title.
#[derive(Debug, Clone)]
pub struct Recording {
    /// The task.
    pub scene: SceneKind,
    /// First heading line.
    pub title: String,
    /// The frames, in order.
    pub frames: Vec<Frame>,
    /// The episode, when the recording is one.
    pub episode: Option<EpisodeFile>,
}

fn input_err(path: &Path, reason: impl Into<String>) -> ReportError {
    ReportError::Input {
        path: path.display().to_string(),
        reason: reason.into(),
    }
}

/// `v` with `digits` decimals, never `-0.00`: a value that rounds to zero prints as zero.
pub fn fixed(v: f64, digits: usize) -> String {
    let s = format!("{v:.digits$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => s,
    }
}

/// A mode goal in task coordinates with units: the card's x and y in cm and its angle in
/// rad, the screwdriver's roll, pitch and yaw in rad.
pub fn goal_words(scene: SceneKind, g: [f64; 3]) -> String {
    match scene {
        SceneKind::Card => format!(
            "x {} cm, y {} cm, θ {} rad",
            fixed(100.0 * g[0], 2),
            fixed(100.0 * g[1], 2),
            fixed(g[2], 3)
        ),
        SceneKind::Screwdriver => format!(
            "roll {}, pitch {}, yaw {} rad",
            fixed(g[0], 3),
            fixed(g[1], 3),
            fixed(g[2], 3)
        ),
    }
}

/// The object's task coordinates in a state (its last three entries).
fn object_of(state: &[f64]) -> [f64; 3] {
    let n = state.len();
    if n < 3 {
        return [f64::NAN; 3];
    }
    [state[n - 3], state[n - 2], state[n - 1]]
}

/// Words for the object's coordinate against a goal.
fn object_words(scene: SceneKind, o: [f64; 3], goal: Option<[f64; 3]>) -> String {
    match scene {
        SceneKind::Screwdriver => match goal {
            Some(g) => format!(
                "yaw {} rad (mode goal {} rad)",
                fixed(o[2], 2),
                fixed(g[2], 2)
            ),
            None => format!("yaw {} rad", fixed(o[2], 2)),
        },
        SceneKind::Card => {
            let task = f64::from(dips_kernel::task::CARD_GOAL_Y);
            match goal {
                Some(g) => format!(
                    "card y {} cm (mode goal {} cm, task goal {} cm)",
                    fixed(100.0 * o[1], 2),
                    fixed(100.0 * g[1], 2),
                    fixed(100.0 * task, 1)
                ),
                None => format!("card y {} cm", fixed(100.0 * o[1], 2)),
            }
        }
    }
}

/// The card's task goal, drawn in every card frame of an episode.
fn task_goals(scene: SceneKind) -> Vec<Goal> {
    match scene {
        SceneKind::Card => vec![Goal {
            coords: [0.0, f64::from(dips_kernel::task::CARD_GOAL_Y), 0.0],
            label: "task goal".into(),
        }],
        SceneKind::Screwdriver => Vec::new(),
    }
}

impl Recording {
    /// Frames of an episode: each mode's start, then the state after every step.
    pub fn of_episode(ep: EpisodeFile) -> Result<Self, ReportError> {
        let scene = ep.scene()?;
        let n = ep.mode_runs.len();
        let mut frames = Vec::new();
        let mut t = 0usize;
        for (m, run) in ep.mode_runs.iter().enumerate() {
            let mut goals = vec![Goal {
                coords: run.goal,
                label: "mode goal".into(),
            }];
            goals.extend(task_goals(scene));
            let h = run.steps.len();
            frames.push(Frame {
                state: run.start_state.clone(),
                contacts: if m == 0 {
                    Vec::new()
                } else {
                    ep.mode_runs[m - 1]
                        .steps
                        .last()
                        .map(|s| s.contacts.clone())
                        .unwrap_or_default()
                },
                goals: goals.clone(),
                label: format!(
                    "mode {}/{n} {} · start · t = {t} s · {}",
                    m + 1,
                    run.mode,
                    object_words(scene, object_of(&run.start_state), Some(run.goal))
                ),
                hold_s: 1.0,
            });
            for (k, step) in run.steps.iter().enumerate() {
                t += 1;
                frames.push(Frame {
                    state: step.state.clone(),
                    contacts: step.contacts.clone(),
                    goals: goals.clone(),
                    label: format!(
                        "mode {}/{n} {} · step {}/{h} · t = {t} s · {}{}",
                        m + 1,
                        run.mode,
                        k + 1,
                        object_words(scene, object_of(&step.state), Some(run.goal)),
                        if step.valid { "" } else { " · INVALID" }
                    ),
                    hold_s: 0.4,
                });
            }
        }
        if frames.is_empty()
            && let Some(start) = &ep.start_state
        {
            // No mode ran: the start, and why (the first planning call's status).
            let why = ep.plans.first().map_or_else(
                || "no mode was executed".to_string(),
                |p| format!("no mode was planned (search {})", p.status),
            );
            frames.push(Frame {
                state: start.clone(),
                contacts: Vec::new(),
                goals: task_goals(scene),
                label: format!(
                    "start · {} · {why}",
                    object_words(scene, object_of(start), None)
                ),
                hold_s: 1.0,
            });
        }
        if let Some(last) = frames.last_mut() {
            last.hold_s = 3.0;
            last.label.push_str(&format!(" · end: {}", ep.outcome()));
        }
        Ok(Self {
            scene,
            title: format!("{} · {} · seed {}", ep.task, ep.method, ep.seed),
            frames,
            episode: Some(ep),
        })
    }

    /// Read an episode's `result.json` or a `dips sim run` trajectory.
    pub fn read(path: &Path) -> Result<Self, ReportError> {
        let text = std::fs::read_to_string(path).map_err(|source| ReportError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let value: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| input_err(path, format!("not JSON: {e}")))?;
        let rec = if value.get("mode_runs").is_some() {
            let ep: EpisodeFile = serde_json::from_value(value)
                .map_err(|e| input_err(path, format!("not an episode's result.json: {e}")))?;
            Self::of_episode(ep).map_err(|e| match e {
                ReportError::Input { reason, .. } => input_err(path, reason),
                other => other,
            })?
        } else if value.get("states").is_some() {
            let traj: SimTrajectory = serde_json::from_value(value)
                .map_err(|e| input_err(path, format!("not a `dips sim run` trajectory: {e}")))?;
            let scene = traj.scene.parse::<SceneKind>().map_err(|_| {
                input_err(
                    path,
                    format!(
                        "unknown scene {:?} (expected screwdriver or card)",
                        traj.scene
                    ),
                )
            })?;
            let len = traj.states.len();
            let frames = traj
                .states
                .iter()
                .enumerate()
                .map(|(k, s)| Frame {
                    state: s.clone(),
                    contacts: traj.contacts.get(k).cloned().unwrap_or_default(),
                    goals: Vec::new(),
                    label: format!(
                        "state {k}/{} · {}{}",
                        len.saturating_sub(1),
                        object_words(scene, object_of(s), None),
                        if traj.valid.get(k).copied().unwrap_or(true) {
                            ""
                        } else {
                            " · INVALID"
                        }
                    ),
                    hold_s: if k + 1 == len { 2.0 } else { 0.5 },
                })
                .collect();
            Self {
                scene,
                title: format!("{} · {}", scene.name(), path.display()),
                frames,
                episode: None,
            }
        } else {
            return Err(input_err(
                path,
                "neither an episode's result.json (no `mode_runs`) nor a `dips sim run` \
                 trajectory (no `states`)",
            ));
        };
        if rec.frames.is_empty() {
            return Err(input_err(path, "holds no states; nothing to draw"));
        }
        Ok(rec)
    }

    /// Which task fingers are lifted (not in contact) in each frame's mode; `None` for
    /// frames outside an episode.
    pub fn lifted(&self, mode: &str) -> Option<Vec<bool>> {
        let m = parse_mode(self.scene, mode).ok()?;
        Some(
            (0..self.scene.task_fingers().len())
                .map(|i| !m.in_contact(i))
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_call_that_found_the_episode_done_is_left_out_of_the_timings() {
        let plan = |modes: &[&str], nodes: u32, seconds: f64| PlanView {
            modes: modes.iter().map(|m| m.to_string()).collect(),
            status: "Found".into(),
            nodes_expanded: nodes,
            seconds,
        };
        let ep = EpisodeFile {
            task: "card".into(),
            method: "dips".into(),
            seed: 0,
            modes: vec!["both".into(), "both".into()],
            final_yaw: None,
            final_distance_m: Some(1e-4),
            valid: true,
            success: None,
            success_rule: None,
            planning_s: vec![2.21, 1.89, 0.001],
            csvto_step_s: Vec::new(),
            mode_runs: Vec::new(),
            start_state: None,
            plans: vec![
                plan(&["both", "both"], 5, 2.21),
                plan(&["both"], 3, 1.89),
                plan(&[], 0, 0.001),
            ],
        };
        assert!(ep.plans[2].finished() && !ep.plans[1].finished());
        assert_eq!(ep.planning_times(), vec![2.21, 1.89]);
    }

    /// An episode whose first planning call planned nothing ran no mode: its report draws the
    /// start it kept and says why; without a start there is nothing to draw, and it says so.
    #[test]
    fn an_episode_that_ran_no_mode_draws_its_start() {
        let ep = |start_state: Option<Vec<f64>>| EpisodeFile {
            task: "card".into(),
            method: "dips".into(),
            seed: 7,
            modes: Vec::new(),
            final_yaw: None,
            final_distance_m: Some(0.06),
            valid: true,
            success: Some(false),
            success_rule: None,
            planning_s: vec![0.5],
            csvto_step_s: Vec::new(),
            mode_runs: Vec::new(),
            start_state,
            plans: vec![PlanView {
                modes: Vec::new(),
                status: "NoPath".into(),
                nodes_expanded: 4,
                seconds: 0.5,
            }],
        };
        let start = vec![0.1; 8 + 3];
        let rec = Recording::of_episode(ep(Some(start.clone()))).unwrap();
        assert_eq!(rec.frames.len(), 1);
        assert_eq!(rec.frames[0].state, start);
        assert!(
            rec.frames[0]
                .label
                .contains("no mode was planned (search NoPath)"),
            "{}",
            rec.frames[0].label
        );
        assert!(Recording::of_episode(ep(None)).unwrap().frames.is_empty());
    }

    #[test]
    fn numbers_never_print_as_negative_zero() {
        assert_eq!(fixed(-0.0001, 2), "0.00");
        assert_eq!(fixed(-0.004, 2), "0.00");
        assert_eq!(fixed(-0.006, 2), "-0.01");
        assert_eq!(fixed(1.5, 1), "1.5");
        assert_eq!(
            goal_words(SceneKind::Card, [0.0, -0.06, -0.0]),
            "x 0.00 cm, y -6.00 cm, θ 0.000 rad"
        );
    }
}
