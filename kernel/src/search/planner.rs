//! The fixed-capacity DIPS A* planner.
//!
//! # Capacities
//! `Planner<K, N, O, S>`: `K` particles per node, `N` nodes in the arena (ids are `u16`), `O`
//! entries in the open list (each open node owns one particle slot; a popped node gives its
//! slot back, so only open nodes hold particles), `S` floats per segment (`T·D`). State
//! vectors hold at most [`MAX_STATE_DIM`] floats and a node has at most [`MAX_MODES`]
//! children. Running out of nodes or open slots stops the search with an approximate
//! result, never a panic.
//!
//! The paper's screwdriver settings (`k = 16`, `T·D = 13·37 = 481`) fit [`PaperPlanner`].

use super::config::{CostToCome, MAX_PLAN_LEN, SearchConfig, SearchVariant};
use super::particles::{
    accumulate_scores, argmax_positive, normalized_weights, resample, weighted_sum,
};
use super::report::{
    ApproximateReason, Capacity, ParticleDiagnostics, SearchReport, SearchStats, SearchStatus,
};
use super::traits::{SegmentSampler, SegmentScorer, TaskObjective};
use crate::budget::Clock;
use crate::mode::{ContactMode, MAX_MODES, MAX_STATE_DIM, ModeId, ModeSet, SegmentDims, Task};
use crate::prior::MarkovPrior;
use crate::rng::KernelRng;
use heapless::binary_heap::{BinaryHeap, Min};

/// A planner sized for the paper: 16 particles, 512 nodes, 256 open nodes, 481 floats per
/// segment (screwdriver `13 × 37`; the card's `9 × 29` fits too). With 3 modes the open list
/// grows by at most 2 per expansion, so this allows at least 127 expansions (85 for the
/// card's 4 modes), far more than the paper's searches perform in their time.
pub type PaperPlanner = Planner<16, 512, 256, 481>;

const NO_NODE: u16 = u16::MAX;
const NO_MODE: u8 = u8::MAX;

/// One planning problem.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// The task: its modes are the candidates of every expansion.
    pub task: Task,
    /// Segment sizes (normally `task.dims()`; any sizes within capacity are accepted).
    pub dims: SegmentDims,
    /// The raw current state, `dims.state_dim` floats.
    pub start: &'a [f32],
    /// The mode executed just before (replanning): the root's sequence is `(executed,)` and
    /// the prior continues from it. `None` on the first call of a trial.
    pub executed: Option<ModeId>,
    /// The contact-mode prior over the task's modes; the search floors it at
    /// [`SearchConfig::p_min`].
    pub prior: &'a MarkovPrior,
    /// The modes the plan may begin with ([`ModeSet::all`] for any): the root is expanded
    /// into these only. A caller that sees a finger off the object leaves out the modes that
    /// need it in contact (`docs/online.md`, "The first mode"). Must name at least one of the
    /// task's modes and none beyond.
    pub first_modes: ModeSet,
}

#[derive(Debug, Clone, Copy)]
struct Node {
    parent: u16,
    mode: u8,
    depth: u8,
    g: f32,
    h: f32,
    log_prior: f32,
    progress: f32,
    phi: f32,
}

const EMPTY_NODE: Node = Node {
    parent: NO_NODE,
    mode: NO_MODE,
    depth: 0,
    g: 0.0,
    h: 0.0,
    log_prior: 0.0,
    progress: 0.0,
    phi: 0.0,
};

/// Open-list entry ordered by `f`, then by creation order (FIFO among equal `f`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct OpenEntry {
    key: u32,
    seq: u32,
    node: u16,
    slot: u16,
}

/// A monotone map from `f32` to `u32` (NaN sorts as `+inf`).
fn order_key(f: f32) -> u32 {
    let f = if f.is_nan() { f32::INFINITY } else { f };
    let b = f.to_bits();
    if b >> 31 == 1 { !b } else { b | 0x8000_0000 }
}

/// The `[c0, c1)` ranges that cover `0..n` with at most `max_batch` (at least 1) each.
fn batches(n: usize, max_batch: usize) -> impl Iterator<Item = (usize, usize)> {
    let step = max_batch.max(1);
    (0..n)
        .step_by(step)
        .map(move |c0| (c0, n.min(c0.saturating_add(step))))
}

