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
//! - At the degenerate points the answer is fixed: `wi` on the horizon
//!   (`wi.z == 0`) has density 0 and is never drawn; `wi = -wo` (no half
//!   vector, possible only for a `wo` on the horizon, which is not valid)
//!   has density 0. Near them, at grazing `wo`, the density is computed from
//!   quantities that keep their digits where `wo + wi` nearly cancels (the
//!   tabulated samplers take wo·h as |wo + wi| / 2), and the battery checks
//!   the agreement of `sample` and `pdf` up to θ_o = 89.999°.
//! - `pdf(wo, wi)` looks up `wi` as given, to the last bit: a caller that
//!   normalises a direction the sampler returned before asking its density
//!   may ask for a neighbouring direction, which at grazing angles can lie
//!   in another cell of the tables.

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
