//! The joint PD's gains and clamps ([`PdGains`]): the vendor's by default
//! ([`PdGains::vendor`]), the DIPS authors' hardware controller's ([`PdGains::paper`]), or a
//! JSON gains file over either ([`PdGains::load`]).
//!
//! Units are the bus's: PWM per rad and PWM per rad/s (full scale 1200 at 12 V), as the
//! vendor's `gains_pd.yaml` gives them.

use std::path::Path;

use dips_world::kinematics::HandJoints;
use serde::{Deserialize, Serialize};

/// The vendor's per-joint PWM caps, bus order (index, middle, ring: roll 375, near 675,
/// middle 450, far 285; thumb 525, 405, 270, 270).
pub const VENDOR_PWM_CAPS: [[f64; 4]; 4] = [
    [375.0, 675.0, 450.0, 285.0],
    [375.0, 675.0, 450.0, 285.0],
    [375.0, 675.0, 450.0, 285.0],
    [525.0, 405.0, 270.0, 270.0],
];

/// The PD's gains, clamps and options. Every field has the vendor's value unless a profile
/// or gains file says otherwise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdGains {
    /// Which set this started from (`vendor`, `paper`), as results record it.
    #[serde(default = "vendor_name")]
    pub name: String,
    /// Proportional gain per joint (PWM per rad), bus order `[finger][joint]`.
    pub kp: HandJoints,
    /// Derivative gain per joint (PWM per rad/s) on the filtered velocity.
    pub kd: HandJoints,
    /// Per-joint cap on |PWM|.
    pub pwm_caps: HandJoints,
    /// Cap on |PWM| of every joint (1200: full scale at 12 V).
    pub global_cap: f64,
    /// Clamp on |reference − position| before the gain (rad); `None`: no clamp.
    pub error_clamp_rad: Option<f64>,
    /// Clamp on the normalised torque (fraction of full scale) after the PD; `None`: none.
    pub torque_clamp: Option<f64>,
    /// Add the hand's gravity torques (from its kinematic model and link masses).
    pub gravity_compensation: bool,
}

fn vendor_name() -> String {
    "vendor".into()
}

/// A gains file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum GainsError {
    /// The file could not be read.
    #[error("gains file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The error.
        source: std::io::Error,
    },
    /// The file is not a gains document.
    #[error(
        "gains file {path}: {message} (expected JSON with kp, kd, pwm_caps as 4×4 arrays in bus \
         order, global_cap, error_clamp_rad, torque_clamp, gravity_compensation)"
    )]
    Format {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// A value out of its range.
    #[error("gains {field}: {value} ({allowed})")]
    Range {
        /// The field, with its joint.
        field: String,
        /// The value.
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
}

impl PdGains {
    /// The vendor's PD (`gains_pd.yaml`): kp 4000 on every joint; kd 150, 200 on each
    /// finger's joint 1, the thumb 300, 200, 200, 150; the per-joint caps; no error or
    /// torque clamp; no gravity compensation.
    pub fn vendor() -> PdGains {
        let finger_kd = [150.0, 200.0, 150.0, 150.0];
        PdGains {
            name: vendor_name(),
            kp: [[4000.0; 4]; 4],
            kd: [
                finger_kd,
                finger_kd,
                finger_kd,
                [300.0, 200.0, 200.0, 150.0],
            ],
            pwm_caps: VENDOR_PWM_CAPS,
            global_cap: 1200.0,
            error_clamp_rad: None,
            torque_clamp: None,
            gravity_compensation: false,
        }
    }

    /// The DIPS authors' hardware controller: the vendor's gains with the position error
    /// clamped to ±0.15 rad, the torque to ±0.65 of full scale, and gravity compensation.
    pub fn paper() -> PdGains {
        PdGains {
            name: "paper".into(),
            error_clamp_rad: Some(0.15),
            torque_clamp: Some(0.65),
            gravity_compensation: true,
            ..PdGains::vendor()
        }
    }

    /// A named set: `vendor` or `paper`.
    pub fn named(name: &str) -> Option<PdGains> {
        match name {
            "vendor" => Some(PdGains::vendor()),
            "paper" => Some(PdGains::paper()),
            _ => None,
        }
    }

    /// Read a gains file (JSON, every field given) and check it.
    pub fn load(path: &Path) -> Result<PdGains, GainsError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| GainsError::Io {
            path: p.clone(),
            source,
        })?;
        let gains: PdGains = serde_json::from_str(&text).map_err(|e| GainsError::Format {
            path: p,
            message: e.to_string(),
        })?;
        gains.validate()?;
        Ok(gains)
    }

    /// Every gain finite and ≥ 0, caps in (0, 1200], clamps positive.
    pub fn validate(&self) -> Result<(), GainsError> {
        let range = |field: String, value: f64, ok: bool, allowed| {
            if ok {
                Ok(())
            } else {
                Err(GainsError::Range {
                    field,
                    value,
                    allowed,
                })
            }
        };
        for f in 0..4 {
            for j in 0..4 {
                let (kp, kd, cap) = (self.kp[f][j], self.kd[f][j], self.pwm_caps[f][j]);
                range(
                    format!("kp[{f}][{j}]"),
                    kp,
                    kp.is_finite() && kp >= 0.0,
                    "≥ 0",
                )?;
                range(
                    format!("kd[{f}][{j}]"),
                    kd,
                    kd.is_finite() && kd >= 0.0,
                    "≥ 0",
                )?;
                range(
                    format!("pwm_caps[{f}][{j}]"),
                    cap,
                    cap > 0.0 && cap <= 1200.0,
                    "in (0, 1200]",
                )?;
            }
        }
        range(
            "global_cap".into(),
            self.global_cap,
            self.global_cap > 0.0 && self.global_cap <= 1200.0,
            "in (0, 1200]",
        )?;
        if let Some(e) = self.error_clamp_rad {
            range("error_clamp_rad".into(), e, e > 0.0 && e.is_finite(), "> 0")?;
        }
        if let Some(t) = self.torque_clamp {
            range("torque_clamp".into(), t, t > 0.0 && t <= 1.0, "in (0, 1]")?;
        }
        Ok(())
    }

    /// The PD's PWM for one joint before the caps: `kp·clamp(e) − kd·v`.
    pub fn pd(&self, finger: usize, joint: usize, error: f64, velocity: f64) -> f64 {
        let e = match self.error_clamp_rad {
            Some(c) => error.clamp(-c, c),
            None => error,
        };
        self.kp[finger][joint] * e - self.kd[finger][joint] * velocity
    }

    /// Apply the torque clamp, the joint's cap and the global cap to a PWM value.
    pub fn clamp(&self, finger: usize, joint: usize, pwm: f64) -> f64 {
        let mut cap = self.pwm_caps[finger][joint].min(self.global_cap);
        if let Some(t) = self.torque_clamp {
            cap = cap.min(t * f64::from(dips_allegro_protocol::scale::FULL_SCALE_PWM));
        }
        if pwm.is_nan() {
            0.0
        } else {
            pwm.clamp(-cap, cap)
        }
    }
}

