//! Training data in memory: the flat sample table, z-score normalisation, the screwdriver's
//! yaw augmentation, the random inpainting masks and the forward-noised batches.

use dips_dataset::{Dataset, mix64};
use dips_kernel::engine::ObjectFrame;
use dips_kernel::mode::{SegmentDims, Task};
use dips_kernel::rng::KernelRng;

use crate::error::{Result, TrainError};

/// Flat trajectories of some demos (raw units).
#[derive(Debug, Clone, Default)]
pub struct Samples {
    /// `[n, T, D]`.
    pub x: Vec<f32>,
    /// `[n, F]`.
    pub context: Vec<f32>,
    /// Number of trajectories.
    pub n: usize,
}

impl Samples {
    /// The trajectories of the demos with indices `demos`.
    pub fn gather(ds: &Dataset, demos: &[usize]) -> Self {
        let mut s = Samples::default();
        for &i in demos {
            let d = &ds.demos[i];
            s.x.extend_from_slice(&d.trajectories);
            s.context.extend_from_slice(&d.contexts);
            s.n += d.len();
        }
        s
    }

    /// A deterministic subset of at most `k` trajectories, evenly spread over the table.
    pub fn subset(&self, k: usize, dims: SegmentDims) -> Self {
        if k >= self.n {
            return self.clone();
        }
        let mut s = Samples::default();
        let (td, f) = (dims.floats(), dims.fingers);
        for j in 0..k {
            let i = j * self.n / k;
            s.x.extend_from_slice(&self.x[i * td..(i + 1) * td]);
            s.context
                .extend_from_slice(&self.context[i * f..(i + 1) * f]);
            s.n += 1;
        }
        s
    }
}

/// The Diffusion Policy's training windows of one demo (spec §5: the demo's per-mode
/// trajectories concatenated, no contact-mode input). A mode's executed rows `[s_t, u_t]` are
/// rows `0..=k` of its last recorded step `k`'s particle 0 (the recorder keeps the executed
/// prefix and the executed particle first); concatenated over the demo's modes they give `L`
/// rows, and every start `j < L` gives one window of `T` rows, the end padded with the last
/// executed state holding still (zero action). Returns `[L, T, D]` and `L`.
pub fn policy_windows(demo: &dips_dataset::DemoRecord) -> (Vec<f32>, usize) {
    let dims = demo.dims();
    let (t, d) = (dims.horizon, dims.dim());
    let mut rows: Vec<f32> = Vec::new();
    for m in 0..demo.modes.len() {
        let last = (0..demo.len())
            .filter(|&i| demo.mode_index[i] == m as i64 && demo.particle[i] == 0)
            .max_by_key(|&i| demo.step[i]);
        let Some(i) = last else { continue };
        let k = usize::try_from(demo.step[i]).unwrap_or(0).min(t - 1);
        rows.extend_from_slice(&demo.trajectory(i)[..(k + 1) * d]);
    }
    let l = rows.len() / d.max(1);
    if l == 0 {
        return (Vec::new(), 0);
    }
    let state = dims.state_dim;
    let mut still = rows[(l - 1) * d..l * d].to_vec();
    still[state..].iter_mut().for_each(|v| *v = 0.0);
    let mut out = Vec::with_capacity(l * t * d);
    for j in 0..l {
        for r in j..j + t {
            if r < l {
                out.extend_from_slice(&rows[r * d..(r + 1) * d]);
            } else {
                out.extend_from_slice(&still);
            }
        }
    }
    (out, l)
}

impl Samples {
    /// The Diffusion Policy's windows ([`policy_windows`]) of the demos with indices `demos`,
    /// with a zero context.
    pub fn gather_policy(ds: &Dataset, demos: &[usize]) -> Self {
        let f = ds.dims().fingers;
        let mut s = Samples::default();
        for &i in demos {
            let (x, l) = policy_windows(&ds.demos[i]);
            s.x.extend_from_slice(&x);
            s.context.extend(std::iter::repeat_n(0.0, l * f));
            s.n += l;
        }
        s
    }
}

