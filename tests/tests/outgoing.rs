//! The outgoing sampler of the adaptive plug-in joins the battery: at the
//! isotropic resolution (128 fine θ_o slices, 256 θ_h x 32 φ_h cells per
//! kept slice) with the `chi2` simplifier, on the built-in `nickel`,
//! `lambert` and `near-mirror`, with wo on the normal, between
//! breakpoints and next to the horizon, and on nickel with wo exactly at
//! one of its breakpoints and halfway to the next. The anisotropic
//! outgoing sampler at 16x8x128x32 (32 θ_o × 16 φ_o fine nodes) on the
//! battery's anisotropic GGX lobe, with wo on the normal, at a θ_o
//! breakpoint, halfway to the next and next to the horizon, just below
//! the φ_o seam at 2π.

use acdf_conformance::brdfs::GgxBrdf;
use acdf_conformance::{check_sampler_family, sampler_battery, SamplerConfig};
use acdf_core::{Brdf, Rgb};
use acdf_outgoing::anisotropic::{ANISOTROPIC_FINE_PER_CELL, FINE_PHI_PER_CELL};
use acdf_outgoing::FINE_PER_CELL;
use acdf_outgoing::{AnisotropicOutgoingSampler, OutgoingBuilder, OutgoingSampler};
use acdf_tabulated::Resolution;
use std::sync::Arc;

fn builtins() -> Vec<Arc<dyn Brdf>> {
    ["nickel", "lambert", "near-mirror"]
        .iter()
        .map(|n| acdf_materials::builtin(n).expect("built-in material"))
        .collect()
}

fn sampler(name: &str, brdf: Arc<dyn Brdf>) -> acdf_core::Result<OutgoingSampler> {
    let r = Resolution::ISOTROPIC;
    let builder = OutgoingBuilder::by_name(name, None, r.theta_o * FINE_PER_CELL)?;
    OutgoingSampler::new(brdf, r, builder)
}

fn config(wo_theta_degrees: Vec<f32>) -> SamplerConfig {
    SamplerConfig {
        samples: 200_000,
        cos_theta_cells: 50,
        phi_cells: 100,
        wo_theta_degrees,
        extreme_samples: 2_000,
        weight_samples: 2_048,
        ..Default::default()
    }
}

sampler_battery!(
    chi2_outgoing,
    build = |b| sampler("chi2", b),
    brdfs = builtins(),
    config = config(vec![0.0, 40.0, 85.0, 89.5])
);

/// wo exactly at a breakpoint of nickel (where one slice has all the
/// weight) and halfway between it and the next (both slices weigh half).
#[test]
fn chi2_outgoing_at_and_between_breakpoints() {
    let nickel = acdf_materials::builtin("nickel").expect("built-in nickel");
    let built = sampler("chi2", nickel.clone()).expect("nickel builds");
    let angles = built.breakpoint_angles();
    assert!(angles.len() >= 3, "{angles:?}");
    let k = angles.len() / 2;
    let at = angles[k].to_degrees();
    let between = (0.5 * (angles[k] + angles[k + 1])).to_degrees();
    let report = check_sampler_family(
        "chi2_outgoing_breakpoints",
        |b| sampler("chi2", b),
        &[nickel],
        &config(vec![at, between]),
    );
    report.print();
    assert!(report.passed(), "{report}");
}

/// The battery's anisotropic GGX lobe (roughness 0.15 along x, 0.4 along y).
fn ggx() -> Arc<dyn Brdf> {
    Arc::new(GgxBrdf {
        alpha_x: 0.15,
        alpha_y: 0.4,
        color: Rgb::new(0.9, 0.8, 0.7),
    })
}

fn anisotropic(brdf: Arc<dyn Brdf>) -> acdf_core::Result<AnisotropicOutgoingSampler> {
    let r: Resolution = "16x8x128x32".parse().expect("a resolution");
    let builder =
        OutgoingBuilder::anisotropic_by_name("chi2", None, r.theta_o * ANISOTROPIC_FINE_PER_CELL)?;
    AnisotropicOutgoingSampler::new(brdf, r, builder, r.phi_o * FINE_PHI_PER_CELL)
}

fn anisotropic_config(wo_theta_degrees: Vec<f32>, wo_phi: f32) -> SamplerConfig {
    SamplerConfig {
        wo_phi,
        ..config(wo_theta_degrees)
    }
}

/// On the normal, exactly at a θ_o breakpoint (its row of slices has all
/// the θ_o weight), halfway to the next and next to the horizon, all just
/// below the φ_o seam at 2π (the last φ_o interval, which blends the last
/// φ_o breakpoint with the first). One test, so that the lobe's tables are
/// built once per battery pass.
#[test]
fn chi2_outgoing_anisotropic() {
    let built = anisotropic(ggx()).expect("the lobe builds");
    let theta = built.theta_breakpoint_angles();
    assert!(theta.len() >= 3, "{theta:?}");
    let k = theta.len() / 2;
    let at = theta[k].to_degrees();
    let between = (0.5 * (theta[k] + theta[k + 1])).to_degrees();
    let report = check_sampler_family(
        "chi2_outgoing_anisotropic",
        anisotropic,
        &[ggx()],
        &anisotropic_config(vec![0.0, at, between, 89.5], std::f32::consts::TAU - 1e-3),
    );
    report.print();
    assert!(report.passed(), "{report}");
}
