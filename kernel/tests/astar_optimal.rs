//! On small random problems with a deterministic sampler (so every sequence has one well
//! defined cost) and an admissible heuristic, the planner returns the optimum found by
//! enumerating every mode sequence up to the maximum depth.

mod common;

use common::{LineObjective, StepSampler, StepScorer, step_dims};
use dips_kernel::budget::NoClock;
use dips_kernel::mode::{MAX_MODES, Task};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::rng::KernelRng;
use dips_kernel::search::{ApproximateReason, Problem, SearchConfig, SearchStatus};

const MAX_D: usize = 4;

/// A random problem: per depth and mode, a displacement in [−1, 0.5] and a base cost in
/// [0.5, 2]; J = base + 0.1·|x| ≥ 0.5 and each step lowers x by at most 1, so
/// φ = 0.5·max(0, x − goal) never overestimates the remaining cost.
#[derive(Clone, Copy)]
struct Instance {
    task: Task,
    depth: usize,
    dx: [[f32; MAX_MODES]; MAX_D],
    base: [[f32; MAX_MODES]; MAX_D],
    goal: f32,
}

impl Instance {
    fn random(rng: &mut KernelRng) -> Self {
        let task = if rng.below(2) == 0 {
            Task::Screwdriver
        } else {
            Task::Card
        };
        let mut dx = [[0.0; MAX_MODES]; MAX_D];
        let mut base = [[0.0; MAX_MODES]; MAX_D];
        for d in 0..MAX_D {
            for m in 0..MAX_MODES {
                dx[d][m] = -1.0 + 1.5 * rng.uniform_f32();
                base[d][m] = 0.5 + 1.5 * rng.uniform_f32();
            }
        }
        Self {
            task,
            depth: 1 + rng.below(MAX_D as u32) as usize,
            dx,
            base,
            goal: -0.5 - 2.5 * rng.uniform_f32(),
        }
    }

    fn step(&self, x: f32, z: f32) -> impl Fn(usize) -> (f32, f32) + '_ {
        move |m| {
            let d = (z as usize).min(MAX_D - 1);
            (self.dx[d][m], self.base[d][m] + 0.1 * x.abs())
        }
    }

    /// Least cost to reach the goal from (x, z) within `left` modes; also reports whether any
    /// visited x lies within `margin` of the goal (then the instance is ambiguous in f32).
    fn brute(&self, x: f32, z: f32, left: usize, ambiguous: &mut bool) -> Option<f32> {
        if (x - self.goal).abs() < 1e-3 {
            *ambiguous = true;
        }
        if x <= self.goal {
            return Some(0.0);
        }
        if left == 0 {
            return None;
        }
        let step = self.step(x, z);
        (0..self.task.mode_count())
            .filter_map(|m| {
                let (dx, j) = step(m);
                self.brute(x + dx, z + 1.0, left - 1, ambiguous)
                    .map(|c| c + j)
            })
            .min_by(f32::total_cmp)
    }
}

#[test]
fn astar_matches_brute_force_on_random_problems() {
    let mut rng = KernelRng::seed_from_u64(2024);
    let mut planner = common::boxed_planner::<2, 1024, 512, 6>();
    let mut checked = 0;
    let mut found = 0;
    while checked < 300 {
        let inst = Instance::random(&mut rng);
        let mut ambiguous = false;
        let want = inst.brute(0.0, 0.0, inst.depth, &mut ambiguous);
        if ambiguous {
            continue;
        }
        checked += 1;
        let k = 1 + rng.below(2) as u16;
        let alpha = if rng.below(2) == 0 { 0.0 } else { 1.0 };
        let task = inst.task;
        let mut sampler = StepSampler {
            task,
            k: usize::from(k),
            step: |x: f32, z: f32, m: usize, _j: usize| inst.step(x, z)(m),
            calls: 0,
        };
        let mut scorer = StepScorer {
            task,
            k: usize::from(k),
            psi: |_z: f32, _m: usize, _j: usize| 0.5,
        };
        let prior = MarkovPrior::uniform(task.mode_count()).unwrap();
        let problem = Problem {
            task,
            dims: step_dims(task),
            start: &[0.0, 0.0],
            executed: None,
            prior: &prior,
            first_modes: dips_kernel::mode::ModeSet::all(task),
        };
        let config = SearchConfig {
            k,
            max_depth: inst.depth as u8,
            alpha,
            beta: 0.0,
            seed: checked,
            ..SearchConfig::default()
        };
        let objective = LineObjective {
            goal: inst.goal,
            slope: 0.5,
        };
        let r = planner.plan(
            &config,
            &problem,
            &mut sampler,
            &mut scorer,
            &objective,
            &mut NoClock,
        );
        match want {
            Some(cost) => {
                found += 1;
                assert_eq!(r.status, SearchStatus::Found, "instance {checked}");
                assert!(
                    (r.cost_to_come - cost).abs() <= 1e-4 * cost.max(1.0),
                    "instance {checked}: A* {} vs brute force {cost}",
                    r.cost_to_come
                );
                // Replaying the returned sequence gives its reported cost and reaches the goal.
                let (mut x, mut z, mut g) = (0.0f32, 0.0f32, 0.0f32);
                for m in &r.modes {
                    let (dx, j) = inst.step(x, z)(m.index());
                    g += j;
                    x += dx;
                    z += 1.0;
                }
                assert!(x <= inst.goal && (g - cost).abs() <= 1e-4 * cost.max(1.0));
            }
            None => assert_eq!(
                r.status,
                SearchStatus::Approximate(ApproximateReason::Exhausted),
                "instance {checked}"
            ),
        }
    }
    // The generator must produce both kinds of instance for the test to mean something.
    assert!(found > 50 && found < 290, "{found} of {checked} solvable");
}
