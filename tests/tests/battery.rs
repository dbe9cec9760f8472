//! The battery applied to the analytic samplers and reference distributions
//! of `acdf_conformance::{samplers, reference}`: correct implementations of
//! both table semantics, a narrow anisotropic lobe, an asymmetric lobe and a
//! table-shaped density on the sphere all pass.

use acdf_conformance::reference::{
    Bilinear2D, PiecewiseConstant1D, PiecewiseConstant2D, PiecewiseLinear1D,
};
use acdf_conformance::samplers::{GgxSampler, TabulatedSampler, TiltedLobeSampler};
use acdf_conformance::{
    brdfs, distribution_1d_battery, distribution_2d_battery, sampler_battery, DistributionConfig,
    SamplerConfig,
};
use acdf_core::Brdf;
use std::sync::Arc;

distribution_1d_battery!(
    reference_piecewise_constant_1d,
    build = |t: &[f32]| PiecewiseConstant1D::new(t)
);
distribution_2d_battery!(
    reference_piecewise_constant_2d,
    build = |t: &[f32], nx, ny| PiecewiseConstant2D::new(t, nx, ny)
);
distribution_1d_battery!(
    reference_piecewise_linear_1d,
    build = |t: &[f32]| PiecewiseLinear1D::new(t),
    config = DistributionConfig::piecewise_linear()
);
distribution_2d_battery!(
    reference_bilinear_2d,
    build = |t: &[f32], nx, ny| Bilinear2D::new(t, nx, ny),
    config = DistributionConfig::piecewise_linear()
);

fn ggx() -> Vec<Arc<dyn Brdf>> {
    vec![Arc::new(brdfs::GgxBrdf {
        alpha_x: 0.15,
        alpha_y: 0.4,
        color: acdf_core::Vec3::ONE,
    })]
}

sampler_battery!(
    ggx_half_vector,
    build = |_| Ok(GgxSampler {
        alpha_x: 0.15,
        alpha_y: 0.4
    }),
    brdfs = ggx()
);
/// The reference samplers below draw a density unrelated to the BRDF they
/// are paired with (only for the weight check), so the support check does
/// not apply to them.
fn unrelated_to_the_brdf() -> SamplerConfig {
    SamplerConfig {
        max_missed_share: None,
        ..SamplerConfig::default()
    }
}

sampler_battery!(
    tilted_lobe,
    build = |_| Ok(TiltedLobeSampler { exponent: 20.0 }),
    brdfs = ggx(),
    config = unrelated_to_the_brdf()
);
sampler_battery!(
    tabulated_sphere,
    build = |_| {
        let table: Vec<f32> = (0..12 * 10).map(|k| ((k * 37) % 11) as f32).collect();
        Ok(TabulatedSampler {
            distribution: PiecewiseConstant2D::new(&table, 12, 10)?,
        })
    },
    brdfs = [Arc::new(brdfs::Lambertian {
        albedo: acdf_core::Vec3::ONE
    }) as Arc<dyn Brdf>],
    config = unrelated_to_the_brdf()
);
