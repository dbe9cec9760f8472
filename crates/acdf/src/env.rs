//! Distant environment lights: the procedural sky with a sun that every
//! experiment uses by default, and latitude-longitude maps read from `.exr`
//! or `.hdr` files.
//!
//! World space has `+y` up. The renderer's camera looks down `-z`, so the sun
//! is placed in front of the sphere (`+z`) and above it, where its highlight
//! is visible.

use std::f32::consts::PI;
use std::path::Path;

use acdf_core::{Rgb, Vec3};

use crate::error::{Error, Result};

/// Radiance arriving from a direction at infinity.
pub trait Environment: Send + Sync {
    /// L(ω) in linear Rec. 709 RGB for the unit world direction `dir` (the
    /// direction towards the light, away from the shaded point). Finite and
    /// non-negative for every input.
    fn radiance(&self, dir: Vec3) -> Rgb;
}

/// A clear sky with a sun: a sky dome blending from `horizon` to `zenith`
/// with the square root of the elevation's sine, a uniform ground below the
/// horizon, and a sun disk of constant radiance.
#[derive(Debug, Clone, PartialEq)]
pub struct Sky {
    /// Unit direction towards the sun's centre.
    pub sun_direction: Vec3,
    /// Angular radius of the sun disk in radians.
    pub sun_radius: f32,
    /// Radiance of every direction inside the sun disk.
    pub sun_radiance: Rgb,
    /// Sky radiance straight up.
    pub zenith: Rgb,
    /// Sky radiance at the horizon.
    pub horizon: Rgb,
    /// Radiance of every direction below the horizon.
    pub ground: Rgb,
}

impl Sky {
    /// The environment of every efficiency measurement (`acdf report`,
    /// `acdf sweep`): the default sky without its sun.
    ///
    /// A small, very bright sun dominates the variance of any BRDF-only
    /// estimator, whatever the sampler: on built-in nickel under the default
    /// sky, uniform and Douglas-Peucker samplers at every tolerance of the
    /// sweep measured the same variance to 0.1% (0.5734 against 0.5736,
    /// `acdf sweep --material builtin:nickel` with the sun), so efficiency
    /// would measure only time. A renderer samples such a sun from the light
    /// side; what the BRDF sampler must follow is the BRDF times the smooth
    /// dome, and that is what this environment measures.
    pub fn dome() -> Sky {
        Sky {
            sun_radiance: Rgb::ZERO,
            ..Sky::default()
        }
    }
}

impl Default for Sky {
    /// The fixed sky of all acdf experiments: a 5° sun at about 33° of
    /// elevation, in front of and to the right of the camera, whose disk
    /// carries roughly as much irradiance as the whole blue dome.
    fn default() -> Sky {
        Sky {
            sun_direction: Vec3::new(0.45, 0.55, 0.7).normalize(),
            sun_radius: 5.0f32.to_radians(),
            sun_radiance: Vec3::new(1.0, 0.92, 0.8) * 50.0,
            zenith: Vec3::new(0.25, 0.42, 0.85),
            horizon: Vec3::new(0.85, 0.9, 1.0),
            ground: Vec3::new(0.22, 0.2, 0.18),
        }
    }
}

impl Environment for Sky {
    /// L(ω) = sun radiance if ω·s ≥ cos r; otherwise, above the horizon,
    /// horizon + (zenith − horizon)·sqrt(ω_y); below it, the ground.
    fn radiance(&self, dir: Vec3) -> Rgb {
        if !dir.is_finite() {
            return Vec3::ZERO;
        }
        let dir = dir.normalize_or_zero();
        if dir.dot(self.sun_direction) >= self.sun_radius.cos() {
            return self.sun_radiance;
        }
        if dir.y >= 0.0 {
            self.horizon.lerp(self.zenith, dir.y.sqrt())
        } else {
            self.ground
        }
    }
}

/// An equirectangular (latitude-longitude) environment map: column u covers
/// the azimuth φ = atan2(x, −z) from −π to π, row v the polar angle
/// θ = acos(y) from 0 (up) to π (down).
#[derive(Debug, Clone)]
pub struct EnvMap {
    width: usize,
    height: usize,
    texels: Vec<Rgb>,
}

impl EnvMap {
    /// Build a map from row-major texels; non-finite and negative values are
    /// set to 0 so that no NaN reaches an estimate.
    pub fn from_texels(width: usize, height: usize, mut texels: Vec<Rgb>) -> Result<EnvMap> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return Err(Error::InvalidArgument {
                what: "environment map",
                value: format!("{width}x{height}"),
                reason: format!("expected {} texels, got {}", width * height, texels.len()),
            });
        }
        for t in &mut texels {
            *t = Vec3::new(sanitise(t.x), sanitise(t.y), sanitise(t.z));
        }
        Ok(EnvMap {
            width,
            height,
            texels,
        })
    }

    /// Read a lat-long `.exr` or `.hdr` file through
    /// [`acdf_lights::EnvMap::open_repaired`]: the same decoding and
    /// checks as the environment samplers' maps (typed errors for files
    /// that cannot be decoded or are not twice as wide as high), with NaN,
    /// infinite and negative values set to 0 as [`from_texels`](Self::from_texels)
    /// does. The texels are read in their own convention and looked up in
    /// this type's (see the type's documentation).
    pub fn open(path: &Path) -> Result<EnvMap> {
        let (map, _) = acdf_lights::EnvMap::open_repaired(path)?;
        let (w, h) = map.size();
        EnvMap::from_texels(w, h, map.texels().to_vec())
    }

    /// Width and height in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
}

fn sanitise(x: f32) -> f32 {
    if x.is_finite() && x > 0.0 {
        x
    } else {
        0.0
    }
}

impl Environment for EnvMap {
    /// The nearest texel to (u, v) = (φ/2π + 1/2, θ/π).
    fn radiance(&self, dir: Vec3) -> Rgb {
        let dir = dir.normalize_or_zero();
        if dir == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let u = 0.5 + dir.x.atan2(-dir.z) / (2.0 * PI);
        let v = dir.y.clamp(-1.0, 1.0).acos() / PI;
        let col = ((u * self.width as f32) as usize).min(self.width - 1);
        let row = ((v * self.height as f32) as usize).min(self.height - 1);
        self.texels[row * self.width + col]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sky_is_bright_in_the_sun_and_finite_everywhere() {
        let sky = Sky::default();
        assert_eq!(sky.radiance(sky.sun_direction), sky.sun_radiance);
        assert_eq!(sky.radiance(-Vec3::Y), sky.ground);
        assert!((sky.radiance(Vec3::Y) - sky.zenith).length() < 1e-6);
        assert_eq!(sky.radiance(Vec3::NAN), Vec3::ZERO);
        assert_eq!(sky.radiance(Vec3::ZERO), sky.horizon);
    }

    #[test]
    fn envmap_looks_up_up_and_down_rows() {
        let texels = vec![
            Vec3::ONE,
            Vec3::ONE,
            Vec3::ZERO,
            Vec3::new(f32::NAN, -1.0, 2.0),
        ];
        let map = EnvMap::from_texels(2, 2, texels).unwrap();
        assert_eq!(map.radiance(Vec3::Y), Vec3::ONE);
        let down = map.radiance(Vec3::new(0.01, -1.0, 0.0));
        assert!(down.is_finite() && down.min_element() >= 0.0);
        assert!(EnvMap::from_texels(2, 2, vec![Vec3::ONE]).is_err());
    }
}
