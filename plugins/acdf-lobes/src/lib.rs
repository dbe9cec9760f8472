//! `acdf-lobes` is the small end of acdf's samplers: per material, a mixture
//! of one cosine (diffuse) lobe and up to three GGX lobes about the normal,
//! with their weights, fitted to the material's f_r cos θ_i so as to
//! minimise the variance of the one-sample estimator of ∫ f_r cos θ_i dω_i
//! (the chi-square divergence between f_r cos θ_i, normalised per outgoing
//! direction, and the mixture's density; see [`mod@fit`]). The whole sampler is
//! [`STORAGE_BYTES`] bytes of parameters, its sampling and its density are
//! analytic and exact, and it is saved and loaded like the tabulated
//! samplers ([`persist`]). Where a material is not shaped like its lobes
//! (the mirror-like metals, a narrow peak on a broad halo) it samples much
//! worse than a table, but it never misses light: its cosine lobe keeps at
//! least [`MIN_DIFFUSE`] of the draws, which makes it the natural defensive
//! partner of the tables.
//!
//! Each GGX lobe draws the half vector h from the distribution of visible
//! normals seen from wo, D_wo(h) = G1(wo) max(0, wo·h) D(h) / cos θ_o, and
//! reflects wo about it; with the Jacobian 1 / (4 wo·h) of the reflection,
//! the density of wi is G1(wo) D(h) / (4 cos θ_o), in which wo·h cancels.
//! Draws that the reflection sends below the horizon fail (`None`); their
//! share is the mass the density does not cover.

#![forbid(unsafe_code)]
// `!(x > 0.0)` is how this crate says "not positive, or NaN": the negated
// comparison is the point, since NaN must take the rejecting branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod fit;
pub mod persist;
#[cfg(test)]
mod tests;

use acdf_core::geometry::reflect;
use acdf_core::warp::square_to_cosine_hemisphere;
use acdf_core::{
    clamp_unit, is_valid_outgoing, BxdfSample, BxdfSampler, Error, Result, Vec2, Vec3,
    ONE_MINUS_EPSILON,
};
use acdf_tabulated::persist::StoredMaterial;
use std::f32::consts::{FRAC_1_PI, TAU};

pub use fit::{fit, fit_with, objective, Fit, FitOptions};

/// The most GGX lobes a mixture has.
pub const MAX_LOBES: usize = 3;

/// The smallest weight of the cosine lobe. It makes the density at least
/// `MIN_DIFFUSE cos θ_i / π` wherever the material reflects light, so no
/// light is ever missed (a GGX lobe of small roughness underflows to 0 in
/// `f32` far from its peak) and every weight f_r cos θ_i / p is bounded by
/// π f_r / `MIN_DIFFUSE` (defensive importance sampling); it costs at most a
/// factor 1 / (1 − `MIN_DIFFUSE`) in variance where the lobes fit perfectly.
pub const MIN_DIFFUSE: f32 = 0.01;

/// The smallest GGX roughness α a lobe may have: the peak density
/// 1 / (π α²) stays far inside `f32`, and the quadrature of the fit still
/// resolves the lobe.
pub const ALPHA_MIN: f32 = 1e-3;

/// The largest GGX roughness α a lobe may have.
pub const ALPHA_MAX: f32 = 1.5;

/// How far the stored weights may sum from 1 (they are `f32`).
const WEIGHT_SUM_TOLERANCE: f32 = 1e-4;

/// The parameters of a mixture: everything a lobes sampler stores.
///
/// The cosine lobe has weight `diffuse`; GGX lobe k < `count` has weight
/// `weights[k]` and roughness `alphas[k]`; the slots past `count` are 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lobes {
    count: u32,
    diffuse: f32,
    weights: [f32; MAX_LOBES],
    alphas: [f32; MAX_LOBES],
}

/// The bytes a lobes sampler stores: its [`Lobes`], a lobe count (u32), the
/// cosine lobe's weight and three (weight, roughness) pairs as `f32`.
pub const STORAGE_BYTES: usize = std::mem::size_of::<Lobes>();

