//! The interface of light sources at infinity and of the samplers that
//! draw directions over the whole sphere for them.
//!
//! A BRDF sampler draws an incident direction from the material's side; a
//! [`SphereSampler`] draws it from the light's side: a direction anywhere on
//! the unit sphere, in the light's own frame, optionally knowing the
//! shading normal it will be used for (an orientation-aware sampler then
//! follows L(ω) max(0, n·ω) instead of L(ω) alone). A [`Light`] pairs the
//! radiance L(ω) with such a sampler; a renderer combining light and BRDF
//! sampling (multiple importance sampling) needs exactly these three
//! operations: radiance by direction, sample, and pdf.
//!
//! The contract every sphere sampler keeps, checked by the conformance
//! battery:
//! - `normal` is `None` or a unit vector in the light's frame; a normal
//!   that is not finite or has no length acts as `None`
//!   ([`usable_normal`]).
//! - `u` outside [0, 1)^2 is mapped by [`clamp_unit`](crate::clamp_unit).
//! - A returned sample has a unit, finite `dir` and a finite pdf > 0 that
//!   equals `pdf(normal, dir)`. `None` is a draw the sampler cannot make
//!   (its probability is the mass the pdf does not cover, so ∫ pdf ≤ 1).
//! - `pdf` is per unit solid angle, finite and non-negative for every
//!   input (0 for a direction that is not finite or has no length).
//! - The batch forms return exactly what the single calls return.

use crate::Rgb;
use glam::{Vec2, Vec3};

/// A direction drawn over the sphere and its solid-angle density.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereSample {
    pub dir: Vec3,
    pub pdf: f32,
}

/// The normal a sampler should use: `normal` when it is finite and has a
/// length (normalised), `None` otherwise.
#[inline]
pub fn usable_normal(normal: Option<Vec3>) -> Option<Vec3> {
    let n = normal?;
    let len2 = n.length_squared();
    (len2.is_finite() && len2 > 0.0).then(|| n / len2.sqrt())
}

/// Draws directions over the whole unit sphere, for a shading normal or
/// none.
pub trait SphereSampler: Send + Sync {
    /// A short name, as used on the command line (`uniform`, `adaptive:chi2`,
    /// `oriented:chi2`, ...).
    fn name(&self) -> &str;

    /// Draw a direction from the uniform pair `u`, for the shading normal
    /// `normal` (ignored by samplers that do not use it); `None` for a draw
    /// the sampler cannot make.
    fn sample(&self, normal: Option<Vec3>, u: Vec2) -> Option<SphereSample>;

    /// The solid-angle density with which [`sample`](Self::sample) draws
    /// `dir` for `normal`.
    fn pdf(&self, normal: Option<Vec3>, dir: Vec3) -> f32;

    /// Heap bytes held by the sampler's tables (what is built so far, for
    /// samplers that build on first use).
    fn storage_bytes(&self) -> usize;

    /// Sample many `u` for one normal: `out[k] = sample(normal, u[k])` for
    /// every `k` below the shorter of the two lengths.
    fn sample_batch(&self, normal: Option<Vec3>, u: &[Vec2], out: &mut [Option<SphereSample>]) {
        for (o, &u) in out.iter_mut().zip(u) {
            *o = self.sample(normal, u);
        }
    }

    /// Densities of many directions for one normal: `out[k] = pdf(normal,
    /// dir[k])` for every `k` below the shorter of the two lengths.
    fn pdf_batch(&self, normal: Option<Vec3>, dir: &[Vec3], out: &mut [f32]) {
        for (o, &d) in out.iter_mut().zip(dir) {
            *o = self.pdf(normal, d);
        }
    }
}

/// The sampler behind a pointer is a sampler: `Box`, `&` and `Arc`.
macro_rules! forward_sphere_sampler {
    ($($ptr:ty),+) => {$(
        impl<T: SphereSampler + ?Sized> SphereSampler for $ptr {
            fn name(&self) -> &str {
                (**self).name()
            }
            fn sample(&self, normal: Option<Vec3>, u: Vec2) -> Option<SphereSample> {
                (**self).sample(normal, u)
            }
            fn pdf(&self, normal: Option<Vec3>, dir: Vec3) -> f32 {
                (**self).pdf(normal, dir)
            }
            fn storage_bytes(&self) -> usize {
                (**self).storage_bytes()
            }
            fn sample_batch(
                &self,
                normal: Option<Vec3>,
                u: &[Vec2],
                out: &mut [Option<SphereSample>],
            ) {
                (**self).sample_batch(normal, u, out)
            }
            fn pdf_batch(&self, normal: Option<Vec3>, dir: &[Vec3], out: &mut [f32]) {
                (**self).pdf_batch(normal, dir, out)
            }
        }
    )+};
}

forward_sphere_sampler!(Box<T>, &T, std::sync::Arc<T>);

/// A direction drawn towards a light, with its density and the radiance
/// arriving from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightSample {
    /// Unit direction towards the light, in the light's frame.
    pub dir: Vec3,
    /// Solid-angle density of `dir`, as [`Light::pdf`] gives it.
    pub pdf: f32,
    /// L(dir) in linear Rec. 709 RGB, as [`Light::radiance`] gives it.
    pub radiance: Rgb,
}

/// A light at infinity: radiance by direction, and a sampler of directions
/// towards it.
///
/// Directions are in the light's frame (for an environment map, the frame
/// of its latitude-longitude convention) and point away from the shaded
/// point, towards the light.
pub trait Light: Send + Sync {
    /// L(dir) in linear Rec. 709 RGB; finite and non-negative for every
    /// input (0 for a direction that is not finite or has no length).
    fn radiance(&self, dir: Vec3) -> Rgb;

    /// Draw a direction towards the light for the shading normal `normal`
    /// (or none), with its pdf and radiance.
    fn sample(&self, normal: Option<Vec3>, u: Vec2) -> Option<LightSample>;

    /// The solid-angle density with which [`sample`](Self::sample) draws
    /// `dir` for `normal`: what multiple importance sampling weighs a
    /// direction found by BRDF sampling with.
    fn pdf(&self, normal: Option<Vec3>, dir: Vec3) -> f32;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unusable_normals_act_as_none() {
        assert_eq!(usable_normal(None), None);
        assert_eq!(usable_normal(Some(Vec3::ZERO)), None);
        assert_eq!(usable_normal(Some(Vec3::new(f32::NAN, 0.0, 1.0))), None);
        assert_eq!(
            usable_normal(Some(Vec3::new(f32::INFINITY, 0.0, 1.0))),
            None
        );
        let n = usable_normal(Some(Vec3::new(0.0, 0.0, 2.0))).unwrap();
        assert_eq!(n, Vec3::Z);
    }
}
