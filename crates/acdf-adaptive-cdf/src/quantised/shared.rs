//! The kept slices of the isotropic outgoing sampler on one shared grid:
//! one set of marginal vertices (θ_h grid indices) and, per marginal
//! segment, one set of conditional vertices (φ_h grid indices), with every
//! slice's own 16-bit CDF values at those vertices.
//!
//! Sharing the vertices is what makes the blend of two slices cheap: a
//! draw searches the drawn slice's CDF values once per axis, and the other
//! slice's density at the drawn point is read at the same indices; a
//! density searches the positions once per axis and reads both slices
//! there. With vertices of their own, each slice needs its own two
//! searches.
//!
//! The grid is the one a simplifier keeps on the grid table: half the
//! mean of the slices' normalised tables p_s and half the sum of their
//! square roots Σ_s √p_s, each scaled to unit mass. The mean puts vertices
//! where the mass is, which a narrow specular peak needs; the root evens
//! out each slice's dynamic range, so that the grid also follows every
//! slice's tails (measured in `docs/results.md`).
//! Wherever any slice holds mass, so does the grid table, so every cell
//! with mass lies in a segment of the grid with a conditional, and each
//! slice's quantised masses keep every positive segment positive
//! ([`quantise`]).
//!
//! A file stores the slices as [`CompactSlices`]: every curve without its
//! two end vertices, which are always (0, 0) and (n, 65535), and a count of
//! inner vertices per conditional in place of its 16-bit offset;
//! [`SharedSlices::storage_bytes`] counts those bytes.

use super::packed::{
    check_curve, check_offsets, conditional_masses, grid_indices, quantise, QuantisedSegment,
    Stored, Q, QF,
};
use crate::curve::Curve;
use crate::packed_env::{row_sums, segment_masses};
use crate::simplify::{ErrorBound, Simplifier};
use crate::AdaptiveCdf2D;
use acdf_core::search::count_one;
#[cfg(target_arch = "x86_64")]
use acdf_core::simd::shared_grid::SharedGrid;
use acdf_core::{Error, Result};

/// Where a point of the unit square lies on the grid: its marginal
/// segment `j`, the index `at` of its conditional segment's first vertex
/// in the conditional arrays, and the factor that turns a slice's two
/// quantised segment masses into its density there.
#[derive(Debug, Clone, Copy)]
pub struct GridCell {
    j: usize,
    at: usize,
    scale: f32,
}

/// A draw from one slice: the point, the cell it lies in, and whether
/// every slice's density is the same over a box around it (the cell's
/// edges are every slice's).
#[derive(Debug, Clone, Copy)]
pub struct GridDraw {
    pub p: (f32, f32),
    pub cell: GridCell,
    pub same_around: bool,
}

/// The slices of an outgoing sampler on their shared grid (module
/// documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct SharedSlices {
    /// The m marginal positions (θ_h grid indices), then per marginal
    /// vertex where its segment's conditional starts in
    /// `conditional_pos` (the last, where they end).
    grid: Vec<u16>,
    m: usize,
    /// The conditionals' positions (φ_h grid indices), one after another;
    /// a marginal segment where no slice has mass has none.
    conditional_pos: Vec<u8>,
    /// Per slice, `stride` values: its m marginal CDF values, then its
    /// CDF values at every conditional position.
    cdf: Vec<u16>,
    stride: usize,
    count: usize,
    /// The most vertices a conditional has, less one (the length of its
    /// search in the batch lanes).
    longest_conditional: usize,
}

/// The share of a chi-square tolerance that the shared grid's marginal
/// (θ_h) gets; its conditionals (φ_h) get the rest. A quarter, where a
/// single table's simplification gives the marginal three quarters: the
/// marginal's vertices are shared by every slice's few values, while the
/// conditionals hold most of each slice's values, and the narrow lobes of
/// mirror-like metals need many θ_h vertices near their peak. On
/// nbrdf:chrome, a quarter lowers the relative variance by a third to a
/// half at 2 to 9 KB against three quarters, and on the mirror-like
/// metals it lowers the storage that reaches 0.95 of the 32x16x256x32
/// table's efficiency; on the plastics and paints the variance at equal
/// storage stays near that of three quarters (`docs/results.md`, "What
/// the mirror-like metals need from `outgoing`"). Other error bounds give
/// both axes the whole tolerance, as for a single table.
pub const SHARED_MARGINAL_SHARE: f64 = 0.25;

