//! The velocity estimate: the vendor's low-pass on position, a difference, the same low-pass
//! on velocity. The vendor's coefficients (0.6, 0.198, 0.198) sum to 0.996, which leaves a
//! 1 % steady-state error in the filtered position; ours (0.6, 0.2, 0.2) have unit gain.

use dips_world::kinematics::HandJoints;

const KEEP: f64 = 0.6;
const MIX: f64 = 0.2;

/// Filtered position and velocity of the sixteen joints.
#[derive(Debug, Clone, PartialEq)]
pub struct JointFilter {
    raw: HandJoints,
    position: HandJoints,
    raw_velocity: HandJoints,
    velocity: HandJoints,
}

impl JointFilter {
    /// A filter at rest at `q`.
    pub fn new(q: HandJoints) -> JointFilter {
        JointFilter {
            raw: q,
            position: q,
            raw_velocity: [[0.0; 4]; 4],
            velocity: [[0.0; 4]; 4],
        }
    }

    /// Take a new reading `dt` seconds after the last.
    pub fn update(&mut self, q: &HandJoints, dt: f64) {
        let dt = dt.max(1e-4);
        let joints = (0..4).flat_map(|f| (0..4).map(move |j| (f, j)));
        for (f, j) in joints {
            let prev = self.position[f][j];
            let p = KEEP * prev + MIX * self.raw[f][j] + MIX * q[f][j];
            let v = (p - prev) / dt;
            self.velocity[f][j] =
                KEEP * self.velocity[f][j] + MIX * self.raw_velocity[f][j] + MIX * v;
            self.raw_velocity[f][j] = v;
            self.position[f][j] = p;
            self.raw[f][j] = q[f][j];
        }
    }

    /// Filtered positions.
    pub fn position(&self) -> &HandJoints {
        &self.position
    }

    /// Filtered velocities.
    pub fn velocity(&self) -> &HandJoints {
        &self.velocity
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_filter_has_unit_gain_and_tracks_a_ramp_velocity() {
        let mut f = JointFilter::new([[0.0; 4]; 4]);
        for _ in 0..200 {
            f.update(&[[1.0; 4]; 4], 0.003);
        }
        assert!((f.position()[2][1] - 1.0).abs() < 1e-9);
        assert!(f.velocity()[2][1].abs() < 1e-6);
        let mut f = JointFilter::new([[0.0; 4]; 4]);
        for k in 1..=300 {
            let q = 0.5 * k as f64 * 0.003;
            f.update(&[[q; 4]; 4], 0.003);
        }
        assert!(
            (f.velocity()[0][0] - 0.5).abs() < 1e-6,
            "{}",
            f.velocity()[0][0]
        );
    }
}
