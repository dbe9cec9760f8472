//! The product sampler (`acdf-product`) joins the battery: draws in
//! proportion to a BRDF sampler's density times an environment map's
//! luminance at one shading normal, wrapped around the outgoing sampler
//! (`chi2`, at the isotropic resolution), as `product` alone builds it.
//!
//! - Every built-in material under the battery's structured sky (a bright
//!   spot across the φ seam), at a generic normal.
//! - nickel (glossy) and lambert at the normals where frames and tables
//!   have edges: both poles, on the φ seam (y = −0), at a corner of the
//!   oriented sampler's default 16 × 32 normal cells (cos θ = 0.625,
//!   φ = 2π · 5/32), on the border of its polar cap (θ = half the polar
//!   angle of its first row's centres), and next to the map's horizon;
//!   under the sky, the one-texel map and the black map (where the
//!   product leaves the BRDF sampler alone).
//! - gray-plastic and nickel under the four shared maps, at the zenith
//!   and a generic normal, θ_o ∈ {30, 89.5}° (skipped without the shared
//!   data). The density has spikes there (a sun texel of a 1k map drawn
//!   with its block's share), which make the battery's stratified Monte
//!   Carlo ∫ pdf heavy-tailed; its bound ∫ pdf ≤ 1 then also asks the
//!   quadrature (see `check_integral_of_pdf`).
//! - `product:cosine` and `product:adaptive:chi2` once each: the family
//!   wraps any BRDF sampler.
//!
//! θ_o ∈ {0, 30, 60, 85, 89.5}° unless said, 200,000 draws per wo on 50 × 100 cells,
//! α = 0.01 (Sidak over each test's chi-square tests). The mutant whose
//! pdf is the product's without the environment factor (the BRDF
//! sampler's alone) while its draws follow the product is rejected by the
//! chi-square test.

use acdf_conformance::{
    assert_rejected, check_sampler, check_sampler_family, env_test_maps, Check, Report,
    SamplerConfig,
};
use acdf_core::{Brdf, BxdfSample, BxdfSampler, Vec2, Vec3};
use acdf_lights::EnvMap;
use acdf_outgoing::{OutgoingBuilder, OutgoingSampler, FINE_PER_CELL};
use acdf_product::{ProductEnv, ProductOptions, ProductSampler};
use acdf_tabulated::Resolution;
use std::sync::Arc;

fn outgoing(brdf: Arc<dyn Brdf>) -> acdf_core::Result<Arc<dyn BxdfSampler>> {
    let r = Resolution::ISOTROPIC;
    let builder = OutgoingBuilder::by_name("chi2", None, r.theta_o * FINE_PER_CELL)?;
    Ok(Arc::new(OutgoingSampler::new(brdf, r, builder)?))
}

fn product(
    base: Arc<dyn BxdfSampler>,
    map: &EnvMap,
    normal: Vec3,
) -> acdf_core::Result<ProductSampler> {
    let options = ProductOptions::default();
    let env = ProductEnv::new(
        Arc::new(map.clone()),
        options.block_columns,
        options.points_per_side,
        options.sub_cells,
    )?;
    ProductSampler::new(base, Arc::new(env), normal, options)
}

fn config() -> SamplerConfig {
    SamplerConfig {
        samples: 200_000,
        cos_theta_cells: 50,
        phi_cells: 100,
        extreme_samples: 2_000,
        weight_samples: 2_048,
        grazing_samples: 500,
        ..Default::default()
    }
}

fn builtin(name: &str) -> Arc<dyn Brdf> {
    acdf_materials::builtin(name).expect("a built-in material")
}

fn test_map(name: &str) -> Arc<EnvMap> {
    env_test_maps()
        .into_iter()
        .find(|(n, _)| *n == name)
        .expect("a battery map")
        .1
}

/// The normals with edges (see the file's documentation).
fn edge_normals() -> Vec<(&'static str, Vec3)> {
    let from = |cos_theta: f64, phi: f64| {
        let s = (1.0 - cos_theta * cos_theta).sqrt();
        Vec3::new(
            (s * phi.cos()) as f32,
            (s * phi.sin()) as f32,
            cos_theta as f32,
        )
    };
    let cap = 0.5 * (1.0 - 1.0 / 16.0f64).acos();
    vec![
        ("zenith", Vec3::Z),
        ("nadir", -Vec3::Z),
        ("seam", Vec3::new(0.8, -0.0, 0.6)),
        (
            "cell-corner",
            from(0.625, std::f64::consts::TAU * 5.0 / 32.0),
        ),
        ("cap-border", from(cap.cos(), 1.3)),
        ("horizon", Vec3::new(-0.2, 0.9, -0.05).normalize()),
    ]
}

fn merge(mut all: Report, r: Report) -> Report {
    all.merge(r);
    all
}

