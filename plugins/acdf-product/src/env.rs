//! The environment factor: a low-resolution copy of the map's luminance,
//! built once per map, looked up bilinearly.

use acdf_core::fast::fast_atan2;
use acdf_core::{Error, Result, Vec3};
use acdf_lights::EnvMap;
use std::f32::consts::{FRAC_1_PI, TAU};

/// The map's luminance averaged (weighted by solid angle) over blocks of
/// texels: `width` × `height` texels of the map's lat-long convention
/// (`acdf_lights::latlong`), so that a lookup with the bilinear tent of
/// one low-resolution texel sees the light of every full-resolution texel
/// near it (a small sun is spread over its block, not missed between
/// lookup points).
#[derive(Debug, Clone)]
pub struct FilteredEnv {
    width: usize,
    height: usize,
    /// Mean luminance per texel, row-major, row 0 at the zenith.
    luminance: Vec<f32>,
}

impl FilteredEnv {
    /// Average `map`'s luminance down to at most `width` columns (and half
    /// as many rows), never more than the map's own; `width` must be at
    /// least 1.
    pub fn new(map: &EnvMap, width: usize) -> Result<FilteredEnv> {
        if width == 0 {
            return Err(Error::InvalidParameter {
                name: "environment width",
                reason: "must be at least 1".into(),
            });
        }
        let (w_full, h_full) = map.size();
        let width = width.min(w_full);
        let height = (width / 2).clamp(1, h_full);
        let grid = map.grid();
        let lum = map.luminance();
        let mut sum = vec![0f64; width * height];
        let mut area = vec![0f64; width * height];
        for j in 0..h_full {
            let omega = grid.texel_solid_angle(j);
            let row = j * height / h_full;
            for k in 0..w_full {
                let i = row * width + k * width / w_full;
                sum[i] += lum[j * w_full + k] as f64 * omega;
                area[i] += omega;
            }
        }
        let luminance = sum
            .iter()
            .zip(&area)
            .map(|(&s, &a)| if a > 0.0 { (s / a) as f32 } else { 0.0 })
            .collect();
        Ok(FilteredEnv {
            width,
            height,
            luminance,
        })
    }

    /// Columns and rows.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Heap bytes of the table.
    pub fn storage_bytes(&self) -> usize {
        self.luminance.len() * std::mem::size_of::<f32>()
    }

    /// Whether every texel is 0.
    pub fn is_black(&self) -> bool {
        self.luminance.iter().all(|&l| l == 0.0)
    }

    /// The luminance towards the unit direction `dir` (the map's frame),
    /// interpolated bilinearly between texel centres: wrapped across the
    /// φ seam, clamped at the poles. 0 for a direction that is not finite.
    #[inline]
    pub fn lookup(&self, dir: Vec3) -> f32 {
        if !dir.is_finite() {
            return 0.0;
        }
        let mut turns = fast_atan2(dir.y, dir.x) * (1.0 / TAU);
        if turns < 0.0 {
            turns += 1.0;
        }
        let theta = fast_atan2((dir.x * dir.x + dir.y * dir.y).sqrt(), dir.z);
        let u = turns * self.width as f32 - 0.5;
        let v = theta * FRAC_1_PI * self.height as f32 - 0.5;
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        let w = self.width as i64;
        let col = |c: i64| c.rem_euclid(w) as usize;
        let row = |r: i64| r.clamp(0, self.height as i64 - 1) as usize;
        let (c0, c1) = (col(u0 as i64), col(u0 as i64 + 1));
        let (r0, r1) = (row(v0 as i64), row(v0 as i64 + 1));
        let at = |r: usize, c: usize| self.luminance[r * self.width + c];
        let top = at(r0, c0) + fu * (at(r0, c1) - at(r0, c0));
        let bottom = at(r1, c0) + fu * (at(r1, c1) - at(r1, c0));
        (top + fv * (bottom - top)).max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use acdf_core::Rgb;

    /// A constant map filters to the constant; one bright texel keeps its
    /// energy (luminance × solid angle) in its block and is seen by a
    /// lookup towards it.
    #[test]
    fn filtering_keeps_the_energy() {
        let constant = EnvMap::from_fn(64, 32, |_, _| Rgb::splat(2.0)).unwrap();
        let f = FilteredEnv::new(&constant, 16).unwrap();
        assert_eq!(f.size(), (16, 8));
        for d in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.4, 0.5).normalize(),
        ] {
            assert!((f.lookup(d) - 2.0).abs() < 1e-5, "{d}");
        }
        let sun = EnvMap::from_fn(64, 32, |k, j| {
            Rgb::splat(if (k, j) == (10, 12) { 1000.0 } else { 0.0 })
        })
        .unwrap();
        let f = FilteredEnv::new(&sun, 16).unwrap();
        let full: f64 = sun.luminance_integral();
        let grid = acdf_lights::LatLong::new(16, 8);
        let filtered: f64 = (0..8)
            .map(|j| {
                (0..16)
                    .map(|k| f.luminance[j * 16 + k] as f64 * grid.texel_solid_angle(j))
                    .sum::<f64>()
            })
            .sum();
        assert!((filtered - full).abs() < 1e-4 * full, "{filtered} {full}");
        let towards = sun.direction_of(sun.grid().texel_centre(10, 12));
        assert!(f.lookup(towards) > 0.0);
        assert_eq!(f.lookup(Vec3::new(f32::NAN, 0.0, 1.0)), 0.0);
        assert!(FilteredEnv::new(&sun, 0).is_err());
    }
}