impl Lobes {
    /// A mixture of a cosine lobe of weight `diffuse` and the GGX lobes
    /// `(weight, alpha)` of `lobes`. Every value must be finite, there must
    /// be at most [`MAX_LOBES`] lobes (none: cosine sampling, for a matte
    /// material no GGX lobe improves), `diffuse` at least [`MIN_DIFFUSE`], every
    /// weight non-negative, every α in [[`ALPHA_MIN`], [`ALPHA_MAX`]], and the
    /// weights must sum to 1 (to 1e-4).
    pub fn new(diffuse: f32, lobes: &[(f32, f32)]) -> Result<Lobes> {
        let invalid = |name, reason: String| Err(Error::InvalidParameter { name, reason });
        if lobes.len() > MAX_LOBES {
            return invalid(
                "lobes",
                format!("{} GGX lobes, not 0 to {MAX_LOBES}", lobes.len()),
            );
        }
        let values = std::iter::once(diffuse).chain(lobes.iter().flat_map(|&(w, a)| [w, a]));
        for (index, value) in values.enumerate() {
            if !value.is_finite() {
                return Err(Error::NonFinite {
                    what: "lobe parameters",
                    index,
                    value: value as f64,
                });
            }
        }
        if !(diffuse >= MIN_DIFFUSE) {
            return invalid(
                "diffuse weight",
                format!("{diffuse} is below the minimum {MIN_DIFFUSE}"),
            );
        }
        let mut out = Lobes {
            count: lobes.len() as u32,
            diffuse,
            weights: [0.0; MAX_LOBES],
            alphas: [0.0; MAX_LOBES],
        };
        for (k, &(weight, alpha)) in lobes.iter().enumerate() {
            if !(weight >= 0.0) {
                return invalid("lobe weight", format!("{weight} is negative"));
            }
            if !(ALPHA_MIN..=ALPHA_MAX).contains(&alpha) {
                return invalid(
                    "lobe roughness",
                    format!("α = {alpha} is outside [{ALPHA_MIN}, {ALPHA_MAX}]"),
                );
            }
            out.weights[k] = weight;
            out.alphas[k] = alpha;
        }
        let sum: f32 = diffuse + out.weights.iter().sum::<f32>();
        if !((sum - 1.0).abs() <= WEIGHT_SUM_TOLERANCE) {
            return invalid("lobe weights", format!("they sum to {sum}, not 1"));
        }
        Ok(out)
    }

    /// The cosine lobe's weight.
    pub fn diffuse(&self) -> f32 {
        self.diffuse
    }

    /// The GGX lobes as (weight, α).
    pub fn lobes(&self) -> impl Iterator<Item = (f32, f32)> + '_ {
        let n = self.count as usize;
        self.weights[..n]
            .iter()
            .copied()
            .zip(self.alphas[..n].iter().copied())
    }

    /// The number of GGX lobes.
    pub fn count(&self) -> usize {
        self.count as usize
    }
}

/// A [`Lobes`] ready to sample: the probability of drawing each component
/// (the cosine lobe first) and the squared roughness of each GGX lobe,
/// derived from the stored parameters alone, so a saved and loaded mixture
/// draws the same bits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mixture {
    lobes: Lobes,
    /// Upper ends of the components' intervals of u.x, the last exactly 1.
    cumulative: [f32; MAX_LOBES + 1],
    /// The probability of each component: differences of `cumulative`.
    probability: [f32; MAX_LOBES + 1],
    alpha2: [f32; MAX_LOBES],
}

impl Mixture {
    /// The mixture of `lobes`: component k is drawn with the probability
    /// its weight gives, the last taking what the `f32` sums leave of 1
    /// (the sums capped at 1, so that no probability is negative when the
    /// weights sum to a little more).
    pub fn new(lobes: Lobes) -> Mixture {
        let n = lobes.count();
        let mut cumulative = [1.0f32; MAX_LOBES + 1];
        let mut probability = [0.0f32; MAX_LOBES + 1];
        let mut sum = lobes.diffuse.min(1.0);
        cumulative[0] = sum;
        for k in 0..n {
            sum = (sum + lobes.weights[k]).min(1.0);
            cumulative[k + 1] = sum;
        }
        cumulative[n] = 1.0;
        let mut low = 0.0;
        for k in 0..=n {
            probability[k] = cumulative[k] - low;
            low = cumulative[k];
        }
        let alpha2 = lobes.alphas.map(|a| a * a);
        Mixture {
            lobes,
            cumulative,
            probability,
            alpha2,
        }
    }

    /// The parameters.
    pub fn lobes(&self) -> &Lobes {
        &self.lobes
    }

    /// The component u picks (0 the cosine lobe, k the GGX lobe k − 1) and
    /// u rescaled to [0, 1) within the component's interval.
    #[inline]
    fn pick(&self, u: f32) -> (usize, f32) {
        let n = self.lobes.count();
        let mut low = 0.0;
        for k in 0..n {
            if u < self.cumulative[k] {
                return (k, self.rescale(u, low, k));
            }
            low = self.cumulative[k];
        }
        (n, self.rescale(u, low, n))
    }

    #[inline]
    fn rescale(&self, u: f32, low: f32, k: usize) -> f32 {
        let p = self.probability[k];
        if p > 0.0 {
            ((u - low) / p).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.0
        }
    }
}

/// The density of wi under GGX lobe α² when its half vectors are drawn
/// from the visible normals of wo: G1(wo) D(h) / (4 cos θ_o), written
/// as D(h) / (2 (cos θ_o + sqrt(cos² θ_o + α² sin² θ_o))) with Smith's G1,
/// and D = α² / (π (α² cos² θ_h + sin² θ_h)²) taken from the unnormalised
/// h = wo + wi, whose length cancels: no wo·h, no normalisation, nothing
/// that loses its digits at grazing angles.
#[inline(always)]
fn visible_ggx_pdf(alpha2: f32, h: Vec3, cos_o: f32, sin2_o: f32) -> f32 {
    let t = alpha2 * h.z * h.z + h.x * h.x + h.y * h.y;
    if !(t > 0.0) {
        return 0.0;
    }
    let r = h.length_squared() / t;
    let d = alpha2 * r * r * FRAC_1_PI;
    d / (2.0 * (cos_o + (cos_o * cos_o + alpha2 * sin2_o).sqrt()))
}

