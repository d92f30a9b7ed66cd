//! Property: for any model dimensions, batch limits and scratch sizes, the sampler's output is
//! bit-identical to one big batch, and inpainting holds the start states exactly.

use dips_kernel::diffusion::*;
use dips_kernel::engine::{DenoiserEngine, ModelDims, Normalization};
use dips_kernel::rng::KernelRng;
use proptest::prelude::*;

/// A per-sample deterministic double: ε depends on the sample's own x, t, context and mask.
#[derive(Debug)]
struct Linear {
    dims: ModelDims,
    mean: Vec<f32>,
    std: Vec<f32>,
    max_batch: usize,
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

fn run(engine: &mut Linear, config: &SamplerConfig, n: usize, chunk: usize, seed: u64) -> Vec<f32> {
    let dims = engine.dims;
    let context: Vec<f32> = (0..n * dims.fingers)
        .map(|i| if i % 3 == 0 { 1.0 } else { -1.0 })
        .collect();
    let starts: Vec<f32> = (0..n * dims.state_dim)
        .map(|i| i as f32 * 0.3 - 2.0)
        .collect();
    let layout = ScratchLayout::new(dims, chunk);
    let mut buf = vec![0.0f32; layout.total()];
    let mut scratch = SamplerScratch::split(&mut buf, &layout).unwrap();
    let mut out = vec![0.0f32; n * dims.floats_per_trajectory()];
    let mut rng = KernelRng::seed_from_u64(seed);
    let request = SampleRequest {
        context: &context,
        start_states: Some(&starts),
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
}
