//! The latitude-longitude parameterisation of the sphere that every
//! environment map and environment sampler of acdf uses.
//!
//! # Convention
//!
//! - `+z` is up: the zenith is (0, 0, 1), θ is the polar angle from `+z`.
//! - φ is the azimuth, measured from `+x` towards `+y` (counter-clockwise
//!   seen from above), in [0, 2π). The seam φ = 0 is the half plane y = 0,
//!   x > 0; a direction there belongs to column 0.
//! - A map of `width` × `height` texels is stored row-major, row 0 at the
//!   top of the image. Column k covers φ ∈ [2πk/W, 2π(k+1)/W), row j covers
//!   θ ∈ [πj/H, π(j+1)/H): row 0 touches the zenith, the last row the nadir,
//!   and the image's left edge is φ = 0.
//! - The direction of a point (u, v) of the unit square is
//!   (sin θ cos φ, sin θ sin φ, cos θ) with φ = 2πu and, *within* the row
//!   j = ⌊vH⌋, cos θ linear in the fraction vH − j: each texel is sampled
//!   uniformly in solid angle, so a density constant over a texel in (u, v)
//!   is constant over the texel in solid angle too, and finite at the poles.
//!
//! This is acdf's spherical convention (`acdf_core::geometry::
//! spherical_direction`, z along the normal) applied to the whole sphere.

use acdf_core::fast::{fast_atan2, grid_cell, sin_cos_turns};
use acdf_core::{Vec2, Vec3};
use std::f64::consts::PI;

/// The texel grid of a latitude-longitude map and the per-row constants
/// that mapping between texels and directions needs.
#[derive(Debug, Clone, PartialEq)]
pub struct LatLong {
    width: usize,
    height: usize,
    /// Per row j: (a, d, upper) with d = cos θ_j − cos θ_{j+1} and a = 1 −
    /// cos θ_j for a row whose centre is in the upper hemisphere, a = 1 +
    /// cos θ_j otherwise: the position within the row is a ± f d, exact
    /// near the pole it measures from.
    rows: Vec<RowConstants>,
    /// W and H as f32, W − 1 and H − 1 as f32.
    wf: f32,
    hf: f32,
    last_col: f32,
    last_row: f32,
    /// The margins (as fractions of a texel) within which a drawn point is
    /// too close to its texel's edge for its texel to be taken as the one a
    /// round trip through its direction finds.
    margin: Vec2,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct RowConstants {
    a: f32,
    d: f32,
    upper: bool,
    /// 1 / (2π H d): a density p(u, v) constant over a texel of this row is
    /// the solid-angle density p · inv_jacobian.
    inv_jacobian: f32,
    /// The solid angle of one texel of the row, 2π d / W, in f64.
    solid_angle: f64,
}

impl LatLong {
    /// The grid of a `width` × `height` map (both at least 1, checked by
    /// the map).
    pub fn new(width: usize, height: usize) -> LatLong {
        let (width, height) = (width.max(1), height.max(1));
        let rows = (0..height)
            .map(|j| {
                let t0 = PI * j as f64 / height as f64;
                let t1 = PI * (j + 1) as f64 / height as f64;
                let (c0, c1) = (t0.cos(), t1.cos());
                // d in the form that keeps its digits near either pole.
                let d = 2.0 * (0.5 * (t1 + t0)).sin() * (0.5 * (t1 - t0)).sin();
                let upper = c0 + c1 >= 0.0;
                let a = if upper {
                    2.0 * (0.5 * t0).sin().powi(2)
                } else {
                    2.0 * (0.5 * t0).cos().powi(2)
                };
                RowConstants {
                    a: a as f32,
                    d: d as f32,
                    upper,
                    inv_jacobian: (1.0 / (2.0 * PI * height as f64 * d)) as f32,
                    solid_angle: 2.0 * PI * d / width as f64,
                }
            })
            .collect();
        LatLong {
            width,
            height,
            rows,
            wf: width as f32,
            hf: height as f32,
            last_col: (width - 1) as f32,
            last_row: (height - 1) as f32,
            margin: Vec2::new(
                (1e-3f32).max(width as f32 * 2e-6),
                (1e-3f32).max(height as f32 * 4e-6),
            ),
        }
    }

    /// Width (columns, φ) and height (rows, θ) in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The number of texels.
    pub fn texel_count(&self) -> usize {
        self.width * self.height
    }

    /// The solid angle of one texel of row `row` (0 for a row out of
    /// range).
    pub fn texel_solid_angle(&self, row: usize) -> f64 {
        self.rows.get(row).map_or(0.0, |r| r.solid_angle)
    }

