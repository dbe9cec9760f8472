//! `acdf-cosine` is the simplest BRDF sampler and the baseline every tabulated
//! sampler must beat: it ignores the BRDF and draws incident directions with
//! density cos θ_i / π (Malley's method: a uniform point on the disk lifted to
//! the hemisphere). It is exact for a Lambertian surface, needs no storage, and
//! is the defensive lobe that other samplers may mix in.

#![forbid(unsafe_code)]

use acdf_core::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use acdf_core::{is_valid_outgoing, BxdfSample, BxdfSampler, Vec2, Vec3};

/// Cosine-weighted hemisphere sampling, p(wi) = cos θ_i / π.
#[derive(Debug, Clone, Copy, Default)]
pub struct CosineSampler;

impl BxdfSampler for CosineSampler {
    fn name(&self) -> &str {
        "cosine"
    }

    /// Draw wi by Malley's method. The rim of the disk maps to the horizon
    /// (cos θ_i = 0, density 0); such a draw is `None`.
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        let wi = square_to_cosine_hemisphere(u);
        let pdf = cosine_hemisphere_pdf(wi);
        (pdf > 0.0).then_some(BxdfSample { wi, pdf })
    }

    /// p(wi) = max(cos θ_i, 0) / π for a valid wo, else 0.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !is_valid_outgoing(wo) || !wi.is_finite() {
            return 0.0;
        }
        cosine_hemisphere_pdf(wi)
    }

    fn storage_bytes(&self) -> usize {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use acdf_core::geometry::spherical_direction;
    use acdf_core::ONE_MINUS_EPSILON;
    use rand::{Rng, SeedableRng};
    use std::f32::consts::{FRAC_PI_2, PI};

    #[test]
    fn sample_and_pdf_agree() {
        let wo = spherical_direction(0.4, 1.0);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        for _ in 0..10_000 {
            let u = Vec2::new(rng.random(), rng.random());
            let s = CosineSampler.sample(wo, u).unwrap();
            approx::assert_relative_eq!(s.pdf, CosineSampler.pdf(wo, s.wi), max_relative = 1e-6);
            assert!((s.wi.length() - 1.0).abs() < 1e-5 && s.wi.z > 0.0);
        }
    }

    /// Midpoint rule over (θ, φ) with 2000 × 64 cells: the pdf times
    /// sin θ integrates to 1 over the hemisphere.
    #[test]
    fn pdf_integrates_to_one_over_the_hemisphere() {
        let wo = Vec3::Z;
        let (nt, np) = (2000, 64);
        let (dt, dp) = (FRAC_PI_2 / nt as f32, 2.0 * PI / np as f32);
        let mut sum = 0.0f64;
        for i in 0..nt {
            let t = (i as f32 + 0.5) * dt;
            for j in 0..np {
                let p = (j as f32 + 0.5) * dp;
                let wi = spherical_direction(t, p);
                sum += (CosineSampler.pdf(wo, wi) * t.sin() * dt * dp) as f64;
            }
        }
        approx::assert_abs_diff_eq!(sum, 1.0, epsilon = 1e-5);
        assert_eq!(CosineSampler.pdf(wo, -Vec3::Z), 0.0);
    }

    #[test]
    fn extreme_u_gives_no_nan() {
        let wo = spherical_direction(1.0, 0.5);
        for a in [0.0, 0.5, ONE_MINUS_EPSILON, 1.0, -0.1, f32::NAN] {
            for b in [0.0, 0.5, ONE_MINUS_EPSILON, 1.0, f32::INFINITY] {
                if let Some(s) = CosineSampler.sample(wo, Vec2::new(a, b)) {
                    assert!(s.wi.is_finite() && s.pdf.is_finite() && s.pdf > 0.0);
                }
            }
        }
        // The centre of the square is the normal.
        let s = CosineSampler.sample(wo, Vec2::splat(0.5)).unwrap();
        approx::assert_relative_eq!(s.wi.z, 1.0);
    }

    #[test]
    fn invalid_wo_gives_none_and_zero() {
        for wo in [Vec3::X, -Vec3::Z, Vec3::splat(f32::NAN)] {
            assert!(CosineSampler.sample(wo, Vec2::splat(0.3)).is_none());
            assert_eq!(CosineSampler.pdf(wo, Vec3::Z), 0.0);
        }
    }
}
