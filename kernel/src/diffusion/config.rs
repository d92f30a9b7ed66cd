//! Sampler settings.

/// Defaults of the DIPS code (`spec/algorithms.md` §4.2, §6).
pub const DEFAULT_GUIDANCE_WEIGHT: f32 = 1.2;
/// Noise scale of the low-temperature ancestral sampling in the DIPS code.
pub const DEFAULT_NOISE_FACTOR: f32 = 0.5;
/// Bound of the denoised estimate `x̂₀` in normalised units (z-scores): `x̂₀` is clipped to
/// `[−10, 10]` before each update. The DIPS code does not clip; Diffuser does
/// (`clip_denoised`). Without it, an imperfect `ε̂` at the noisiest steps, where `√ᾱ_t` is
/// about 2e-4, is amplified without bound and the samples diverge (`docs/training.md`). The
/// training data lie within ±7.3 z in 99.9 % of entries, so the bound leaves real
/// trajectories alone.
pub const DEFAULT_DENOISED_CLIP: f32 = 10.0;

/// How the reverse process is run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SamplingMethod {
    /// Ancestral DDPM over every training step; the posterior noise σ_t is multiplied by
    /// `noise_factor` (1 is the textbook sampler, 0.5 the DIPS code's).
    Ddpm {
        /// Multiplier of the posterior standard deviation.
        noise_factor: f32,
    },
    /// Ancestral DDPM over `steps` evenly spaced training steps (`1 ≤ steps ≤
    /// diffusion_steps`, the same steps as [`SamplingMethod::Ddim`]): each step draws from the
    /// posterior `q(x_t' | x_t, x̂0)` of the jump `t → t'`, its standard deviation scaled by
    /// `noise_factor` as in [`SamplingMethod::Ddpm`]. With `steps` = every training step it is
    /// that sampler up to rounding (the jump's β is `1 − ᾱ_t/ᾱ_t'` instead of the schedule's).
    DdpmStrided {
        /// Number of denoising steps.
        steps: u16,
        /// Multiplier of the posterior standard deviation.
        noise_factor: f32,
    },
    /// DDIM over `steps` evenly spaced training steps (`1 ≤ steps ≤ diffusion_steps`);
    /// `eta` 0 is deterministic, 1 matches DDPM's variance.
    Ddim {
        /// Number of denoising steps.
        steps: u16,
        /// Stochasticity η.
        eta: f32,
    },
}

/// Settings of one sampling call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SamplerConfig {
    /// DDPM or DDIM.
    pub method: SamplingMethod,
    /// Classifier-free guidance weight `w` in `ε = ε_u + w (ε_c − ε_u)` (1: conditioned only,
    /// 0: unconditioned only).
    pub guidance_weight: f32,
    /// `x̂₀` is clipped to `[−clip_denoised, clip_denoised]` (normalised units) at every step,
    /// and DDIM's `ε̂` is re-derived from the clipped `x̂₀`; `f32::INFINITY` turns clipping
    /// off (the DIPS code's sampler). Not carried on the wire: firmware uses the default.
    pub clip_denoised: f32,
}

impl Default for SamplerConfig {
    /// DDPM with noise factor 0.5 and guidance weight 1.2, as the DIPS code samples.
    fn default() -> Self {
        Self {
            method: SamplingMethod::Ddpm {
                noise_factor: DEFAULT_NOISE_FACTOR,
            },
            guidance_weight: DEFAULT_GUIDANCE_WEIGHT,
            clip_denoised: DEFAULT_DENOISED_CLIP,
        }
    }
}

impl SamplerConfig {
    /// DDIM with `steps` steps, η = 0, and the default guidance weight.
    pub fn ddim(steps: u16) -> Self {
        Self {
            method: SamplingMethod::Ddim { steps, eta: 0.0 },
            ..Self::default()
        }
    }
}

