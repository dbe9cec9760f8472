//! The adaptive plug-in joins the battery: `AdaptiveCdf1D`, `AdaptiveCdf2D`
//! and the adaptive measured-BRDF sampler, once per simplifier at its default
//! tolerance. The sampler runs on the built-in `nickel`, `lambert` and
//! `near-mirror` at the isotropic resolution (32 θ_o slices of 256 θ_h x 32
//! φ_h), with fewer draws, cells and outgoing directions than the default
//! battery to stay within about a minute.

use acdf_adaptive::AdaptiveBrdfSampler;
use acdf_adaptive_cdf::{simplifier_by_name, AdaptiveBuilder, AdaptiveCdf1D, AdaptiveCdf2D};
use acdf_conformance::{
    distribution_1d_battery, distribution_2d_battery, sampler_battery, DistributionConfig,
    SamplerConfig,
};
use acdf_core::Brdf;
use acdf_tabulated::{Resolution, TabulatedBrdfSampler};
use std::sync::Arc;

fn builtins() -> Vec<Arc<dyn Brdf>> {
    ["nickel", "lambert", "near-mirror"]
        .iter()
        .map(|n| acdf_materials::builtin(n).expect("built-in material"))
        .collect()
}

fn sampler(name: &str, brdf: Arc<dyn Brdf>) -> acdf_core::Result<AdaptiveBrdfSampler> {
    TabulatedBrdfSampler::new(
        brdf,
        Resolution::ISOTROPIC,
        AdaptiveBuilder::by_name(name, None)?,
    )
}

fn one_d(name: &str, t: &[f32]) -> acdf_core::Result<AdaptiveCdf1D> {
    let s = simplifier_by_name(name)?;
    AdaptiveCdf1D::from_values(t, &*s, s.default_tolerance())
}

fn two_d(name: &str, t: &[f32], nx: usize, ny: usize) -> acdf_core::Result<AdaptiveCdf2D> {
    let s = simplifier_by_name(name)?;
    AdaptiveCdf2D::from_values(t, nx, ny, &*s, s.default_tolerance())
}

fn distribution_config() -> DistributionConfig {
    DistributionConfig {
        samples: 100_000,
        ..Default::default()
    }
}

fn sampler_config() -> SamplerConfig {
    SamplerConfig {
        samples: 100_000,
        cos_theta_cells: 50,
        phi_cells: 100,
        wo_theta_degrees: vec![0.0, 45.0, 85.0],
        extreme_samples: 2_000,
        weight_samples: 2_048,
        ..Default::default()
    }
}

macro_rules! join {
    ($simplifier:literal, $d1:ident, $d2:ident) => {
        distribution_1d_battery!(
            $d1,
            build = |t: &[f32]| one_d($simplifier, t),
            config = distribution_config()
        );
        distribution_2d_battery!(
            $d2,
            build = |t: &[f32], nx, ny| two_d($simplifier, t, nx, ny),
            config = distribution_config()
        );
    };
    ($simplifier:literal, $d1:ident, $d2:ident, $s:ident) => {
        join!($simplifier, $d1, $d2);
        sampler_battery!(
            $s,
            build = |b| sampler($simplifier, b),
            brdfs = builtins(),
            config = sampler_config()
        );
    };
}

join!("dp", dp_1d, dp_2d, dp_sampler);
join!("vw", vw_1d, vw_2d, vw_sampler);
join!("rw", rw_1d, rw_2d, rw_sampler);
join!("optimal", optimal_1d, optimal_2d, optimal_sampler);
join!("chi2", chi2_1d, chi2_2d, chi2_sampler);
// The classic variants share the sampler code path; their distributions
// are checked, their samplers only by the unit tests, to keep within a
// minute.
join!("dp-perp", dp_perp_1d, dp_perp_2d);
join!("vw-area", vw_area_1d, vw_area_2d);
join!("opheim", opheim_1d, opheim_2d, opheim_sampler);

/// No simplifier merges a positive cell into a segment of density 0: on a
/// table of zero runs broken by single cells of 1e-12 (next to cells of 1
/// and 0.5), every positive cell keeps a positive pdf at its centre, for
/// every simplifier of `SIMPLIFIERS` at its default tolerance and at 100
/// times it. (Each segment between kept vertices carries the mass of the
/// cells it covers, and the stored CDF rises by at least one f32 step over
/// a segment with a positive cell.)
#[test]
fn positive_cells_keep_a_positive_density() {
    use acdf_core::{Distribution2D, Vec2};
    let (nx, ny) = (16usize, 64usize);
    let mut table = vec![0.0f32; nx * ny];
    for k in (0..nx * ny).step_by(37) {
        table[k] = 1e-12;
    }
    table[5 * nx + 3] = 1.0;
    table[40 * nx + 9] = 0.5;
    for entry in acdf_adaptive_cdf::simplify::SIMPLIFIERS {
        let s = (entry.make)();
        for tolerance in [s.default_tolerance(), 100.0 * s.default_tolerance()] {
            let d = AdaptiveCdf2D::from_values(&table, nx, ny, &*s, tolerance).unwrap();
            for (k, &v) in table.iter().enumerate() {
                if v > 0.0 {
                    let p = Vec2::new(
                        ((k % nx) as f32 + 0.5) / nx as f32,
                        ((k / nx) as f32 + 0.5) / ny as f32,
                    );
                    assert!(
                        d.pdf(p) > 0.0,
                        "{} at {tolerance}: cell {k} of value {v} has pdf 0",
                        entry.name
                    );
                }
            }
        }
    }
}
