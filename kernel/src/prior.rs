//! The Markov contact-mode prior `p(c_0) · Π p(c_n | c_{n-1})` (paper §"Probabilistic
//! Contact Sequence Search", `spec/algorithms.md` §3.4).
//!
//! The table has one row per mode of the task plus a virtual start row (row 0) that holds
//! `p(c_0)`; row `i + 1` holds the transitions out of mode `i`. Columns are the task's modes.
//!
//! Fitting counts first modes and transitions in demonstration sequences and normalises each
//! row. **A row without any data is uniform.** [`MarkovPrior::with_floor`] then enforces the
//! paper's minimum probability `p_min`: every entry below `p_min` is raised to `p_min` and the
//! mass is taken from the remaining entries in proportion to their values, repeated until no
//! entry falls below `p_min` (taking mass can push another entry under the floor).

use crate::mode::{MAX_MODES, ModeId, Task};
use core::fmt;

/// Rows of the table: the virtual start plus one per mode.
pub const PRIOR_ROWS: usize = MAX_MODES + 1;

/// Why a prior could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum PriorError {
    /// Zero modes or more than [`MAX_MODES`].
    ModeCount,
    /// A sequence names a mode outside the table.
    UnknownMode,
    /// `p_min` is negative, not finite, or `p_min · modes > 1`.
    InvalidPMin,
    /// A given probability row is negative, not finite, or sums to zero.
    InvalidRow,
}

impl fmt::Display for PriorError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PriorError::ModeCount => "prior: mode count is zero or above capacity",
            PriorError::UnknownMode => "prior: sequence names a mode outside the table",
            PriorError::InvalidPMin => "prior: p_min must be finite, >= 0 and p_min*modes <= 1",
            PriorError::InvalidRow => "prior: probability row is negative, non-finite or zero",
        })
    }
}

impl core::error::Error for PriorError {}

/// A 1-step Markov prior over a task's modes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkovPrior {
    modes: usize,
    /// `p[0]` = `p(c_0)`, `p[i + 1][j]` = `p(c_n = j | c_{n-1} = i)`.
    p: [[f32; MAX_MODES]; PRIOR_ROWS],
}

impl MarkovPrior {
    /// Every row uniform.
    pub fn uniform(modes: usize) -> Result<Self, PriorError> {
        if modes == 0 || modes > MAX_MODES {
            return Err(PriorError::ModeCount);
        }
        let mut p = [[0.0; MAX_MODES]; PRIOR_ROWS];
        for row in p.iter_mut().take(modes + 1) {
            row[..modes].fill(1.0 / modes as f32);
        }
        Ok(Self { modes, p })
    }

    /// The paper's hand-designed prior for `task`, floored at `p_min` (spec `algorithms.md`
    /// §3.4), for kernels that have not been given one fitted to demonstrations.
    /// - Screwdriver (modes turn, index-regrasp, thumb-middle-regrasp): start with a turn;
    ///   after a turn either regrasp; after a regrasp the other regrasp or a turn. With
    ///   `p_min = 0.1` this is exactly the spec's matrix: `p(c₀) = [.8, .1, .1]`, and
    ///   `.1` to repeat a mode, `.45` for each other mode.
    /// - Card: uniform over its four modes.
    pub fn paper(task: Task, p_min: f32) -> Result<Self, PriorError> {
        let raw = match task {
            Task::Screwdriver => Self::from_rows(
                &[1.0, 0.0, 0.0],
                &[&[0.0, 0.5, 0.5], &[0.5, 0.0, 0.5], &[0.5, 0.5, 0.0]],
            )?,
            Task::Card => Self::uniform(task.mode_count())?,
        };
        raw.with_floor(p_min)
    }

    /// A prior from explicit rows: `start` is `p(c_0)`, `rows[i]` the transitions out of mode
    /// `i`. Each row is renormalised to sum to one.
    pub fn from_rows(start: &[f32], rows: &[&[f32]]) -> Result<Self, PriorError> {
        let modes = start.len();
        if modes == 0 || modes > MAX_MODES || rows.len() != modes {
            return Err(PriorError::ModeCount);
        }
        let mut p = [[0.0; MAX_MODES]; PRIOR_ROWS];
        for (r, src) in core::iter::once(start)
            .chain(rows.iter().copied())
            .enumerate()
        {
            if src.len() != modes {
                return Err(PriorError::ModeCount);
            }
            let mut sum = 0.0f64;
            for &v in src {
                if !v.is_finite() || v < 0.0 {
                    return Err(PriorError::InvalidRow);
                }
                sum += f64::from(v);
            }
            if sum <= 0.0 {
                return Err(PriorError::InvalidRow);
            }
            for (dst, &v) in p[r].iter_mut().zip(src) {
                *dst = (f64::from(v) / sum) as f32;
            }
        }
        Ok(Self { modes, p })
    }

