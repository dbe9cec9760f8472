//! The interface of BRDF samplers: draw an incident direction for a given
//! outgoing one, and report the density of any pair.
//!
//! The contract every sampler keeps, checked by the conformance battery:
//! - `wo` must be a unit vector strictly above the horizon (`wo.z > 0`); for
//!   any other `wo` (at or below the horizon, or not finite) `sample` returns
//!   `None` and `pdf` returns 0. See [`is_valid_outgoing`].
//! - `u` outside [0, 1)^2 is mapped by [`clamp_unit`](crate::clamp_unit).
//! - A returned sample has `wi.z > 0`, a unit `wi`, and a finite pdf > 0 that
//!   equals `pdf(wo, wi)`. A draw that would land at or below the horizon is
//!   `None`; its probability is the mass the pdf does not cover, so ∫ pdf ≤ 1.
//! - `pdf` is finite and non-negative for every input, and 0 for `wi.z <= 0`.

use crate::Brdf;
use glam::{Vec2, Vec3};

/// A sampled incident direction and its solid-angle density.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BxdfSample {
    pub wi: Vec3,
    pub pdf: f32,
}

/// Whether `wo` is an outgoing direction samplers accept: finite and strictly
/// above the horizon.
#[inline(always)]
pub fn is_valid_outgoing(wo: Vec3) -> bool {
    // 0 · w is ±0 for every finite w and NaN for an infinity or NaN, so
    // one compare of the sum tests all three components: every `sample`
    // and `pdf` starts here.
    wo.z > 0.0 && (wo * 0.0).element_sum() == 0.0
}

/// Draws incident directions for a given outgoing direction.
pub trait BxdfSampler: Send + Sync {
    /// A short name, as used on the command line (`cosine`, `uniform`, ...).
    fn name(&self) -> &str;

    /// Draw wi for the given wo from the uniform pair `u`; `None` when the
    /// draw falls at or below the horizon or `wo` is not valid.
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample>;

    /// The solid-angle density with which [`sample`](Self::sample) draws `wi`
    /// given `wo`.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32;

    /// Heap bytes held by the sampler's tables (what is built so far, for
    /// samplers that build on first use).
    fn storage_bytes(&self) -> usize;

    /// Sample many `u` for one `wo`: `out[k] = sample(wo, u[k])` for every
    /// `k` below the shorter of the two lengths. Fast samplers override it.
    fn sample_batch(&self, wo: Vec3, u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        for (o, &u) in out.iter_mut().zip(u) {
            *o = self.sample(wo, u);
        }
    }

    /// Densities of many `wi` for one `wo`: `out[k] = pdf(wo, wi[k])` for every
    /// `k` below the shorter of the two lengths.
    fn pdf_batch(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
        for (o, &wi) in out.iter_mut().zip(wi) {
            *o = self.pdf(wo, wi);
        }
    }

    /// Sample many (wo, u) pairs, each with its own outgoing direction (a
    /// wavefront renderer's batch of shading points): `out[k] =
    /// sample(wo[k], u[k])` for every `k` below the shortest length. Fast
    /// samplers override it to overlap the draws.
    fn sample_each(&self, wo: &[Vec3], u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        for ((o, &wo), &u) in out.iter_mut().zip(wo).zip(u) {
            *o = self.sample(wo, u);
        }
    }

    /// Densities of many (wo, wi) pairs: `out[k] = pdf(wo[k], wi[k])` for
    /// every `k` below the shortest length.
    fn pdf_each(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
        for ((o, &wo), &wi) in out.iter_mut().zip(wo).zip(wi) {
            *o = self.pdf(wo, wi);
        }
    }
}

impl<T: BxdfSampler + ?Sized> BxdfSampler for Box<T> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        (**self).sample(wo, u)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        (**self).pdf(wo, wi)
    }
    fn storage_bytes(&self) -> usize {
        (**self).storage_bytes()
    }
    fn sample_batch(&self, wo: Vec3, u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        (**self).sample_batch(wo, u, out)
    }
    fn pdf_batch(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
        (**self).pdf_batch(wo, wi, out)
    }
    fn sample_each(&self, wo: &[Vec3], u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        (**self).sample_each(wo, u, out)
    }
    fn pdf_each(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
        (**self).pdf_each(wo, wi, out)
    }
}