/// The cos/sin column pairs of a task (from the contract's column names).
pub fn angle_columns(task: Task) -> Vec<(usize, usize)> {
    let Some(layout) = dips_onnx::tasks::task_layout(task.name()) else {
        return Vec::new();
    };
    let cols = layout.columns();
    let mut pairs = Vec::new();
    for (i, c) in cols.iter().enumerate() {
        if let Some(rest) = c.strip_prefix("cos_")
            && let Some(j) = cols.iter().position(|s| *s == format!("sin_{rest}"))
        {
            pairs.push((i, j));
        }
    }
    pairs
}

/// Per-column z-score normalisation, `normalized = (raw − mean)/std`.
#[derive(Debug, Clone, PartialEq)]
pub struct Normalizer {
    /// Means.
    pub mean: Vec<f32>,
    /// Standard deviations (> 0).
    pub std: Vec<f32>,
}

impl Normalizer {
    /// Mean and std per column over every row of `s` (in `f64`); cos/sin columns get mean 0,
    /// std 1 unless `normalize_angles`; every std is at least `std_floor`.
    pub fn fit(s: &Samples, task: Task, std_floor: f32, normalize_angles: bool) -> Result<Self> {
        let d = task.dims().dim();
        let rows = s.x.len() / d.max(1);
        if rows == 0 {
            return Err(TrainError::DatasetUnusable(
                "no training trajectories".into(),
            ));
        }
        let mut sum = vec![0f64; d];
        let mut sq = vec![0f64; d];
        for row in s.x.chunks_exact(d) {
            for (j, &v) in row.iter().enumerate() {
                sum[j] += f64::from(v);
                sq[j] += f64::from(v) * f64::from(v);
            }
        }
        let n = rows as f64;
        let mut mean: Vec<f32> = sum.iter().map(|v| (v / n) as f32).collect();
        let mut std: Vec<f32> = sum
            .iter()
            .zip(&sq)
            .map(|(s, q)| {
                let m = s / n;
                ((q / n - m * m).max(0.0).sqrt() as f32).max(std_floor)
            })
            .collect();
        let raw_angles = if normalize_angles {
            Vec::new()
        } else {
            angle_columns(task)
        };
        for (c, s_) in raw_angles {
            for j in [c, s_] {
                mean[j] = 0.0;
                std[j] = 1.0;
            }
        }
        Ok(Self { mean, std })
    }

    /// Normalise `[.., D]` rows in place.
    pub fn normalize(&self, x: &mut [f32]) {
        let d = self.mean.len();
        for row in x.chunks_exact_mut(d) {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = (*v - m) / s;
            }
        }
    }

    /// Undo [`Self::normalize`] on `[.., D]` rows in place.
    pub fn denormalize(&self, x: &mut [f32]) {
        let d = self.mean.len();
        for row in x.chunks_exact_mut(d) {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = *v * s + m;
            }
        }
    }
}

/// Move every trajectory of `s` (raw rows of `dims`) from the world's frame into `frame`: the
/// columns the frame measures from the start ([`ObjectFrame::start_columns`]) are taken less
/// their row 0's value in every row, so row 0 holds zeros there. The world's frame changes
/// nothing. The sampler undoes it (`dips_kernel::diffusion::sample`).
pub fn to_object_frame(s: &mut Samples, frame: ObjectFrame, dims: SegmentDims) {
    let cols = frame.start_columns(dims.fingers, dims.state_dim);
    let d = dims.dim();
    if cols.is_empty() || d == 0 {
        return;
    }
    for traj in s.x.chunks_exact_mut(dims.floats()) {
        let start: Vec<f32> = traj[cols.clone()].to_vec();
        for row in traj.chunks_exact_mut(d) {
            for (v, s0) in row[cols.clone()].iter_mut().zip(&start) {
                *v -= s0;
            }
        }
    }
}

