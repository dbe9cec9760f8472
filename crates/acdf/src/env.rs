//! The procedural sky with a sun that the efficiency experiments use
//! (`acdf report`, `sweep`, `survey`, `build --target-efficiency`), in
//! their frame with `+y` up. `acdf render` bakes it into a map in the
//! environment maps' convention (`+z` up, [`acdf_lights::latlong`]); maps
//! read from files are `acdf_lights::EnvMap`.

use acdf_core::{Rgb, Vec3};

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
}