    /// The polar angles (θ_top, θ_bottom) of row `row`.
    pub fn row_thetas(&self, row: usize) -> (f64, f64) {
        let h = self.height as f64;
        (PI * row as f64 / h, PI * (row + 1) as f64 / h)
    }

    /// The azimuths (φ_left, φ_right) of column `column`.
    pub fn column_phis(&self, column: usize) -> (f64, f64) {
        let w = self.width as f64;
        (
            2.0 * PI * column as f64 / w,
            2.0 * PI * (column + 1) as f64 / w,
        )
    }

    /// The factor that turns a density p(u, v), constant over a texel of
    /// row `row`, into the solid-angle density there: 1 / (2π H (cos θ_top
    /// − cos θ_bottom)).
    #[inline(always)]
    pub fn inv_jacobian(&self, row: usize) -> f32 {
        self.rows[row].inv_jacobian
    }

    /// The texel (column, row) holding `dir`; `None` for a direction that
    /// is not finite or has no length. Directions need not be unit. On the
    /// poles (x = y = 0) the column is 0.
    #[inline(always)]
    pub fn texel_of(&self, dir: Vec3) -> Option<(usize, usize)> {
        // 0 · w is ±0 for finite w and NaN otherwise.
        if (dir * 0.0).element_sum() != 0.0 || dir == Vec3::ZERO {
            return None;
        }
        let phi = fast_atan2(dir.y, dir.x);
        // Turns in (-1/2, 1/2]; a negative angle wraps to the top. -0 (the
        // seam approached from y < 0 in sign only) stays in column 0.
        let mut t = phi * (0.5 * std::f32::consts::FRAC_1_PI);
        if t < 0.0 {
            t += 1.0;
        }
        let column = grid_cell(t * self.wf, self.last_col);
        let r = (dir.x * dir.x + dir.y * dir.y).sqrt();
        let theta = fast_atan2(r, dir.z);
        let row = grid_cell(
            theta * (self.hf * std::f32::consts::FRAC_1_PI),
            self.last_row,
        );
        Some((column, row))
    }

    /// The centre of texel (column, row) in the unit square: where a
    /// density constant over the texel is looked up.
    #[inline(always)]
    pub fn texel_centre(&self, column: usize, row: usize) -> Vec2 {
        Vec2::new(
            (column as f32 + 0.5) / self.wf,
            (row as f32 + 0.5) / self.hf,
        )
    }

    /// The unit direction of the point `fraction` (each in [0, 1]) inside
    /// texel (column, row): φ linear in the column fraction, cos θ linear in
    /// the row fraction.
    #[inline(always)]
    pub fn direction_in_texel(&self, column: usize, row: usize, fraction: Vec2) -> Vec3 {
        let rc = &self.rows[row.min(self.height - 1)];
        // s: 1 − cos θ (upper rows) or 1 + cos θ (lower rows), exact near
        // the pole it is measured from.
        let (s, z) = if rc.upper {
            let s = rc.a + fraction.y * rc.d;
            (s, 1.0 - s)
        } else {
            let s = rc.a - fraction.y * rc.d;
            (s, s - 1.0)
        };
        let sin_theta = (s * (2.0 - s)).max(0.0).sqrt();
        let (sin_phi, cos_phi) = sin_cos_turns((column as f32 + fraction.x) / self.wf);
        Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, z.clamp(-1.0, 1.0))
    }

    /// The direction of a point `p` of the unit square (see the module
    /// documentation), with its texel (column, row) and whether `p` is far
    /// enough inside that texel for a round trip through the direction
    /// ([`texel_of`](Self::texel_of)) to find the same texel.
    #[inline(always)]
    pub fn direction_of_point(&self, p: Vec2) -> (Vec3, usize, usize, bool) {
        let (column, row, fraction) = self.cell_of_point(p);
        let m = self.margin;
        let inside = (fraction.x >= m.x)
            & (fraction.x <= 1.0 - m.x)
            & (fraction.y >= m.y)
            & (fraction.y <= 1.0 - m.y);
        let fraction = fraction.clamp(Vec2::ZERO, Vec2::ONE);
        (
            self.direction_in_texel(column, row, fraction),
            column,
            row,
            inside,
        )
    }

    /// The texel (column, row) of a point `p` of the unit square and the
    /// point's position inside it, as fractions of the texel (unclamped).
    #[inline(always)]
    fn cell_of_point(&self, p: Vec2) -> (usize, usize, Vec2) {
        let (x, y) = (p.x * self.wf, p.y * self.hf);
        let column = grid_cell(x, self.last_col);
        let row = grid_cell(y, self.last_row);
        (column, row, Vec2::new(x - column as f32, y - row as f32))
    }

