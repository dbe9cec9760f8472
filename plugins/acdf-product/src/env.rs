//! The environment's side of the product, built once per map: the map's
//! texels grouped into blocks of its lat-long grid, each block's light
//! (luminance × solid angle) and the CDFs that draw a texel inside a
//! block in proportion to its light.

use acdf_core::{Error, Frame, Result, Vec2, Vec3};
use acdf_lights::EnvMap;
use std::sync::Arc;

/// A map cut into `columns` × `rows` blocks of texels (block column c
/// holds the texel columns k with ⌊k · columns / W⌋ = c, rows alike), with
/// per block:
///
/// - its light M_b = Σ_t Y_t Ω_t over its texels t (Y the luminance, Ω the
///   texel's solid angle);
/// - the CDFs that draw a texel t of the block with probability
///   Y_t Ω_t / M_b (a row of the block by its light, then a texel of that
///   row), whose direction is then uniform in solid angle over the texel,
///   so that the density of a direction in texel t is Y_t / M_b;
/// - s × s points spread over the block, where the BRDF factor is
///   evaluated per query.
#[derive(Debug, Clone)]
pub struct ProductEnv {
    map: Arc<EnvMap>,
    columns: usize,
    rows: usize,
    /// The block column of each texel column, the block row of each
    /// texel row.
    block_of_column: Vec<u32>,
    block_of_row: Vec<u32>,
    /// The first texel column of each block column (and W at the end),
    /// the first texel row of each block row (and H).
    column_start: Vec<usize>,
    row_start: Vec<usize>,
    /// M_b per block, row-major over the blocks.
    light: Vec<f64>,
    /// Per block column c and texel row j, at [c · H + j]: the block's
    /// CDF over its rows, the value after row j.
    row_cdf: Vec<f32>,
    /// Per texel, at [j · W + k]: the CDF over the texels of its row
    /// within its block, the value after texel k.
    column_cdf: Vec<f32>,
    /// Points per block, s²; the points, block after block (map frame).
    points_per_block: usize,
    points: Vec<Vec3>,
}

/// A CDF from non-negative masses: the running sums divided by the total,
/// the last exactly 1; all 0 when the total is 0.
fn cdf_into(masses: impl Iterator<Item = f64>, out: &mut [f32]) -> f64 {
    let mut running = 0.0;
    let mut sums = Vec::with_capacity(out.len());
    for m in masses {
        running += m;
        sums.push(running);
    }
    if running > 0.0 {
        for (o, s) in out.iter_mut().zip(&sums) {
            *o = (s / running) as f32;
        }
        if let Some(last) = out.last_mut() {
            *last = 1.0;
        }
    }
    running
}

/// The index of the first value of `cdf` above `u`, its CDF interval
/// (lo, hi) and u's place in it; `None` when no value is above `u` (a
/// block or row without light).
#[inline]
fn find(cdf: &[f32], u: f64) -> Option<(usize, f64)> {
    let i = cdf.partition_point(|&v| v as f64 <= u);
    let hi = *cdf.get(i)? as f64;
    let lo = if i == 0 { 0.0 } else { cdf[i - 1] as f64 };
    Some((i, ((u - lo) / (hi - lo)).clamp(0.0, 1.0)))
}

