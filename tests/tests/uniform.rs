//! The uniform plug-in joins the battery: `PiecewiseConstant1D`,
//! `PiecewiseConstant2D` and the uniformly tabulated measured-BRDF sampler
//! on the built-in `lambert`, `nickel` and `near-mirror`, at the isotropic
//! resolution (32 θ_o slices of 256 θ_h × 32 φ_h) and at the paper's
//! (32 × 16 slices; only the slices the battery's wo touch are built), plus
//! the isotropic sampler with a 10% cosine lobe mixed in. The samplers use
//! 200 000 draws per (BRDF, wo) instead of the default 10^6 to keep the
//! file within a couple of minutes.

use acdf_conformance::{
    distribution_1d_battery, distribution_2d_battery, sampler_battery, SamplerConfig,
};
use acdf_core::Brdf;
use acdf_tabulated::Resolution;
use acdf_uniform::{
    PiecewiseConstant1D, PiecewiseConstant2D, PiecewiseConstantBuilder, UniformBrdfSampler,
};
use std::sync::Arc;

fn builtins() -> Vec<Arc<dyn Brdf>> {
    ["lambert", "nickel", "near-mirror"]
        .iter()
        .map(|n| acdf_materials::builtin(n).expect("built-in material"))
        .collect()
}

fn sampler(brdf: Arc<dyn Brdf>, resolution: Resolution) -> acdf_core::Result<UniformBrdfSampler> {
    UniformBrdfSampler::new(brdf, resolution, PiecewiseConstantBuilder)
}

fn config() -> SamplerConfig {
    SamplerConfig {
        samples: 200_000,
        extreme_samples: 5_000,
        weight_samples: 4_096,
        ..Default::default()
    }
}

distribution_1d_battery!(
    uniform_piecewise_constant_1d,
    build = |t: &[f32]| PiecewiseConstant1D::new(t)
);

distribution_2d_battery!(
    uniform_piecewise_constant_2d,
    build = |t: &[f32], nx, ny| PiecewiseConstant2D::new(t, nx, ny)
);

sampler_battery!(
    uniform_isotropic,
    build = |b| sampler(b, Resolution::ISOTROPIC),
    brdfs = builtins(),
    config = config()
);

// The glossy stand-ins, for the support check above all: at grazing wo
// their lobes cross the horizon inside cells.
sampler_battery!(
    uniform_isotropic_glossy,
    build = |b| sampler(b, Resolution::ISOTROPIC),
    brdfs = ["gray-plastic", "blue-metallic-paint"]
        .map(|n| acdf_materials::builtin(n).expect("built-in material")),
    config = config()
);

sampler_battery!(
    uniform_paper,
    build = |b| sampler(b, Resolution::PAPER),
    brdfs = builtins(),
    config = config()
);

sampler_battery!(
    uniform_isotropic_cosine_mix,
    build = |b| sampler(b, Resolution::ISOTROPIC)?.with_cosine_mix(0.1),
    brdfs = builtins(),
    config = config()
);