    /// The direction of `p` moved, if need be, inside its texel by the
    /// margin, so that a round trip through it finds the texel of `p`: for
    /// the rare draw within rounding of its texel's edge whose direction
    /// would land in a neighbour (see `finish_draw`).
    pub fn direction_of_point_inside(&self, p: Vec2) -> Vec3 {
        let (column, row, fraction) = self.cell_of_point(p);
        let m = self.margin;
        self.direction_in_texel(column, row, fraction.clamp(m, Vec2::ONE - m))
    }

    /// The unit direction at the centre of texel (column, row) in solid
    /// angle (cos θ halfway through the row, φ halfway through the column).
    pub fn texel_direction(&self, column: usize, row: usize) -> Vec3 {
        self.direction_in_texel(column, row, Vec2::splat(0.5))
    }

    /// A bound on the angle between the centre direction of a texel of row
    /// `row` ([`texel_direction`](Self::texel_direction)) and any direction
    /// inside the texel.
    pub fn texel_radius(&self, row: usize) -> f64 {
        let (t0, t1) = self.row_thetas(row);
        let (p0, p1) = self.column_phis(0);
        let sin_max = if t0 <= 0.5 * PI && t1 >= 0.5 * PI {
            1.0
        } else {
            t0.sin().max(t1.sin())
        };
        // Half the row's θ extent (the centre in cos θ lies inside it) and
        // half the column's arc at the widest latitude.
        let dt = t1 - t0;
        let arc = sin_max * (p1 - p0);
        (dt * dt + 0.25 * arc * arc).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texel_round_trips_and_solid_angles_sum_to_the_sphere() {
        for (w, h) in [(1, 1), (2, 1), (8, 4), (64, 32), (1024, 512)] {
            let g = LatLong::new(w, h);
            let total: f64 = (0..h).map(|j| g.texel_solid_angle(j) * w as f64).sum();
            assert!((total - 4.0 * PI).abs() < 1e-9, "{w}x{h}: {total}");
            for j in (0..h).step_by((h / 8).max(1)) {
                for k in (0..w).step_by((w / 8).max(1)) {
                    let d = g.texel_direction(k, j);
                    assert!((d.length() - 1.0).abs() < 1e-6);
                    assert_eq!(g.texel_of(d), Some((k, j)), "{w}x{h} texel {k},{j}");
                }
            }
        }
    }

    #[test]
    fn conventions_hold() {
        let g = LatLong::new(8, 4);
        // Zenith in row 0, nadir in the last row, the seam in column 0.
        assert_eq!(g.texel_of(Vec3::Z).map(|t| t.1), Some(0));
        assert_eq!(g.texel_of(-Vec3::Z).map(|t| t.1), Some(3));
        assert_eq!(g.texel_of(Vec3::new(1.0, 0.0, 0.0)), Some((0, 2)));
        assert_eq!(g.texel_of(Vec3::new(1.0, -0.0, 0.1)), Some((0, 1)));
        // Just below the seam: the last column.
        assert_eq!(g.texel_of(Vec3::new(1.0, -1e-6, 0.1)), Some((7, 1)));
        // +y is a quarter turn.
        assert_eq!(g.texel_of(Vec3::new(0.0, 1.0, 0.1)), Some((2, 1)));
        assert_eq!(g.texel_of(Vec3::ZERO), None);
        assert_eq!(g.texel_of(Vec3::new(f32::NAN, 0.0, 1.0)), None);
        // Points of the square map to their texel, the top row to the zenith.
        let (d, k, j, _) = g.direction_of_point(Vec2::new(0.0, 0.0));
        assert_eq!((k, j), (0, 0));
        assert!((d - Vec3::Z).length() < 1e-6);
        let (d, _, j, _) = g.direction_of_point(Vec2::splat(acdf_core::ONE_MINUS_EPSILON));
        assert_eq!(j, 3);
        assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-6 && d.z < -0.999);
    }

    #[test]
    fn texel_radius_bounds_the_corners() {
        let g = LatLong::new(16, 8);
        for j in 0..8 {
            let c = g.texel_direction(3, j);
            let r = g.texel_radius(j);
            for f in [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE] {
                let d = g.direction_in_texel(3, j, f);
                let angle = (c.dot(d) as f64).clamp(-1.0, 1.0).acos();
                assert!(angle <= r + 1e-5, "row {j}: {angle} > {r}");
            }
        }
    }
}