fn take_slot(free: &[u16], free_len: &mut usize) -> Option<u16> {
    if *free_len == 0 {
        return None;
    }
    *free_len -= 1;
    free.get(*free_len).copied()
}

fn push_open<const O: usize>(
    open: &mut BinaryHeap<OpenEntry, Min, O>,
    next_seq: &mut u32,
    node: u16,
    slot: u16,
    f: f32,
) -> Result<(), Capacity> {
    let entry = OpenEntry {
        key: order_key(f),
        seq: *next_seq,
        node,
        slot,
    };
    *next_seq = next_seq.wrapping_add(1);
    open.push(entry).map_err(|_| Capacity::OpenList)
}

/// The particles of one node: end states (raw layout) and accumulated scores.
#[derive(Debug, Clone, Copy)]
struct Particles<const K: usize> {
    state: [[f32; MAX_STATE_DIM]; K],
    score: [f32; K],
    len: usize,
}

impl<const K: usize> Particles<K> {
    const EMPTY: Self = Self {
        state: [[0.0; MAX_STATE_DIM]; K],
        score: [0.0; K],
        len: 0,
    };

    /// `1 / Σ w²` of the normalised scores.
    fn effective(&self) -> f32 {
        let mut w = [0.0f32; K];
        normalized_weights(&self.score[..self.len], &mut w[..self.len]);
        let s2: f32 = w[..self.len].iter().map(|x| x * x).sum();
        if s2 > 0.0 { 1.0 / s2 } else { f32::NAN }
    }

    /// Score-weighted mean of the end states (uniform when every score is zero).
    fn mean_state(&self, sd: usize, out: &mut [f32; MAX_STATE_DIM]) {
        let mut w = [0.0f32; K];
        normalized_weights(&self.score[..self.len], &mut w[..self.len]);
        out.fill(0.0);
        for (s, &wi) in self.state[..self.len].iter().zip(&w) {
            for (o, &v) in out[..sd].iter_mut().zip(&s[..sd]) {
                *o += wi * v;
            }
        }
    }
}

/// Count one child in [`ParticleDiagnostics`]: the effective numbers of its scores and of
/// Ψ alone, the distinct samples drawn, its mode's spread of end progress, and how far the
/// scores move the mean progress. `progress(j)` is sample `j`'s end progress.
fn observe_child<const K: usize>(
    d: &mut ParticleDiagnostics,
    mode: usize,
    scores: &[f32],
    psi: &[f32],
    valid: &[bool],
    drawn: &[u16],
    progress: impl Fn(usize) -> f32,
) {
    let k = scores.len();
    let ess = |v: &mut dyn Iterator<Item = f32>| {
        let (mut s, mut s2) = (0.0f32, 0.0f32);
        for x in v {
            s += x;
            s2 += x * x;
        }
        if s2 > 0.0 { s * s / s2 } else { 0.0 }
    };
    let e_scores = ess(&mut scores.iter().copied());
    let e_psi = ess(&mut psi.iter().zip(valid).map(|(&p, &ok)| {
        if ok && p.is_finite() {
            p.clamp(0.0, 1.0)
        } else {
            0.0
        }
    }));
    d.children += 1;
    d.ess_scores_sum += e_scores;
    d.ess_scores_min = d.ess_scores_min.min(e_scores);
    d.ess_psi_sum += e_psi;
    d.ess_psi_min = d.ess_psi_min.min(e_psi);
    let mut seen = [false; K];
    for &j in drawn {
        seen[usize::from(j)] = true;
    }
    d.distinct_sum += seen[..k].iter().filter(|&&b| b).count() as u32;
    for (&p, &ok) in psi.iter().zip(valid) {
        if ok {
            d.count_psi(p);
        }
    }
    let (mut n, mut sum, mut sum2, mut wsum, mut wtot) = (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0.0f32);
    for j in (0..k).filter(|&j| valid[j]) {
        let x = progress(j);
        if !x.is_finite() {
            continue;
        }
        n += 1.0;
        sum += x;
        sum2 += x * x;
        wsum += scores[j] * x;
        wtot += scores[j];
    }
    if n > 0.0 && mode < MAX_MODES {
        let mean = sum / n;
        let var = (sum2 / n - mean * mean).max(0.0);
        d.progress_spread_sum[mode] += libm::sqrtf(var);
        d.mode_children[mode] += 1;
        if wtot > 0.0 {
            d.weight_shift_sum += libm::fabsf(wsum / wtot - mean);
        }
    }
}

