//! `dips bench csvto`: the time of one online CSVTO step.
//!
//! The workload is the screwdriver turn mode from the world's start state with the DIPS
//! settings (N = 16, α_J = 5e-3, H = 12): one warm-up solve (100 iterations, not timed in
//! `step_s`), then `repeats` online solves of 25 iterations on the full horizon, each from
//! the particles the previous one left. `step_s` is their median wall time and
//! `step_cpu_s` their median CPU time over all threads.

use std::time::Instant;

use clap::Args;
use dips_kernel::rng::KernelRng;
use serde_json::json;

use dips_csvto::{Problem, solve};
use dips_exec::problems::init::default_particles;
use dips_exec::problems::{AllegroProblem, Mode, ProblemSpec};
use dips_exec::{ExecSettings, mode_goal};
use dips_world::kinematics::HandModel;
use dips_world::scenes::SceneKind;
use dips_world::world::World;

/// `dips bench csvto`.
#[derive(Debug, Args)]
pub struct CsvtoBenchArgs {
    /// Number of timed online solves.
    #[arg(long, default_value_t = 7)]
    pub repeats: usize,
    /// Seed of the initial particles.
    #[arg(
        long,
        default_value_t = 0,
        allow_negative_numbers = true,
        value_parser = crate::search_args::parse_seed
    )]
    pub seed: u64,
    /// Print JSON instead of readable `key: value` lines.
    #[arg(long)]
    pub json: bool,
}

/// CPU seconds (user + system, all threads) this process has used, from `/proc/self/stat`
/// (Linux; `None` elsewhere). Reported beside the wall time because the machine is shared:
/// `step_cpu_s / threads` is what one step takes on otherwise idle cores.
fn process_cpu_s() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
    let rest = &text[text.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    // Linux reports clock ticks of 1/100 s (USER_HZ) on every mainstream architecture.
    Some((utime + stime) / 100.0)
}

/// Run the benchmark and print its JSON figures.
pub fn run(args: CsvtoBenchArgs) -> anyhow::Result<()> {
    let settings = ExecSettings::for_task(SceneKind::Screwdriver);
    let hand = HandModel::allegro_v4();
    let world = World::new(SceneKind::Screwdriver);
    let start = world.state();
    let spec = ProblemSpec {
        task: SceneKind::Screwdriver,
        mode: Mode::Turn,
        horizon: settings.horizon,
        goal: mode_goal(Mode::Turn, &start, Default::default()),
        start,
    };
    let problem = AllegroProblem::new(&hand, &spec)?;
    let mut rng = KernelRng::seed_from_u64(args.seed);
    let mut particles = default_particles(&problem, Mode::Turn, settings.particles, &mut rng);
    let t0 = Instant::now();
    solve(
        &problem,
        &mut particles,
        settings.warmup_iters,
        &settings.csvto,
    )?;
    let warmup_s = t0.elapsed().as_secs_f64();
    let mut times = Vec::with_capacity(args.repeats);
    let mut cpu = Vec::with_capacity(args.repeats);
    let mut violation = 0.0;
    for _ in 0..args.repeats.max(1) {
        let t = Instant::now();
        let c = process_cpu_s();
        let rep = solve(
            &problem,
            &mut particles,
            settings.online_iters,
            &settings.csvto,
        )?;
        times.push(t.elapsed().as_secs_f64());
        cpu.push(process_cpu_s().zip(c).map(|(b, a)| b - a));
        violation = rep.max_eq_violation[0];
    }
    let mut cpu_sorted: Vec<f64> = cpu.iter().flatten().copied().collect();
    cpu_sorted.sort_by(f64::total_cmp);
    let step_cpu_s = cpu_sorted.get(cpu_sorted.len() / 2).copied();
    let mut sorted = times.clone();
    sorted.sort_by(f64::total_cmp);
    let step_s = sorted[sorted.len() / 2];
    let out = json!({
        "bench": "csvto",
        "task": "screwdriver",
        "mode": "turn",
        "particles": settings.particles,
        "iterations": settings.online_iters,
        "horizon": settings.horizon,
        "row_dim": problem.row_dim(),
        "constraints_per_step": problem.n_eq(0) + problem.n_ineq(0),
        "threads": rayon::current_num_threads(),
        "step_s": step_s,
        "step_s_all": times,
        "step_cpu_s": step_cpu_s,
        "warmup_s": warmup_s,
        "warmup_iterations": settings.warmup_iters,
        "best_max_eq_violation": violation,
    });
    crate::output::figures(args.json, &out)?;
    Ok(())
}