/// What a file stores of [`SharedSlices`]: each curve without its end
/// vertices, which are always (0, 0) and (n, 65535) (n the cells of its
/// axis), so that only the inner vertices cost storage.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CompactSlices {
    /// The marginal positions (θ_h grid indices) but the first and last.
    pub marginal_inner: Vec<u16>,
    /// Per marginal segment, the number of inner vertices of its
    /// conditional, or [`NO_CONDITIONAL`] for a segment without mass.
    pub counts: Vec<u8>,
    /// The conditionals' inner positions (φ_h grid indices), one
    /// conditional after another.
    pub conditional_inner: Vec<u8>,
    /// Per slice, its marginal's inner CDF values, then each
    /// conditional's.
    pub slice_inner: Vec<Vec<u16>>,
}

/// The count of [`CompactSlices`] that marks a marginal segment without a
/// conditional (a conditional has at most 254 inner vertices, since a
/// slice has at most 255 φ_h cells).
pub const NO_CONDITIONAL: u8 = u8::MAX;

/// Entries after the CDF values and the conditional positions that are
/// not part of them: a lane gather reads four bytes at an entry, so the
/// last value (two bytes) and the last position (one byte) need them
/// (`acdf_core::simd::shared_grid`). They are not stored in files or counted as storage.
const CDF_PAD: usize = 1;
const POSITION_PAD: usize = 3;

