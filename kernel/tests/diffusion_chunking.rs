//! Property: for any model dimensions, batch limits and scratch sizes, the sampler's output is
//! bit-identical to one big batch, and inpainting holds the start states exactly; a model in the
//! segment-start object frame samples what the same model in the world's frame samples from
//! starts with the object at the origin, moved to the start.

use dips_kernel::diffusion::*;
use dips_kernel::engine::{DenoiserEngine, ModelDims, Normalization, ObjectFrame};
use dips_kernel::rng::KernelRng;
use proptest::prelude::*;

/// A per-sample deterministic double: ε depends on the sample's own x, t, context and mask.
#[derive(Debug)]
struct Linear {
    dims: ModelDims,
    mean: Vec<f32>,
    std: Vec<f32>,
    max_batch: usize,
    frame: ObjectFrame,
}

impl DenoiserEngine for Linear {
    type Error = ();

    fn dims(&self) -> ModelDims {
        self.dims
    }

    fn normalization(&self) -> Normalization<'_> {
        Normalization {
            mean: &self.mean,
            std: &self.std,
        }
    }

    fn max_batch(&self) -> usize {
        self.max_batch
    }

    fn object_frame(&self) -> ObjectFrame {
        self.frame
    }

    fn predict_eps(
        &mut self,
        batch: usize,
        x: &[f32],
        t: &[f32],
        context: &[f32],
        cond_mask: &[f32],
        eps: &mut [f32],
    ) -> Result<(), ()> {
        if batch > self.max_batch {
            return Err(());
        }
        let td = self.dims.floats_per_trajectory();
        let f = self.dims.fingers;
        for b in 0..batch {
            let ctx: f32 = context[b * f..(b + 1) * f].iter().sum();
            let shift = 0.05 * cond_mask[b] * ctx + 0.001 * t[b];
            for i in 0..td {
                eps[b * td + i] = 0.4 * x[b * td + i] + shift + 0.01 * i as f32;
            }
        }
        Ok(())
    }
}

fn starts_of(dims: ModelDims, n: usize) -> Vec<f32> {
    (0..n * dims.state_dim)
        .map(|i| i as f32 * 0.3 - 2.0)
        .collect()
}

fn run(engine: &mut Linear, config: &SamplerConfig, n: usize, chunk: usize, seed: u64) -> Vec<f32> {
    let starts = starts_of(engine.dims, n);
    run_from(engine, config, &starts, n, chunk, seed)
}

fn run_from(
    engine: &mut Linear,
    config: &SamplerConfig,
    starts: &[f32],
    n: usize,
    chunk: usize,
    seed: u64,
) -> Vec<f32> {
    let dims = engine.dims;
    let context: Vec<f32> = (0..n * dims.fingers)
        .map(|i| if i % 3 == 0 { 1.0 } else { -1.0 })
        .collect();
    let layout = ScratchLayout::new(dims, chunk);
    let mut buf = vec![0.0f32; layout.total()];
    let mut scratch = SamplerScratch::split(&mut buf, &layout).unwrap();
    let mut out = vec![0.0f32; n * dims.floats_per_trajectory()];
    let mut rng = KernelRng::seed_from_u64(seed);
    let request = SampleRequest {
        context: &context,
        start_states: Some(starts),
    };
    sample(engine, config, &request, &mut rng, &mut scratch, &mut out).unwrap();
    for (traj, s0) in out
        .chunks(dims.floats_per_trajectory())
        .zip(starts.chunks(dims.state_dim.max(1)))
    {
        assert_eq!(&traj[..dims.state_dim], &s0[..dims.state_dim]);
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 48,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn chunking_never_changes_the_samples(
        horizon in 1usize..5,
        state_dim in 0usize..4,
        action_dim in 1usize..4,
        fingers in 0usize..4,
        steps in 1usize..12,
        n in 1usize..9,
        max_batch in 2usize..12,
        chunk in 1usize..10,
        ddim in any::<bool>(),
        eta in 0.0f32..1.0,
        w in 0.0f32..2.0,
        seed in any::<u64>(),
    ) {
        let dims = ModelDims { horizon, state_dim, action_dim, fingers, diffusion_steps: steps };
        let d = dims.dim();
        let mk = |max_batch| Linear {
            dims,
            mean: (0..d).map(|j| j as f32 * 0.5 - 1.0).collect(),
            std: (0..d).map(|j| 0.5 + j as f32 * 0.25).collect(),
            max_batch,
            frame: ObjectFrame::World,
        };
        let config = SamplerConfig {
            method: if ddim {
                SamplingMethod::Ddim { steps: (steps as u16).div_ceil(2), eta }
            } else {
                SamplingMethod::Ddpm { noise_factor: eta }
            },
            guidance_weight: w,
            ..SamplerConfig::default()
        };
        let whole = run(&mut mk(usize::MAX), &config, n, n, seed);
        let split = run(&mut mk(max_batch), &config, n, chunk, seed);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        prop_assert_eq!(bits(&whole), bits(&split));
        prop_assert!(whole.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn a_segment_start_model_samples_the_world_model_moved_to_the_start(
        horizon in 1usize..5,
        fingers in 1usize..4,
        action_dim in 1usize..4,
        steps in 1usize..12,
        n in 1usize..6,
        seed in any::<u64>(),
    ) {
        let state_dim = 4 * fingers + 4;
        let dims = ModelDims { horizon, state_dim, action_dim, fingers, diffusion_steps: steps };
        let d = dims.dim();
        let mk = |frame| Linear {
            dims,
            mean: (0..d).map(|j| j as f32 * 0.5 - 1.0).collect(),
            std: (0..d).map(|j| 0.5 + j as f32 * 0.25).collect(),
            max_batch: usize::MAX,
            frame,
        };
        let config = SamplerConfig::default();
        let starts = starts_of(dims, n);
        let cols = ObjectFrame::SegmentStart.start_columns(fingers, state_dim);
        prop_assert_eq!(cols.clone(), 4 * fingers..4 * fingers + 2);
        let mut at_origin = starts.clone();
        for s0 in at_origin.chunks_mut(state_dim) {
            s0[cols.clone()].fill(0.0);
        }
        let relative = run_from(&mut mk(ObjectFrame::SegmentStart), &config, &starts, n, n, seed);
        let world = run_from(&mut mk(ObjectFrame::World), &config, &at_origin, n, n, seed);
        let td = dims.floats_per_trajectory();
        for ((r, w), s0) in relative.chunks(td).zip(world.chunks(td)).zip(starts.chunks(state_dim)) {
            prop_assert_eq!(&r[..state_dim], s0, "row 0 is the start, in the world's frame");
            for (row, (rr, wr)) in r.chunks(d).zip(w.chunks(d)).enumerate().skip(1) {
                for c in 0..d {
                    let want = if cols.contains(&c) { wr[c] + s0[c] } else { wr[c] };
                    prop_assert_eq!(rr[c].to_bits(), want.to_bits(), "row {} column {}", row, c);
                }
            }
        }
    }
}
