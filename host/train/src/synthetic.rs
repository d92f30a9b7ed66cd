//! A tiny synthetic dataset in the real format, for tests and measurements: smooth, mode-
//! dependent trajectories (joints move by their actions, the object's angle turns in contact
//! modes, forces only on contact fingers) plus particle noise. It exercises every column but
//! is not physics.

use std::collections::BTreeMap;
use std::path::Path;

use dips_dataset::{DatasetError, DemoRecord, write_demo};
use dips_kernel::mode::{ModeId, Task};

use crate::data::stream;

/// One synthetic demo: `modes` modes, `steps` online steps per mode, `particles` per step.
pub fn demo(task: Task, seed: u64, modes: usize, steps: usize, particles: usize) -> DemoRecord {
    let mut rng = stream(seed, 0xda7a, 0);
    let dims = task.dims();
    let (t_rows, d, f) = (dims.horizon, dims.dim(), dims.fingers);
    let nq = 4 * f;
    let obj = nq; // two plain columns, then cos/sin
    let act = dims.state_dim;
    let forces = dims.action_dim - nq;
    let mut rec = DemoRecord {
        task,
        seed,
        modes: Vec::new(),
        trajectories: Vec::new(),
        contexts: Vec::new(),
        mode_index: Vec::new(),
        step: Vec::new(),
        particle: Vec::new(),
        metadata: BTreeMap::from([("generator".to_string(), "dips-train synthetic".to_string())]),
    };
    let mut q: Vec<f32> = (0..nq).map(|_| rng.uniform_f32() * 0.6 - 0.3).collect();
    let mut angle = rng.uniform_f32() * 6.0 - 3.0;
    let mut ab = [rng.uniform_f32() * 0.02, rng.uniform_f32() * 0.02];
    for m in 0..modes {
        let id = ModeId(rng.below(task.mode_count() as u32) as u8);
        let Some(mode) = task.contact_mode(id) else {
            continue;
        };
        rec.modes
            .push(task.mode_name(id).unwrap_or_default().to_string());
        let mut signs = vec![0f32; f];
        mode.write_signs(&mut signs);
        let turning = mode.contact_count() > 0;
        // Per-mode joint velocity: contact fingers push one way, regrasping ones swing back.
        let vel: Vec<f32> = (0..nq)
            .map(|j| 0.01 * signs[j / 4] * (1.0 + (j % 4) as f32 * 0.3))
            .collect();
        for step in 0..steps {
            for p in 0..particles {
                let mut traj = vec![0f32; t_rows * d];
                let mut qq = q.clone();
                let (mut a, mut ab_) = (angle, ab);
                for r in 0..t_rows {
                    let row = &mut traj[r * d..(r + 1) * d];
                    row[..nq].copy_from_slice(&qq);
                    row[obj] = ab_[0];
                    row[obj + 1] = ab_[1];
                    row[obj + 2] = a.cos();
                    row[obj + 3] = a.sin();
                    if r + 1 < t_rows {
                        for j in 0..nq {
                            let dq = vel[j] + 0.002 * rng.normal_f32() * (p as f32 + 1.0) / 4.0;
                            row[act + j] = dq;
                            qq[j] += dq;
                        }
                        for k in 0..forces {
                            let finger = k / 3;
                            let on = finger >= f || signs[finger] > 0.0;
                            row[act + nq + k] = if on {
                                [1.5, -0.5, 0.8][k % 3] + 0.1 * rng.normal_f32()
                            } else {
                                0.0
                            };
                        }
                        if turning {
                            a -= 0.04;
                            ab_[1] -= 0.001;
                        }
                        ab_[0] += 0.0005 * rng.normal_f32();
                    }
                }
                rec.trajectories.extend(traj);
                rec.contexts.extend_from_slice(&signs);
                rec.mode_index.push(m as i64);
                rec.step.push(step as i64);
                rec.particle.push(p as i64);
            }
            // The executed step: the first action of the mean plan.
            for j in 0..nq {
                q[j] += vel[j];
            }
            if turning {
                angle -= 0.04;
                ab[1] -= 0.001;
            }
        }
    }
    rec
}

/// Write `demos` synthetic demos (seeds `first_seed..`) to `dir/demos/`.
pub fn write_dataset(
    dir: &Path,
    task: Task,
    demos: usize,
    first_seed: u64,
    modes: usize,
    steps: usize,
    particles: usize,
) -> Result<(), DatasetError> {
    let dd = dir.join("demos");
    std::fs::create_dir_all(&dd).map_err(|source| DatasetError::Io {
        path: dd.clone(),
        source,
    })?;
    for i in 0..demos as u64 {
        let seed = first_seed + i;
        let rec = demo(task, seed, modes, steps, particles);
        write_demo(&dd.join(format!("demo_{seed:06}.safetensors")), &rec)?;
    }
    Ok(())
}
