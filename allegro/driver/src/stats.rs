//! What the control loop measured: its period's distribution and the frames it counted
//! ([`LoopStats`]), as `result.json` records them.

use serde::{Deserialize, Serialize};

/// Period percentiles of the loop (ms).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PeriodStats {
    /// Loop ticks measured (intervals between complete pose sets).
    pub ticks: u64,
    /// Mean period (ms).
    pub mean_ms: f64,
    /// Median period (ms).
    pub p50_ms: f64,
    /// 99th percentile (ms).
    pub p99_ms: f64,
    /// Longest period (ms).
    pub max_ms: f64,
    /// Standard deviation of the period (ms): the jitter.
    pub jitter_ms: f64,
}

/// Frame counts and periods of one controller's life.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LoopStats {
    /// The loop's period.
    pub period: PeriodStats,
    /// Frames the host sent.
    pub frames_sent: u64,
    /// SET_TORQUE frames among them.
    pub torque_frames: u64,
    /// Frames received.
    pub frames_received: u64,
    /// Complete pose sets (four fingers) received.
    pub pose_sets: u64,
    /// Frames that were not of the protocol (malformed, unknown, extended ids): counted and
    /// ignored.
    pub bad_frames: u64,
    /// Frames of the protocol from another device id, or not expected: ignored.
    pub ignored_frames: u64,
    /// Ticks where a PWM hit its cap.
    pub saturated_ticks: u64,
    /// How the loop's thread was scheduled (`fifo:80`, or `normal (why)`).
    pub scheduling: String,
}

/// Collects loop intervals.
#[derive(Debug, Clone, Default)]
pub(crate) struct Intervals {
    ms: Vec<f64>,
}

/// Intervals kept at most (≈ 50 min at 333 Hz); the percentiles cover the first ones beyond.
const MAX_INTERVALS: usize = 1_000_000;

impl Intervals {
    pub(crate) fn push(&mut self, ms: f64) {
        if self.ms.len() < MAX_INTERVALS {
            self.ms.push(ms);
        }
    }

    pub(crate) fn stats(&self, ticks: u64) -> PeriodStats {
        if self.ms.is_empty() {
            return PeriodStats {
                ticks,
                ..PeriodStats::default()
            };
        }
        let mut s = self.ms.clone();
        s.sort_by(f64::total_cmp);
        let n = s.len();
        let at = |q: f64| s[((q * (n - 1) as f64).round() as usize).min(n - 1)];
        let mean = s.iter().sum::<f64>() / n as f64;
        let var = s.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        PeriodStats {
            ticks,
            mean_ms: mean,
            p50_ms: at(0.5),
            p99_ms: at(0.99),
            max_ms: s[n - 1],
            jitter_ms: var.sqrt(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_of_a_known_set() {
        let mut i = Intervals::default();
        for k in 1..=100 {
            i.push(f64::from(k));
        }
        let s = i.stats(100);
        assert_eq!((s.p50_ms, s.p99_ms, s.max_ms), (51.0, 99.0, 100.0));
        assert!((s.mean_ms - 50.5).abs() < 1e-12);
        assert_eq!(Intervals::default().stats(0), PeriodStats::default());
    }
}
