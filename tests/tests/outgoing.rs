//! The outgoing sampler of the adaptive plug-in joins the battery: at the
//! isotropic resolution (128 fine θ_o slices, 256 θ_h x 32 φ_h cells per
//! kept slice) with the `chi2` simplifier, on the built-in `nickel`,
//! `lambert` and `near-mirror`, with wo on the normal, between
//! breakpoints and next to the horizon, and on nickel with wo exactly at
//! one of its breakpoints and halfway to the next. The anisotropic
//! outgoing sampler at 16x8x128x32 (32 θ_o × 16 φ_o fine nodes) on the
//! battery's anisotropic GGX lobe, with wo on the normal, at a θ_o
//! breakpoint, halfway to the next and next to the horizon: with the
//! lobe's mirror symmetries (its slices cover φ_o from 0 to π/2) in the
//! fourth quadrant, just below 2π, and in the second and third (mirrored
//! into the arc), and round the whole circle just below its seam at 2π.
//! At the default resolution (64 θ_o × 32 φ_o fine nodes, 256 x 32
//! cells) the anisotropic sampler keeps within its storage cap on GGX
//! lobes of three roughness pairs.

use acdf_conformance::brdfs::GgxBrdf;
use acdf_conformance::{check_sampler_family, sampler_battery, SamplerConfig};
use acdf_core::BxdfSampler;
use acdf_core::{Brdf, Rgb};
use acdf_outgoing::anisotropic::{Symmetry, ANISOTROPIC_FINE_PER_CELL, FINE_PHI_PER_CELL};
use acdf_outgoing::{AnisotropicOutgoingSampler, OutgoingBuilder, OutgoingSampler};
use acdf_outgoing::{DEFAULT_MAX_BYTES, FINE_PER_CELL};
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

/// The anisotropic sampler at 16x8x128x32 with the symmetry given
/// (`None`: found).
fn anisotropic_with(
    brdf: Arc<dyn Brdf>,
    symmetry: Option<Symmetry>,
) -> acdf_core::Result<AnisotropicOutgoingSampler> {
    let r: Resolution = "16x8x128x32".parse().expect("a resolution");
    let builder =
        OutgoingBuilder::anisotropic_by_name("chi2", None, r.theta_o * ANISOTROPIC_FINE_PER_CELL)?;
    AnisotropicOutgoingSampler::with_symmetry(
        brdf,
        r,
        builder,
        r.phi_o * FINE_PHI_PER_CELL,
        symmetry,
    )
}

fn anisotropic_config(wo_theta_degrees: Vec<f32>, wo_phi: f32) -> SamplerConfig {
    SamplerConfig {
        wo_phi,
        ..config(wo_theta_degrees)
    }
}

/// On the normal, exactly at a θ_o breakpoint (its row of slices has all
/// the θ_o weight), halfway to the next and next to the horizon, all just
/// below φ_o = 2π: with the lobe's mirrors, a wo mirrored into the arc's
/// first interval; round the whole circle, the last φ_o interval, which
/// blends the last φ_o breakpoint with the first. One test per case, so
/// that the lobe's tables are built once per battery pass.
#[test]
fn chi2_outgoing_anisotropic() {
    check_anisotropic(None, std::f32::consts::TAU - 1e-3);
}

/// As [`chi2_outgoing_anisotropic`] round the whole circle, across its
/// seam.
#[test]
fn chi2_outgoing_anisotropic_whole_circle() {
    check_anisotropic(Some(Symmetry::None), std::f32::consts::TAU - 1e-3);
}

/// As [`chi2_outgoing_anisotropic`] in the second and third quadrants
/// (x mirrored, then both), between the arc's breakpoints.
#[test]
fn chi2_outgoing_anisotropic_mirrored_quadrants() {
    check_anisotropic(None, 2.0);
    check_anisotropic(None, 4.0);
}

/// The battery at the wo of [`chi2_outgoing_anisotropic`], at azimuth
/// `wo_phi`, with the symmetry given (`None`: found, both mirrors).
fn check_anisotropic(symmetry: Option<Symmetry>, wo_phi: f32) {
    let built = anisotropic_with(ggx(), symmetry).expect("the lobe builds");
    let expected = symmetry.unwrap_or(Symmetry::MirrorXY);
    assert_eq!(built.symmetry(), expected);
    let theta = built.theta_breakpoint_angles();
    assert!(theta.len() >= 3, "{theta:?}");
    let k = theta.len() / 2;
    let at = theta[k].to_degrees();
    let between = (0.5 * (theta[k] + theta[k + 1])).to_degrees();
    let report = check_sampler_family(
        "chi2_outgoing_anisotropic",
        |b| anisotropic_with(b, symmetry),
        &[ggx()],
        &anisotropic_config(vec![0.0, at, between, 89.5], wo_phi),
    );
    report.print();
    assert!(report.passed(), "{report}");
}

/// At the default tolerance and the registry's resolution for an
/// anisotropic material (32x16x256x32: 64 θ_o × 32 φ_o fine nodes), the
/// anisotropic sampler keeps within [`DEFAULT_MAX_BYTES`] on the GGX lobe
/// of the `anisotropic_rgl` example (α 0.1 × 0.3) and two other roughness
/// pairs, using both mirrors.
#[test]
fn anisotropic_default_keeps_within_the_storage_cap() {
    let r: Resolution = "32x16x256x32".parse().expect("a resolution");
    for (alpha_x, alpha_y) in [(0.1, 0.3), (0.05, 0.2), (0.3, 0.6)] {
        let brdf = Arc::new(GgxBrdf {
            alpha_x,
            alpha_y,
            color: Rgb::splat(0.8),
        });
        let builder = OutgoingBuilder::anisotropic_by_name(
            "chi2",
            None,
            r.theta_o * ANISOTROPIC_FINE_PER_CELL,
        )
        .expect("the default builder");
        let s = AnisotropicOutgoingSampler::new(brdf, r, builder, r.phi_o * FINE_PHI_PER_CELL)
            .expect("the lobe builds");
        assert_eq!(s.symmetry(), Symmetry::MirrorXY);
        assert!(
            s.storage_bytes() <= DEFAULT_MAX_BYTES,
            "α {alpha_x} x {alpha_y}: {} bytes",
            s.storage_bytes()
        );
    }
}
