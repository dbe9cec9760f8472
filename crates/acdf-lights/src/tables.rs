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

/// Y · Ω · g per texel for the normals within the angle `radius` of
/// `normal` (unit): the table of an orientation-aware sampler's node, whose
/// normals all draw from it.
///
/// g(α), with α the angle from `normal` to the texel's centre, is the root
/// mean square of max(0, n·ω) over the normals n of the cap of that radius
/// (by a midpoint rule over the cap), which minimises the mean over the cap
/// of the estimator's second moment for a texel of constant radiance. A
/// texel that some normal of the cap sees in part (α within 90° plus the
/// radius and the texel's own angular radius) gets at least a small
/// positive g, so that every texel any of the normals sees has a positive
/// density: the table follows the integrand of the irradiance
/// E(n) = ∫ L max(0, n·ω) dω and covers it for every n of the cap.
pub fn oriented_table(map: &EnvMap, normal: Vec3, radius: f64) -> Vec<f32> {
    let grid = map.grid();
    let (w, h) = grid.size();
    let n = normal.as_dvec3().normalize_or_zero();
    let g = CapWeight::new(radius);
    // Column centres (cos φ, sin φ).
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
        let reach = radius + grid.texel_radius(j);
        let (cos_r, sin_r) = if reach < 0.5 * std::f64::consts::PI {
            (reach.cos(), reach.sin())
        } else {
            (0.0, 1.0)
        };
        let omega = grid.texel_solid_angle(j);
        for (k, &(cp, sp)) in columns.iter().enumerate() {
            let y = lum[j * w + k] as f64;
            if y <= 0.0 {
                out.push(0.0);
                continue;
            }
            let c = (n.x * sin_t * cp + n.y * sin_t * sp + n.z * cos_t).clamp(-1.0, 1.0);
            let s = (1.0 - c * c).max(0.0).sqrt();
            // cos(α − reach): positive when a normal of the cap sees part
            // of the texel.
            let upper = if c >= cos_r {
                1.0
            } else {
                c * cos_r + s * sin_r
            };
            let weight = if upper > 0.0 {
                g.at(c).max(1e-3 * upper)
            } else {
                0.0
            };
            out.push((y * omega * weight) as f32);
        }
    }
    out
}

/// g(cos α) of [`oriented_table`]: the root mean square of max(0, n·ω)
/// over the normals n of a cap, tabulated in cos α and interpolated
/// linearly.
struct CapWeight {
    values: Vec<f64>,
}

impl CapWeight {
    const POINTS: usize = 512;

    fn new(radius: f64) -> CapWeight {
        // The cap by a midpoint rule, equal in solid angle: rings equal in
        // cos β, points equal in ψ.
        const RINGS: usize = 12;
        const AROUND: usize = 24;
        let cos_cap = radius.min(std::f64::consts::PI).cos();
        let ring: Vec<(f64, f64)> = (0..RINGS)
            .map(|i| {
                let cb = 1.0 - (1.0 - cos_cap) * (i as f64 + 0.5) / RINGS as f64;
                (cb, (1.0 - cb * cb).max(0.0).sqrt())
            })
            .collect();
        let around: Vec<f64> = (0..AROUND)
            .map(|i| (std::f64::consts::TAU * (i as f64 + 0.5) / AROUND as f64).cos())
            .collect();
        let values = (0..Self::POINTS)
            .map(|i| {
                let c = -1.0 + 2.0 * i as f64 / (Self::POINTS - 1) as f64;
                let s = (1.0 - c * c).max(0.0).sqrt();
                let mut sum = 0.0;
                for &(cb, sb) in &ring {
                    for &cpsi in &around {
                        let d = (c * cb + s * sb * cpsi).max(0.0);
                        sum += d * d;
                    }
                }
                (sum / (RINGS * AROUND) as f64).sqrt()
            })
            .collect();
        CapWeight { values }
    }

    fn at(&self, c: f64) -> f64 {
        let x = (c.clamp(-1.0, 1.0) + 1.0) * 0.5 * (Self::POINTS - 1) as f64;
        let i = (x as usize).min(Self::POINTS - 2);
        let f = x - i as f64;
        self.values[i] * (1.0 - f) + self.values[i + 1] * f
    }
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
        let t = oriented_table(&map, n, 0.0);
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
