//! Scripted fingertip motions turned into actions (joint deltas in `docs/contracts.md` §2 order):
//! the moves used by the physical checks, the benchmark and the CLI examples.

use nalgebra::{Point3, Vector3};

use super::World;
use crate::kinematics::Finger;
use crate::scenes::screwdriver;

/// Joint deltas (task order) that move each listed fingertip centre by `dp` (world frame) in a
/// straight line: iterated damped least squares on a copy of the joints, clamped to limits.
/// Fingers not listed keep zero deltas.
pub fn tip_moves_to_action(world: &World, moves: &[(Finger, Vector3<f64>)]) -> Vec<f64> {
    let hand = world.hand_model();
    let base = world.hand_base();
    let q = world.joints();
    let mut dq = vec![0.0; world.scene().action_dim()];
    for (k, f) in world.scene().task_fingers().iter().enumerate() {
        if let Some((_, dp)) = moves.iter().find(|(g, _)| g == f) {
            let q0 = q[f.index()];
            let target = hand.tip_center(&base, *f, &q0) + dp;
            let q1 = hand.solve_tip_ik(&base, *f, &q0, &target, 30);
            for j in 0..4 {
                dq[4 * k + j] = q1[j] - q0[j];
            }
        }
    }
    dq
}

/// Screwdriver pinch-and-turn: thumb and middle move `squeeze` toward the shaft axis and
/// `turn` along the clockwise (negative-yaw) tangent; the index presses the cap down by
/// `squeeze`.
pub fn pinch_turn_action(world: &World, squeeze: f64, turn: f64) -> Vec<f64> {
    let tips = world.tip_centers();
    let pivot: Point3<f64> = screwdriver::pivot();
    let mut moves = vec![(Finger::Index, Vector3::new(0.0, 0.0, -squeeze))];
    for f in [Finger::Middle, Finger::Thumb] {
        let p = tips[f.index()];
        let radial = Vector3::new(p.x - pivot.x, p.y - pivot.y, 0.0).normalize();
        let tangent = (-Vector3::z()).cross(&radial);
        moves.push((f, -radial * squeeze + tangent * turn));
    }
    tip_moves_to_action(world, &moves)
}

/// Card push: index and middle tips move `dy` along world y while pressing `press` down.
pub fn card_push_action(world: &World, dy: f64, press: f64) -> Vec<f64> {
    let dp = Vector3::new(0.0, dy, -press);
    tip_moves_to_action(world, &[(Finger::Index, dp), (Finger::Middle, dp)])
}

/// Each task fingertip's closest contact with the object: (finger, signed distance, outward
/// normal of the object at the closest point), in task order.
pub fn tip_contacts(world: &World) -> Vec<(Finger, f64, Vector3<f64>)> {
    let tips = world.tip_centers();
    let r = world.hand_model().tip_radius;
    let pose = world.object().pose();
    world
        .scene()
        .task_fingers()
        .iter()
        .filter_map(|f| {
            world
                .object_body()
                .sphere_contact(&pose, &tips[f.index()], r, f64::INFINITY)
                .map(|k| (*f, k.phi, k.normal))
        })
        .collect()
}

/// The action that moves every task fingertip along its contact normal until it is `gap`
/// clear of the object (the start of the graze probes in `docs/world.md`).
pub fn back_off_action(world: &World, gap: f64) -> Vec<f64> {
    let moves: Vec<(Finger, Vector3<f64>)> = tip_contacts(world)
        .into_iter()
        .map(|(f, phi, n)| (f, n * (gap - phi)))
        .collect();
    tip_moves_to_action(world, &moves)
}