/// Rotate the yaw's (cos, sin) columns of every row of one raw trajectory by `delta`.
///
/// Only the yaw pair turns. The screwdriver is axisymmetric about its own axis, so a yaw
/// offset relabels the object's orientation while the hand (joints), the contact points and
/// the world-frame forces stay exactly as they are: the force columns are not rotated.
pub fn rotate_yaw(traj: &mut [f32], d: usize, cos_col: usize, sin_col: usize, delta: f32) {
    let (sd, cd) = (delta.sin(), delta.cos());
    for row in traj.chunks_exact_mut(d) {
        let (c, s) = (row[cos_col], row[sin_col]);
        row[cos_col] = c * cd - s * sd;
        row[sin_col] = s * cd + c * sd;
    }
}

/// Independent random streams, each a function of `(seed, purpose, index)` only: the whole
/// generator state of a run is its step counter.
pub fn stream(seed: u64, purpose: u64, index: u64) -> KernelRng {
    KernelRng::seed_from_u64(mix64(mix64(seed ^ purpose.rotate_left(32)) ^ index))
}

/// Stream purposes.
pub mod purpose {
    /// Parameter initialisation of the denoiser.
    pub const INIT_DENOISER: u64 = 1;
    /// Parameter initialisation of the discriminator.
    pub const INIT_DISCRIMINATOR: u64 = 2;
    /// Per-epoch data order.
    pub const ORDER: u64 = 3;
    /// Per-step noise, masks, steps and dropout.
    pub const STEP: u64 = 4;
    /// The held-out evaluation's fixed draws.
    pub const EVAL: u64 = 5;
    /// The sampler that makes the discriminator's diffused trajectories.
    pub const SAMPLER: u64 = 6;
    /// Discriminator data order.
    pub const DISC_ORDER: u64 = 7;
    /// Discriminator input noise (diffusion step and noise per trajectory).
    pub const DISC_NOISE: u64 = 8;
    /// Discriminator yaw augmentation (one angle per trajectory).
    pub const DISC_AUGMENT: u64 = 9;
}

/// The permutation of `n` items for `epoch` (Fisher–Yates on its own stream).
pub fn epoch_order(seed: u64, purpose: u64, epoch: u64, n: usize) -> Vec<usize> {
    let mut rng = stream(seed, purpose, epoch);
    let mut v: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        let j = rng.below((i + 1) as u32) as usize;
        v.swap(i, j);
    }
    v
}

/// The sample indices of optimiser step `step` with batch `b` over `n` items: position
/// `p = step·b + j` is item `order(p / n)[p % n]`.
pub fn batch_indices(
    seed: u64,
    purpose: u64,
    step: usize,
    b: usize,
    n: usize,
    cache: &mut Option<(u64, Vec<usize>)>,
) -> Vec<usize> {
    (0..b)
        .map(|j| {
            let p = step * b + j;
            let epoch = (p / n) as u64;
            if cache.as_ref().is_none_or(|(e, _)| *e != epoch) {
                *cache = Some((epoch, epoch_order(seed, purpose, epoch, n)));
            }
            cache.as_ref().map_or(0, |(_, o)| o[p % n])
        })
        .collect()
}

/// Draw the inpainting mask of one trajectory (spec §4.3): `true` = given (clean, not in the
/// loss). Row 0 given w.p. `start_given` (the spec's 0.5), the last row w.p. 0.5, every row
/// also w.p. 0.25; if every row ends up given, one random row is un-given.
pub fn draw_mask(rows: usize, start_given: f32, rng: &mut KernelRng) -> Vec<bool> {
    let mut m = vec![false; rows];
    m[0] = rng.uniform_f32() < start_given;
    m[rows - 1] |= rng.uniform_f32() < 0.5;
    for v in m.iter_mut() {
        *v |= rng.uniform_f32() < 0.25;
    }
    if m.iter().all(|&g| g) {
        let i = rng.below(rows as u32) as usize;
        m[i] = false;
    }
    m
}

