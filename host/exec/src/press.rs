//! How hard CSVTO's contact fingers press while a mode is executed.
//!
//! Every contact finger of a CSVTO problem presses with at least a minimum normal force (the
//! `f_min + n·f ≤ 0` rows). Ours is [`MIN_NORMAL_FORCE`], 0.05 N, enough to keep a finger's
//! force off the friction pyramid's apex; on our world's rigid contacts any press moves the
//! card. On a hand with compliant contacts (MuJoCo, `docs/mujoco.md`) a 10 g card is dragged
//! by the friction of the press, and a press of 0.05 N (half the card's weight) lets the tips
//! slide over a card that does not move. [`Press::Firm`] raises the minimum for execution
//! only: the planner, the models and the data the models were trained on are unchanged.

use dips_kernel::name::UnknownValue;

use crate::problems::allegro::MIN_NORMAL_FORCE;

/// A contact finger's minimum normal force under [`Press::Firm`] (N): three times the card's
/// weight. One probe on the card's MuJoCo tuning seeds 500–529, not a sweep
/// (`docs/mujoco.md`, "A firmer press").
pub const FIRM_NORMAL_FORCE: f64 = 0.3;

/// The minimum normal force of the contact fingers of executed modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Press {
    /// [`MIN_NORMAL_FORCE`]: the problems the data were generated with, and every run before
    /// this setting existed.
    #[default]
    Light,
    /// [`FIRM_NORMAL_FORCE`].
    Firm,
}

impl Press {
    /// Both, in `--press` order.
    pub const ALL: [Self; 2] = [Self::Light, Self::Firm];
    /// Both names, in [`Press::ALL`] order.
    pub const NAMES: [&'static str; 2] = [Self::Light.name(), Self::Firm.name()];

    /// The name used by `--press`, `eval.json`, protocols and `result.json`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Light => "light",
            Self::Firm => "firm",
        }
    }

    /// The minimum normal force (N).
    pub const fn newtons(self) -> f64 {
        match self {
            Self::Light => MIN_NORMAL_FORCE,
            Self::Firm => FIRM_NORMAL_FORCE,
        }
    }

    /// Whether this is the default (left out of files).
    pub fn is_light(&self) -> bool {
        *self == Self::Light
    }
}

impl std::str::FromStr for Press {
    type Err = UnknownValue;

    /// A press by its name ([`Press::name`]); the error names the value and both.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        UnknownValue::find("press", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl std::fmt::Display for Press {
    /// The press's name ([`Press::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::{AllegroProblem, Mode, ProblemSpec};
    use dips_csvto::{Problem, StepConstraints};
    use dips_world::kinematics::HandModel;
    use dips_world::scenes::SceneKind;

    #[test]
    fn names_round_trip_and_unknown_ones_are_named() {
        for p in Press::ALL {
            assert_eq!(p.name().parse::<Press>().unwrap(), p);
        }
        let e = "hard".parse::<Press>().unwrap_err().to_string();
        assert!(
            e.contains("hard") && e.contains("light") && e.contains("firm"),
            "{e}"
        );
        assert_eq!(Press::default().newtons(), MIN_NORMAL_FORCE);
    }

    /// The firmer press moves every contact finger's minimum-force row by the difference and
    /// nothing else.
    #[test]
    fn the_firm_press_raises_only_the_minimum_force_rows() {
        let model = HandModel::allegro_v4();
        let scene = SceneKind::Card;
        let q = scene.default_joints();
        let mut start: Vec<f64> = scene
            .task_fingers()
            .iter()
            .flat_map(|f| q[f.index()])
            .collect();
        start.extend_from_slice(&[0.0, 0.0, 0.0]);
        let spec = ProblemSpec {
            task: scene,
            mode: Mode::CardBoth,
            horizon: 4,
            goal: [0.0, -0.06, 0.0],
            start,
        };
        let light = AllegroProblem::new(&model, &spec).unwrap();
        let firm = AllegroProblem::new(&model, &spec)
            .unwrap()
            .with_min_normal_force(Press::Firm.newtons());
        assert_eq!(firm.min_normal_force(), FIRM_NORMAL_FORCE);
        let x = crate::problems::init::default_particles(
            &light,
            Mode::CardBoth,
            1,
            &mut dips_kernel::rng::KernelRng::seed_from_u64(3),
        )
        .remove(0);
        let n = light.row_dim();
        let mut changed = Vec::new();
        for t in 0..light.horizon() {
            let prev = if t == 0 {
                light.start_state().to_vec()
            } else {
                x[(t - 1) * n..(t - 1) * n + light.state_dim()].to_vec()
            };
            let row = &x[t * n..(t + 1) * n];
            let (mut a, mut b) = (StepConstraints::default(), StepConstraints::default());
            let width = light.state_dim() + n;
            a.reset(light.n_eq(t), light.n_ineq(t), width);
            b.reset(firm.n_eq(t), firm.n_ineq(t), width);
            light.step_constraints(t, &prev, row, &mut a);
            firm.step_constraints(t, &prev, row, &mut b);
            assert_eq!(a.eq, b.eq);
            assert_eq!(a.jac_ineq, b.jac_ineq);
            changed.extend(
                a.ineq
                    .iter()
                    .zip(&b.ineq)
                    .filter(|(u, v)| u != v)
                    .map(|(u, v)| v - u),
            );
        }
        // Two contact fingers, one row each per step.
        assert_eq!(changed.len(), 2 * 4);
        for d in changed {
            assert!(
                (d - (FIRM_NORMAL_FORCE - MIN_NORMAL_FORCE)).abs() < 1e-12,
                "{d}"
            );
        }
    }
}