#[test]
fn product_on_every_builtin_under_the_sky() {
    let sky = test_map("sky64x32");
    let normal = Vec3::new(0.3, -0.5, 0.6).normalize();
    let brdfs: Vec<Arc<dyn Brdf>> = acdf_materials::BUILTIN_NAMES
        .iter()
        .map(|n| builtin(n))
        .collect();
    let report = check_sampler_family(
        "product_builtins",
        |b| product(outgoing(b)?, &sky, normal),
        &brdfs,
        &config(),
    );
    report.print();
    assert!(report.passed(), "{report}");
}

#[test]
fn product_at_the_edge_normals() {
    let mut report = Report::new("product_edges");
    for material in ["nickel", "lambert"] {
        let brdf = builtin(material);
        let base = outgoing(brdf.clone()).expect("the outgoing sampler builds");
        for map_name in ["sky64x32", "one-texel", "black"] {
            let map = test_map(map_name);
            for (label, n) in edge_normals() {
                let s = product(base.clone(), &map, n).expect("the product builds");
                let subject = format!("product {material} {map_name} {label}");
                report = merge(report, check_sampler(&subject, &s, Some(&*brdf), &config()));
            }
        }
    }
    report.print();
    assert!(report.passed(), "{report}");
}

#[test]
fn product_under_the_shared_maps() {
    let dir = acdf_materials::shared_data_dir()
        .map(|d| d.join("envmaps"))
        .filter(|d| d.is_dir());
    let Some(dir) = dir else {
        acdf_materials::testing::skip_without_data("shared environment maps not found");
        return;
    };
    let mut report = Report::new("product_shared_maps");
    for stem in [
        "empty_warehouse_01",
        "potsdamer_platz",
        "rooitou_park",
        "studio_small_03",
    ] {
        let path = dir.join(format!("{stem}_1k.hdr"));
        let map = EnvMap::open(&path).expect("a shared map loads");
        for material in ["gray-plastic", "nickel"] {
            let brdf = builtin(material);
            let base = outgoing(brdf.clone()).expect("the outgoing sampler builds");
            for n in [Vec3::Z, Vec3::new(0.5, 0.4, 0.3).normalize()] {
                let s = product(base.clone(), &map, n).expect("the product builds");
                let subject = format!("product {material} {stem} {n}");
                let config = SamplerConfig {
                    wo_theta_degrees: vec![30.0, 89.5],
                    ..config()
                };
                report = merge(report, check_sampler(&subject, &s, Some(&*brdf), &config));
            }
        }
    }
    report.print();
    assert!(report.passed(), "{report}");
}

#[test]
fn product_wraps_any_brdf_sampler() {
    let sky = test_map("sky64x32");
    let normal = Vec3::new(1.0, -0.0, 0.2).normalize();
    let brdf = builtin("gray-plastic");
    let adaptive =
        acdf_adaptive::adaptive_sampler(brdf.clone(), Resolution::ISOTROPIC, "chi2", None)
            .expect("the adaptive sampler builds");
    let mut report = Report::new("product_wrapped");
    for (label, base) in [
        (
            "cosine",
            Arc::new(acdf_cosine::CosineSampler) as Arc<dyn BxdfSampler>,
        ),
        ("adaptive:chi2", Arc::new(adaptive)),
    ] {
        let s = product(base, &sky, normal).expect("the product builds");
        assert_eq!(s.name(), format!("product:{label}"));
        report = merge(report, check_sampler(s.name(), &s, Some(&*brdf), &config()));
    }
    report.print();
    assert!(report.passed(), "{report}");
}

/// Draws from the product, density of the BRDF sampler alone: the pdf of
/// the product without the environment factor. `sample` reports the
/// density `pdf` gives, so only the distribution can tell.
struct WithoutEnvironment(ProductSampler);

impl BxdfSampler for WithoutEnvironment {
    fn name(&self) -> &str {
        "mutant_product_without_environment"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        let s = self.0.sample(wo, u)?;
        let pdf = self.pdf(wo, s.wi);
        (pdf > 0.0).then_some(BxdfSample { wi: s.wi, pdf })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.brdf_sampler().pdf(wo, wi)
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_the_product_without_the_environment_factor() {
    let sky = test_map("sky64x32");
    let brdf = builtin("gray-plastic");
    let s = product(
        outgoing(brdf.clone()).expect("the outgoing sampler builds"),
        &sky,
        Vec3::new(0.3, -0.5, 0.6).normalize(),
    )
    .expect("the product builds");
    let report = check_sampler(
        "mutant_product_without_environment",
        &WithoutEnvironment(s),
        Some(&*brdf),
        &SamplerConfig {
            samples: 50_000,
            ..config()
        },
    );
    assert_rejected(&report, Check::ChiSquare);
}