/// A sampler name that is not one of `ddpm`, `ddpm:STEPS`, `ddim:STEPS` or `ddim:STEPS:ETA`
/// (`1 ≤ STEPS ≤ 65535`, `0 ≤ ETA ≤ 1`): [`SamplerConfig`]'s `FromStr`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SamplerNameError;

impl core::fmt::Display for SamplerNameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(
            "expected `ddpm`, `ddpm:STEPS` or `ddim:STEPS[:ETA]` (1 ≤ STEPS ≤ 65535, 0 ≤ ETA ≤ 1)",
        )
    }
}

impl core::error::Error for SamplerNameError {}

impl core::str::FromStr for SamplerConfig {
    type Err = SamplerNameError;

    /// The sampler a name stands for, with the default guidance weight, noise factor and
    /// clip: `ddpm` (every training step, [`SamplingMethod::Ddpm`]), `ddpm:STEPS`
    /// ([`SamplingMethod::DdpmStrided`]), `ddim:STEPS` (η = 0) or `ddim:STEPS:ETA`.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        if name == "ddpm" {
            return Ok(Self::default());
        }
        let steps = |s: &str| {
            s.parse::<u16>()
                .ok()
                .filter(|&n| n > 0)
                .ok_or(SamplerNameError)
        };
        if let Some(s) = name.strip_prefix("ddpm:") {
            return Ok(Self {
                method: SamplingMethod::DdpmStrided {
                    steps: steps(s)?,
                    noise_factor: DEFAULT_NOISE_FACTOR,
                },
                ..Self::default()
            });
        }
        let rest = name.strip_prefix("ddim:").ok_or(SamplerNameError)?;
        let (s, eta) = match rest.split_once(':') {
            Some((s, e)) => (
                s,
                e.parse::<f32>()
                    .ok()
                    .filter(|v| (0.0..=1.0).contains(v))
                    .ok_or(SamplerNameError)?,
            ),
            None => (rest, 0.0),
        };
        Ok(Self {
            method: SamplingMethod::Ddim {
                steps: steps(s)?,
                eta,
            },
            ..Self::default()
        })
    }
}

impl core::fmt::Display for SamplingMethod {
    /// The method's name as [`SamplerConfig`]'s `FromStr` reads it (`ddpm`, `ddpm:16`,
    /// `ddim:8`, `ddim:8:0.5`); the DDPM noise factor is not part of it.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Ddpm { .. } => f.write_str("ddpm"),
            Self::DdpmStrided { steps, .. } => write!(f, "ddpm:{steps}"),
            Self::Ddim { steps, eta: 0.0 } => write!(f, "ddim:{steps}"),
            Self::Ddim { steps, eta } => write!(f, "ddim:{steps}:{eta}"),
        }
    }
}

#[cfg(test)]
mod name_tests {
    use super::*;
    use core::str::FromStr;

    #[test]
    fn names_round_trip() {
        for name in ["ddpm", "ddpm:16", "ddim:8", "ddim:32:0.5", "ddim:1:1"] {
            let c = SamplerConfig::from_str(name).unwrap();
            let mut buf = heapless::String::<32>::new();
            core::fmt::write(&mut buf, format_args!("{}", c.method)).unwrap();
            assert_eq!(buf.as_str(), name);
        }
        assert_eq!(
            SamplerConfig::from_str("ddpm").unwrap(),
            SamplerConfig::default()
        );
        assert_eq!(
            SamplerConfig::from_str("ddim:8").unwrap(),
            SamplerConfig::ddim(8)
        );
    }

    #[test]
    fn bad_names_are_errors() {
        for name in [
            "",
            "ddpm:0",
            "ddim:",
            "ddim:8:1.5",
            "ddim:x",
            "ddpm:70000",
            "DDPM",
            "ddim:8:",
        ] {
            assert_eq!(
                SamplerConfig::from_str(name),
                Err(SamplerNameError),
                "{name}"
            );
        }
    }
}