impl SharedSlices {
    /// The slices of the tables `tables` (row-major, `n_y` rows of `n_x`,
    /// not normalised) on the grid that `simplifier` at `tolerance` keeps
    /// on their grid table (module documentation; its first θ_h row
    /// pinned, as every BRDF table of this crate has it; a chi-square
    /// tolerance split by [`SHARED_MARGINAL_SHARE`]). A slice without
    /// any mass takes the grid table's masses. Errors when the vertices
    /// are too many for the 16-bit offsets, or the cells for the 8-bit φ_h
    /// positions.
    pub fn build(
        tables: &[Vec<f32>],
        n_x: usize,
        n_y: usize,
        simplifier: &dyn Simplifier,
        tolerance: f64,
    ) -> Result<Self> {
        if n_x > u8::MAX as usize || n_y > Q as usize {
            return Err(Error::InvalidParameter {
                name: "resolution",
                reason: format!(
                    "{n_y} theta_h x {n_x} phi_h cells: the outgoing sampler stores at most 65535 theta_h and 255 phi_h cells"
                ),
            });
        }
        let too_many = |what: &str| Error::InvalidParameter {
            name: "outgoing slices",
            reason: format!("{what} do not fit the stored indices"),
        };
        // Every table's row sums, once, and its total.
        let rows: Vec<Vec<f64>> = tables.iter().map(|t| row_sums(t, n_x)).collect();
        let totals: Vec<f64> = rows.iter().map(|r| r.iter().sum()).collect();
        let (mut mean, mut roots) = (vec![0.0f64; n_x * n_y], vec![0.0f64; n_x * n_y]);
        for (t, &total) in tables.iter().zip(&totals) {
            if total > 0.0 {
                for ((m, r), &v) in mean.iter_mut().zip(roots.iter_mut()).zip(t.iter()) {
                    let p = v as f64 / total;
                    *m += p;
                    *r += p.sqrt();
                }
            }
        }
        let (mean_total, root_total) = (mean.iter().sum::<f64>(), roots.iter().sum::<f64>());
        let grid_table: Vec<f64> = if mean_total > 0.0 {
            mean.iter()
                .zip(&roots)
                .map(|(&m, &r)| 0.5 * (m / mean_total + r / root_total))
                .collect()
        } else {
            mean
        };
        // Which rows hold mass is decided in f64, where no slice's mass
        // underflows.
        let grid_rows: Vec<f64> = grid_table
            .chunks_exact(n_x)
            .map(|r| r.iter().sum())
            .collect();
        let positive = |a: u16, b: u16| grid_rows[a as usize..b as usize].iter().sum::<f64>() > 0.0;
        let grid_table: Vec<f32> = grid_table.iter().map(|&v| v as f32).collect();
        // The shared positions; without any mass, one uniform cell.
        let any_mass = grid_table.iter().any(|&v| v > 0.0);
        let split = match simplifier.bound() {
            ErrorBound::ChiSquare => (
                SHARED_MARGINAL_SHARE * tolerance,
                (1.0 - SHARED_MARGINAL_SHARE) * tolerance,
            ),
            _ => (tolerance, tolerance),
        };
        let grid = any_mass
            .then(|| {
                AdaptiveCdf2D::from_values_pinned_split(&grid_table, n_x, n_y, simplifier, split, 1)
            })
            .transpose()?;
        let marginal_pos = match &grid {
            Some(g) => grid_indices(g.marginal_positions(), n_y)?,
            None => vec![0, n_y as u16],
        };
        let m = marginal_pos.len();
        let mut offsets = vec![0u16];
        let mut conditional_pos: Vec<u8> = Vec::new();
        for (j, w) in marginal_pos.windows(2).enumerate() {
            if grid.is_none() || positive(w[0], w[1]) {
                let kept = grid
                    .as_ref()
                    .filter(|g| j < g.conditional_count())
                    .map(|g| g.conditional_positions(j));
                let pos = match kept {
                    Some(xs) if xs.len() >= 2 => grid_indices(xs, n_x)?,
                    _ => vec![0, n_x as u16],
                };
                conditional_pos.extend(pos.iter().map(|&p| p as u8));
            }
            offsets.push(
                u16::try_from(conditional_pos.len())
                    .map_err(|_| too_many("the conditional vertices"))?,
            );
        }
        let c = conditional_pos.len();
        let stride = m + c;
        let mut cdf = Vec::with_capacity(stride * tables.len());
        let grid_table_rows = row_sums(&grid_table, n_x);
        for ((t, t_rows), &total) in tables.iter().zip(&rows).zip(&totals) {
            let (table, rows): (&[f32], &[f64]) = if total > 0.0 {
                (t, t_rows)
            } else {
                (&grid_table, &grid_table_rows)
            };
            let segment_mass = segment_masses(rows, &marginal_pos);
            if segment_mass.iter().sum::<f64>() > 0.0 {
                cdf.extend(quantise(&segment_mass));
            } else {
                // All tables zero: the uniform density.
                cdf.extend([0, Q]);
            }
            for (j, w) in marginal_pos.windows(2).enumerate() {
                let (a, b) = (offsets[j] as usize, offsets[j + 1] as usize);
                if a == b {
                    continue;
                }
                let pos: Vec<u16> = conditional_pos[a..b].iter().map(|&p| p as u16).collect();
                let mut masses = conditional_masses(table, n_x, (w[0], w[1]), &pos);
                if !(masses.iter().sum::<f64>() > 0.0) {
                    // This slice has no mass in the segment, so the
                    // conditional is never drawn from and its density is
                    // multiplied by zero; any valid curve does.
                    masses = pos.windows(2).map(|p| (p[1] - p[0]) as f64).collect();
                }
                cdf.extend(quantise(&masses));
            }
        }
        Ok(SharedSlices::assemble(
            [marginal_pos, offsets].concat(),
            m,
            conditional_pos,
            cdf,
            tables.len(),
        ))
    }

    /// The slices of their arrays (unpadded; `grid` the marginal positions
    /// then the offsets), padded for the lanes.
    fn assemble(
        grid: Vec<u16>,
        m: usize,
        mut conditional_pos: Vec<u8>,
        mut cdf: Vec<u16>,
        count: usize,
    ) -> Self {
        let stride = m + conditional_pos.len();
        let longest_conditional = grid
            .get(m..)
            .unwrap_or(&[])
            .windows(2)
            .map(|w| (w[1] as usize).saturating_sub(w[0] as usize + 1))
            .max()
            .unwrap_or(0)
            .max(1);
        conditional_pos.extend([0; POSITION_PAD]);
        cdf.extend([0; CDF_PAD]);
        SharedSlices {
            grid,
            m,
            conditional_pos,
            cdf,
            stride,
            count,
            longest_conditional,
        }
    }

