//! The environment's side of the product, built once per map: the map's
//! texels grouped into blocks of its lat-long grid, each block's light
//! (luminance × solid angle) and the CDFs that draw a texel inside a
//! block in proportion to its light.

use acdf_core::{Error, Frame, Result, Vec2, Vec3};
use acdf_lights::EnvMap;
use std::sync::Arc;

/// A map cut into `columns` × `rows` blocks of texels (block column c
/// holds the texel columns k with ⌊k · columns / W⌋ = c, rows alike), each
/// block cut again into kc × kr sub-cells along its texel columns and rows
/// (k = `sub_cells` per side, fewer where a block has fewer texels per
/// side, so that every sub-cell holds whole texels), with:
///
/// - per block, its light M_b = Σ_t Y_t Ω_t over its texels t (Y the
///   luminance, Ω the texel's solid angle), and per sub-cell f its light
///   M_f and mean radiance M_f / Ω_f;
/// - the CDFs that draw a texel t of a sub-cell with probability
///   Y_t Ω_t / M_f (a row of the sub-cell by its light, then a texel of
///   that row), whose direction is then uniform in solid angle over the
///   texel, so that the density of a direction in texel t is Y_t / M_f;
/// - s × s points spread over each block, where the BRDF factor is
///   evaluated per query, and each sub-cell's centre, where the BRDF factor
///   is evaluated when a query refines the block.
///
/// With one sub-cell per block (`sub_cells` 1) a sub-cell is its block.
#[derive(Debug, Clone)]
pub struct ProductEnv {
    map: Arc<EnvMap>,
    columns: usize,
    rows: usize,
    /// Sub-cells per block along a row (kc) and a column (kr).
    sub_columns: usize,
    sub_rows: usize,
    /// Per texel column: its sub-cell column over the whole map (columns ×
    /// kc of them), its block column and its sub-cell column in the block;
    /// per texel row likewise (no division when a direction is located).
    column_place: Vec<[u32; 3]>,
    row_place: Vec<[u32; 3]>,
    /// Per texel, at [j · W + k]: Y_t / M_f, the density of a draw inside
    /// its sub-cell f (0 in a sub-cell without light).
    texel_density: Vec<f32>,
    /// The first texel column of each sub-cell column (and W at the end),
    /// the first texel row of each sub-cell row (and H).
    column_start: Vec<usize>,
    row_start: Vec<usize>,
    /// M_b per block, row-major over the blocks.
    light: Vec<f64>,
    /// M_f per sub-cell, row-major over the map's sub-cells.
    cell_light: Vec<f64>,
    /// M_f / Ω_f per sub-cell, as `cell_light`.
    cell_radiance: Vec<f32>,
    /// The centre of each sub-cell (map frame), as `cell_light`.
    cell_centres: Vec<Vec3>,
    /// Per sub-cell column c and texel row j, at [c · H + j]: the
    /// sub-cell's CDF over its rows, the value after row j.
    row_cdf: Vec<f32>,
    /// Per texel, at [j · W + k]: the CDF over the texels of its row
    /// within its sub-cell, the value after texel k.
    column_cdf: Vec<f32>,
    /// Points per block, s²; the points, block after block (map frame).
    points_per_block: usize,
    points: Vec<Vec3>,
}

