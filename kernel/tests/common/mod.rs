//! Test doubles for the search: samplers, scorers, objectives and clocks.
#![allow(dead_code, unreachable_pub, missing_docs)]

use dips_kernel::budget::Clock;
use dips_kernel::mode::{ContactMode, ModeId, SegmentDims, Task};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::rng::KernelRng;
use dips_kernel::search::{Planner, Problem, SegmentSampler, SegmentScorer, TaskObjective};

/// The screwdriver prior of the paper's trials: start 0.8 on turn, transitions 0.45/0.45
/// away from the current mode, 0.1 to stay.
pub fn paper_prior() -> MarkovPrior {
    MarkovPrior::from_rows(
        &[0.8, 0.1, 0.1],
        &[&[0.1, 0.45, 0.45], &[0.45, 0.1, 0.45], &[0.45, 0.45, 0.1]],
    )
    .unwrap()
}

/// The screwdriver problem in its real sizes from `start`, after `executed` (if any).
pub fn screwdriver_problem<'a>(
    start: &'a [f32],
    executed: Option<ModeId>,
    prior: &'a MarkovPrior,
) -> Problem<'a> {
    Problem {
        task: Task::Screwdriver,
        dims: Task::Screwdriver.dims(),
        start,
        executed,
        prior,
        first_modes: dips_kernel::mode::ModeSet::all(Task::Screwdriver),
    }
}

/// A boxed empty planner. Not inlined, so that in debug builds the temporary that
/// `Box::new` builds on the stack is freed before the caller goes on.
#[inline(never)]
pub fn boxed_planner<const K: usize, const N: usize, const O: usize, const S: usize>()
-> Box<Planner<K, N, O, S>> {
    Box::new(Planner::new())
}

/// Which task mode (its index) a contact vector is.
pub fn mode_index(task: Task, m: ContactMode) -> usize {
    task.mode_by_contact(m).map_or(usize::MAX, |id| id.index())
}

/// A deterministic two-column-state sampler: state `(x, z)`, one action column `a`, `T = 2`.
/// `step(x, z, mode, j)` gives `(dx, a)` where `j` is the position within the mode's block of
/// `k` entries. The segment is `[[x, z, a], [x + dx, z + 1, 0]]`.
pub struct StepSampler<F> {
    pub task: Task,
    pub k: usize,
    pub step: F,
    pub calls: u32,
}

impl<F: FnMut(f32, f32, usize, usize) -> (f32, f32)> SegmentSampler for StepSampler<F> {
    type Error = ();
    fn max_batch(&self) -> usize {
        usize::MAX
    }
    fn sample(
        &mut self,
        dims: &SegmentDims,
        starts: &[f32],
        modes: &[ContactMode],
        _rng: &mut KernelRng,
        out: &mut [f32],
    ) -> Result<(), ()> {
        self.calls += 1;
        assert_eq!((dims.horizon, dims.state_dim, dims.action_dim), (2, 2, 1));
        for (i, &m) in modes.iter().enumerate() {
            let (x, z) = (starts[2 * i], starts[2 * i + 1]);
            let (dx, a) = (self.step)(x, z, mode_index(self.task, m), i % self.k);
            out[6 * i..6 * i + 6].copy_from_slice(&[x, z, a, x + dx, z + 1.0, 0.0]);
        }
        Ok(())
    }
}

/// Scores `psi(z_start, mode, j)` on [`StepSampler`] segments.
pub struct StepScorer<F> {
    pub task: Task,
    pub k: usize,
    pub psi: F,
}

impl<F: FnMut(f32, usize, usize) -> f32> SegmentScorer for StepScorer<F> {
    type Error = ();
    fn max_batch(&self) -> usize {
        usize::MAX
    }
    fn score(
        &mut self,
        _dims: &SegmentDims,
        segments: &[f32],
        modes: &[ContactMode],
        out: &mut [f32],
    ) -> Result<(), ()> {
        for (i, &m) in modes.iter().enumerate() {
            out[i] = (self.psi)(segments[6 * i + 1], mode_index(self.task, m), i % self.k);
        }
        Ok(())
    }
}

/// Progress `x` (column 0), `J` = the action column of row 0, `φ = slope · max(0, x − goal)`,
/// goal reached when `x ≤ goal`.
pub struct LineObjective {
    pub goal: f32,
    pub slope: f32,
}