    /// Fit from demonstration sequences: the first mode of each sequence is counted in the
    /// start row, each consecutive pair in its transition row. Rows without data are uniform.
    /// No floor is applied (see [`MarkovPrior::with_floor`]).
    pub fn fit<I, S>(modes: usize, sequences: I) -> Result<Self, PriorError>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<[ModeId]>,
    {
        if modes == 0 || modes > MAX_MODES {
            return Err(PriorError::ModeCount);
        }
        let mut counts = [[0u64; MAX_MODES]; PRIOR_ROWS];
        for seq in sequences {
            let seq = seq.as_ref();
            let mut from = 0usize;
            for &m in seq {
                if m.index() >= modes {
                    return Err(PriorError::UnknownMode);
                }
                counts[from][m.index()] += 1;
                from = m.index() + 1;
            }
        }
        let mut p = [[0.0; MAX_MODES]; PRIOR_ROWS];
        for (row, c) in p.iter_mut().zip(&counts).take(modes + 1) {
            let total: u64 = c[..modes].iter().sum();
            for (dst, &n) in row[..modes].iter_mut().zip(&c[..modes]) {
                *dst = if total == 0 {
                    1.0 / modes as f32
                } else {
                    (n as f64 / total as f64) as f32
                };
            }
        }
        Ok(Self { modes, p })
    }

    /// [`MarkovPrior::fit`] followed by [`MarkovPrior::with_floor`].
    pub fn fit_with_floor<I, S>(modes: usize, sequences: I, p_min: f32) -> Result<Self, PriorError>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<[ModeId]>,
    {
        Self::fit(modes, sequences)?.with_floor(p_min)
    }

    /// Raise every probability below `p_min` to `p_min`, taking the mass from the other
    /// entries of its row in proportion to their values, until no entry is below `p_min`.
    pub fn with_floor(&self, p_min: f32) -> Result<Self, PriorError> {
        if !p_min.is_finite() || p_min < 0.0 || f64::from(p_min) * self.modes as f64 > 1.0 + 1e-6 {
            return Err(PriorError::InvalidPMin);
        }
        let mut out = *self;
        for row in out.p.iter_mut().take(self.modes + 1) {
            floor_row(&mut row[..self.modes], f64::from(p_min));
        }
        Ok(out)
    }

    /// Number of modes.
    pub const fn modes(&self) -> usize {
        self.modes
    }

    /// `p(to | from)`; `from = None` is the virtual start (`p(c_0)`). Zero for unknown modes.
    pub fn probability(&self, from: Option<ModeId>, to: ModeId) -> f32 {
        let row = from.map_or(0, |m| m.index() + 1);
        if row > self.modes || to.index() >= self.modes {
            return 0.0;
        }
        self.p[row][to.index()]
    }

    /// `log p(to | from)` (`-inf` for a zero probability or an unknown mode).
    pub fn log_probability(&self, from: Option<ModeId>, to: ModeId) -> f32 {
        libm::logf(self.probability(from, to))
    }

    /// `log p(C) = log p(c_0) + Σ log p(c_n | c_{n-1})`; zero for the empty sequence.
    pub fn log_likelihood(&self, seq: &[ModeId]) -> f32 {
        self.log_likelihood_from(None, seq)
    }

    /// The log-likelihood of `seq` continuing after the already executed mode `prev`
    /// (replanning): `Σ log p(c_n | c_{n-1})` with `c_{-1} = prev`, no start term.
    pub fn log_likelihood_after(&self, prev: ModeId, seq: &[ModeId]) -> f32 {
        self.log_likelihood_from(Some(prev), seq)
    }

    fn log_likelihood_from(&self, mut from: Option<ModeId>, seq: &[ModeId]) -> f32 {
        let mut sum = 0.0f32;
        for &m in seq {
            sum += self.log_probability(from, m);
            from = Some(m);
        }
        sum
    }
}

