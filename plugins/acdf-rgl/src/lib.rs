//! `acdf-rgl` is the importance sampler that ships inside every RGL `.bsdf`
//! file (Dupuy and Jakob 2018), as an acdf [`BxdfSampler`] named `rgl`: the
//! sampler the data's authors built for these materials, and so the baseline
//! the tabulated and adaptive samplers are compared with on RGL data.
//!
//! For a given `wo` (the file's parameter direction ω_i, see
//! [`acdf_materials::rgl`] for the naming), a uniform pair u is warped twice:
//! first through the inverse CDFs of the luminance density, giving a point s
//! of the warped square, then s through the inverse CDFs of the visible-normal
//! density, giving the half vector's square coordinates u_m = (u_θ, u_φ).
//! Both densities are bilinear interpolants blended linearly between the
//! θ_i slices around θ(wo); both warps are [`BlendedBilinear::sample`] (a
//! binary search and one quadratic per axis). The half vector ω_m reflects
//! `wo` into `wi`. The solid-angle density is
//!
//! p(wi | wo) = p_vndf(u_m) · p_lum(s) / J,  J = max(2π² u_θ sin θ_m, 1e-6) · 4 (wo · ω_m).
//!
//! The vndf vanishes on the column u_θ = 0, so the density is 0 exactly at
//! θ_m = 0 (for instance wo = wi = normal): such a pair is never drawn, though
//! f_r is not 0 there. Draws whose reflection falls at or below the horizon
//! are `None`; their probability is the mass that `pdf` does not cover.
//!
//! This is the density the format specifies (and Mitsuba 3 reports), kept
//! as is so that it matches the reference values. It is not exactly the
//! density of the draws in one place: the floor of J at 1e-6 applies for
//! θ_m below about 1.6e-5 rad, where the true Jacobian is smaller, so inside
//! that cone around the mirror direction `pdf` underestimates. The draws
//! landing there are rare (7.7e-5 of them for the metal `ilm_solo_m_68` at
//! normal incidence, 3e-5 for `chm_mint`, none for the matte paint; counted
//! over 2·10^6 draws), and the pdf returned with them is still `pdf(wo, wi)`.

#![forbid(unsafe_code)]

use acdf_core::{clamp_unit, is_valid_outgoing, BxdfSample, BxdfSampler, Vec2, Vec3};
pub use acdf_materials::rgl::{Bilinear2D, BlendedBilinear, RglBrdf};
use glam::DVec2;
use std::sync::Arc;

/// The RGL file's own sampler (luminance warp, then visible-normal warp).
#[derive(Debug, Clone)]
pub struct RglSampler {
    brdf: Arc<RglBrdf>,
}

impl RglSampler {
    /// The sampler of the material `brdf`; it shares the material's tables.
    pub fn new(brdf: Arc<RglBrdf>) -> RglSampler {
        RglSampler { brdf }
    }

    /// The material whose tables are sampled.
    pub fn brdf(&self) -> &Arc<RglBrdf> {
        &self.brdf
    }

    /// The density p_vndf(u_m) p_lum(s) / J in f64 for the pair
    /// (wo, wi); 0 when either is invalid or below the horizon.
    pub fn pdf_f64(&self, wo: Vec3, wi: Vec3) -> f64 {
        let Some(l) = self.brdf.lookup(wo, wi) else {
            return 0.0;
        };
        let p_lum = self
            .brdf
            .luminance_density()
            .at(l.incident.blend)
            .density(l.s);
        let pdf = l.vndf_pdf * p_lum / l.jacobian;
        if pdf.is_finite() && pdf > 0.0 {
            pdf
        } else {
            0.0
        }
    }
}

impl BxdfSampler for RglSampler {
    fn name(&self) -> &str {
        "rgl"
    }

    /// s = luminance warp of u, u_m = vndf warp of s, ω_m from
    /// (θ_m = u_θ² π/2, φ_m = 2π u_φ − π + φ(wo)), wi = 2 (wo·ω_m) ω_m − wo,
    /// with density p_vndf(u_m) p_lum(s) / J.
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        let incident = self.brdf.incident(wo)?;
        let u = DVec2::new(clamp_unit(u.x) as f64, clamp_unit(u.y) as f64);
        let (s, _) = self.brdf.luminance_density().at(incident.blend).sample(u);
        let (u_m, _) = self.brdf.vndf().at(incident.blend).sample(s);
        let wm = self.brdf.microfacet_normal(&incident, u_m);
        let cos_d = incident.w.dot(wm);
        let wi = (2.0 * cos_d * wm - incident.w).normalize_or_zero();
        // normalize_or_zero keeps wi finite, so this also catches the zero vector.
        if wi.z <= 0.0 {
            return None;
        }
        let wi = wi.as_vec3();
        // The density is re-evaluated at the f32 direction handed out, so
        // that it equals `pdf(wo, wi)` exactly: near θ_m = 0 the density
        // varies like sqrt(θ_m), and rounding wi to f32 moves θ_m by ~1e-7.
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0 && wi.z > 0.0).then_some(BxdfSample { wi, pdf })
    }

    /// p(wi | wo) = p_vndf(u_m) p_lum(s) / J (see the crate documentation);
    /// 0 for invalid or below-horizon directions.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !is_valid_outgoing(wo) {
            return 0.0;
        }
        let p = self.pdf_f64(wo, wi) as f32;
        if p.is_finite() {
            p
        } else {
            f32::MAX
        }
    }

    /// The tables are the material's; the sampler adds none of its own but
    /// reports the vndf and luminance tables it reads.
    fn storage_bytes(&self) -> usize {
        self.brdf.vndf().storage_bytes() + self.brdf.luminance_density().storage_bytes()
    }
}

#[cfg(test)]
mod tests;
