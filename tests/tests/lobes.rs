//! The fitted-lobe sampler (`acdf-lobes`) joins the battery: fitted to the
//! battery's ordinary BRDFs and the five built-in materials, and to
//! measured ones (three MERL materials of the Neural-BRDF file baked into
//! MERL tables, as `acdf` evaluates them, and the sharpest and the
//! smoothest RGL files), which print `skipping: ...` and pass when the
//! shared data is absent (fail with `ACDF_REQUIRE_DATA=1`). Draws are cut
//! to 200,000 per outgoing direction over 50 × 100 cells (the default is
//! 10^6 over 100 × 200), since each material is also fitted.
//!
//! The battery must reject the family broken: a mixture whose `pdf` (and
//! the density its draws return) has the cosine lobe's weight raised from
//! 0.30 to 0.33, drawn from the true weights, is caught by the chi-square
//! test.

use acdf_conformance::{
    assert_rejected, brdfs, check_sampler, sampler_battery, Check, SamplerConfig,
};
use acdf_core::{Brdf, BxdfSample, BxdfSampler, Vec2, Vec3};
use acdf_lobes::{Lobes, LobesSampler, Mixture};
use std::sync::Arc;

mod shared;

fn config() -> SamplerConfig {
    SamplerConfig {
        samples: 200_000,
        cos_theta_cells: 50,
        phi_cells: 100,
        extreme_samples: 2_000,
        weight_samples: 4_096,
        ..Default::default()
    }
}

fn builtins() -> Vec<Arc<dyn Brdf>> {
    acdf_materials::BUILTIN_NAMES
        .iter()
        .map(|n| acdf_materials::builtin(n).expect("built-in material"))
        .collect()
}

sampler_battery!(
    lobes,
    build = |b| LobesSampler::new(b.as_ref()),
    brdfs = brdfs::ordinary_brdfs().into_iter().chain(builtins()),
    config = config()
);

/// Fit and check one measured material.
fn measured(label: &str, brdf: Arc<dyn Brdf>) {
    let sampler = LobesSampler::new(brdf.as_ref()).expect("the fit succeeds");
    let report = check_sampler(label, &sampler, Some(&*brdf), &config());
    report.print();
    assert!(report.passed(), "{report}");
}

fn nbrdf(name: &str) {
    if let Some(brdf) = shared::nbrdf(name) {
        measured(&format!("lobes_nbrdf_{name}"), brdf);
    }
}

#[test]
fn lobes_nbrdf_chrome() {
    nbrdf("chrome");
}

#[test]
fn lobes_nbrdf_gray_plastic() {
    nbrdf("gray-plastic");
}

#[test]
fn lobes_nbrdf_blue_metallic_paint() {
    nbrdf("blue-metallic-paint");
}

fn rgl(stem: &str) {
    if let Some(brdf) = shared::rgl(stem) {
        measured(&format!("lobes_rgl_{stem}"), brdf);
    }
}

#[test]
fn lobes_rgl_ilm_solo_m_68() {
    rgl("ilm_solo_m_68_rgb");
}

#[test]
fn lobes_rgl_paper_white() {
    rgl("paper_white_rgb");
}

/// Draws from `truth`, but reports the density of `claimed` (for the draw
/// and in `pdf`), so that `sample` and `pdf` agree and only the
/// distributional checks can see the bug.
struct WrongWeight {
    truth: Mixture,
    claimed: Mixture,
}

impl BxdfSampler for WrongWeight {
    fn name(&self) -> &str {
        "mutant-lobes-weight"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        let s = self.truth.sample(wo, u)?;
        let pdf = self.claimed.pdf(wo, s.wi);
        (pdf > 0.0).then_some(BxdfSample { wi: s.wi, pdf })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.claimed.pdf(wo, wi)
    }
    fn storage_bytes(&self) -> usize {
        self.truth.storage_bytes()
    }
}

/// One weight changed by 0.03 (the cosine lobe's, from 0.30 to 0.33, the
/// GGX lobe's from 0.70 to 0.67 so that they still sum to 1) is rejected
/// by the chi-square test; the true mixture passes the same checks.
#[test]
fn rejects_a_mixture_with_one_weight_changed() {
    let truth = Mixture::new(Lobes::new(0.30, &[(0.70, 0.2)]).unwrap());
    let claimed = Mixture::new(Lobes::new(0.33, &[(0.67, 0.2)]).unwrap());
    let config = SamplerConfig {
        max_missed_share: None,
        ..config()
    };
    let healthy = check_sampler("lobes_healthy", &truth, None, &config);
    healthy.print();
    assert!(healthy.passed(), "{healthy}");
    let report = check_sampler(
        "mutant_lobes_weight",
        &WrongWeight { truth, claimed },
        None,
        &config,
    );
    assert_rejected(&report, Check::ChiSquare);
}

/// A material that reflects nothing has nothing to fit: a typed error.
#[test]
fn a_zero_material_is_a_typed_error() {
    assert!(matches!(
        LobesSampler::new(&brdfs::ZeroBrdf),
        Err(acdf_core::Error::ZeroMaterial { .. })
    ));
}
