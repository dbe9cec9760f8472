//! The tables environment samplers are built from: one non-negative value
//! per texel, row-major as the map, proportional to the probability the
//! sampler should give the texel.
//!
//! Every table weighs a texel by its solid angle Ω_j = 2π (cos θ_j − cos
//! θ_{j+1}) / W, the exact form of the classic "luminance × sin θ" (sin θ at
//! the row's centre times the row's Δθ agrees with it to second order in
//! Δθ). With the sampling of a texel uniform in solid angle
//! ([`latlong`](crate::latlong)), a table of Y · Ω gives a solid-angle
//! density exactly proportional to the luminance Y of the nearest texel.

use acdf_core::Vec3;
use std::f64::consts::PI;

use crate::envmap::EnvMap;

/// Which function of the map a lat-long table follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TableKind {
    /// Y(L) · Ω: directions in proportion to the luminance arriving from
    /// them; the classic environment sampling density. A black map gives
    /// Ω alone, uniform directions.
    Luminance,
    /// max(0, Y(L) − Ȳ) · Ω with Ȳ the mean luminance over the sphere: the
    /// compensated density for multiple importance sampling, which leaves
    /// the directions darker than the mean to the other strategy (a BRDF
    /// sampler). It does not cover the whole map: used alone it is biased.
    /// A map that is nowhere above its mean (a constant map) gives Ω alone,
    /// uniform directions.
    Compensated,
}

impl TableKind {
    /// The table of `map` for this kind.
    pub fn table(self, map: &EnvMap) -> Vec<f32> {
        match self {
            TableKind::Luminance => luminance_table(map),
            TableKind::Compensated => compensated_table(map),
        }
    }
}

/// Y · Ω per texel; Ω alone (uniform directions) for a black map.
pub fn luminance_table(map: &EnvMap) -> Vec<f32> {
    if map.is_black() {
        weighted(map, |_, _| 1.0)
    } else {
        weighted(map, |y, _| y)
    }
}

/// max(0, Y − Ȳ) · Ω per texel, Ȳ = ∫ Y dω / 4π; Ω alone when that is 0
/// everywhere.
pub fn compensated_table(map: &EnvMap) -> Vec<f32> {
    let mean = map.luminance_integral() / (4.0 * PI);
    let table = weighted(map, |y, _| (y - mean).max(0.0));
    if table.iter().all(|&v| v <= 0.0) {
        weighted(map, |_, _| 1.0)
    } else {
        table
    }
}

/// Y · Ω · c per texel for the normal `normal` (unit), where c is
/// max(0, n·ω_c) at the texel's centre ω_c, except on texels that the
/// horizon of n cuts: there c is at least half the largest n·ω over the
/// texel (bounded through the texel's angular radius), so that every texel
/// with a lit part gets a positive value. The table follows the integrand
/// of the irradiance E(n) = ∫ L max(0, n·ω) dω.
pub fn oriented_table(map: &EnvMap, normal: Vec3) -> Vec<f32> {
    let grid = map.grid();
    let (w, h) = grid.size();
    let n = normal.as_dvec3().normalize_or_zero();
    // Column centres (cos φ, sin φ) and row centres (sin θ, cos θ, radius).
    let columns: Vec<(f64, f64)> = (0..w)
        .map(|k| {
            let (p0, p1) = grid.column_phis(k);
            let p = 0.5 * (p0 + p1);
            (p.cos(), p.sin())
        })
        .collect();
    let mut out = Vec::with_capacity(w * h);
    let lum = map.luminance();
    for j in 0..h {
        let (t0, t1) = grid.row_thetas(j);
        let cos_t = 0.5 * (t0.cos() + t1.cos());
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let r = grid.texel_radius(j);
        let (cos_r, sin_r) = (r.cos(), r.sin());
        let omega = grid.texel_solid_angle(j);
        for (k, &(cp, sp)) in columns.iter().enumerate() {
            let y = lum[j * w + k] as f64;
            if y <= 0.0 {
                out.push(0.0);
                continue;
            }
            let c = n.x * sin_t * cp + n.y * sin_t * sp + n.z * cos_t;
            let c = c.clamp(-1.0, 1.0);
            let s = (1.0 - c * c).max(0.0).sqrt();
            // cos(α − r) and cos(α + r), α the angle to the centre.
            let upper = if c >= cos_r {
                1.0
            } else {
                c * cos_r + s * sin_r
            };
            let lower = c * cos_r - s * sin_r;
            let weight = if lower >= 0.0 {
                c
            } else if upper > 0.0 {
                c.max(0.5 * upper)
            } else {
                0.0
            };
            out.push((y * omega * weight) as f32);
        }
    }
    out
}

/// f(Y, row) · Ω_row per texel.
fn weighted(map: &EnvMap, f: impl Fn(f64, usize) -> f64) -> Vec<f32> {
    let grid = map.grid();
    let (w, _) = grid.size();
    map.luminance()
        .chunks_exact(w)
        .enumerate()
        .flat_map(|(j, row)| {
            let omega = grid.texel_solid_angle(j);
            let f = &f;
            row.iter().map(move |&y| (f(y as f64, j) * omega) as f32)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use acdf_core::Rgb;

    #[test]
    fn tables_weigh_texels_by_solid_angle() {
        let map = EnvMap::from_fn(8, 4, |k, _| Rgb::splat(if k == 3 { 4.0 } else { 1.0 })).unwrap();
        let t = luminance_table(&map);
        let g = map.grid();
        assert!((t[0] as f64 - g.texel_solid_angle(0)).abs() < 1e-6);
        assert!((t[8 + 3] as f64 - 4.0 * g.texel_solid_angle(1)).abs() < 1e-6);
        // The mean is (7 + 4) / 8: only column 3 is above it.
        let c = compensated_table(&map);
        assert!(c
            .iter()
            .enumerate()
            .all(|(i, &v)| (v > 0.0) == (i % 8 == 3)));
        let flat = EnvMap::from_fn(8, 4, |_, _| Rgb::ONE).unwrap();
        assert_eq!(compensated_table(&flat), luminance_table(&flat));
        // A black map samples uniform directions.
        let black = EnvMap::from_fn(8, 4, |_, _| Rgb::ZERO).unwrap();
        assert_eq!(luminance_table(&black), luminance_table(&flat));
        assert_eq!(compensated_table(&black), luminance_table(&flat));
    }

    #[test]
    fn oriented_tables_keep_every_texel_with_a_lit_part() {
        let map = EnvMap::from_fn(64, 32, |_, _| Rgb::ONE).unwrap();
        let n = Vec3::new(0.3, -0.2, 0.9).normalize();
        let t = oriented_table(&map, n);
        let g = map.grid();
        for j in 0..32 {
            for k in 0..64 {
                let lit = [0.0, 1.0].iter().any(|&fx| {
                    [0.0, 0.5, 1.0].iter().any(|&fy| {
                        g.direction_in_texel(k, j, acdf_core::Vec2::new(fx, fy))
                            .dot(n)
                            > 0.0
                    })
                });
                if lit {
                    assert!(t[j * 64 + k] > 0.0, "texel {k},{j}");
                }
            }
        }
        // Texels well below the horizon hold 0.
        let (k, j) = g.texel_of(-n).unwrap();
        assert_eq!(t[j * 64 + k], 0.0);
    }
}
