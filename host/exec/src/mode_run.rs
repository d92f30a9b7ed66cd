//! One contact mode executed closed-loop in the world.

use std::time::Instant;

use dips_kernel::rng::KernelRng;
use dips_kernel::task::CardGoals;
use serde::Serialize;

use super::settings::ExecSettings;
use crate::problems::init::default_particles;
use crate::problems::{AllegroProblem, Mode, ProblemError, ProblemSpec};
use crate::regrasp_guard::{GuardAction, guard_regrasps};
use dips_csvto::{CsvtoError, Problem, SolveReport, solve};
use dips_world::hand::{Hand, HandError, add_task_deltas};
use dips_world::kinematics::HandModel;
use dips_world::scenes::SceneKind;

/// The object goal of `mode` from the raw state `start` (`[q, o]`) with the card's `card`
/// goals: the kernel's [`dips_kernel::task::mode_goal`], the one definition the search's `J`
/// uses too (turn to `yaw − π/6` with roll and pitch at 0; card moves to `(0, y − 0.02, 0)`,
/// with [`CardGoals::Capped`] never past the task goal; regrasps hold).
pub fn mode_goal(mode: Mode, start: &[f64], card: CardGoals) -> [f64; 3] {
    let o = &start[start.len() - 3..];
    dips_kernel::task::mode_goal(mode, [o[0], o[1], o[2]], card)
}

/// Command the hand to its measured joints plus `dq`, the task fingers' joint deltas in
/// contract order (4 per task finger); the other fingers hold.
pub fn command_deltas<H: Hand + ?Sized>(hand: &mut H, dq: &[f64]) -> Result<(), HandError> {
    let targets = add_task_deltas(hand.scene(), hand.joint_positions(), dq);
    hand.command(&targets)
}

/// Errors from closed-loop execution.
#[derive(Debug, thiserror::Error)]
pub enum ExecError {
    /// The hand (or world) failed a step.
    #[error(transparent)]
    Hand(#[from] HandError),
    /// The problem could not be built from the measured state.
    #[error(transparent)]
    Problem(#[from] ProblemError),
    /// Given initial particles do not fit the mode's problem.
    #[error(
        "initial particle {index} has {got} values; the {mode} problem needs {expected} \
         ({horizon} rows of {row})"
    )]
    InitialParticles {
        /// Which particle.
        index: usize,
        /// Its length.
        got: usize,
        /// Expected length.
        expected: usize,
        /// Mode name.
        mode: &'static str,
        /// Rows.
        horizon: usize,
        /// Row width.
        row: usize,
    },
    /// No initial particles were given.
    #[error("no initial particles")]
    NoParticles,
    /// The execution or CSVTO settings cannot be run, or CSVTO was called wrongly.
    #[error(transparent)]
    Csvto(#[from] CsvtoError),
}

/// What one executed step did.
#[derive(Debug, Clone, Serialize)]
pub struct StepLog {
    /// Seconds spent in the CSVTO solve before this step.
    pub solve_s: f64,
    /// Iterations of that solve.
    pub iters: usize,
    /// The best particle's largest equality violation.
    pub max_eq_violation: f64,
    /// The best particle's largest inequality violation.
    pub max_ineq_violation: f64,
    /// The executed joint command `Δq₀`.
    pub dq: Vec<f64>,
    /// The planned state after the step (best particle's first row).
    pub planned_state: Vec<f64>,
    /// The world state after the step.
    pub state: Vec<f64>,
    /// Signed distance of every task finger's tip sphere to the object after the step (m),
    /// from the measured joints and object pose and the planner's analytic geometry.
    pub tip_sdf: Vec<f64>,
    /// Whether the object is still valid.
    pub valid: bool,
    /// What the regrasp guard did to each task finger's command
    /// ([`RegraspGuard`](crate::regrasp_guard::RegraspGuard)); empty when it changed none
    /// (and then left out of `result.json`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub guarded: Vec<Option<GuardAction>>,
    /// The contacts and their forces after the step, where the hand senses them
    /// ([`Hand::contact_readings`]; the simulated world always does); empty otherwise.
    pub contacts: Vec<dips_world::world::ContactReport>,
}

/// One executed mode.
#[derive(Debug, Clone, Serialize)]
pub struct ModeRun {
    /// Mode name.
    pub mode: &'static str,
    /// The object goal it aimed for.
    pub goal: [f64; 3],
    /// World state at the start.
    pub start_state: Vec<f64>,
    /// World state at the end.
    pub end_state: Vec<f64>,
    /// Per step.
    pub steps: Vec<StepLog>,
    /// Regrasp target distances (m) at the end, one per regrasping finger (task order).
    pub regrasp_target_distance: Vec<f64>,
}

impl ModeRun {
    /// Solve times in seconds, one per step (the first is the warm-up).
    pub fn solve_times(&self) -> Vec<f64> {
        self.steps.iter().map(|s| s.solve_s).collect()
    }