/// How a training mask gives the start row (spec §4.3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartRow {
    /// Probability that row 0 is given ([`draw_mask`]).
    pub given: f32,
    /// A given row 0 gives its state columns only, as the planner inpaints it; its controls
    /// stay noised and in the loss. `false`: the whole row, as the spec's training masks.
    pub state_only: bool,
}

/// One forward-noised training batch (flat, ready for tensors).
#[derive(Debug, Clone)]
pub struct NoisedBatch {
    /// `[B,T,D]` network input: `√ᾱ x₀ + √(1−ᾱ) ε` with given rows replaced by `x₀`.
    pub x_t: Vec<f32>,
    /// `[B,T,D]` the noise target.
    pub eps: Vec<f32>,
    /// `[B,T,D]` 1 where the entry is in the loss (not given), else 0.
    pub weight: Vec<f32>,
    /// `[B]` step indices.
    pub t: Vec<f32>,
    /// `[B,F]`.
    pub context: Vec<f32>,
    /// `[B]` 1 conditioned, 0 context dropped.
    pub cond_mask: Vec<f32>,
}

/// Build a noised batch from normalised clean trajectories `x0 [B,T,D]`.
pub fn noise_batch(
    x0: &[f32],
    context: Vec<f32>,
    dims: SegmentDims,
    alpha_bar: &[f32],
    dropout: f32,
    start: StartRow,
    rng: &mut KernelRng,
) -> NoisedBatch {
    let (td, d) = (dims.floats(), dims.dim());
    let b = x0.len() / td;
    let mut x_t = vec![0.0; x0.len()];
    let mut eps = vec![0.0; x0.len()];
    let mut weight = vec![0.0; x0.len()];
    let mut t = vec![0.0; b];
    let mut cond_mask = vec![0.0; b];
    for i in 0..b {
        let ti = rng.below(alpha_bar.len() as u32) as usize;
        t[i] = ti as f32;
        cond_mask[i] = if rng.uniform_f32() < dropout {
            0.0
        } else {
            1.0
        };
        let mask = draw_mask(dims.horizon, start.given, rng);
        let (sa, sb) = (alpha_bar[ti].sqrt(), (1.0 - alpha_bar[ti]).sqrt());
        for (r, &given) in mask.iter().enumerate() {
            for c in 0..d {
                let k = i * td + r * d + c;
                let e = rng.normal_f32();
                eps[k] = e;
                if given && !(r == 0 && start.state_only && c >= dims.state_dim) {
                    x_t[k] = x0[k];
                } else {
                    x_t[k] = sa * x0[k] + sb * e;
                    weight[k] = 1.0;
                }
            }
        }
    }
    NoisedBatch {
        x_t,
        eps,
        weight,
        t,
        context,
        cond_mask,
    }
}

#[cfg(test)]
mod policy_tests {
    use super::*;
    use dips_dataset::DemoRecord;

    /// A card demo of two modes, 2 steps each, 2 particles per step; every float encodes
    /// (mode, step, particle, row, column).
    fn demo() -> DemoRecord {
        let task = Task::Card;
        let dims = task.dims();
        let (t, d) = (dims.horizon, dims.dim());
        let mut r = DemoRecord {
            task,
            seed: 7,
            modes: vec!["index".into(), "middle".into()],
            trajectories: Vec::new(),
            contexts: Vec::new(),
            mode_index: Vec::new(),
            step: Vec::new(),
            particle: Vec::new(),
            metadata: Default::default(),
        };
        for m in 0..2i64 {
            for k in 0..2i64 {
                for p in 0..2i64 {
                    for row in 0..t {
                        for c in 0..d {
                            r.trajectories.push(
                                (1000 * m + 100 * k + 10 * p) as f32 + row as f32 + c as f32 * 1e-3,
                            );
                        }
                    }
                    r.contexts.extend([1.0, -1.0]);
                    r.mode_index.push(m);
                    r.step.push(k);
                    r.particle.push(p);
                }
            }
        }
        r
    }

