//! The environment samplers against the environment battery
//! (`acdf_conformance::env`): every family over the structured sky and the
//! extreme maps, for no normal and for the test normals; the broken
//! samplers the battery must reject (a missing sin θ, a seam shifted by one
//! column, a pdf off by 5%); the real maps where the shared data is present.

use std::sync::Arc;

use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_adaptive_env::{adaptive_env_sampler, oriented_env_sampler, OrientedEnvSampler};
use acdf_conformance::{
    assert_rejected, check_env_family, check_env_sampler, env_test_maps, env_test_normals, Check,
    EnvConfig, EnvTarget, Report,
};
use acdf_core::{SphereSample, SphereSampler, Vec2, Vec3};
use acdf_lights::{EnvMap, LatLongSampler, NormalGrid, TableKind};
use acdf_uniform::{uniform_env_sampler, PiecewiseConstant2D};

fn assert_passed(report: &Report) {
    report.print();
    assert!(report.passed(), "{report}");
}

#[test]
fn uniform_follows_the_luminance_exactly() {
    let report = check_env_family(
        "uniform",
        |m: &Arc<EnvMap>| uniform_env_sampler(m, TableKind::Luminance),
        &env_test_maps(),
        &[None],
        &EnvConfig::default(),
    );
    assert_passed(&report);
}

#[test]
fn uniform_compensated_follows_its_target() {
    let report = check_env_family(
        "uniform-comp",
        |m: &Arc<EnvMap>| uniform_env_sampler(m, TableKind::Compensated),
        &env_test_maps(),
        &[None],
        &EnvConfig {
            target: EnvTarget::Compensated,
            ..EnvConfig::default()
        },
    );
    assert_passed(&report);
}

/// The chi-square simplifier bounds the divergence of the table from the
/// adaptive density: (1 + 3t/4)(1 + t/4) − 1 ≈ t at tolerance t, plus the
/// f32 rounding of the stored CDFs.
#[test]
fn adaptive_chi2_stays_within_its_budget() {
    let t = 0.02;
    let builder = AdaptiveBuilder::by_name("chi2", Some(t)).unwrap();
    let report = check_env_family(
        "adaptive:chi2",
        |m: &Arc<EnvMap>| adaptive_env_sampler(m, TableKind::Luminance, &builder),
        &env_test_maps(),
        &[None],
        &EnvConfig {
            max_divergence: (1.0 + 0.75 * t) * (1.0 + 0.25 * t) - 1.0 + 1e-4,
            ..EnvConfig::default()
        },
    );
    assert_passed(&report);
}

/// Vertical-error simplifiers bound no divergence; at their default
/// tolerance the test maps stay within 0.05 of the luminance.
#[test]
fn adaptive_dp_and_compensated_pass() {
    let builder = AdaptiveBuilder::by_name("dp", None).unwrap();
    let mut report = check_env_family(
        "adaptive:dp",
        |m: &Arc<EnvMap>| adaptive_env_sampler(m, TableKind::Luminance, &builder),
        &env_test_maps(),
        &[None],
        &EnvConfig {
            max_divergence: 0.05,
            ..EnvConfig::default()
        },
    );
    report.merge(check_env_family(
        "adaptive-comp:dp",
        |m: &Arc<EnvMap>| adaptive_env_sampler(m, TableKind::Compensated, &builder),
        &env_test_maps(),
        &[None],
        &EnvConfig {
            target: EnvTarget::Compensated,
            max_divergence: 0.05,
            ..EnvConfig::default()
        },
    ));
    assert_passed(&report);
}

/// The orientation-aware sampler with its default (no defensive share:
/// each normal draws from its region's table alone) over the test normals
/// (the poles, the seam, near the horizon): exact densities, every lit
/// texel covered by the region's table, and a
/// divergence from L max(0, n·ω) of at most 2 (the plain luminance table
/// has 21 for a normal below the structured sky's sun, see below). On the
/// 1 × 1 and 2 × 1 maps a texel spans a hemisphere, over which max(0, n·ω)
/// is no constant: there only the divergence is not checked.
#[test]
fn oriented_follows_the_irradiance_integrand() {
    let builder = AdaptiveBuilder::by_name("dp", None).unwrap();
    let build = |m: &Arc<EnvMap>| {
        oriented_env_sampler(
            m.clone(),
            builder.clone(),
            NormalGrid::new(4, 8)?,
            OrientedEnvSampler::DEFAULT_DEFENSIVE,
        )
    };
    let config = EnvConfig {
        samples: 100_000,
        target: EnvTarget::Oriented,
        max_divergence: 2.0,
        ..EnvConfig::default()
    };
    let (fine, coarse): (Vec<_>, Vec<_>) = env_test_maps()
        .into_iter()
        .partition(|(_, m)| m.size().0 >= 32);
    let mut report = check_env_family("oriented:dp", build, &fine, &env_test_normals(), &config);
    report.merge(check_env_family(
        "oriented:dp",
        build,
        &coarse,
        &env_test_normals(),
        &EnvConfig {
            max_divergence: f64::INFINITY,
            ..config
        },
    ));
    assert_passed(&report);
}

