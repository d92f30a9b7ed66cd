//! Scaling between the bus's integers and physical values.
//!
//! - Encoder: `rad = counts × (333.3 / 65536) × π / 180` (±166.6° over the i16 range); the V4
//!   applies no per-joint offset or sign on the host.
//! - Torque: `pwm = normalised × 1200` at 12 V, the normalised torque clamped to [−1, 1]
//!   first. The hand has no torque sensing.

/// Degrees per encoder count: 333.3° over the 16-bit range.
pub const DEGREES_PER_COUNT: f64 = 333.3 / 65536.0;
/// Radians per encoder count.
pub const RADIANS_PER_COUNT: f64 = DEGREES_PER_COUNT * core::f64::consts::PI / 180.0;
/// Full-scale PWM at the V4's 12 V supply: a normalised torque of 1.
pub const FULL_SCALE_PWM: i16 = 1200;

/// Round half away from zero and saturate into i16 (`as` saturates; NaN becomes 0).
fn round_i16(x: f64) -> i16 {
    if x >= 0.0 {
        (x + 0.5) as i16
    } else {
        (x - 0.5) as i16
    }
}

/// Radians of an encoder reading.
pub fn counts_to_radians(counts: i16) -> f64 {
    f64::from(counts) * RADIANS_PER_COUNT
}

/// The encoder reading nearest to an angle (saturating at ±166.6°; NaN reads 0).
pub fn radians_to_counts(rad: f64) -> i16 {
    round_i16(rad / RADIANS_PER_COUNT)
}

/// PWM of a normalised torque, clamped to [−1, 1] first (NaN sends 0).
pub fn normalised_to_pwm(torque: f64) -> i16 {
    if torque.is_nan() {
        return 0;
    }
    round_i16(torque.clamp(-1.0, 1.0) * f64::from(FULL_SCALE_PWM))
}

/// Normalised torque of a PWM value (PWM beyond full scale reads beyond ±1).
pub fn pwm_to_normalised(pwm: i16) -> f64 {
    f64::from(pwm) / f64::from(FULL_SCALE_PWM)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_radians_round_trip_within_half_a_count() {
        for c in [i16::MIN, -12345, -1, 0, 1, 2, 999, 0x0A34, i16::MAX] {
            assert_eq!(radians_to_counts(counts_to_radians(c)), c);
        }
        for i in -290..=290 {
            let rad = f64::from(i) * 0.01;
            let back = counts_to_radians(radians_to_counts(rad));
            assert!(
                (back - rad).abs() <= 0.5 * RADIANS_PER_COUNT + 1e-15,
                "{rad}"
            );
        }
        // 166.6° saturates; NaN is 0.
        assert_eq!(radians_to_counts(10.0), i16::MAX);
        assert_eq!(radians_to_counts(-10.0), i16::MIN);
        assert_eq!(radians_to_counts(f64::NAN), 0);
        // One count is 333.3/65536 ≈ 0.005086°, 88.76 µrad.
        assert!((RADIANS_PER_COUNT - 8.876_4e-5).abs() < 1e-8);
    }

    #[test]
    fn pwm_is_normalised_torque_times_1200_clamped() {
        assert_eq!(normalised_to_pwm(0.5), 600);
        assert_eq!(normalised_to_pwm(-0.25), -300);
        assert_eq!(normalised_to_pwm(2.0), 1200);
        assert_eq!(normalised_to_pwm(-7.0), -1200);
        assert_eq!(normalised_to_pwm(f64::NAN), 0);
        assert_eq!(normalised_to_pwm(f64::INFINITY), 1200);
        assert_eq!(pwm_to_normalised(600), 0.5);
        for p in -1200..=1200 {
            assert_eq!(normalised_to_pwm(pwm_to_normalised(p)), p);
        }
    }
}