    #[test]
    fn windows_follow_the_executed_rows_across_modes() {
        let demo = demo();
        let dims = demo.dims();
        let (t, d) = (dims.horizon, dims.dim());
        let (x, l) = policy_windows(&demo);
        // Each mode's last step is 1: its particle 0's rows 0 and 1 were executed.
        assert_eq!(l, 4);
        assert_eq!(x.len(), l * t * d);
        let first_col = |w: usize, row: usize| x[(w * t + row) * d];
        // Window 0: mode 0's rows 0, 1 (step 1, particle 0), then mode 1's rows 0, 1.
        assert_eq!(first_col(0, 0), 100.0);
        assert_eq!(first_col(0, 1), 101.0);
        assert_eq!(first_col(0, 2), 1100.0);
        assert_eq!(first_col(0, 3), 1101.0);
        // Past the end: the last executed state, holding still.
        assert_eq!(first_col(0, 4), 1101.0);
        let w3_row1 = &x[(3 * t + 1) * d..(3 * t + 2) * d];
        assert_eq!(w3_row1[0], 1101.0);
        assert!(w3_row1[dims.state_dim..].iter().all(|&v| v == 0.0));
        // Window 3 starts at the last executed row.
        assert_eq!(first_col(3, 0), 1101.0);
    }
}

#[cfg(test)]
mod mask_tests {
    use super::*;

    /// The start row is given with the asked probability (always at 1, never at 0, about
    /// half the time at the spec's 0.5), and never every row at once.
    #[test]
    fn start_row_given_with_the_asked_probability() {
        let mut rng = KernelRng::seed_from_u64(3);
        for (p, lo, hi) in [(1.0, 1.0, 1.0), (0.0, 0.2, 0.3), (0.5, 0.58, 0.67)] {
            let n = 4000;
            let mut given = 0;
            for _ in 0..n {
                let m = draw_mask(13, p, &mut rng);
                assert!(!m.iter().all(|&g| g));
                given += usize::from(m[0]);
            }
            let share = given as f64 / n as f64;
            // Row 0 is also given by the every-row draw (0.25), unless un-given when every
            // row was given (rare).
            assert!((lo..=hi).contains(&share), "p {p}: start given in {share}");
        }
    }

    /// With `state_only`, a given start row keeps its state columns clean and out of the
    /// loss while its controls are noised and in the loss, as the planner's inpainting
    /// leaves them; without it the whole row is given. Other given rows are whole either way.
    #[test]
    fn a_state_only_start_row_leaves_its_controls_noised() {
        let dims = SegmentDims {
            horizon: 4,
            state_dim: 3,
            action_dim: 2,
            fingers: 2,
        };
        let (b, d, td) = (64, dims.dim(), dims.floats());
        let x0: Vec<f32> = (0..b * td).map(|i| (i % 7) as f32 + 1.0).collect();
        let alpha_bar = vec![0.5f32; 8];
        for state_only in [false, true] {
            let start = StartRow {
                given: 1.0,
                state_only,
            };
            let mut rng = KernelRng::seed_from_u64(5);
            let nb = noise_batch(
                &x0,
                vec![1.0; b * 2],
                dims,
                &alpha_bar,
                0.0,
                start,
                &mut rng,
            );
            for i in 0..b {
                let row0 = i * td..i * td + d;
                for (c, k) in row0.enumerate() {
                    let clean = nb.x_t[k] == x0[k] && nb.weight[k] == 0.0;
                    let noised = nb.x_t[k] != x0[k] && nb.weight[k] == 1.0;
                    if c < dims.state_dim || !state_only {
                        assert!(clean, "state_only {state_only}: row 0 column {c} given");
                    } else {
                        assert!(noised, "state_only {state_only}: row 0 control {c} noised");
                    }
                }
            }
        }
    }
}