impl Default for PdGains {
    fn default() -> PdGains {
        PdGains::vendor()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vendor_and_paper_gains_and_their_clamps() {
        let v = PdGains::vendor();
        v.validate().unwrap();
        assert_eq!(v.kd[3], [300.0, 200.0, 200.0, 150.0]);
        assert_eq!(v.kd[0][1], 200.0);
        // 0.2 rad of error: 800 PWM, capped at the index roll's 375.
        assert_eq!(v.clamp(0, 0, v.pd(0, 0, 0.2, 0.0)), 375.0);
        assert_eq!(v.clamp(0, 1, v.pd(0, 1, 0.2, 0.0)), 675.0);
        assert_eq!(v.clamp(0, 1, f64::NAN), 0.0);
        let p = PdGains::paper();
        // The error clamps at 0.15 rad: 600 PWM; the torque at 0.65 × 1200 = 780.
        assert_eq!(p.pd(0, 1, 1.0, 0.0), 600.0);
        assert_eq!(p.clamp(0, 1, 5000.0), 675.0);
        assert_eq!(PdGains::named("paper"), Some(p));
        assert_eq!(PdGains::named("fast"), None);
    }

    #[test]
    fn a_gains_file_round_trips_and_bad_ones_say_what_is_wrong() {
        let dir = std::env::temp_dir().join(format!("dips-gains-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("gains.json");
        let mut g = PdGains::vendor();
        g.kp[1][2] = 2500.0;
        std::fs::write(&path, serde_json::to_string_pretty(&g).unwrap()).unwrap();
        assert_eq!(PdGains::load(&path).unwrap(), g);
        g.kd[0][0] = -1.0;
        std::fs::write(&path, serde_json::to_string(&g).unwrap()).unwrap();
        let e = PdGains::load(&path).unwrap_err().to_string();
        assert_eq!(e, "gains kd[0][0]: -1 (≥ 0)");
        std::fs::write(&path, r#"{"kp": 1}"#).unwrap();
        let e = PdGains::load(&path).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("gains file {}: ", path.display())),
            "{e}"
        );
        assert!(e.contains("expected JSON with kp"), "{e}");
        let e = PdGains::load(&dir.join("missing.json")).unwrap_err();
        assert!(matches!(e, GainsError::Io { .. }), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