/// How much of the light reflected towards one `wo` a sampler can never
/// draw: the result of [`missed_share`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissedShare {
    /// ∫_{p = 0} Y(f) cos θ_i dω / ∫ Y(f) cos θ_i dω; 0 when the BRDF
    /// reflects nothing at wo.
    pub share: f64,
    /// The incident direction of the largest missed term, if any.
    pub worst: Option<Vec3>,
}

/// The share of the reflected luminance that `sampler` can never draw at
/// `wo`, ∫_{p = 0} Y(f) cos θ_i dω / ∫ Y(f) cos θ_i dω over the upper
/// hemisphere (f = `brdf.eval`, p = `sampler.pdf`, Y the luminance), by the
/// midpoint rule on `n_cos` × `n_phi` cells of equal solid angle (equal
/// steps in cos θ_i and φ_i, each evaluated at its centre).
///
/// An unbiased estimator of the light reflected towards wo needs p > 0
/// wherever f cos θ_i > 0: the share is the fraction by which a sampler
/// used alone is biased dark, whatever the sample count, and neither a
/// chi-square test nor the integral of the pdf sees it (sample and pdf
/// still agree). Deterministic: the cells are summed in a fixed order.
pub fn missed_share(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    wo: Vec3,
    n_cos: usize,
    n_phi: usize,
) -> MissedShare {
    let (n_cos, n_phi) = (n_cos.max(1), n_phi.max(1));
    let (mut all, mut missed) = (0.0f64, 0.0f64);
    let mut worst: Option<(f64, Vec3)> = None;
    let mut wi = vec![Vec3::ZERO; n_phi];
    let mut pdf = vec![0.0f32; n_phi];
    for k in 0..n_cos {
        let cos_t = (k as f64 + 0.5) / n_cos as f64;
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        for (l, w) in wi.iter_mut().enumerate() {
            let phi = std::f64::consts::TAU * (l as f64 + 0.5) / n_phi as f64;
            *w = Vec3::new(
                (sin_t * phi.cos()) as f32,
                (sin_t * phi.sin()) as f32,
                cos_t as f32,
            );
        }
        sampler.pdf_batch(wo, &wi, &mut pdf);
        for (&wi, &p) in wi.iter().zip(&pdf) {
            let g = brdf.luminance(wo, wi) as f64 * wi.z as f64;
            if !(g.is_finite() && g > 0.0) {
                continue;
            }
            all += g;
            // A NaN density draws nothing either.
            let drawable = p > 0.0;
            if !drawable {
                missed += g;
                if worst.is_none_or(|(largest, _)| g > largest) {
                    worst = Some((g, wi));
                }
            }
        }
    }
    MissedShare {
        share: if all > 0.0 { missed / all } else { 0.0 },
        worst: worst.map(|(_, wi)| wi),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every component is tested for infinity and NaN, and z for the
    /// horizon; finite directions above it pass whatever their length.
    #[test]
    fn outgoing_directions_are_finite_and_above_the_horizon() {
        let bad = [f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        for b in bad {
            assert!(!is_valid_outgoing(Vec3::new(b, 0.0, 0.5)));
            assert!(!is_valid_outgoing(Vec3::new(0.0, b, 0.5)));
            assert!(!is_valid_outgoing(Vec3::new(0.3, 0.1, b)));
        }
        for z in [0.0, -0.0, -1e-30, -1.0] {
            assert!(!is_valid_outgoing(Vec3::new(0.0, 0.0, z)));
        }
        for wo in [
            Vec3::Z,
            Vec3::new(-0.0, 0.0, 1e-30),
            Vec3::new(3e38, -3e38, 2.0),
        ] {
            assert!(is_valid_outgoing(wo), "{wo}");
        }
    }
}