impl ProductEnv {
    /// Cut `map` into at most `columns` block columns (and half as many
    /// block rows, at least 1), never more than the map's texels, with
    /// `points_per_side`² evaluation points per block. A typed error for a
    /// count of 0.
    pub fn new(map: Arc<EnvMap>, columns: usize, points_per_side: usize) -> Result<ProductEnv> {
        if columns == 0 || points_per_side == 0 {
            return Err(Error::InvalidParameter {
                name: "product blocks",
                reason: "block columns and points per side must be at least 1".into(),
            });
        }
        let (w, h) = map.size();
        let columns = columns.min(w);
        let rows = (columns / 2).clamp(1, h);
        let block_of_column: Vec<u32> = (0..w).map(|k| (k * columns / w) as u32).collect();
        let block_of_row: Vec<u32> = (0..h).map(|j| (j * rows / h) as u32).collect();
        let starts = |n: usize, blocks: usize| -> Vec<usize> {
            (0..=blocks).map(|c| (c * n).div_ceil(blocks)).collect()
        };
        let (column_start, row_start) = (starts(w, columns), starts(h, rows));
        let grid = map.grid();
        let lum = map.luminance();
        let mut light = vec![0f64; columns * rows];
        let mut row_cdf = vec![0f32; h * columns];
        let mut column_cdf = vec![0f32; w * h];
        let mut row_light = vec![0f64; h * columns];
        for j in 0..h {
            let omega = grid.texel_solid_angle(j);
            for c in 0..columns {
                let (k0, k1) = (column_start[c], column_start[c + 1]);
                let texels = &lum[j * w + k0..j * w + k1];
                row_light[j * columns + c] = cdf_into(
                    texels.iter().map(|&y| y.max(0.0) as f64 * omega),
                    &mut column_cdf[j * w + k0..j * w + k1],
                );
            }
        }
        for r in 0..rows {
            let (j0, j1) = (row_start[r], row_start[r + 1]);
            for c in 0..columns {
                let mut cdf = vec![0f32; j1 - j0];
                light[r * columns + c] =
                    cdf_into((j0..j1).map(|j| row_light[j * columns + c]), &mut cdf);
                row_cdf[c * h + j0..c * h + j1].copy_from_slice(&cdf);
            }
        }
        let s = points_per_side;
        let mut points = Vec::with_capacity(columns * rows * s * s);
        for r in 0..rows {
            for c in 0..columns {
                let (u0, u1) = (
                    column_start[c] as f32 / w as f32,
                    column_start[c + 1] as f32 / w as f32,
                );
                let (v0, v1) = (
                    row_start[r] as f32 / h as f32,
                    row_start[r + 1] as f32 / h as f32,
                );
                for sy in 0..s {
                    for sx in 0..s {
                        let fx = (sx as f32 + 0.5) / s as f32;
                        let fy = (sy as f32 + 0.5) / s as f32;
                        points.push(
                            map.direction_of(Vec2::new(u0 + fx * (u1 - u0), v0 + fy * (v1 - v0))),
                        );
                    }
                }
            }
        }
        Ok(ProductEnv {
            map,
            columns,
            rows,
            block_of_column,
            block_of_row,
            column_start,
            row_start,
            light,
            row_cdf,
            column_cdf,
            points_per_block: s * s,
            points,
        })
    }

    /// Block columns and rows.
    pub fn blocks(&self) -> (usize, usize) {
        (self.columns, self.rows)
    }

    /// Evaluation points per block, s².
    pub fn points_per_block(&self) -> usize {
        self.points_per_block
    }

    /// The number of blocks.
    pub fn block_count(&self) -> usize {
        self.light.len()
    }

    /// M_b of block `b`.
    pub fn light(&self, b: usize) -> f64 {
        self.light[b]
    }

    /// Whether the map has no light.
    pub fn is_black(&self) -> bool {
        self.light.iter().all(|&m| m == 0.0)
    }

    /// Heap bytes of the tables (the map itself not counted).
    pub fn storage_bytes(&self) -> usize {
        self.light.len() * 8
            + (self.row_cdf.len() + self.column_cdf.len()) * 4
            + (self.block_of_column.len() + self.block_of_row.len()) * 4
            + (self.column_start.len() + self.row_start.len()) * 8
            + self.points.len() * std::mem::size_of::<Vec3>()
    }

    /// The evaluation points above the horizon of the shading frame
    /// `frame`, in its local frame, with their blocks.
    pub fn local_points(&self, frame: &Frame) -> LocalPoints {
        let mut out = LocalPoints {
            dirs: Vec::new(),
            blocks: Vec::new(),
        };
        for (i, &p) in self.points.iter().enumerate() {
            let local = frame.to_local(p);
            if local.z > 0.0 {
                out.dirs.push(local);
                out.blocks.push((i / self.points_per_block) as u32);
            }
        }
        out
    }