/// The oriented target's bound has teeth: the plain luminance table, which
/// ignores the normal, exceeds it on the structured sky.
#[test]
fn plain_luminance_fails_the_oriented_target() {
    let (_, sky) = env_test_maps().remove(0);
    let uniform = uniform_env_sampler(&sky, TableKind::Luminance).unwrap();
    let report = check_env_sampler(
        "uniform-as-oriented",
        &uniform,
        &sky,
        &[Some(Vec3::new(0.3, -0.5, -0.6).normalize())],
        &EnvConfig {
            samples: 50_000,
            target: EnvTarget::Oriented,
            max_divergence: 2.0,
            ..EnvConfig::default()
        },
    );
    report.print();
    assert!(report.failed(Check::Target), "{report}");
}

/// Lazy building: a query builds only the table of its normal's region.
#[test]
fn oriented_builds_only_the_cells_it_needs() {
    let (_, sky) = env_test_maps().remove(0);
    let builder = AdaptiveBuilder::by_name("dp", None).unwrap();
    let s = oriented_env_sampler(sky, builder, NormalGrid::new(4, 8).unwrap(), 0.0).unwrap();
    assert_eq!(s.built_nodes(), 0);
    let before = s.storage_bytes();
    s.pdf(None, Vec3::Z);
    assert_eq!(s.built_nodes(), 0);
    let n = Vec3::new(0.3, -0.5, 0.6).normalize();
    s.sample(Some(n), Vec2::new(0.4, 0.7)).unwrap();
    assert_eq!(s.built_nodes(), 1);
    assert!(s.storage_bytes() > before);
    // The same normal again builds nothing more; the pole builds its cap.
    s.pdf(Some(n), Vec3::X);
    assert_eq!(s.built_nodes(), 1);
    s.pdf(Some(Vec3::Z), Vec3::X);
    assert_eq!(s.built_nodes(), 2);
    // Many threads asking for the same region build it once.
    std::thread::scope(|scope| {
        for _ in 0..4 {
            scope.spawn(|| s.sample(Some(-n), Vec2::new(0.1, 0.2)));
        }
    });
    assert_eq!(s.built_nodes(), 3);
    assert!(s.built_nodes() < s.node_count());
}

// ---------------------------------------------------------------- mutants

fn mutant_config() -> EnvConfig {
    EnvConfig {
        samples: 100_000,
        ..EnvConfig::default()
    }
}

/// The table built from the luminance alone, without the texels' solid
/// angle (the classic "missing sin θ"): the sampler is consistent with its
/// own pdf, which is a valid density, but it over-samples the poles; only
/// the target check can see it.
#[test]
fn rejects_a_missing_sin_theta() {
    for (name, map) in env_test_maps()
        .into_iter()
        .filter(|(n, _)| *n == "constant" || *n == "sky64x32")
    {
        let (w, h) = map.size();
        let table: Vec<f32> = map.luminance().to_vec();
        let d = PiecewiseConstant2D::new(&table, w, h).unwrap();
        let mutant = LatLongSampler::new("mutant-no-sin", map.grid().clone(), d);
        let report = check_env_sampler(name, &mutant, &map, &[None], &mutant_config());
        assert_rejected(&report, Check::Target);
    }
}

/// Draws whose azimuth is shifted by one column (the seam moved), with the
/// unshifted density reported for them: consistent with `pdf` at every
/// draw, but drawn from a rotated density.
struct SeamShift<S> {
    inner: S,
    columns: usize,
}