/// The result node of a search, with its particles' mean state copied out.
#[derive(Debug, Clone, Copy)]
struct Outcome {
    node: u16,
    state: [f32; MAX_STATE_DIM],
    particles: u8,
    effective: f32,
}

/// Read-only inputs of one call, gathered so the helpers take few arguments.
struct Ctx<'a> {
    config: &'a SearchConfig,
    task: Task,
    dims: SegmentDims,
    prior: MarkovPrior,
    k: usize,
    stored: usize,
    first_modes: ModeSet,
}

/// The DIPS A* planner with fixed capacities (see the module docs).
///
/// The struct is large (see `docs/search.md` for `size_of` at the paper's settings): keep it
/// in a `static` or a `Box`, not on a small stack. [`Planner::new`] is `const`.
#[derive(Debug)]
pub struct Planner<const K: usize, const N: usize, const O: usize, const S: usize> {
    nodes: [Node; N],
    node_count: usize,
    open: BinaryHeap<OpenEntry, Min, O>,
    next_seq: u32,
    slots: [Particles<K>; O],
    free: [u16; O],
    free_len: usize,
    parent: Particles<K>,
    starts: [[[f32; MAX_STATE_DIM]; K]; MAX_MODES],
    segments: [[[f32; S]; K]; MAX_MODES],
    contact: [[ContactMode; K]; MAX_MODES],
    psi: [[f32; K]; MAX_MODES],
    cost: [[f32; K]; MAX_MODES],
    valid: [[bool; K]; MAX_MODES],
    diag: ParticleDiagnostics,
}