    /// The block of the texel holding the world direction `dir`, and Y_t /
    /// M_b there (the density of a draw inside block b at `dir`); `None`
    /// for a direction that is not finite or has no length.
    #[inline]
    pub fn block_density(&self, dir: Vec3) -> Option<(usize, f32)> {
        let (k, j) = self.map.texel_of(dir)?;
        let b = self.block_of_row[j] as usize * self.columns + self.block_of_column[k] as usize;
        let m = self.light[b];
        let y = self.map.luminance()[j * self.map.size().0 + k] as f64;
        Some((b, if m > 0.0 { (y / m) as f32 } else { 0.0 }))
    }

    /// Draw a world direction inside block `b` with density Y_t / M_b:
    /// `u.x` picks the row by its light and the place in it along θ, `u.y`
    /// the texel of that row by its light and the place along φ. `None`
    /// for a block without light.
    #[inline]
    pub fn sample_in_block(&self, b: usize, u: Vec2) -> Option<Vec3> {
        let (r, c) = (b / self.columns, b % self.columns);
        let (j0, j1) = (self.row_start[r], self.row_start[r + 1]);
        let (k0, k1) = (self.column_start[c], self.column_start[c + 1]);
        let (w, h) = self.map.size();
        let (dj, fy) = find(&self.row_cdf[c * h + j0..c * h + j1], u.x as f64)?;
        let j = j0 + dj;
        let (dk, fx) = find(&self.column_cdf[j * w + k0..j * w + k1], u.y as f64)?;
        let f = Vec2::new(fx as f32, fy as f32).clamp(Vec2::ZERO, Vec2::ONE);
        Some(self.map.grid().direction_in_texel(k0 + dk, j, f))
    }
}

/// The evaluation points of a [`ProductEnv`] above one shading frame's
/// horizon, in that frame, with the block each belongs to.
#[derive(Debug, Clone)]
pub struct LocalPoints {
    pub(crate) dirs: Vec<Vec3>,
    pub(crate) blocks: Vec<u32>,
}

impl LocalPoints {
    /// The number of points.
    pub fn len(&self) -> usize {
        self.dirs.len()
    }

    /// Whether no point is above the horizon.
    pub fn is_empty(&self) -> bool {
        self.dirs.is_empty()
    }

    /// Heap bytes.
    pub fn storage_bytes(&self) -> usize {
        self.dirs.len() * (std::mem::size_of::<Vec3>() + 4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use acdf_core::Rgb;

    /// The blocks' light sums to the map's; a draw inside a block lands in
    /// it, on a texel with light, with the density the block reports.
    #[test]
    fn blocks_keep_the_light_and_draw_inside() {
        let map = Arc::new(
            EnvMap::from_fn(64, 32, |k, j| {
                Rgb::splat(if (k, j) == (10, 12) {
                    1000.0
                } else if j < 16 {
                    0.5
                } else {
                    0.0
                })
            })
            .unwrap(),
        );
        let env = ProductEnv::new(map.clone(), 16, 2).unwrap();
        assert_eq!(env.blocks(), (16, 8));
        let total: f64 = (0..env.block_count()).map(|b| env.light(b)).sum();
        let full = map.luminance_integral();
        assert!((total - full).abs() < 1e-6 * full, "{total} {full}");
        for b in 0..env.block_count() {
            // Inside the texels: on an edge, rounding may find the neighbour.
            for u in [Vec2::new(0.1, 0.9), Vec2::new(0.7, 0.3), Vec2::splat(0.5)] {
                match env.sample_in_block(b, u) {
                    Some(d) => {
                        let (found, density) = env.block_density(d).unwrap();
                        assert_eq!(found, b);
                        assert!(density > 0.0);
                    }
                    None => assert_eq!(env.light(b), 0.0, "block {b}"),
                }
            }
        }
        assert!(ProductEnv::new(map, 0, 2).is_err());
    }
}
