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
    config = without_support_check()
);

// The support check on the materials whose every cell the uniform
// tables keep positive. On near-mirror (a lobe to the power 10⁴), cells
// far from the lobe hold values some 1e-17 of the peak's, and the
// piecewise-constant distribution, which stores its CDFs in f32 and takes
// a cell's mass as a difference of them, gives them density 0.
sampler_battery!(
    uniform_isotropic_support,
    build = |b| sampler(b, Resolution::ISOTROPIC),
    brdfs = ["lambert", "nickel", "gray-plastic", "blue-metallic-paint"]
        .map(|n| acdf_materials::builtin(n).expect("built-in material")),
    config = config()
);

sampler_battery!(
    uniform_paper,
    build = |b| sampler(b, Resolution::PAPER),
    brdfs = builtins(),
    config = without_support_check()
);

sampler_battery!(
    uniform_isotropic_cosine_mix,
    build = |b| sampler(b, Resolution::ISOTROPIC)?.with_cosine_mix(0.1),
    brdfs = builtins(),
    config = config()
);

/// [`config`] without the support check, for the batteries that include
/// near-mirror (see `uniform_isotropic_support`).
fn without_support_check() -> SamplerConfig {
    SamplerConfig {
        max_missed_share: None,
        ..config()
    }
}