/// Draw a half vector from GGX's visible normals seen from wo and reflect
/// wo about it: in the configuration stretched by 1/α the visible normals
/// of the unit hemisphere are c + s, c uniform on the spherical cap
/// z > −s.z of the unit sphere and s the stretched wo; stretching back by α
/// gives h. `None` when h or wi falls on or below the horizon.
#[inline(always)]
fn sample_visible_ggx(wo: Vec3, alpha: f32, u: Vec2) -> Option<Vec3> {
    let s = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let phi = TAU * u.x;
    // The cap's height z runs from 1 down to −s.z; m.z = z + s.z.
    let m_z = (1.0 - u.y) * (1.0 + s.z);
    let z = m_z - s.z;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sin_phi, cos_phi) = phi.sin_cos();
    let m = Vec3::new(r * cos_phi + s.x, r * sin_phi + s.y, m_z);
    let h = Vec3::new(alpha * m.x, alpha * m.y, m.z).try_normalize()?;
    if !(h.z > 0.0) {
        return None;
    }
    let wi = reflect(wo, h).try_normalize()?;
    (wi.z > 0.0).then_some(wi)
}

impl BxdfSampler for Mixture {
    fn name(&self) -> &str {
        persist::KIND
    }

    /// Pick a component with u.x, draw from it with u.x rescaled and u.y,
    /// and return the mixture's density of the draw.
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        if self.lobes.count() == 0 {
            // Cosine sampling alone: the same bits as the general path
            // (its one component has probability 1), without the pick and
            // the mixture's sum.
            let wi = square_to_cosine_hemisphere(Vec2::new(clamp_unit(u.x), clamp_unit(u.y)));
            let pdf = wi.z * FRAC_1_PI;
            return (pdf > 0.0).then_some(BxdfSample { wi, pdf });
        }
        let (k, v) = self.pick(clamp_unit(u.x));
        let u = Vec2::new(v, clamp_unit(u.y));
        let wi = if k == 0 {
            square_to_cosine_hemisphere(u)
        } else {
            sample_visible_ggx(wo, self.lobes.alphas[k - 1], u)?
        };
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0 && pdf.is_finite()).then_some(BxdfSample { wi, pdf })
    }

    /// p(wi) = w_d cos θ_i / π + Σ_k w_k G1_k(wo) D_k(h) / (4 cos θ_o) for
    /// wi above the horizon, else 0.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !is_valid_outgoing(wo) || !(wi.z > 0.0) || !wi.is_finite() {
            return 0.0;
        }
        let mut p = self.probability[0] * wi.z * FRAC_1_PI;
        if self.lobes.count() == 0 {
            return p;
        }
        let h = wo + wi;
        let sin2_o = wo.x * wo.x + wo.y * wo.y;
        for k in 0..self.lobes.count() {
            p += self.probability[k + 1] * visible_ggx_pdf(self.alpha2[k], h, wo.z, sin2_o);
        }
        p
    }

    fn storage_bytes(&self) -> usize {
        STORAGE_BYTES
    }
}

/// The fitted-lobe sampler of one material: a [`Mixture`] and the material
/// it was fitted to (its name and fingerprint, which a loaded file is
/// checked against).
#[derive(Debug, Clone)]
pub struct LobesSampler {
    mixture: Mixture,
    material: StoredMaterial,
}

impl LobesSampler {
    /// Fit a mixture to `brdf` ([`fit()`]).
    pub fn new(brdf: &dyn acdf_core::Brdf) -> Result<LobesSampler> {
        Ok(LobesSampler::from_lobes(
            fit(brdf)?,
            StoredMaterial {
                name: brdf.name().to_string(),
                isotropic: brdf.is_isotropic(),
                fingerprint: brdf.fingerprint(),
            },
        ))
    }

    /// The sampler of given lobes for `material`.
    pub fn from_lobes(lobes: Lobes, material: StoredMaterial) -> LobesSampler {
        LobesSampler {
            mixture: Mixture::new(lobes),
            material,
        }
    }

    /// The parameters.
    pub fn lobes(&self) -> &Lobes {
        self.mixture.lobes()
    }

    /// The material the mixture was fitted to.
    pub fn material(&self) -> &StoredMaterial {
        &self.material
    }
}

impl BxdfSampler for LobesSampler {
    fn name(&self) -> &str {
        persist::KIND
    }
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        self.mixture.sample(wo, u)
    }
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.mixture.pdf(wo, wi)
    }
    fn storage_bytes(&self) -> usize {
        STORAGE_BYTES
    }
}