impl<const K: usize, const N: usize, const O: usize, const S: usize> Default
    for Planner<K, N, O, S>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<const K: usize, const N: usize, const O: usize, const S: usize> Planner<K, N, O, S> {
    /// An empty planner. Capacities are checked at compile time: `K ≥ 1`, `N` and `O` in
    /// `1..65535` (node and slot ids are `u16`).
    pub const fn new() -> Self {
        const {
            assert!(K >= 1 && K < u16::MAX as usize, "K must be in 1..65535");
            assert!(N >= 1 && N < u16::MAX as usize, "N must be in 1..65535");
            assert!(O >= 1 && O < u16::MAX as usize, "O must be in 1..65535");
        }
        Self {
            nodes: [EMPTY_NODE; N],
            node_count: 0,
            open: BinaryHeap::new(),
            next_seq: 0,
            slots: [Particles::EMPTY; O],
            free: [0; O],
            free_len: 0,
            parent: Particles::EMPTY,
            starts: [[[0.0; MAX_STATE_DIM]; K]; MAX_MODES],
            segments: [[[0.0; S]; K]; MAX_MODES],
            contact: [[ContactMode::PLACEHOLDER; K]; MAX_MODES],
            psi: [[0.0; K]; MAX_MODES],
            cost: [[0.0; K]; MAX_MODES],
            valid: [[false; K]; MAX_MODES],
            diag: ParticleDiagnostics::EMPTY,
        }
    }

    /// Plan a contact-mode sequence from `problem.start` (Algorithm 1 inside A*).
    ///
    /// Never panics and never allocates; every outcome, including bad input and exhausted
    /// capacity, is a [`SearchStatus`]. The same config (seed included), problem and models
    /// give a bit-identical report.
    pub fn plan<Sa, Sc, C, Cl>(
        &mut self,
        config: &SearchConfig,
        problem: &Problem<'_>,
        sampler: &mut Sa,
        scorer: &mut Sc,
        objective: &C,
        clock: &mut Cl,
    ) -> SearchReport
    where
        Sa: SegmentSampler,
        Sc: SegmentScorer,
        C: TaskObjective,
        Cl: Clock,
    {
        let t0 = clock.now_us();
        let mut stats = SearchStats::default();
        self.diag = ParticleDiagnostics::EMPTY;
        let mut report = match self.setup(config, problem, sampler, scorer, objective) {
            Err(status) => SearchReport::empty(status, problem.executed),
            Ok(ctx) => self.search(
                &ctx, problem, sampler, scorer, objective, clock, t0, &mut stats,
            ),
        };
        stats.elapsed_ms =
            u32::try_from(clock.now_us().saturating_sub(t0) / 1000).unwrap_or(u32::MAX);
        report.stats = stats;
        report.particle_diagnostics = self.diag;
        report
    }

    /// Validate everything and build the root.
    fn setup<'a, Sa: SegmentSampler, Sc: SegmentScorer, C: TaskObjective>(
        &mut self,
        config: &'a SearchConfig,
        problem: &Problem<'_>,
        sampler: &Sa,
        scorer: &Sc,
        objective: &C,
    ) -> Result<Ctx<'a>, SearchStatus> {
        config.validate().map_err(SearchStatus::InvalidConfig)?;
        let task = problem.task;
        let dims = problem.dims;
        let n_modes = task.mode_count();
        let k = usize::from(config.k);
        if n_modes > MAX_MODES {
            return Err(SearchStatus::CapacityExceeded(Capacity::Modes));
        }
        if k > K {
            return Err(SearchStatus::CapacityExceeded(Capacity::Particles));
        }
        if dims.state_dim > MAX_STATE_DIM {
            return Err(SearchStatus::CapacityExceeded(Capacity::StateDim));
        }
        if dims.floats() > S {
            return Err(SearchStatus::CapacityExceeded(Capacity::SegmentFloats));
        }
        if dims.state_dim == 0
            || dims.horizon == 0
            || dims.fingers != task.finger_names().len()
            || problem.prior.modes() != n_modes
            || !objective.accepts(&dims)
            || !sampler.accepts(&dims)
            || !scorer.accepts(&dims)
            || problem.executed.is_some_and(|m| m.index() >= n_modes)
            || !problem.first_modes.valid_for(task)
        {
            return Err(SearchStatus::InvalidProblem);
        }
        let prior = problem
            .prior
            .with_floor(config.p_min)
            .map_err(|_| SearchStatus::InvalidConfig(super::config::ConfigError::PMin))?;
        let sd = dims.state_dim;
        if problem.start.len() != sd || !problem.start.iter().all(|v| v.is_finite()) {
            return Err(SearchStatus::InvalidStart);
        }
        let progress = objective.progress(problem.start);
        let phi = objective.terminal_cost(progress);
        if !progress.is_finite() || !phi.is_finite() {
            return Err(SearchStatus::InvalidGoal);
        }
        let stored = match config.variant {
            SearchVariant::Particles => k,
            SearchVariant::MaxLikelihood => 1,
        };

        // Reset the storage.
        self.node_count = 0;
        self.open.clear();
        self.next_seq = 0;
        for (i, f) in self.free.iter_mut().enumerate() {
            // Hand slots out from 0 upwards.
            *f = (O - 1 - i) as u16;
        }
        self.free_len = O;

        // The root: `stored` copies of the start state with zero scores.
        let Some(slot) = self.take_slot() else {
            return Err(SearchStatus::CapacityExceeded(Capacity::OpenList));
        };
        let p = &mut self.slots[usize::from(slot)];
        p.len = stored;
        for (s, sc) in p.state[..stored].iter_mut().zip(&mut p.score[..stored]) {
            s[..sd].copy_from_slice(problem.start);
            *sc = 0.0;
        }
        let root = Node {
            parent: NO_NODE,
            mode: problem.executed.map_or(NO_MODE, |m| m.0),
            depth: 0,
            g: 0.0,
            h: config.alpha * phi,
            log_prior: 0.0,
            progress,
            phi,
        };
        self.nodes[0] = root;
        self.node_count = 1;
        self.push_open(0, slot, root.g + root.h)
            .map_err(SearchStatus::CapacityExceeded)?;
        Ok(Ctx {
            config,
            task,
            dims,
            prior,
            k,
            stored,
            first_modes: problem.first_modes,
        })
    }

    /// The A* loop.
    #[allow(clippy::too_many_arguments)]
    fn search<Sa, Sc, C, Cl>(
        &mut self,
        ctx: &Ctx<'_>,
        problem: &Problem<'_>,
        sampler: &mut Sa,
        scorer: &mut Sc,
        objective: &C,
        clock: &mut Cl,
        t0: u64,
        stats: &mut SearchStats,
    ) -> SearchReport
    where
        Sa: SegmentSampler,
        Sc: SegmentScorer,
        C: TaskObjective,
        Cl: Clock,
    {
        let config = ctx.config;
        let sd = ctx.dims.state_dim;
        let mut rng = KernelRng::seed_from_u64(config.seed);
        stats.nodes_generated = 1;
        stats.max_open = 1;
        let mut best: Option<Outcome> = None;
        let mut found: Option<Outcome> = None;
        let mut stop = ApproximateReason::Exhausted;
        while let Some(entry) = self.open.pop() {
            stats.nodes_popped += 1;
            let slot = usize::from(entry.slot);
            self.parent = self.slots[slot];
            self.give_slot(entry.slot);
            let node = self.nodes[usize::from(entry.node)];

            if best.is_none_or(|b| node.phi < self.nodes[usize::from(b.node)].phi) {
                let mut state = [0.0; MAX_STATE_DIM];
                self.parent.mean_state(sd, &mut state);
                best = Some(Outcome {
                    node: entry.node,
                    state,
                    particles: u8::try_from(self.parent.len).unwrap_or(u8::MAX),
                    effective: self.parent.effective(),
                });
            }
            if objective.goal_reached(node.progress) {
                let mut state = [0.0; MAX_STATE_DIM];
                self.parent.mean_state(sd, &mut state);
                found = Some(Outcome {
                    node: entry.node,
                    state,
                    particles: u8::try_from(self.parent.len).unwrap_or(u8::MAX),
                    effective: self.parent.effective(),
                });
                break;
            }
            if usize::from(node.depth) >= usize::from(config.max_depth) {
                continue;
            }
            if config.node_budget > 0 && stats.nodes_expanded >= config.node_budget {
                stop = ApproximateReason::NodeBudget;
                break;
            }
            // Read before every expansion, budget or not: a host clock reports progress from it.
            let elapsed_us = clock.now_us().saturating_sub(t0);
            if config.time_budget_ms > 0 && elapsed_us >= u64::from(config.time_budget_ms) * 1000 {
                stop = ApproximateReason::TimeBudget;
                break;
            }
            if clock.cancelled() {
                stop = ApproximateReason::Cancelled;
                break;
            }
            if let Err(reason) = self.expand(
                ctx, entry.node, &node, sampler, scorer, objective, &mut rng, stats,
            ) {
                stop = reason;
                break;
            }
        }
        let (status, outcome) = match found {
            Some(o) => (SearchStatus::Found, Some(o)),
            None => (SearchStatus::Approximate(stop), best),
        };
        self.report(status, outcome, problem.executed, sd)
    }

    /// Expand one node: one batched sampler call over every candidate mode × particle, the
    /// scores, then one child per mode (Algorithm 1 for each mode).
    #[allow(clippy::too_many_arguments)]
    fn expand<Sa, Sc, C>(
        &mut self,
        ctx: &Ctx<'_>,
        node_id: u16,
        node: &Node,
        sampler: &mut Sa,
        scorer: &mut Sc,
        objective: &C,
        rng: &mut KernelRng,
        stats: &mut SearchStats,
    ) -> Result<(), ApproximateReason>
    where
        Sa: SegmentSampler,
        Sc: SegmentScorer,
        C: TaskObjective,
    {
        let config = ctx.config;
        let dims = &ctx.dims;
        let (k, sd, floats, d) = (ctx.k, dims.state_dim, dims.floats(), dims.dim());
        let n_modes = ctx.task.mode_count();
        let n = n_modes * k;

        // The batch: entry i = m·k + j is mode m from parent particle j (or the single stored
        // trajectory in the max-likelihood variant).
        {
            let starts = self.starts.as_flattened_mut().as_flattened_mut();
            let contact = self.contact.as_flattened_mut();
            for (m, mode) in ctx.task.candidate_modes().enumerate() {
                let cm = ctx
                    .task
                    .contact_mode(mode)
                    .unwrap_or(ContactMode::PLACEHOLDER);
                for j in 0..k {
                    let i = m * k + j;
                    let src = if ctx.stored == 1 { 0 } else { j };
                    starts[i * sd..(i + 1) * sd].copy_from_slice(&self.parent.state[src][..sd]);
                    contact[i] = cm;
                }
            }
        }
        let starts = &self.starts.as_flattened().as_flattened()[..n * sd];
        let contact = &self.contact.as_flattened()[..n];
        let segments = &mut self.segments.as_flattened_mut().as_flattened_mut()[..n * floats];
        for (c0, c1) in batches(n, sampler.max_batch()) {
            stats.sampler_calls += 1;
            sampler
                .sample(
                    dims,
                    &starts[c0 * sd..c1 * sd],
                    &contact[c0..c1],
                    rng,
                    &mut segments[c0 * floats..c1 * floats],
                )
                .map_err(|_| ApproximateReason::SamplerFailed)?;
        }
        stats.segments_sampled += n as u32;
        let psi = &mut self.psi.as_flattened_mut()[..n];
        for (c0, c1) in batches(n, scorer.max_batch()) {
            stats.scorer_calls += 1;
            scorer
                .score(
                    dims,
                    &segments[c0 * floats..c1 * floats],
                    &contact[c0..c1],
                    &mut psi[c0..c1],
                )
                .map_err(|_| ApproximateReason::ScorerFailed)?;
        }
        let cost = &mut self.cost.as_flattened_mut()[..n];
        let valid = &mut self.valid.as_flattened_mut()[..n];
        for i in 0..n {
            let seg = &segments[i * floats..(i + 1) * floats];
            let ok = seg.iter().all(|v| v.is_finite());
            cost[i] = if ok {
                objective.segment_cost(contact[i], dims, seg)
            } else {
                f32::NAN
            };
            valid[i] = ok && cost[i].is_finite();
        }
        stats.nodes_expanded += 1;

        // γ^d with d = depth(parent) (the paper's definition), by repeated multiplication.
        let mut discount = 1.0f32;
        for _ in 0..node.depth {
            discount *= config.gamma;
        }
        let from = (node.mode != NO_MODE).then_some(ModeId(node.mode));
        let end_row = (dims.horizon - 1) * d;
        for (m, mode) in ctx.task.candidate_modes().enumerate() {
            if node.depth == 0 && !ctx.first_modes.contains(mode) {
                // The plan may not begin with this mode (its segments were sampled with the
                // batch and are dropped).
                continue;
            }
            let base = m * k;
            let mut parent_scores = [0.0f32; K];
            for (j, p) in parent_scores[..k].iter_mut().enumerate() {
                *p = self.parent.score[if ctx.stored == 1 { 0 } else { j }];
            }
            let mut scores = [0.0f32; K];
            let total = accumulate_scores(
                &parent_scores[..k],
                &psi[base..base + k],
                &valid[base..base + k],
                discount,
                &mut scores[..k],
            );
            // The chosen batch indices (relative to `base`) of the child's particles.
            let mut idx = [0u16; K];
            let kept = match config.variant {
                SearchVariant::Particles => {
                    let drawable = total > 0.0 && total.is_finite();
                    if drawable && resample(&scores[..k], rng, &mut idx[..k]) {
                        k
                    } else {
                        0
                    }
                }
                SearchVariant::MaxLikelihood => match argmax_positive(&scores[..k]) {
                    Some(j) => {
                        idx[0] = j as u16;
                        1
                    }
                    None => 0,
                },
            };
            if kept == 0 {
                stats.dead_children += 1;
                continue;
            }
            observe_child::<K>(
                &mut self.diag,
                m,
                &scores[..k],
                &psi[base..base + k],
                &valid[base..base + k],
                &idx[..kept],
                |j| {
                    let seg = (base + j) * floats + end_row;
                    objective.progress(&segments[seg..seg + sd])
                },
            );
            let mut child = Particles::<K>::EMPTY;
            child.len = kept;
            for (i, &j) in idx[..kept].iter().enumerate() {
                let seg = (base + usize::from(j)) * floats;
                child.state[i][..sd].copy_from_slice(&segments[seg + end_row..seg + end_row + sd]);
                child.score[i] = scores[usize::from(j)];
            }
            let mut w = [0.0f32; K];
            normalized_weights(&child.score[..kept], &mut w[..kept]);
            let seg_cost = weighted_sum(
                &w[..kept],
                idx[..kept].iter().map(|&j| cost[base + usize::from(j)]),
            );
            let progress = weighted_sum(
                &w[..kept],
                child.state[..kept]
                    .iter()
                    .map(|s| objective.progress(&s[..sd])),
            );
            let g = match config.cost_to_come {
                CostToCome::Cumulative => node.g + seg_cost,
                CostToCome::LastSegment => seg_cost,
            };
            let log_prior = node.log_prior + ctx.prior.log_probability(from, mode);
            let phi = objective.terminal_cost(progress);
            let h = config.alpha * phi
                - if config.beta > 0.0 {
                    config.beta * log_prior
                } else {
                    0.0
                };
            let child_node = Node {
                parent: node_id,
                mode: mode.0,
                depth: node.depth + 1,
                g,
                h,
                log_prior,
                progress,
                phi,
            };
            if self.node_count >= N {
                return Err(ApproximateReason::Capacity(Capacity::Nodes));
            }
            let Some(slot) = take_slot(&self.free, &mut self.free_len) else {
                return Err(ApproximateReason::Capacity(Capacity::OpenList));
            };
            let id = self.node_count as u16;
            self.nodes[self.node_count] = child_node;
            self.node_count += 1;
            self.slots[usize::from(slot)] = child;
            push_open(&mut self.open, &mut self.next_seq, id, slot, g + h)
                .map_err(ApproximateReason::Capacity)?;
            stats.nodes_generated += 1;
            stats.max_open = stats.max_open.max(self.open.len() as u32);
        }
        Ok(())
    }

    fn take_slot(&mut self) -> Option<u16> {
        take_slot(&self.free, &mut self.free_len)
    }

    fn give_slot(&mut self, slot: u16) {
        if self.free_len < O {
            self.free[self.free_len] = slot;
            self.free_len += 1;
        }
    }

    fn push_open(&mut self, node: u16, slot: u16, f: f32) -> Result<(), Capacity> {
        push_open(&mut self.open, &mut self.next_seq, node, slot, f)
    }

    fn report(
        &self,
        status: SearchStatus,
        outcome: Option<Outcome>,
        executed: Option<ModeId>,
        sd: usize,
    ) -> SearchReport {
        let mut report = SearchReport::empty(status, executed);
        let Some(outcome) = outcome else {
            return report;
        };
        let node = self.nodes[usize::from(outcome.node)];
        let mut path = [ModeId(0); MAX_PLAN_LEN];
        let len = usize::from(node.depth).min(MAX_PLAN_LEN);
        let mut cur = outcome.node;
        for slot in path[..len].iter_mut().rev() {
            let n = self.nodes[usize::from(cur)];
            *slot = ModeId(n.mode);
            cur = n.parent;
        }
        for &m in &path[..len] {
            // Capacity is MAX_PLAN_LEN and len <= MAX_PLAN_LEN: cannot fail.
            let _ = report.modes.push(m);
        }
        let _ = report
            .terminal_state
            .extend_from_slice(&outcome.state[..sd]);
        report.expected_progress = node.progress;
        report.terminal_cost = node.phi;
        report.cost_to_come = node.g;
        report.heuristic = node.h;
        report.particles = outcome.particles;
        report.effective_particles = outcome.effective;
        report
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_key_is_monotone() {
        let xs = [
            f32::NEG_INFINITY,
            -1e9,
            -1.0,
            -0.0,
            0.0,
            1e-30,
            1.0,
            1e9,
            f32::INFINITY,
        ];
        for w in xs.windows(2) {
            assert!(order_key(w[0]) <= order_key(w[1]), "{w:?}");
        }
        assert_eq!(order_key(f32::NAN), order_key(f32::INFINITY));
    }

    #[test]
    fn batches_cover_the_range_in_order() {
        let all = |n, m| batches(n, m).collect::<std::vec::Vec<_>>();
        assert_eq!(all(7, 3), [(0, 3), (3, 6), (6, 7)]);
        assert_eq!(all(6, 3), [(0, 3), (3, 6)]);
        assert_eq!(all(2, 0), [(0, 1), (1, 2)]);
        assert_eq!(all(5, usize::MAX), [(0, 5)]);
        assert!(all(0, 4).is_empty());
    }

    #[test]
    fn paper_planner_memory_stays_within_budget() {
        // docs/search.md: 425,512 bytes on x86_64; keep it well under 512 KiB.
        let size = core::mem::size_of::<PaperPlanner>();
        assert!(size <= 448 * 1024, "PaperPlanner is {size} bytes");
        // Particle slots dominate: one per open entry.
        assert!(size >= 256 * core::mem::size_of::<Particles<16>>());
    }
}