impl TaskObjective for LineObjective {
    fn segment_cost(&self, _mode: ContactMode, dims: &SegmentDims, segment: &[f32]) -> f32 {
        segment[dims.state_dim]
    }
    fn progress(&self, state: &[f32]) -> f32 {
        state[0]
    }
    fn terminal_cost(&self, x: f32) -> f32 {
        self.slope * (x - self.goal).max(0.0)
    }
    fn goal_reached(&self, x: f32) -> bool {
        x <= self.goal
    }
}

/// The dims of [`StepSampler`] for a task.
pub fn step_dims(task: Task) -> SegmentDims {
    SegmentDims {
        horizon: 2,
        state_dim: 2,
        action_dim: 1,
        fingers: task.finger_names().len(),
    }
}

/// A noisy analytic screwdriver sampler in the real layout (`13 × 37`): turn modes rotate
/// the yaw by about −π/6, regrasps hold it; joints and forces get noise from the planner's
/// stream. Uses no heap.
pub struct NoisyScrewdriver {
    pub noise: f32,
}

impl SegmentSampler for NoisyScrewdriver {
    type Error = ();
    fn max_batch(&self) -> usize {
        usize::MAX
    }
    fn sample(
        &mut self,
        dims: &SegmentDims,
        starts: &[f32],
        modes: &[ContactMode],
        rng: &mut KernelRng,
        out: &mut [f32],
    ) -> Result<(), ()> {
        let (t_rows, d, sd) = (dims.horizon, dims.dim(), dims.state_dim);
        for (i, m) in modes.iter().enumerate() {
            let s0 = &starts[i * sd..(i + 1) * sd];
            let seg = &mut out[i * t_rows * d..(i + 1) * t_rows * d];
            let yaw0 = libm::atan2f(s0[15], s0[14]);
            let turning = m.contact_count() == 3;
            let total = if turning {
                -core::f32::consts::FRAC_PI_6 * (1.0 + self.noise * rng.normal_f32())
            } else {
                0.05 * self.noise * rng.normal_f32()
            };
            for t in 0..t_rows {
                let row = &mut seg[t * d..(t + 1) * d];
                row[..sd].copy_from_slice(s0);
                let frac = t as f32 / (t_rows - 1) as f32;
                if t > 0 {
                    for q in &mut row[..12] {
                        *q += 0.01 * self.noise * rng.normal_f32();
                    }
                }
                let yaw = yaw0 + frac * total;
                row[14] = libm::cosf(yaw);
                row[15] = libm::sinf(yaw);
                for a in &mut row[sd..] {
                    *a = if t + 1 < t_rows {
                        0.05 * rng.normal_f32()
                    } else {
                        0.0
                    };
                }
            }
        }
        Ok(())
    }
}

/// Ψ decreasing with the segment's action magnitude, in (0, 1].
pub struct SmoothScorer;

impl SegmentScorer for SmoothScorer {
    type Error = ();
    fn max_batch(&self) -> usize {
        usize::MAX
    }
    fn score(
        &mut self,
        dims: &SegmentDims,
        segments: &[f32],
        modes: &[ContactMode],
        out: &mut [f32],
    ) -> Result<(), ()> {
        let n = dims.floats();
        for (i, o) in out.iter_mut().enumerate().take(modes.len()) {
            let e: f32 = segments[i * n..(i + 1) * n].iter().map(|v| v * v).sum();
            *o = libm::expf(-0.01 * e);
        }
        Ok(())
    }
}

/// A clock that advances `step_us` every time it is read.
pub struct TickClock {
    pub now: u64,
    pub step_us: u64,
}

impl Clock for TickClock {
    fn now_us(&mut self) -> u64 {
        self.now += self.step_us;
        self.now
    }
}

/// A raw screwdriver start state at the nominal pose with the given yaw.
pub fn screwdriver_start(yaw: f32) -> [f32; 16] {
    let mut s = [0.0f32; 16];
    s[..12].copy_from_slice(&[
        0.1, 0.5, 0.5, 0.5, -0.1, 0.5, 0.65, 0.65, 1.2, 0.3, 0.2, 1.0,
    ]);
    s[14] = libm::cosf(yaw);
    s[15] = libm::sinf(yaw);
    s
}