/// A CDF from non-negative masses: the running sums divided by the total,
/// the last exactly 1; all 0 when the total is 0.
pub(crate) fn cdf_into(masses: impl Iterator<Item = f64>, out: &mut [f32]) -> f64 {
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
pub(crate) fn find(cdf: &[f32], u: f64) -> Option<(usize, f64)> {
    let i = cdf.partition_point(|&v| v as f64 <= u);
    let hi = *cdf.get(i)? as f64;
    let lo = if i == 0 { 0.0 } else { cdf[i - 1] as f64 };
    Some((i, ((u - lo) / (hi - lo)).clamp(0.0, 1.0)))
}

/// The starts of `blocks` near-equal runs of `n` items (and n at the end),
/// each run cut again into `k` near-equal runs (every run at least k long).
fn nested_starts(n: usize, blocks: usize, k: usize) -> Vec<usize> {
    let mut out = Vec::with_capacity(blocks * k + 1);
    for c in 0..blocks {
        let (a, b) = ((c * n).div_ceil(blocks), ((c + 1) * n).div_ceil(blocks));
        out.extend((0..k).map(|i| a + (i * (b - a)).div_ceil(k)));
    }
    out.push(n);
    out
}

/// Per item of `0..n`, the run r of `starts` ([`nested_starts`], `k`
/// runs per block) holding it, its block r / k and its run in the block
/// r % k.
fn places(starts: &[usize], k: usize) -> Vec<[u32; 3]> {
    let mut out = Vec::with_capacity(*starts.last().unwrap_or(&0));
    for (r, w) in starts.windows(2).enumerate() {
        let place = [r as u32, (r / k) as u32, (r % k) as u32];
        out.extend(std::iter::repeat_n(place, w[1] - w[0]));
    }
    out
}

impl ProductEnv {
    /// Cut `map` into at most `columns` block columns (and half as many
    /// block rows, at least 1), never more than the map's texels, with
    /// `points_per_side`² evaluation points per block and at most
    /// `sub_cells`² sub-cells per block. A typed error for a count of 0,
    /// or more than 4 sub-cells per side.
    pub fn new(
        map: Arc<EnvMap>,
        columns: usize,
        points_per_side: usize,
        sub_cells: usize,
    ) -> Result<ProductEnv> {
        if columns == 0 || points_per_side == 0 || !(1..=4).contains(&sub_cells) {
            return Err(Error::InvalidParameter {
                name: "product blocks",
                reason: format!(
                    "block columns and points per side must be at least 1, \
                     sub-cells per side from 1 to 4 (got {columns}, {points_per_side}, {sub_cells})"
                ),
            });
        }
        let (w, h) = map.size();
        let columns = columns.min(w);
        let rows = (columns / 2).clamp(1, h);
        // Every block is at least ⌊W / columns⌋ texels wide.
        let (kc, kr) = (sub_cells.min(w / columns), sub_cells.min(h / rows));
        let (column_start, row_start) = (nested_starts(w, columns, kc), nested_starts(h, rows, kr));
        let (cell_columns, cell_rows) = (columns * kc, rows * kr);
        let grid = map.grid();
        let lum = map.luminance();
        let mut cell_light = vec![0f64; cell_columns * cell_rows];
        let mut cell_omega = vec![0f64; cell_columns * cell_rows];
        let mut row_cdf = vec![0f32; h * cell_columns];
        let mut column_cdf = vec![0f32; w * h];
        let mut row_light = vec![0f64; h * cell_columns];
        for j in 0..h {
            let omega = grid.texel_solid_angle(j);
            for c in 0..cell_columns {
                let (k0, k1) = (column_start[c], column_start[c + 1]);
                let texels = &lum[j * w + k0..j * w + k1];
                row_light[j * cell_columns + c] = cdf_into(
                    texels.iter().map(|&y| y.max(0.0) as f64 * omega),
                    &mut column_cdf[j * w + k0..j * w + k1],
                );
            }
        }
        for r in 0..cell_rows {
            let (j0, j1) = (row_start[r], row_start[r + 1]);
            let omega: f64 = (j0..j1).map(|j| grid.texel_solid_angle(j)).sum();
            for c in 0..cell_columns {
                let mut cdf = vec![0f32; j1 - j0];
                cell_light[r * cell_columns + c] =
                    cdf_into((j0..j1).map(|j| row_light[j * cell_columns + c]), &mut cdf);
                cell_omega[r * cell_columns + c] =
                    omega * (column_start[c + 1] - column_start[c]) as f64;
                row_cdf[c * h + j0..c * h + j1].copy_from_slice(&cdf);
            }
        }
        let mut light = vec![0f64; columns * rows];
        for (f, &m) in cell_light.iter().enumerate() {
            let (r, c) = (f / cell_columns / kr, f % cell_columns / kc);
            light[r * columns + c] += m;
        }
        let mut texel_density = vec![0f32; w * h];
        for r in 0..cell_rows {
            for c in 0..cell_columns {
                let m = cell_light[r * cell_columns + c];
                if m > 0.0 {
                    for j in row_start[r]..row_start[r + 1] {
                        for k in column_start[c]..column_start[c + 1] {
                            texel_density[j * w + k] = (lum[j * w + k].max(0.0) as f64 / m) as f32;
                        }
                    }
                }
            }
        }
        let cell_radiance = cell_light
            .iter()
            .zip(&cell_omega)
            .map(|(&m, &o)| if o > 0.0 { (m / o) as f32 } else { 0.0 })
            .collect();
        let uv = |k: usize, j: usize| Vec2::new(k as f32 / w as f32, j as f32 / h as f32);
        let mut cell_centres = Vec::with_capacity(cell_light.len());
        for r in 0..cell_rows {
            for c in 0..cell_columns {
                let (a, b) = (
                    uv(column_start[c], row_start[r]),
                    uv(column_start[c + 1], row_start[r + 1]),
                );
                cell_centres.push(map.direction_of(0.5 * (a + b)));
            }
        }
        let s = points_per_side;
        let mut points = Vec::with_capacity(columns * rows * s * s);
        for r in 0..rows {
            for c in 0..columns {
                let a = uv(column_start[c * kc], row_start[r * kr]);
                let b = uv(column_start[(c + 1) * kc], row_start[(r + 1) * kr]);
                for sy in 0..s {
                    for sx in 0..s {
                        let fx = (sx as f32 + 0.5) / s as f32;
                        let fy = (sy as f32 + 0.5) / s as f32;
                        points.push(map.direction_of(Vec2::new(
                            a.x + fx * (b.x - a.x),
                            a.y + fy * (b.y - a.y),
                        )));
                    }
                }
            }
        }
        Ok(ProductEnv {
            map,
            columns,
            rows,
            sub_columns: kc,
            sub_rows: kr,
            column_place: places(&column_start, kc),
            row_place: places(&row_start, kr),
            texel_density,
            column_start,
            row_start,
            light,
            cell_light,
            cell_radiance,
            cell_centres,
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

    /// Sub-cells per block along a row and along a column.
    pub fn sub_cells(&self) -> (usize, usize) {
        (self.sub_columns, self.sub_rows)
    }

    /// Sub-cells per block, kc × kr.
    pub fn sub_cells_per_block(&self) -> usize {
        self.sub_columns * self.sub_rows
    }

    /// The map.
    pub fn map(&self) -> &Arc<EnvMap> {
        &self.map
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
        (self.light.len() + self.cell_light.len()) * 8
            + (self.row_cdf.len() + self.column_cdf.len() + self.cell_radiance.len()) * 4
            + (self.column_place.len() + self.row_place.len()) * 12
            + self.texel_density.len() * 4
            + (self.column_start.len() + self.row_start.len()) * 8
            + (self.points.len() + self.cell_centres.len()) * std::mem::size_of::<Vec3>()
    }

    /// The map's index of sub-cell `s` (row-major in its block) of block
    /// `b`.
    #[inline]
    pub fn cell_index(&self, b: usize, s: usize) -> usize {
        let (r, c) = (b / self.columns, b % self.columns);
        let row = r * self.sub_rows + s / self.sub_columns;
        let column = c * self.sub_columns + s % self.sub_columns;
        row * self.columns * self.sub_columns + column
    }

    /// M_f of the map's sub-cell `f` ([`cell_index`](Self::cell_index)).
    #[inline]
    pub fn cell_light(&self, f: usize) -> f64 {
        self.cell_light[f]
    }

    /// The direction (map frame) at the centre of the map's sub-cell `f`.
    #[inline]
    pub fn cell_centre(&self, f: usize) -> Vec3 {
        self.cell_centres[f]
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

    /// Where the world direction `dir` falls: its block, its sub-cell in
    /// the block, and its texel (k, j); `None` for a direction that is not
    /// finite or has no length.
    #[inline]
    fn locate(&self, dir: Vec3) -> Option<(usize, usize, usize, usize)> {
        let (k, j) = self.map.texel_of(dir)?;
        let ([cc, bc, sc], [cr, br, sr]) = (self.column_place[k], self.row_place[j]);
        let b = br as usize * self.columns + bc as usize;
        let s = sr as usize * self.sub_columns + sc as usize;
        let f = cr as usize * self.columns * self.sub_columns + cc as usize;
        Some((b, s, f, j * self.map.size().0 + k))
    }

    /// The block and sub-cell (in the block) of the world direction `dir`,
    /// and Y_t / M_f there (the density of a draw inside that sub-cell at
    /// `dir`); `None` for a direction that is not finite or has no length.
    #[inline]
    pub fn cell_density(&self, dir: Vec3) -> Option<(usize, usize, f32)> {
        let (b, s, _, t) = self.locate(dir)?;
        Some((b, s, self.texel_density[t]))
    }

    /// The block of the world direction `dir` and the mean radiance
    /// M_f / Ω_f of its sub-cell; `None` as [`cell_density`](Self::cell_density).
    #[inline]
    pub fn block_radiance(&self, dir: Vec3) -> Option<(usize, f32)> {
        let (b, _, f, _) = self.locate(dir)?;
        Some((b, self.cell_radiance[f]))
    }

    /// Draw a world direction inside the map's sub-cell `f` with density
    /// Y_t / M_f: `u.x` picks the row by its light and the place in it
    /// along θ, `u.y` the texel of that row by its light and the place
    /// along φ. `None` for a sub-cell without light.
    #[inline]
    pub fn sample_in_cell(&self, f: usize, u: Vec2) -> Option<Vec3> {
        let cell_columns = self.columns * self.sub_columns;
        let (r, c) = (f / cell_columns, f % cell_columns);
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
        let env = ProductEnv::new(map.clone(), 16, 2, 2).unwrap();
        assert_eq!(env.blocks(), (16, 8));
        assert_eq!(env.sub_cells(), (2, 2));
        let total: f64 = (0..env.block_count()).map(|b| env.light(b)).sum();
        let full = map.luminance_integral();
        assert!((total - full).abs() < 1e-6 * full, "{total} {full}");
        for b in 0..env.block_count() {
            let cells: f64 = (0..4).map(|s| env.cell_light(env.cell_index(b, s))).sum();
            assert!((cells - env.light(b)).abs() <= 1e-9 * env.light(b));
            for s in 0..4 {
                let f = env.cell_index(b, s);
                // Inside the texels: on an edge, rounding may find the neighbour.
                for u in [Vec2::new(0.1, 0.9), Vec2::new(0.7, 0.3), Vec2::splat(0.5)] {
                    match env.sample_in_cell(f, u) {
                        Some(d) => {
                            let (found, sub, density) = env.cell_density(d).unwrap();
                            assert_eq!((found, sub), (b, s));
                            assert!(density > 0.0);
                        }
                        None => assert_eq!(env.cell_light(f), 0.0, "block {b} cell {s}"),
                    }
                }
            }
        }
        // A block of fewer texels than sub-cells per side keeps whole texels.
        let coarse = ProductEnv::new(map.clone(), 64, 1, 4).unwrap();
        assert_eq!(coarse.sub_cells(), (1, 1));
        assert!(ProductEnv::new(map.clone(), 0, 2, 1).is_err());
        assert!(ProductEnv::new(map.clone(), 8, 2, 0).is_err());
        assert!(ProductEnv::new(map, 8, 2, 5).is_err());
    }
}
