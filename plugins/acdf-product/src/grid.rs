//! The equal-area grid of the upper hemisphere the product is formed on.
//!
//! A point p of the unit square goes to the disk by Shirley and Chiu's
//! concentric map (area-preserving up to the constant π/4) and from the
//! disk to the hemisphere by Lambert's azimuthal equal-area lift
//! z = 1 − r², (x, y) scaled by √(2 − r²) (solid angle = 2 × disk area).
//! The composition carries area in the square to solid angle with the
//! constant factor 2π, so the N × N square cells are N² cells of equal
//! solid angle 2π / N², roughly square everywhere (no sliver at the
//! pole), and a point uniform in a square cell is uniform in solid angle
//! over its cell.

use acdf_core::warp::square_to_concentric_disk;
use acdf_core::{Vec2, Vec3};
use std::f32::consts::FRAC_PI_4;

/// The direction of the point `p` of the unit square (p clamped to
/// [0, 1)² by the concentric map).
#[inline]
pub fn square_to_hemisphere(p: Vec2) -> Vec3 {
    let d = square_to_concentric_disk(p);
    let r2 = d.length_squared();
    // 1 − r² as (1 − r)(1 + r) keeps its digits near the rim (the horizon).
    let r = r2.sqrt();
    let z = ((1.0 - r) * (1.0 + r)).max(0.0);
    let s = (2.0 - r2).max(0.0).sqrt();
    Vec3::new(d.x * s, d.y * s, z)
}

/// The point of the unit square whose direction is `w` (unit, `w.z > 0`):
/// the inverse of [`square_to_hemisphere`]. `None` at or below the
/// horizon and for a direction that is not finite.
#[inline]
pub fn hemisphere_to_square(w: Vec3) -> Option<Vec2> {
    if !(w.z > 0.0) || !w.is_finite() {
        return None;
    }
    // The disk point: (x, y) / √(1 + z), of radius r = √(1 − z).
    let k = 1.0 / (1.0 + w.z).sqrt();
    let (x, y) = (w.x * k, w.y * k);
    let r = (x * x + y * y).sqrt();
    if r == 0.0 {
        return Some(Vec2::splat(0.5));
    }
    let r = r.min(1.0);
    let (a, b) = if x.abs() >= y.abs() {
        let a = r.copysign(x);
        (a, a * (y / x).atan() / FRAC_PI_4)
    } else {
        let b = r.copysign(y);
        (b * (x / y).atan() / FRAC_PI_4, b)
    };
    Some(Vec2::new(0.5 * (a + 1.0), 0.5 * (b + 1.0)))
}

/// The cells of the grid and, in each, the stratified points at which the
/// product is evaluated to weigh the cell.
#[derive(Debug, Clone)]
pub struct HemisphereGrid {
    /// Cells per side of the unit square: N² cells in all.
    side: usize,
    /// Points per side of a cell: s² points per cell.
    points_per_side: usize,
    /// The s² points of every cell, cell after cell (cells row-major over
    /// the square, y outer).
    points: Vec<Vec3>,
}

impl HemisphereGrid {
    /// The grid of `side` × `side` cells with `points_per_side`² points in
    /// each, at the centres of the cell's strata. Both must be at least 1
    /// (checked by the caller, [`ProductOptions`](crate::ProductOptions)).
    pub fn new(side: usize, points_per_side: usize) -> HemisphereGrid {
        let (n, s) = (side.max(1), points_per_side.max(1));
        let mut points = Vec::with_capacity(n * n * s * s);
        for cy in 0..n {
            for cx in 0..n {
                for sy in 0..s {
                    for sx in 0..s {
                        let p = Vec2::new(
                            (cx as f32 + (sx as f32 + 0.5) / s as f32) / n as f32,
                            (cy as f32 + (sy as f32 + 0.5) / s as f32) / n as f32,
                        );
                        points.push(square_to_hemisphere(p));
                    }
                }
            }
        }
        HemisphereGrid {
            side: n,
            points_per_side: s,
            points,
        }
    }

    /// The number of cells, N².
    pub fn cell_count(&self) -> usize {
        self.side * self.side
    }

    /// The number of points per cell, s².
    pub fn points_per_cell(&self) -> usize {
        self.points_per_side * self.points_per_side
    }

    /// The evaluation points, cell after cell, in the local frame.
    pub fn points(&self) -> &[Vec3] {
        &self.points
    }

    /// The solid angle of one cell: 2π / N².
    pub fn cell_solid_angle(&self) -> f32 {
        std::f32::consts::TAU / self.cell_count() as f32
    }

    /// The cell holding the direction of `w` (need not be unit), `None` at
    /// or below the horizon.
    #[inline]
    pub fn cell_of(&self, w: Vec3) -> Option<usize> {
        let p = hemisphere_to_square(w.normalize_or_zero())?;
        let n = self.side;
        let top = (n - 1) as f32;
        let cx = (p.x * n as f32).clamp(0.0, top) as usize;
        let cy = (p.y * n as f32).clamp(0.0, top) as usize;
        Some(cy * n + cx)
    }

    /// The direction of the point `f` ∈ [0, 1)² inside cell `cell`.
    #[inline]
    pub fn direction_in_cell(&self, cell: usize, f: Vec2) -> Vec3 {
        let n = self.side;
        let (cx, cy) = (cell % n, cell / n);
        let p = Vec2::new((cx as f32 + f.x) / n as f32, (cy as f32 + f.y) / n as f32);
        square_to_hemisphere(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The map and its inverse round-trip, and every direction is unit and
    /// above the horizon.
    #[test]
    fn the_map_round_trips() {
        for i in 0..64 {
            for j in 0..64 {
                let p = Vec2::new((i as f32 + 0.37) / 64.0, (j as f32 + 0.61) / 64.0);
                let w = square_to_hemisphere(p);
                assert!((w.length() - 1.0).abs() < 1e-5, "{p} {w}");
                assert!(w.z > 0.0, "{p} {w}");
                let q = hemisphere_to_square(w).unwrap();
                assert!((q - p).abs().max_element() < 2e-5, "{p} {q}");
            }
        }
        assert_eq!(hemisphere_to_square(Vec3::Z), Some(Vec2::splat(0.5)));
        assert_eq!(hemisphere_to_square(Vec3::X), None);
        assert_eq!(hemisphere_to_square(Vec3::new(f32::NAN, 0.0, 1.0)), None);
    }

    /// Equal area: a cell's share of uniformly spread directions (by the
    /// exact inverse on a fine (cos θ, φ) grid) is 1 / N² to quadrature
    /// accuracy.
    #[test]
    fn cells_have_equal_solid_angle() {
        let grid = HemisphereGrid::new(4, 1);
        let mut counts = [0usize; 16];
        let (nz, nphi) = (600, 1200);
        for i in 0..nz {
            for j in 0..nphi {
                let z = (i as f32 + 0.5) / nz as f32;
                let phi = std::f32::consts::TAU * (j as f32 + 0.5) / nphi as f32;
                let s = (1.0 - z * z).sqrt();
                let w = Vec3::new(s * phi.cos(), s * phi.sin(), z);
                counts[grid.cell_of(w).unwrap()] += 1;
            }
        }
        for c in counts {
            let share = c as f64 / (nz * nphi) as f64;
            assert!((share - 1.0 / 16.0).abs() < 2e-3, "{share}");
        }
    }
}
