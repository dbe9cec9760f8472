//! Analytic samplers written for the battery: they exercise it on shapes the
//! cosine sampler does not have (a narrow anisotropic lobe, a lobe whose pdf
//! is not symmetric in wo and wi, a tabulated density with jumps), and they
//! are the healthy originals from which `tests/mutants.rs` derives broken
//! ones.

use acdf_core::geometry::{half_vector, phi, reflect};
use acdf_core::{
    clamp_unit, is_valid_outgoing, BxdfSample, BxdfSampler, Distribution2D, Frame, Vec2, Vec3,
};
use std::f32::consts::{PI, TAU};

/// The anisotropic GGX distribution of normals for a unit h:
/// D(h) = 1 / (π α_x α_y (h_x²/α_x² + h_y²/α_y² + h_z²)²).
#[inline]
pub fn ggx_d(h: Vec3, alpha_x: f32, alpha_y: f32) -> f32 {
    let s = h.x * h.x / (alpha_x * alpha_x) + h.y * h.y / (alpha_y * alpha_y) + h.z * h.z;
    1.0 / (PI * alpha_x * alpha_y * s * s)
}

/// The axis of [`TiltedLobeSampler`]: halfway between the mirror direction
/// of wo and the normal, normalize(reflect(wo, z) + z). Not an involution,
/// which is what makes the lobe's pdf asymmetric in (wo, wi).
#[inline]
pub fn tilted_axis(wo: Vec3) -> Vec3 {
    (reflect(wo, Vec3::Z) + Vec3::Z).normalize_or(Vec3::Z)
}

/// Half-vector sampling of anisotropic GGX: h ∝ D(h) cos θ_h, wi = the
/// mirror of wo about h, p(wi) = D(h) cos θ_h / (4 |wo·h|). Draws whose wi
/// falls at or below the horizon are `None`, so ∫ pdf < 1 at grazing wo.
#[derive(Debug, Clone, Copy)]
pub struct GgxSampler {
    pub alpha_x: f32,
    pub alpha_y: f32,
}

impl BxdfSampler for GgxSampler {
    fn name(&self) -> &str {
        "ggx-half-vector"
    }

    /// The slope (x̃, ỹ) = (α_x r cos 2πu_y, α_y r sin 2πu_y) with
    /// r² = u_x / (1 - u_x) has density 1 / (π α_x α_y (1 + x̃²/α_x² +
    /// ỹ²/α_y²)²), the GGX slope density; h = normalize(x̃, ỹ, 1).
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        let (ux, uy) = (clamp_unit(u.x), clamp_unit(u.y));
        let r = (ux / (1.0 - ux)).sqrt();
        let (s, c) = (TAU * uy).sin_cos();
        let h = Vec3::new(self.alpha_x * r * c, self.alpha_y * r * s, 1.0).normalize();
        let wi = reflect(wo, h);
        if wi.z <= 0.0 || !wi.is_finite() {
            return None;
        }
        let wi = wi.normalize();
        // Recomputed from the final wi so that it equals pdf(wo, wi) exactly.
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0 && pdf.is_finite()).then_some(BxdfSample { wi, pdf })
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !is_valid_outgoing(wo) || wi.z <= 0.0 || !wi.is_finite() {
            return 0.0;
        }
        let Some(h) = half_vector(wi, wo) else {
            return 0.0;
        };
        let p = ggx_d(h, self.alpha_x, self.alpha_y) * h.z.abs() / (4.0 * wo.dot(h).abs());
        if p.is_finite() {
            p
        } else {
            0.0
        }
    }

    fn storage_bytes(&self) -> usize {
        0
    }
}

/// A cosine-power lobe around [`tilted_axis`]`(wo)`:
/// p(wi | wo) = (n + 1) / (2π) max(0, wi·a(wo))^n for wi.z > 0.
/// Since a(wo) is not the mirror of wo, p(wi | wo) ≠ p(wo | wi).
#[derive(Debug, Clone, Copy)]
pub struct TiltedLobeSampler {
    pub exponent: f32,
}

impl BxdfSampler for TiltedLobeSampler {
    fn name(&self) -> &str {
        "tilted-lobe"
    }

    /// cos α = u_x^(1/(n+1)) about the axis, azimuth 2πu_y.
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        let cos_a = clamp_unit(u.x).powf(1.0 / (self.exponent + 1.0));
        let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
        let (s, c) = (TAU * clamp_unit(u.y)).sin_cos();
        let frame = Frame::from_z(tilted_axis(wo));
        let wi = frame
            .to_world(Vec3::new(sin_a * c, sin_a * s, cos_a))
            .normalize();
        if wi.z <= 0.0 || !wi.is_finite() {
            return None;
        }
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then_some(BxdfSample { wi, pdf })
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !is_valid_outgoing(wo) || wi.z <= 0.0 || !wi.is_finite() {
            return 0.0;
        }
        let c = wi.dot(tilted_axis(wo)).max(0.0);
        (self.exponent + 1.0) / TAU * c.powf(self.exponent)
    }

    fn storage_bytes(&self) -> usize {
        0
    }
}

/// A wo-independent sampler that draws (φ/2π, cos θ) from a 2D distribution
/// over the unit square: p(wi) = p_2D(φ/2π, cos θ) / (2π), since
/// dω = d(cos θ) dφ. It puts table-shaped jumps on the sphere.
#[derive(Debug, Clone)]
pub struct TabulatedSampler<D> {
    pub distribution: D,
}

impl<D: Distribution2D> TabulatedSampler<D> {
    /// The point of the unit square that `wi` corresponds to.
    pub fn square_point(wi: Vec3) -> Vec2 {
        Vec2::new((phi(wi) / TAU).min(acdf_core::ONE_MINUS_EPSILON), wi.z)
    }
}

impl<D: Distribution2D> BxdfSampler for TabulatedSampler<D> {
    fn name(&self) -> &str {
        "tabulated"
    }

    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        let p = self.distribution.sample(u).p;
        let z = p.y;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (s, c) = (TAU * p.x).sin_cos();
        let wi = Vec3::new(r * c, r * s, z);
        if z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0 && pdf.is_finite()).then_some(BxdfSample { wi, pdf })
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !is_valid_outgoing(wo) || wi.z <= 0.0 || !wi.is_finite() {
            return 0.0;
        }
        self.distribution.pdf(Self::square_point(wi)) / TAU
    }

    fn storage_bytes(&self) -> usize {
        self.distribution.storage_bytes()
    }
}