/// Floor one row (sums to one) at `p_min`, iterating until stable.
fn floor_row(row: &mut [f32], p_min: f64) {
    let mut orig = [0.0f64; MAX_MODES];
    for (o, &v) in orig.iter_mut().zip(row.iter()) {
        *o = f64::from(v);
    }
    let n = row.len();
    let mut floored = [false; MAX_MODES];
    let mut cur = orig;
    // Each pass floors at least one more entry or stops, so `n` passes suffice.
    for _ in 0..=n {
        let mut changed = false;
        for i in 0..n {
            if !floored[i] && cur[i] < p_min {
                floored[i] = true;
                changed = true;
            }
        }
        if !changed {
            break;
        }
        let n_floored = floored[..n].iter().filter(|&&f| f).count();
        let free_mass = (1.0 - n_floored as f64 * p_min).max(0.0);
        let free_orig: f64 = (0..n).filter(|&i| !floored[i]).map(|i| orig[i]).sum();
        for i in 0..n {
            cur[i] = if floored[i] {
                p_min
            } else if free_orig > 0.0 {
                orig[i] * free_mass / free_orig
            } else {
                0.0
            };
        }
    }
    for (dst, &v) in row.iter_mut().zip(&cur) {
        *dst = v as f32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_priors_are_the_spec_matrices() {
        let p = MarkovPrior::paper(Task::Screwdriver, 0.1).unwrap();
        let close = |a: f32, b: f32| (a - b).abs() < 1e-6;
        for (to, want) in [(0, 0.8), (1, 0.1), (2, 0.1)] {
            assert!(close(p.probability(None, ModeId(to)), want), "start → {to}");
        }
        for from in 0..3u8 {
            for to in 0..3u8 {
                let want = if from == to { 0.1 } else { 0.45 };
                let got = p.probability(Some(ModeId(from)), ModeId(to));
                assert!(close(got, want), "{from} → {to}: {got}");
            }
        }
        let c = MarkovPrior::paper(Task::Card, 0.1).unwrap();
        assert!(close(c.probability(Some(ModeId(2)), ModeId(3)), 0.25));
        assert_eq!(
            MarkovPrior::paper(Task::Card, 0.3),
            Err(PriorError::InvalidPMin)
        );
    }

    #[test]
    fn floor_examples_from_the_spec() {
        let mut r = [0.0f32, 0.0, 1.0];
        floor_row(&mut r, 0.1);
        assert_eq!(r, [0.1, 0.1, 0.8]);
        let mut r = [0.0f32, 0.5, 0.5];
        floor_row(&mut r, 0.1);
        assert_eq!(r, [0.1, 0.45, 0.45]);
    }

    #[test]
    fn floor_iterates_until_stable() {
        // 0.12 drops below 0.3 once 0.3 is given to the zero entry: it must be floored too.
        let mut r = [0.0f32, 0.12, 0.88];
        floor_row(&mut r, 0.3);
        assert!(
            (r[0] - 0.3).abs() < 1e-6 && (r[1] - 0.3).abs() < 1e-6,
            "{r:?}"
        );
        assert!((r[2] - 0.4).abs() < 1e-6, "{r:?}");
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert_eq!(MarkovPrior::uniform(0), Err(PriorError::ModeCount));
        assert_eq!(
            MarkovPrior::uniform(MAX_MODES + 1),
            Err(PriorError::ModeCount)
        );
        let u = MarkovPrior::uniform(3).unwrap();
        assert_eq!(u.with_floor(0.4), Err(PriorError::InvalidPMin));
        assert_eq!(u.with_floor(f32::NAN), Err(PriorError::InvalidPMin));
        assert_eq!(
            MarkovPrior::fit(2, [[ModeId(2)]]),
            Err(PriorError::UnknownMode)
        );
        assert_eq!(
            MarkovPrior::from_rows(&[1.0, -1.0], &[&[1.0, 1.0], &[1.0, 1.0]]),
            Err(PriorError::InvalidRow)
        );
        assert_eq!(
            MarkovPrior::from_rows(&[1.0, 1.0], &[&[1.0, 1.0]]),
            Err(PriorError::ModeCount)
        );
    }

    #[test]
    fn log_likelihood_sums_rows() {
        let p = MarkovPrior::from_rows(&[0.2, 0.8], &[&[0.5, 0.5], &[0.25, 0.75]]).unwrap();
        let seq = [ModeId(1), ModeId(0), ModeId(1)];
        let want = libm::logf(0.8) + libm::logf(0.25) + libm::logf(0.5);
        assert!((p.log_likelihood(&seq) - want).abs() < 1e-6);
        let want = libm::logf(0.75) + libm::logf(0.25) + libm::logf(0.5);
        assert!((p.log_likelihood_after(ModeId(1), &seq) - want).abs() < 1e-6);
        assert_eq!(p.log_likelihood(&[]), 0.0);
        assert_eq!(p.probability(None, ModeId(5)), 0.0);
    }
}