impl<S: SphereSampler> SphereSampler for SeamShift<S> {
    fn name(&self) -> &str {
        "mutant-seam"
    }
    fn sample(&self, n: Option<Vec3>, u: Vec2) -> Option<SphereSample> {
        let s = self.inner.sample(n, u)?;
        let a = std::f32::consts::TAU / self.columns as f32;
        let (sa, ca) = a.sin_cos();
        let dir = Vec3::new(
            ca * s.dir.x - sa * s.dir.y,
            sa * s.dir.x + ca * s.dir.y,
            s.dir.z,
        );
        let pdf = self.inner.pdf(n, dir);
        (pdf > 0.0).then_some(SphereSample { dir, pdf })
    }
    fn pdf(&self, n: Option<Vec3>, dir: Vec3) -> f32 {
        self.inner.pdf(n, dir)
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_a_seam_shifted_by_one_column() {
    let (_, sky) = env_test_maps().remove(0);
    let mutant = SeamShift {
        inner: uniform_env_sampler(&sky, TableKind::Luminance).unwrap(),
        columns: sky.size().0,
    };
    let report = check_env_sampler("sky64x32", &mutant, &sky, &[None], &mutant_config());
    assert_rejected(&report, Check::ChiSquare);
}

/// Every density, returned and evaluated, 5% too high.
struct ScaledPdf<S>(S);

impl<S: SphereSampler> SphereSampler for ScaledPdf<S> {
    fn name(&self) -> &str {
        "mutant-pdf-1.05"
    }
    fn sample(&self, n: Option<Vec3>, u: Vec2) -> Option<SphereSample> {
        self.0.sample(n, u).map(|s| SphereSample {
            dir: s.dir,
            pdf: 1.05 * s.pdf,
        })
    }
    fn pdf(&self, n: Option<Vec3>, dir: Vec3) -> f32 {
        1.05 * self.0.pdf(n, dir)
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_a_pdf_off_by_five_percent() {
    let (_, sky) = env_test_maps().remove(0);
    let mutant = ScaledPdf(uniform_env_sampler(&sky, TableKind::Luminance).unwrap());
    let report = check_env_sampler("sky64x32", &mutant, &sky, &[None], &mutant_config());
    assert_rejected(&report, Check::Integral);
}

// ---------------------------------------------------------------- real maps

/// The shared maps, or `None` (with the reason printed) where absent.
fn shared_maps() -> Option<Vec<(String, Arc<EnvMap>)>> {
    let dir = acdf_materials::shared_data_dir().map(|d| d.join("envmaps"));
    let Some(dir) = dir.filter(|d| d.is_dir()) else {
        acdf_materials::testing::skip_without_data(
            "no ../shared/data/envmaps (set ACDF_SHARED_DATA)",
        );
        return None;
    };
    let mut maps = Vec::new();
    for name in [
        "rooitou_park_1k.hdr",
        "potsdamer_platz_1k.hdr",
        "studio_small_03_1k.hdr",
        "empty_warehouse_01_1k.hdr",
    ] {
        let path = dir.join(name);
        if !path.exists() {
            acdf_materials::testing::skip_without_data(format_args!("{name}: absent"));
            continue;
        }
        maps.push((name.to_string(), Arc::new(EnvMap::open(&path).unwrap())));
    }
    Some(maps)
}

/// The uniform and `adaptive:dp` samplers and the oriented one (for two
/// normals) on each shared map: the full battery at 1024 × 512.
#[test]
fn samplers_pass_on_the_shared_maps() {
    let Some(maps) = shared_maps() else { return };
    let dp = AdaptiveBuilder::by_name("dp", None).unwrap();
    let mut report = Report::new("shared maps");
    for (name, map) in &maps {
        let named = [(name.as_str(), map.clone())];
        let config = EnvConfig {
            samples: 300_000,
            ..EnvConfig::default()
        };
        report.merge(check_env_family(
            "uniform",
            |m: &Arc<EnvMap>| uniform_env_sampler(m, TableKind::Luminance),
            &named,
            &[None],
            &EnvConfig {
                // The f32 CDFs of a row holding a bright source cannot
                // resolve the dimmest texels beside it (2.8e-6 of the
                // light on studio_small_03).
                max_missed: Some(1e-5),
                ..config.clone()
            },
        ));
        report.merge(check_env_family(
            "adaptive:dp",
            |m: &Arc<EnvMap>| adaptive_env_sampler(m, TableKind::Luminance, &dp),
            &named,
            &[None],
            &EnvConfig {
                max_divergence: 0.2,
                ..config.clone()
            },
        ));
        report.merge(check_env_family(
            "oriented:dp",
            |m: &Arc<EnvMap>| {
                oriented_env_sampler(m.clone(), dp.clone(), NormalGrid::DEFAULT, 0.05)
            },
            &named,
            &[Some(Vec3::new(0.2, 0.3, 0.93).normalize()), Some(-Vec3::Z)],
            &EnvConfig {
                target: EnvTarget::Oriented,
                max_divergence: 2.0,
                ..config
            },
        ));
    }
    assert_passed(&report);
}