    /// The smallest world sdf of finger `i` over the steps before the last.
    pub fn min_mid_sdf(&self, i: usize) -> f64 {
        let n = self.steps.len();
        self.steps[..n.saturating_sub(1)]
            .iter()
            .map(|s| s.tip_sdf[i])
            .fold(f64::INFINITY, f64::min)
    }

    /// The largest world sdf of finger `i` over the steps before the last.
    pub fn max_mid_sdf(&self, i: usize) -> f64 {
        let n = self.steps.len();
        self.steps[..n.saturating_sub(1)]
            .iter()
            .map(|s| s.tip_sdf[i])
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// World sdf of finger `i` at the end of the mode.
    pub fn final_sdf(&self, i: usize) -> f64 {
        self.steps.last().map_or(f64::NAN, |s| s.tip_sdf[i])
    }
}

/// The raw state row `[task joints, object coordinates]` of a hand.
pub fn hand_state<H: Hand + ?Sized>(hand: &H) -> Vec<f64> {
    let joints = hand.joint_positions();
    let mut s: Vec<f64> = hand
        .scene()
        .task_fingers()
        .iter()
        .flat_map(|f| joints[f.index()])
        .collect();
    s.extend_from_slice(&hand.object_pose().coords);
    s
}

/// [`hand_state`] with the object's true pose ([`Hand::true_object_pose`]): what an episode's
/// outcome (final yaw, the card's distance to its goal) is scored on.
pub fn true_hand_state<H: Hand + ?Sized>(hand: &H) -> Vec<f64> {
    let mut s = hand_state(hand);
    let n = s.len() - 3;
    s[n..].copy_from_slice(&hand.true_object_pose().coords);
    s
}

/// The signed distance (m) from each of the task's fingertips to the object, in task-finger
/// order, at the hand's measured state: what a planning call sees of its contacts
/// (`dips_planning::first_mode`). Negative is penetration.
pub fn fingertip_distances<H: Hand + ?Sized>(
    hand: &H,
    model: &HandModel,
) -> Result<Vec<f64>, ExecError> {
    let task = hand.scene();
    let state = hand_state(hand);
    let mode = task.modes()[0];
    let spec = ProblemSpec {
        task,
        mode,
        horizon: 1,
        goal: mode_goal(mode, &state, CardGoals::default()),
        start: state.clone(),
    };
    let problem = AllegroProblem::new(model, &spec)?;
    Ok(problem.finger_sdfs(&state))
}

/// The best particle's largest constraint violation (equality or inequality).
fn worst_violation(report: &SolveReport) -> f64 {
    report.max_eq_violation[0].max(report.max_ineq_violation[0])
}

/// Drop the first `rows` rows of every particle (the executed steps).
fn shift(particles: &mut [Vec<f64>], n: usize) {
    for p in particles.iter_mut() {
        p.drain(..n);
    }
}

/// Replace the forces of the contact fingers whose given (diffused) forces the profile
/// does not keep ([`ExecProfile::redraws_diffused_forces`](crate::settings::ExecProfile::redraws_diffused_forces)) by the
/// default initialisation's, row by row; nothing is drawn when no finger's are replaced, so
/// the simulation profile's runs are unchanged bit for bit.
fn redraw_forces(
    problem: &AllegroProblem,
    mode: Mode,
    settings: &ExecSettings,
    particles: &mut [Vec<f64>],
    rng: &mut KernelRng,
) {
    let task = problem.task();
    let slots: Vec<usize> = task
        .task_fingers()
        .iter()
        .enumerate()
        .filter(|&(_, &f)| settings.profile.redraws_diffused_forces(task, mode, f))
        .filter_map(|(i, _)| problem.contact_slot(i))
        .collect();
    if slots.is_empty() {
        return;
    }
    let fresh = default_particles(problem, mode, particles.len(), rng);
    let n = problem.row_dim();
    for (p, d) in particles.iter_mut().zip(&fresh) {
        for (row, drow) in p.chunks_exact_mut(n).zip(d.chunks_exact(n)) {
            for &s in &slots {
                for k in 0..3 {
                    let c = problem.force_col(s, k);
                    row[c] = drow[c];
                }
            }
        }
    }
}

/// The problem of `spec`, whose start is the measured state, after the settings' pose
/// estimate ([`PoseEstimate`](crate::pose_estimate::PoseEstimate)) has replaced the start's object coordinates; with
/// `set_goal` (a mode's first solve) the mode's goal is taken from the estimated start.
fn estimated_problem<H: Hand + ?Sized>(
    hand: &H,
    model: &HandModel,
    spec: &mut ProblemSpec,
    settings: &ExecSettings,
    set_goal: bool,
) -> Result<AllegroProblem, ExecError> {
    let build = |spec: &ProblemSpec| {
        AllegroProblem::new(model, spec).map(|p| p.with_min_normal_force(settings.press.newtons()))
    };
    let problem = build(spec)?;
    if settings.pose_estimate.is_tracker() {
        return Ok(problem);
    }
    let readings = hand.contact_readings();
    spec.start = settings
        .pose_estimate
        .apply(&problem, &spec.start, readings.as_deref());
    if set_goal {
        spec.goal = mode_goal(spec.mode, &spec.start, settings.card_goals);
    }
    Ok(build(spec)?)
}

/// Execute `mode` on `hand` (the quasi-static world, a recorder around it, or a real hand)
/// closed-loop: warm-up solve on `initial` particles (or the default initialisation), then a
/// re-solve at every step with the shrinking horizon, commanding `q + Δq₀` of the best
/// particle. `progress` receives one line per step.
pub fn run_mode<H: Hand + ?Sized>(
    hand: &mut H,
    model: &HandModel,
    mode: Mode,
    settings: &ExecSettings,
    initial: Option<Vec<Vec<f64>>>,
    rng: &mut KernelRng,
    progress: &mut dyn FnMut(&str),
) -> Result<ModeRun, ExecError> {
    run_mode_observed(
        hand,
        model,
        mode,
        settings,
        initial,
        rng,
        progress,
        &mut |_| {},
    )
}

/// The particles of one online step, handed to the observer of [`run_mode_observed`] after
/// the step's solve and before its command is executed.
#[derive(Debug)]
pub struct StepParticles<'a> {
    /// The step within the mode (0 = the warm-up solve).
    pub step: usize,
    /// The step's problem: horizon `H − step`, starting at the measured state.
    pub problem: &'a AllegroProblem,
    /// Every particle in the problem's layout, best first (the best one is executed).
    pub particles: &'a [Vec<f64>],
}

/// [`run_mode`] with an observer that sees every step's solved particles (datasets record
/// them).
#[allow(clippy::too_many_arguments)]
pub fn run_mode_observed<H: Hand + ?Sized>(
    hand: &mut H,
    model: &HandModel,
    mode: Mode,
    settings: &ExecSettings,
    initial: Option<Vec<Vec<f64>>>,
    rng: &mut KernelRng,
    progress: &mut dyn FnMut(&str),
    observe: &mut dyn FnMut(StepParticles<'_>),
) -> Result<ModeRun, ExecError> {
    settings.validate()?;
    let task: SceneKind = hand.scene();
    let start_state = hand_state(hand);
    let h = settings.horizon;
    let mut spec = ProblemSpec {
        task,
        mode,
        horizon: h,
        start: start_state.clone(),
        goal: mode_goal(mode, &start_state, settings.card_goals),
    };
    let mut problem = estimated_problem(hand, model, &mut spec, settings, true)?;
    let goal = spec.goal;
    let n = problem.row_dim();
    let given_initial = initial.is_some();
    let mut particles = match initial {
        Some(p) => {
            if p.is_empty() {
                return Err(ExecError::NoParticles);
            }
            if let Some((index, bad)) = p.iter().enumerate().find(|(_, x)| x.len() != h * n) {
                return Err(ExecError::InitialParticles {
                    index,
                    got: bad.len(),
                    expected: h * n,
                    mode: mode.name(),
                    horizon: h,
                    row: n,
                });
            }
            let mut p = p;
            redraw_forces(&problem, mode, settings, &mut p, rng);
            p
        }
        None => default_particles(&problem, mode, settings.particles, rng),
    };
    let nq = 4 * problem.fingers();
    let mut steps = Vec::with_capacity(h);
    for k in 0..h {
        let iters = if k == 0 {
            settings.warmup_iters
        } else {
            shift(&mut particles, n);
            spec.start = hand_state(hand);
            spec.horizon = h - k;
            problem = estimated_problem(hand, model, &mut spec, settings, false)?;
            settings.online_iters
        };
        let t0 = Instant::now();
        let mut report = solve(&problem, &mut particles, iters, &settings.csvto)?;
        let mut iters = iters;
        if k == 0 {
            // A warm-up that has not converged leaves every online solve to recover from an
            // infeasible plan (measured: the card then barely moves). Re-run it and keep the
            // attempt with the lowest penalty.
            let mut retries = 0;
            let first = worst_violation(&report);
            while retries < settings.warmup_retries
                && worst_violation(&report) > settings.warmup_tolerance
            {
                retries += 1;
                let mut again = if given_initial {
                    particles.clone()
                } else {
                    default_particles(&problem, mode, settings.particles, rng)
                };
                let r = solve(&problem, &mut again, settings.warmup_iters, &settings.csvto)?;
                iters += settings.warmup_iters;
                if r.penalties[0] < report.penalties[0] {
                    particles = again;
                    report = r;
                }
            }
            if retries > 0 {
                progress(&format!(
                    "{} warm-up: constraint violation {first:.1e} above {:.0e}, re-run {retries} \
                     time(s), kept {:.1e} (usual at a mode's start; CSVTO's steps reduce it)",
                    mode.name(),
                    settings.warmup_tolerance,
                    worst_violation(&report)
                ));
            }
        }
        let solve_s = t0.elapsed().as_secs_f64();
        observe(StepParticles {
            step: k,
            problem: &problem,
            particles: &particles,
        });
        let best = &particles[0];
        let mut dq: Vec<f64> = (0..nq)
            .map(|c| best[problem.dq_col(c / 4, c % 4)])
            .collect();
        let planned_state = problem.to_world_units(&best[..problem.state_dim()]);
        let mut guarded = Vec::new();
        if !settings.regrasp_guard.is_off() {
            let actions = guard_regrasps(&problem, &hand_state(hand), &mut dq, k + 1 == h);
            if actions.iter().any(Option::is_some) {
                guarded = actions;
            }
        }
        command_deltas(hand, &dq)?;
        let state = hand_state(hand);
        let o = problem.object_pose(&state);
        let tip_sdf = problem.finger_sdfs(&state);
        let valid = hand.true_object_pose().valid(task);
        // Fixed decimals without "-0.00".
        let f = |v: f64, d: usize| {
            let s = format!("{v:.d$}");
            match s.strip_prefix('-') {
                Some(r) if r.chars().all(|c| c == '0' || c == '.') => r.to_string(),
                _ => s,
            }
        };
        let object = match task {
            SceneKind::Card => format!(
                "card x {} cm, y {} cm, θ {} rad",
                f(o[0] * 100.0, 2),
                f(o[1] * 100.0, 2),
                f(o[2], 3)
            ),
            SceneKind::Screwdriver => format!(
                "roll {}, pitch {}, yaw {} rad",
                f(o[0], 3),
                f(o[1], 3),
                f(o[2], 3)
            ),
        };
        let tips: Vec<String> = tip_sdf.iter().map(|v| f(v * 1e3, 1)).collect();
        progress(&format!(
            "{} step {}/{}: solve {:.2} s ({} it), constraint violation {:.1e}, {object}, \
             fingertip distance [{}] mm{}",
            mode.name(),
            k + 1,
            h,
            solve_s,
            iters,
            report.max_eq_violation[0],
            tips.join(", "),
            if valid { "" } else { " INVALID" }
        ));
        steps.push(StepLog {
            solve_s,
            iters,
            max_eq_violation: report.max_eq_violation[0],
            max_ineq_violation: report.max_ineq_violation[0],
            dq,
            planned_state,
            state,
            tip_sdf,
            valid,
            guarded,
            contacts: hand.contact_readings().unwrap_or_default(),
        });
    }
    let end_state = hand_state(hand);
    let o = problem.object_pose(&end_state);
    let regrasp_target_distance = (0..problem.fingers())
        .filter(|&i| !problem.in_contact(i))
        .map(|i| {
            let q = AllegroProblem::finger_joints(&end_state, i);
            problem.target_distance(i, &q, &o)
        })
        .collect();
    Ok(ModeRun {
        mode: mode.name(),
        goal,
        start_state,
        end_state,
        steps,
        regrasp_target_distance,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::settings::ExecProfile;

    fn turn_problem() -> AllegroProblem {
        let task = SceneKind::Screwdriver;
        let q = task.default_joints();
        let mut start: Vec<f64> = task
            .task_fingers()
            .iter()
            .flat_map(|f| q[f.index()])
            .collect();
        start.extend_from_slice(&[0.0, 0.0, 0.0]);
        let spec = ProblemSpec {
            task,
            mode: Mode::Turn,
            horizon: 4,
            start,
            goal: [0.0, 0.0, -0.5],
        };
        AllegroProblem::new(&HandModel::allegro_v4(), &spec).expect("valid spec")
    }

    /// The hardware profile replaces the thumb's and middle finger's given `turn` forces, and
    /// nothing else; the simulation profile changes nothing and draws nothing.
    #[test]
    fn the_hardware_profile_redraws_only_thumb_and_middle_turn_forces() {
        let problem = turn_problem();
        let (n, h) = (problem.row_dim(), problem.horizon());
        let given = vec![vec![7.0; n * h]; 3];
        let sim = ExecSettings::for_task(SceneKind::Screwdriver);
        let hw = ExecSettings::for_profile(SceneKind::Screwdriver, ExecProfile::Hardware).unwrap();
        let mut rng = KernelRng::seed_from_u64(5);
        let mut kept = given.clone();
        redraw_forces(&problem, Mode::Turn, &sim, &mut kept, &mut rng);
        assert_eq!(kept, given);
        assert_eq!(rng.next_u64(), KernelRng::seed_from_u64(5).next_u64());
        let mut redrawn = given.clone();
        redraw_forces(&problem, Mode::Turn, &hw, &mut redrawn, &mut rng);
        // Screwdriver fingers: index (slot 0), middle (slot 1), thumb (slot 2).
        let problem_ref = &problem;
        let force_cols = |slot: usize| (0..3).map(move |k| problem_ref.force_col(slot, k));
        let replaced: Vec<usize> = force_cols(1).chain(force_cols(2)).collect();
        for p in &redrawn {
            for row in p.chunks_exact(n) {
                for (c, &v) in row.iter().enumerate() {
                    if replaced.contains(&c) {
                        assert!(v.abs() < 2.0, "column {c} redrawn to a default force: {v}");
                    } else {
                        assert_eq!(v, 7.0, "column {c} kept");
                    }
                }
            }
        }
        // Regrasp modes keep their given forces under either profile.
        let mut regrasp = given.clone();
        redraw_forces(&problem, Mode::IndexRegrasp, &hw, &mut regrasp, &mut rng);
        assert_eq!(regrasp, given);
    }
}
