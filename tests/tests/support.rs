//! The support check on measured data: the tabulated samplers (`uniform`
//! and `adaptive:chi2`) must have a positive pdf wherever the measured
//! material reflects light, at outgoing angles up to 89.5°.
//!
//! The battery's other checks run on the built-in materials (`uniform.rs`,
//! `adaptive.rs`); measured tables add what analytic lobes lack: entries
//! that are exactly 0, lobes that a grazing horizon cuts, and anisotropic
//! files served by several φ_o cells. Materials: the three MERL materials
//! of the Neural-BRDF file baked into MERL tables (as `acdf` evaluates
//! them), and two RGL files (the sharp `ilm_solo_m_68` and the
//! anisotropic, if any, else the first). Isotropic materials use the
//! isotropic resolution, anisotropic ones the paper's (32 × 16 φ_o cells,
//! built on first use, so only the slices the tested wo touch).
//!
//! The missed share ∫_{p=0} f cos θ_i dω / ∫ f cos θ_i dω is taken by the
//! midpoint rule on 128 × 256 cells in (cos θ_i, φ_i)
//! ([`acdf_core::missed_share`], luminance-weighted) at θ_o ∈ {0, 0.05,
//! 0.087 (inside the first θ_o cell), 30, 60, 70, 80, 85, 89, 89.5}° and
//! φ_o = 1 rad; the bound is 1e-7, the
//! battery's. The tests print `skipping: ...` and pass when the shared data
//! is absent.

use acdf_adaptive::AdaptiveBrdfSampler;
use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_core::geometry::spherical_direction;
use acdf_core::{missed_share, Brdf, BxdfSampler};
use acdf_tabulated::Resolution;
use acdf_uniform::{PiecewiseConstantBuilder, UniformBrdfSampler};
use std::sync::Arc;

mod shared;

const THETA_O_DEGREES: [f32; 10] = [0.0, 0.05, 0.087, 30.0, 60.0, 70.0, 80.0, 85.0, 89.0, 89.5];
const BOUND: f64 = 1e-7;

/// Check both tabulated samplers on `brdf`; panics naming the worst wo.
fn check(label: &str, brdf: Arc<dyn Brdf>) {
    let resolution = if brdf.is_isotropic() {
        Resolution::ISOTROPIC
    } else {
        Resolution::PAPER
    };
    let uniform = UniformBrdfSampler::new(brdf.clone(), resolution, PiecewiseConstantBuilder)
        .expect("the uniform sampler builds");
    let chi2: AdaptiveBrdfSampler = AdaptiveBrdfSampler::new(
        brdf.clone(),
        resolution,
        AdaptiveBuilder::by_name("chi2", None).expect("chi2 is a simplifier"),
    )
    .expect("the adaptive sampler builds");
    let samplers: [(&str, &dyn BxdfSampler); 2] = [("uniform", &uniform), ("adaptive:chi2", &chi2)];
    for (name, sampler) in samplers {
        for theta in THETA_O_DEGREES {
            let wo = spherical_direction(theta.to_radians(), 1.0);
            let missed = missed_share(&*brdf, sampler, wo, 128, 256);
            println!(
                "{label} {name} ({resolution}) θ_o {theta}°: missed {:.3e}",
                missed.share
            );
            assert!(
                missed.share <= BOUND,
                "{label} {name} ({resolution}) θ_o {theta}°: pdf is 0 on {:.3e} of f cos θ_i \
                 (bound {BOUND:e}), most at wi = {:?}",
                missed.share,
                missed.worst
            );
        }
    }
}

fn nbrdf(name: &str) {
    if let Some(brdf) = shared::nbrdf(name) {
        check(&format!("nbrdf:{name}"), brdf);
    }
}

#[test]
fn nbrdf_nickel() {
    nbrdf("nickel");
}

#[test]
fn nbrdf_gray_plastic() {
    nbrdf("gray-plastic");
}

#[test]
fn nbrdf_blue_metallic_paint() {
    nbrdf("blue-metallic-paint");
}

/// The RGL files of the shared database: the sharp `ilm_solo_m_68`, and
/// the first anisotropic file, if the database has one.
#[test]
fn rgl_files() {
    let Some(dir) = acdf_materials::rgl::shared_dir() else {
        acdf_materials::testing::skip_without_data(
            "shared RGL data not found (set ACDF_SHARED_DATA)",
        );
        return;
    };
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("the RGL folder is readable")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "bsdf"))
        .collect();
    files.sort();
    let open = |path: &std::path::Path| -> Arc<dyn Brdf> {
        Arc::new(acdf_materials::rgl::RglBrdf::open(path).expect("the shared RGL file loads"))
    };
    let sharp = dir.join("ilm_solo_m_68_rgb.bsdf");
    if sharp.is_file() {
        check("ilm_solo_m_68", open(&sharp));
    }
    match files
        .iter()
        .map(|p| (p, open(p)))
        .find(|(_, b)| !b.is_isotropic())
    {
        Some((path, brdf)) => check(&path.display().to_string(), brdf),
        None => println!("no anisotropic RGL file in {}", dir.display()),
    }
}
