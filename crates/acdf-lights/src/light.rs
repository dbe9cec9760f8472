//! An environment map as a [`Light`]: its radiance, and any sphere sampler
//! for the directions.

use std::sync::Arc;

use acdf_core::{Light, LightSample, Rgb, SphereSampler, Vec2, Vec3};

use crate::envmap::EnvMap;

/// An environment map lit from infinity, sampled by `S`.
///
/// The radiance is the nearest-texel lookup ([`EnvMap::radiance`]), the
/// function the samplers' tables follow, so that L / pdf is as flat as the
/// sampler makes it. For multiple importance sampling, build `S` from the
/// compensated table ([`TableKind::Compensated`](crate::TableKind)) and
/// weigh BRDF-sampled directions with [`Light::pdf`].
#[derive(Debug, Clone)]
pub struct EnvironmentLight<S> {
    map: Arc<EnvMap>,
    sampler: S,
}

impl<S: SphereSampler> EnvironmentLight<S> {
    /// The light of `map`, sampled by `sampler` (built for the same map).
    pub fn new(map: Arc<EnvMap>, sampler: S) -> Self {
        EnvironmentLight { map, sampler }
    }

    /// The map.
    pub fn map(&self) -> &EnvMap {
        &self.map
    }

    /// The sampler.
    pub fn sampler(&self) -> &S {
        &self.sampler
    }
}

impl<S: SphereSampler> Light for EnvironmentLight<S> {
    fn radiance(&self, dir: Vec3) -> Rgb {
        self.map.radiance(dir)
    }

    fn sample(&self, normal: Option<Vec3>, u: Vec2) -> Option<LightSample> {
        let s = self.sampler.sample(normal, u)?;
        Some(LightSample {
            dir: s.dir,
            pdf: s.pdf,
            radiance: self.map.radiance(s.dir),
        })
    }

    fn pdf(&self, normal: Option<Vec3>, dir: Vec3) -> f32 {
        self.sampler.pdf(normal, dir)
    }
}