    /// Slices of their stored arrays, as a decoder reads them (check with
    /// [`validate`](Self::validate) before use): the marginal positions,
    /// the offsets, the conditional positions, and per slice its marginal
    /// then conditional CDF values.
    pub fn from_arrays(
        marginal_pos: &[u16],
        offsets: &[u16],
        conditional_pos: Vec<u8>,
        slice_cdfs: &[Vec<u16>],
    ) -> Self {
        SharedSlices::assemble(
            [marginal_pos, offsets].concat(),
            marginal_pos.len(),
            conditional_pos,
            slice_cdfs.concat(),
            slice_cdfs.len(),
        )
    }

    /// The number of slices.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether there are no slices.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The shared marginal positions (θ_h grid indices).
    pub fn marginal_pos(&self) -> &[u16] {
        &self.grid[..self.m]
    }

    /// Per marginal vertex, where its segment's conditional starts in the
    /// conditional arrays (the last, where they end).
    pub fn offsets(&self) -> &[u16] {
        &self.grid[self.m..]
    }

    /// The stored arrays as the batch kernel of `acdf_core::simd` reads
    /// them; `None` if their shape does not allow it.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub fn lane_grid(&self) -> Option<SharedGrid<'_>> {
        SharedGrid::new(
            &self.grid,
            &self.conditional_pos,
            &self.cdf,
            self.count,
            self.longest_conditional,
            QF,
        )
    }

    /// The shared conditional positions (φ_h grid indices).
    pub fn conditional_pos(&self) -> &[u8] {
        &self.conditional_pos[..self.conditional_pos.len() - POSITION_PAD]
    }

    /// Slice `s`'s CDF values: the marginal's, then the conditionals'.
    pub fn slice_cdf(&self, s: usize) -> &[u16] {
        &self.cdf[s * self.stride..(s + 1) * self.stride]
    }

    /// The marginal curve of slice `s`.
    #[inline(always)]
    fn marginal(&self, s: usize) -> Curve<'_, u16, u16> {
        Curve::new(&self.grid, 0, &self.cdf, s * self.stride, self.m)
    }

    /// Where conditional j starts and ends in the conditional arrays.
    #[inline(always)]
    fn conditional_range(&self, j: usize) -> (usize, usize) {
        let at = &self.grid[self.m + j..self.m + j + 2];
        (at[0] as usize, at[1] as usize)
    }

    /// The cell of marginal segment j and the conditional segment starting
    /// at vertex `at`.
    #[inline(always)]
    fn cell(&self, j: usize, at: usize, n: (f32, f32)) -> GridCell {
        let y = &self.grid[j..j + 2];
        let x = &self.conditional_pos[at..at + 2];
        let width = (y[1] - y[0]) as f32 * (x[1] - x[0]) as f32;
        GridCell {
            j,
            at,
            scale: (n.0 * n.1) / (width * (QF * QF)),
        }
    }

    /// Draw (x, y) from slice `s` with u in [0, 1)^2: y from its marginal
    /// with u.y, x from the conditional of y's segment with u.x; with the
    /// cell drawn and whether the densities are the same over the box
    /// (x, y) ± `margin` (unit coordinates). `n` is (n_x, n_y).
    #[inline(always)]
    pub fn sample(
        &self,
        s: usize,
        u_x: f32,
        u_y: f32,
        n: (f32, f32),
        margin: (f32, f32),
    ) -> GridDraw {
        let (n_x, n_y) = n;
        let (y, j, sy) = self.marginal(s).sample(n_y, u_y);
        let (a, b) = self.conditional_range(j);
        let c_at = s * self.stride + self.m + a;
        let conditional = Curve::new(&self.conditional_pos, a, &self.cdf, c_at, b - a);
        let (x, i, sx) = conditional.sample(n_x, u_x);
        GridDraw {
            p: (x, y),
            cell: self.cell(j, a + i, n),
            same_around: sy.inside(y * n_y, margin.1 * n_y) & sx.inside(x * n_x, margin.0 * n_x),
        }
    }

    /// The cell of (x, y) in [0, 1)^2 (`None` where no slice has mass) and
    /// whether it holds the box (x, y) ± `margin`.
    #[inline(always)]
    pub fn locate(
        &self,
        x: f32,
        y: f32,
        n: (f32, f32),
        margin: (f32, f32),
    ) -> (Option<GridCell>, bool) {
        let (n_x, n_y) = n;
        let m = self.m;
        let ty = y * n_y;
        let j = count_one(&self.grid, 1, m - 2, u16::key(ty));
        let sy = QuantisedSegment {
            p: (self.grid[j] as f32, self.grid[j + 1] as f32),
            c: (0, 0),
        };
        let same_y = sy.inside(ty, margin.1 * n_y);
        let (a, b) = self.conditional_range(j);
        if a == b {
            return (None, same_y);
        }
        let tx = x * n_x;
        let i = count_one(&self.conditional_pos, a + 1, b - a - 2, u8::key(tx));
        let sx = QuantisedSegment {
            p: (
                self.conditional_pos[a + i] as f32,
                self.conditional_pos[a + i + 1] as f32,
            ),
            c: (0, 0),
        };
        let same_x = sx.inside(tx, margin.0 * n_x);
        (Some(self.cell(j, a + i, n)), same_y & same_x)
    }

    /// Slice `s`'s density over the unit square in `cell`: the product of
    /// its two quantised segment masses, scaled.
    #[inline(always)]
    pub fn density(&self, s: usize, cell: &GridCell) -> f32 {
        let base = s * self.stride;
        let my = &self.cdf[base + cell.j..base + cell.j + 2];
        let mx = &self.cdf[base + self.m + cell.at..base + self.m + cell.at + 2];
        let mass = (my[1] - my[0]) as f32 * (mx[1] - mx[0]) as f32;
        mass * cell.scale
    }

    /// Slice `s`'s density at (x, y) in [0, 1)^2, `n` = (n_x, n_y).
    pub fn pdf(&self, s: usize, x: f32, y: f32, n: (f32, f32)) -> f32 {
        match self.locate(x, y, n, (0.0, 0.0)).0 {
            Some(cell) => self.density(s, &cell),
            None => 0.0,
        }
    }

    /// Bytes kept, as [`compact`](Self::compact) stores them: two per
    /// inner marginal position and inner CDF value, one per segment's
    /// count and inner conditional position. The first and last vertex of
    /// every curve are always (0, 0) and (n, 65535), so they are not stored.
    pub fn storage_bytes(&self) -> usize {
        let (vertices, conditionals) = self.conditional_vertices();
        let inner_conditional = vertices - 2 * conditionals;
        let inner = self.m - 2 + inner_conditional;
        2 * (self.m - 2) + (self.m - 1) + inner_conditional + 2 * inner * self.count
    }

    /// The arrays that determine the slices: every curve without its two
    /// end vertices, and per marginal segment the count of its
    /// conditional's inner vertices (module documentation of
    /// [`CompactSlices`]).
    pub fn compact(&self) -> CompactSlices {
        let m = self.m;
        let offsets = self.offsets();
        let pos = self.conditional_pos();
        let mut counts = Vec::with_capacity(m - 1);
        let mut conditional_inner = Vec::new();
        for w in offsets.windows(2) {
            let (a, b) = (w[0] as usize, w[1] as usize);
            if a == b {
                counts.push(NO_CONDITIONAL);
            } else {
                // At most n_x - 1 <= 254 inner vertices: below the marker.
                counts.push((b - a - 2) as u8);
                conditional_inner.extend_from_slice(&pos[a + 1..b - 1]);
            }
        }
        let slice_inner = (0..self.count)
            .map(|s| {
                let values = self.slice_cdf(s);
                let mut inner = values[1..m - 1].to_vec();
                for w in offsets.windows(2) {
                    let (a, b) = (w[0] as usize, w[1] as usize);
                    if b > a {
                        inner.extend_from_slice(&values[m + a + 1..m + b - 1]);
                    }
                }
                inner
            })
            .collect();
        CompactSlices {
            marginal_inner: self.marginal_pos()[1..m - 1].to_vec(),
            counts,
            conditional_inner,
            slice_inner,
        }
    }

    /// The slices of their [`compact`](Self::compact) arrays on a grid of
    /// `n_x` × `n_y` cells, checked ([`validate`](Self::validate)): the
    /// end vertices put back, (0, 0) and (n, 65535) on every curve.
    pub fn from_compact(
        c: &CompactSlices,
        n_x: usize,
        n_y: usize,
    ) -> std::result::Result<Self, String> {
        let (x_end, y_end) = (
            u8::try_from(n_x).map_err(|_| format!("{n_x} phi_h cells do not fit 8 bits"))?,
            u16::try_from(n_y).map_err(|_| format!("{n_y} theta_h cells do not fit 16 bits"))?,
        );
        let m = c.marginal_inner.len() + 2;
        if c.counts.len() != m - 1 {
            return Err(format!(
                "{} conditional counts for {} marginal segments",
                c.counts.len(),
                m - 1
            ));
        }
        let marginal_pos = [&[0][..], &c.marginal_inner, &[y_end][..]].concat();
        let mut offsets = vec![0u16];
        let mut conditional_pos = Vec::new();
        let mut inner = c.conditional_inner.iter();
        let mut ranges = Vec::new();
        for &k in &c.counts {
            if k != NO_CONDITIONAL {
                let start = conditional_pos.len();
                conditional_pos.push(0);
                for _ in 0..k {
                    let p = inner
                        .next()
                        .ok_or("fewer conditional positions than counted")?;
                    conditional_pos.push(*p);
                }
                conditional_pos.push(x_end);
                ranges.push((start, k as usize));
            }
            offsets.push(
                u16::try_from(conditional_pos.len())
                    .map_err(|_| "the conditional vertices do not fit the offsets".to_string())?,
            );
        }
        if inner.next().is_some() {
            return Err("more conditional positions than counted".into());
        }
        let expected = m - 2 + c.conditional_inner.len();
        let mut cdfs = Vec::with_capacity(c.slice_inner.len());
        for values in &c.slice_inner {
            if values.len() != expected {
                return Err(format!(
                    "{} inner CDF values on a grid of {expected} inner vertices",
                    values.len()
                ));
            }
            let mut cdf = Vec::with_capacity(m + conditional_pos.len());
            cdf.push(0);
            cdf.extend_from_slice(&values[..m - 2]);
            cdf.push(Q);
            let mut at = m - 2;
            for &(_, k) in &ranges {
                cdf.push(0);
                cdf.extend_from_slice(&values[at..at + k]);
                cdf.push(Q);
                at += k;
            }
            cdfs.push(cdf);
        }
        let slices = SharedSlices::from_arrays(&marginal_pos, &offsets, conditional_pos, &cdfs);
        slices.validate(n_x, n_y)?;
        Ok(slices)
    }

    /// The number of marginal vertices.
    pub fn marginal_vertex_count(&self) -> usize {
        self.m
    }

    /// The number of conditional vertices, and of non-empty conditionals.
    pub fn conditional_vertices(&self) -> (usize, usize) {
        let stored = self.offsets().windows(2).filter(|w| w[1] > w[0]).count();
        (self.conditional_pos().len(), stored)
    }

    /// Check what a decoder read: the grid's curves run from 0 to n with
    /// increasing positions; every slice's CDF values run from 0 to 65535
    /// without decreasing; a marginal segment without a conditional has no
    /// mass in any slice.
    pub fn validate(&self, n_x: usize, n_y: usize) -> std::result::Result<(), String> {
        let m = self.m;
        let offsets = self.offsets();
        let c = self.conditional_pos().len();
        check_offsets(offsets, m, c)?;
        let values = self.cdf.len() - CDF_PAD;
        if self.count == 0 || self.stride != m + c || values != self.count * self.stride {
            return Err(format!(
                "{} CDF values for {} slices of {} vertices",
                values,
                self.count,
                m + c
            ));
        }
        for s in 0..self.count {
            let values = self.slice_cdf(s);
            let marginal_cdf = &values[..m];
            check_curve("marginal", self.marginal_pos(), marginal_cdf, n_y)?;
            for j in 0..m - 1 {
                let (a, b) = (offsets[j] as usize, offsets[j + 1] as usize);
                if a == b {
                    if marginal_cdf[j + 1] > marginal_cdf[j] {
                        return Err(format!(
                            "slice {s}: mass in segment {j}, which has no conditional"
                        ));
                    }
                    continue;
                }
                check_curve(
                    "conditional",
                    &self.conditional_pos[a..b],
                    &values[m + a..m + b],
                    n_x,
                )?;
            }
        }
        Ok(())
    }
}
