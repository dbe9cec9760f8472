//! Piecewise-constant distributions over [0, 1) and [0, 1)^2 built from
//! uniformly spaced tables.
//!
//! A table of `n` non-negative values f_k describes the step function
//! f(x) = f_k for x in [k/n, (k+1)/n). Its cumulative distribution is stored
//! at the right edge of every cell, P_k = (f_0 + ... + f_k) / (f_0 + ... +
//! f_{n-1}), accumulated in `f64` and rounded once to `f32`; the value
//! P_{-1} = 0 at x = 0 is implicit and not stored. Rounding is monotone, so
//! the stored CDF is non-decreasing, and the last entry is exactly 1.
//!
//! **The density is defined by the stored CDF**, not by the original values:
//! the density of cell k is p_k = n (P_k - P_{k-1}). That is exactly the
//! density with which [`Distribution1D::sample`] maps a uniform `u` to `x`,
//! so `sample`, `pdf` and `invert` agree to rounding, a cell is never drawn
//! where `pdf` is zero, and a cell that `pdf` calls zero is never drawn. It
//! differs from f_k / ∫f only by the `f32` rounding of the CDF (an absolute
//! error of at most 2^-24 in a cell's probability).
//!
//! **Searching.** A draw finds its cell as the number of stored CDF entries
//! at or below u. The 1D CDF and the 2D marginal keep a guide table (the
//! cutpoint method: for each of n equal intervals of u, 256 for the
//! marginal, the range of cells it can land in), so the expected search is
//! a single 8-wide SIMD compare;
//! a 2D conditional of up to 64 cells is counted by comparing every entry.
//! Both give exactly the cell of a binary search, so the mapping from u to
//! x stays monotone. Where the CPU has AVX2, `sample_batch` and `pdf_batch`
//! run in SIMD lanes instead (`distribution/gather.rs`: 32 draws per stage,
//! both searches by binary lifting with gathers); elsewhere `sample_batch`
//! runs sixteen draws in scalar stages. Both return exactly what `sample`
//! and `pdf` return.
//!
//! **All-zero input.** A table (or a row of a 2D table) that sums to zero
//! falls back to the uniform density; `integral()` then reports 0. In a 2D
//! table a zero row gets a uniform conditional, but its marginal probability
//! is 0 unless the whole table is zero, so it is never drawn.

use crate::persist::{ByteReader, ByteWriter, Persist, PersistError};
#[cfg(target_arch = "x86_64")]
mod gather;
use acdf_core::fast::grid_cell;
use acdf_core::search;
use acdf_core::{
    clamp_unit, validate_table, Distribution1D, Distribution2D, Error, Result, Sample1D, Sample2D,
    Vec2, ONE_MINUS_EPSILON,
};

/// The largest number of cells along one axis: beyond 2^24 neighbouring
/// cell boundaries k/n are no longer distinct `f32` values.
pub const MAX_CELLS: usize = 1 << 24;

/// The number of entries of `cdf` that are `<= u`, for a non-decreasing
/// `cdf`, by the shared branch-free search ([`acdf_core::search`]).
#[inline(always)]
pub(crate) fn count_at_or_below(cdf: &[f32], u: f32) -> usize {
    search::count_short_or_search(cdf, 0, cdf.len(), u)
}

/// The cutpoint index (guide table) of a stored CDF: the shared
/// [`search::Guide`] over its searched entries (all but the last, which is
/// 1), with G equal intervals of u (G = n for a 1D distribution, a fixed
/// [`MARGINAL_GUIDE_CELLS`] for a 2D marginal), so that the search inspects
/// a handful of entries instead of log n and returns exactly the cell of a
/// plain search. Derived from the CDF (rebuilt when a distribution is read
/// back, never stored); a CDF of more than 2^16 searched entries is
/// searched without it. The count within an interval compares a window of
/// [`GUIDE_WINDOW`] entries, narrower than the shared guide's: here G is
/// at least the number of cells, so intervals hold few entries.
#[derive(Debug, Clone, PartialEq, Default)]
struct Guide {
    index: search::Guide,
    /// G.
    cells: usize,
}

/// G of a 2D marginal's guide, whatever the number of rows.
///
/// A fixed G lets the guide cell of u.y be found from u.y alone, with a
/// constant scale, instead of after G is read from the distribution. One
/// draw at a time that matters: a tabulated sampler locates the slice from
/// wo just before it draws, and a scale read from the slice put the cell's
/// multiply, clamps and conversion after that lookup on every draw's chain.
/// The uniform sampler's `sample` ran 6 to 14% faster with the constant
/// (built-in nickel, 256 rows, so the same guide as G = n: 17.0-17.4 to
/// 18.5-19.4 M/s, a scratch loop of the bench's calls, best of 15 runs of
/// 10^6, three alternating runs on a Zen 5 machine; a row count passed in
/// by the sampler and checked against the slice's gained only 3 to 4%).
/// 256 is the default θ_h resolution; marginals with many more rows get
/// wider guide intervals, and those wider than [`GUIDE_WINDOW`] are
/// searched: on a nickel slice of 1024 rows a draw that waits for the one
/// before took 19.5-19.6 ns against 19.0-19.4 with G = n (and 90 rows,
/// 18.8-19.1 against 19.1-19.3; scratch loop, two alternating runs).
pub(crate) const MARGINAL_GUIDE_CELLS: usize = 256;

/// The widest guide interval searched with fixed, branch-free comparisons
/// (one 8-wide SIMD compare).
pub(crate) const GUIDE_WINDOW: usize = 8;

impl Guide {
    /// The guide of a stored CDF (all n entries, the last being 1; the
    /// searched entries are the first n - 1) with G = n intervals.
    fn new(cdf: &[f32]) -> Guide {
        Self::with_cells(cdf, cdf.len())
    }

    /// The guide of a stored CDF with G = `g_count` intervals (at least 1).
    fn with_cells(cdf: &[f32], g_count: usize) -> Guide {
        Guide {
            index: search::Guide::new(&cdf[..cdf.len().saturating_sub(1)], g_count),
            cells: g_count,
        }
    }

    /// cell(u) = min(floor(u G), G - 1); NaN and negatives give 0.
    #[inline(always)]
    fn cell(&self, u: f32) -> usize {
        search::Guide::cell(u, self.cells)
    }

    /// Whether there is no guide.
    #[inline(always)]
    fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// Heap bytes of the index.
    fn bytes(&self) -> usize {
        self.index.bytes()
    }

    /// The number of entries of `cdf[..n - 1]` that are `<= u`, for the CDF
    /// the guide was built from and u in [0, 1).
    #[inline(always)]
    fn count_at_or_below(&self, cdf: &[f32], u: f32) -> usize {
        if self.is_empty() {
            return count_at_or_below(&cdf[..cdf.len() - 1], u);
        }
        self.count_from_cell(cdf, u, self.cell(u))
    }

    /// [`count_at_or_below`](Self::count_at_or_below) for a guide that
    /// exists, given g = [`cell`](Self::cell)`(u)`.
    #[inline(always)]
    fn count_from_cell(&self, cdf: &[f32], u: f32, g: usize) -> usize {
        let n = cdf.len();
        let lo = self.index.counts();
        let (a, b) = (lo[g] as usize, lo[g + 1] as usize);
        if b - a <= GUIDE_WINDOW && n >= GUIDE_WINDOW {
            // Count a fixed window of entries from a (moved left to stay
            // inside the table): entries before a are below u and entries
            // from b on (the last entry, 1, included) above it, so the count
            // is exact; a fixed-size window compiles to SIMD compares.
            let start = a.min(n - GUIDE_WINDOW);
            start + count_window(window(cdf, start), u)
        } else {
            a + count_at_or_below(&cdf[a..b], u)
        }
    }
}

/// The eight entries of `cdf` from `start` (which must leave room for them).
#[inline(always)]
fn window(cdf: &[f32], start: usize) -> &[f32; GUIDE_WINDOW] {
    cdf[start..start + GUIDE_WINDOW]
        .try_into()
        .expect("the caller leaves room for a window")
}

/// The number of entries of a non-decreasing window that are `<= u`, for u
/// not NaN.
///
/// On x86_64 this is two 4-wide compares (SSE2, part of the baseline) whose
/// sign bits form a mask; the window is sorted, so the mask is a run of ones
/// from bit 0 and the count is the position of its first zero. Elsewhere the
/// entries are compared one by one.
#[inline(always)]
fn count_window(w: &[f32; GUIDE_WINDOW], u: f32) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_cmple_ps, _mm_loadu_ps, _mm_movemask_ps, _mm_set1_ps};
        // SAFETY: SSE2 is enabled on every x86_64 target, and both loads
        // read four floats inside the eight of `w`.
        let mask = unsafe {
            let uv = _mm_set1_ps(u);
            let lo = _mm_cmple_ps(_mm_loadu_ps(w.as_ptr()), uv);
            let hi = _mm_cmple_ps(_mm_loadu_ps(w.as_ptr().add(4)), uv);
            (_mm_movemask_ps(lo) | (_mm_movemask_ps(hi) << 4)) as u32
        };
        (!mask).trailing_zeros() as usize
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        w.iter().map(|&c| (c <= u) as usize).sum()
    }
}

/// The number of entries of a non-decreasing `row` that are `<= u`, for a
/// row whose length is a multiple of 8 (at most [`LINEAR_ROW`]).
///
/// The last entry of each block of eight is compared first: the blocks
/// whose last entry is `<= u` are wholly counted, and only the next block
/// is counted entry by entry ([`count_window`]). Both steps are fixed
/// sequences of compares with no data-dependent branch, so a row of 32
/// costs three scalar and two 4-wide compares.
#[inline(always)]
pub(crate) fn count_linear(row: &[f32], u: f32) -> usize {
    let blocks = row.len() / GUIDE_WINDOW;
    let mut full = 0;
    for b in 0..blocks - 1 {
        full += (row[b * GUIDE_WINDOW + GUIDE_WINDOW - 1] <= u) as usize;
    }
    let start = full * GUIDE_WINDOW;
    start + count_window(window(row, start), u)
}

/// The number of entries of `row` that are `<= u`, comparing them all:
/// for short rows of other lengths.
#[inline(always)]
fn count_all(row: &[f32], u: f32) -> usize {
    row.iter().map(|&c| (c <= u) as usize).sum()
}

/// The longest row counted by [`count_linear`] or [`count_all`].
pub(crate) const LINEAR_ROW: usize = 64;

/// The cell of x in a uniform grid of `n` cells over [0, 1): floor(x n),
/// clamped to [0, n-1]; the one rule `sample` and `pdf` share. `nf` is n
/// as `f32` (exact, since n <= [`MAX_CELLS`]).
#[inline(always)]
fn cell_of(x: f32, n: usize, nf: f32) -> usize {
    debug_assert_eq!(nf, n as f32);
    // Negative and NaN give 0.
    grid_cell(x * nf, nf - 1.0)
}

/// Fill `cdf` (length n) with the normalised running sums of `values`, in
/// `f64`; returns the total. A zero total gives the uniform CDF (k+1)/n.
fn build_cdf(values: impl Iterator<Item = f64>, cdf: &mut [f32]) -> f64 {
    let n = cdf.len();
    let mut running = Vec::with_capacity(n);
    let mut total = 0.0f64;
    for v in values {
        total += v;
        running.push(total);
    }
    fill_cdf(&running, total, cdf);
    total
}

/// Normalise the running sums (the last of which is `total`) into `cdf`.
fn fill_cdf(running: &[f64], total: f64, cdf: &mut [f32]) {
    let n = cdf.len();
    if total > 0.0 && total.is_finite() {
        for (c, &r) in cdf.iter_mut().zip(running) {
            *c = (r / total) as f32;
        }
    } else {
        for (k, c) in cdf.iter_mut().enumerate() {
            *c = ((k + 1) as f64 / n as f64) as f32;
        }
    }
    // Exactly 1 whatever the rounding, so every u < 1 finds a cell.
    cdf[n - 1] = 1.0;
}

/// P_{k-1}, the stored CDF at the left edge of cell k (0 for k = 0),
/// without a branch: k = 0 is common (peaked tables put much of their mass
/// in the first cell) and unpredictable.
#[inline(always)]
fn lower_edge(cdf: &[f32], k: usize) -> f32 {
    // 1 when k != 0, from the top bit of k | -k.
    let nonzero = (k | k.wrapping_neg()) >> (usize::BITS - 1);
    let mask = (nonzero as u32).wrapping_neg();
    f32::from_bits(cdf[k.saturating_sub(1)].to_bits() & mask)
}

/// Given the cell k with P_{k-1} <= u < P_k (found by a search over all but
/// the last entry, which is 1 > u), the position `du` in [0, 1) of u inside
/// it and the cell's probability P_k - P_{k-1} > 0.
#[inline(always)]
fn within_cell(cdf: &[f32], k: usize, u: f32) -> (f32, f32) {
    let lower = lower_edge(cdf, k);
    let mass = cdf[k] - lower;
    let du = ((u - lower) / mass).clamp(0.0, ONE_MINUS_EPSILON);
    (du, mass)
}

/// x = (k + du) / n, computed as (k + du) · `inv` with `inv` = 1 / nf in
/// `f32`, nudged by an ulp if rounding carried it out of cell k (so that
/// `pdf(x)` finds the cell it was drawn from).
#[inline(always)]
fn position_in_cell(k: usize, du: f32, n: usize, nf: f32, inv: f32) -> f32 {
    let kf = k as u32 as f32;
    let mut x = ((kf + du) * inv).min(ONE_MINUS_EPSILON);
    // x n - k in [0, 1) is floor(x n) = k, which is `cell_of(x) == k` for
    // the k < n of a draw: the form the box test of the draw computes too
    // (`inside_drawn_cell`), so the two share it.
    let f = x * nf - kf;
    if (0.0..1.0).contains(&f) {
        return x;
    }
    // Rare: rounding put x on a boundary. A couple of ulps always suffice.
    while cell_of(x, n, nf) > k {
        x = x.next_down();
    }
    while cell_of(x, n, nf) < k {
        x = x.next_up();
    }
    x
}

/// Reject an axis longer than [`MAX_CELLS`].
fn check_cells(what: &'static str, n: usize) -> Result<()> {
    if n > MAX_CELLS {
        return Err(Error::InvalidParameter {
            name: what,
            reason: format!("{n} cells along one axis; at most {MAX_CELLS} are supported"),
        });
    }
    Ok(())
}

/// The probability of cell k under a stored CDF.
#[inline(always)]
fn cell_mass(cdf: &[f32], k: usize) -> f32 {
    cdf[k] - lower_edge(cdf, k)
}

/// P(x) for a stored CDF: the running probability up to cell floor(x n) plus
/// the linear part inside it; x is clamped to [0, 1].
#[inline]
fn cdf_at(cdf: &[f32], x: f32) -> f32 {
    let n = cdf.len();
    if !(x > 0.0) {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let nf = n as f32;
    let k = cell_of(x, n, nf);
    let lower = if k == 0 { 0.0 } else { cdf[k - 1] };
    let t = (x * nf - k as f32).clamp(0.0, 1.0);
    (lower + t * (cdf[k] - lower)).min(1.0)
}

/// A piecewise-constant density over [0, 1) from `n` uniform cells.
#[derive(Debug, Clone, PartialEq)]
pub struct PiecewiseConstant1D {
    cdf: Vec<f32>,
    integral: f64,
    /// Derived from `cdf`.
    guide: Guide,
}

impl PiecewiseConstant1D {
    /// Build from the cell values f_k; rejects empty tables, more than
    /// [`MAX_CELLS`] cells and entries that are NaN, infinite or negative
    /// (see [`validate_table`]). A table that sums to zero gives the uniform
    /// density with `integral() == 0`.
    pub fn new(values: &[f32]) -> Result<Self> {
        check_cells("PiecewiseConstant1D cells", values.len())?;
        validate_table("PiecewiseConstant1D", values)?;
        let mut cdf = vec![0.0f32; values.len()];
        let total = build_cdf(values.iter().map(|&v| v as f64), &mut cdf);
        Ok(PiecewiseConstant1D {
            integral: total / values.len() as f64,
            guide: Guide::new(&cdf),
            cdf,
        })
    }

    /// The number of cells n.
    pub fn count(&self) -> usize {
        self.cdf.len()
    }

    /// The normalised CDF at the right edge of each cell: P_k = P((k+1)/n),
    /// non-decreasing, the last entry exactly 1 (P(0) = 0 is implicit).
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }

    /// The normalised density of cell k, p_k = n (P_k - P_{k-1}); zero for
    /// k >= n.
    pub fn cell_pdf(&self, k: usize) -> f32 {
        if k >= self.cdf.len() {
            return 0.0;
        }
        cell_mass(&self.cdf, k) * self.cdf.len() as f32
    }

    /// The normalised density of every cell, p_k (allocates; for building
    /// other distributions and for tests, not for sampling).
    pub fn func(&self) -> Vec<f32> {
        (0..self.count()).map(|k| self.cell_pdf(k)).collect()
    }

    /// The sample for a clamped `u` once its cell k is known.
    #[inline(always)]
    fn finish(&self, k: usize, u: f32) -> Sample1D {
        let n = self.cdf.len();
        let nf = n as f32;
        let (du, mass) = within_cell(&self.cdf, k, u);
        Sample1D {
            x: position_in_cell(k, du, n, nf, 1.0 / nf),
            pdf: mass * nf,
        }
    }
}

impl Distribution1D for PiecewiseConstant1D {
    /// x = (k + (u - P_{k-1}) / (P_k - P_{k-1})) / n for the cell k with
    /// P_{k-1} <= u < P_k; density n (P_k - P_{k-1}) > 0.
    #[inline]
    fn sample(&self, u: f32) -> Sample1D {
        let u = clamp_unit(u);
        let k = self.guide.count_at_or_below(&self.cdf, u);
        self.finish(k, u)
    }

    /// p(x) = n (P_k - P_{k-1}) with k = floor(x n); 0 outside [0, 1).
    #[inline]
    fn pdf(&self, x: f32) -> f32 {
        if !(0.0..1.0).contains(&x) {
            return 0.0;
        }
        let n = self.cdf.len();
        let nf = n as f32;
        cell_mass(&self.cdf, cell_of(x, n, nf)) * nf
    }

    /// P(x), piecewise linear between the stored CDF values.
    fn invert(&self, x: f32) -> f32 {
        cdf_at(&self.cdf, x)
    }

    /// ∫₀¹ f = (Σ f_k) / n, of the values given to [`new`](Self::new).
    fn integral(&self) -> f64 {
        self.integral
    }

    /// The CDF and its guide table.
    fn storage_bytes(&self) -> usize {
        self.cdf.capacity() * std::mem::size_of::<f32>() + self.guide.bytes()
    }

    /// The same samples as [`sample`](Distribution1D::sample): where the CPU
    /// has AVX2, 32 at a time in SIMD lanes (`distribution/gather.rs`);
    /// elsewhere one at a time (the guided search has no loop-carried
    /// dependence, so the out-of-order core overlaps consecutive draws).
    fn sample_batch(&self, u: &[f32], out: &mut [Sample1D]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && self.fits_lanes() {
            // SAFETY: the CPU has just been found to support AVX2, and the
            // CDF fits the lanes.
            unsafe { self.sample_batch_gather(u, out) };
            return;
        }
        for (o, &u) in out.iter_mut().zip(u) {
            *o = self.sample(u);
        }
    }
}

/// A piecewise-constant density over [0, 1)^2 from a row-major table of
/// `ny` rows of `nx` cells: a marginal CDF over the rows (y) and one
/// conditional CDF over x per row, stored flat for locality.
#[derive(Debug, Clone, PartialEq)]
pub struct PiecewiseConstant2D {
    nx: usize,
    ny: usize,
    /// `ny` rows of `nx` entries: P(x < (k+1)/nx | row).
    conditional: Vec<f32>,
    /// `ny` entries: P(y < (j+1)/ny).
    marginal: Vec<f32>,
    integral: f64,
    /// The guide of `marginal`, derived from it.
    marginal_guide: Guide,
    /// nx and ny as `f32` and their reciprocals, derived from them: a draw
    /// would otherwise convert both and divide twice.
    scale: GridScale,
}

/// The two axis lengths of a 2D grid as `f32` and their reciprocals.
#[derive(Debug, Clone, Copy, PartialEq)]
struct GridScale {
    nxf: f32,
    nyf: f32,
    inv_nx: f32,
    inv_ny: f32,
}

impl GridScale {
    fn new(nx: usize, ny: usize) -> Self {
        let (nxf, nyf) = (nx as f32, ny as f32);
        GridScale {
            nxf,
            nyf,
            inv_nx: 1.0 / nxf,
            inv_ny: 1.0 / nyf,
        }
    }
}

impl PiecewiseConstant2D {
    /// Build from `values` (row-major, `ny` rows of `nx`); rejects zero
    /// dimensions, a length other than nx·ny, and entries that are NaN,
    /// infinite or negative. Zero rows and an all-zero table fall back to
    /// uniform as described in the module documentation.
    pub fn new(values: &[f32], nx: usize, ny: usize) -> Result<Self> {
        const WHAT: &str = "PiecewiseConstant2D";
        if nx == 0 || ny == 0 {
            return Err(Error::EmptyTable { what: WHAT });
        }
        check_cells("PiecewiseConstant2D nx", nx)?;
        check_cells("PiecewiseConstant2D ny", ny)?;
        let expected = nx.checked_mul(ny).ok_or_else(|| Error::InvalidParameter {
            name: "nx * ny",
            reason: format!("{nx} x {ny} overflows"),
        })?;
        if values.len() != expected {
            return Err(Error::SizeMismatch {
                what: WHAT,
                expected,
                got: values.len(),
            });
        }
        validate_table(WHAT, values)?;
        let mut conditional = vec![0.0f32; expected];
        let mut running = Vec::with_capacity(nx.max(ny));
        let mut row_sums = Vec::with_capacity(ny);
        for (row, cdf) in values
            .chunks_exact(nx)
            .zip(conditional.chunks_exact_mut(nx))
        {
            running.clear();
            let mut total = 0.0f64;
            for &v in row {
                total += v as f64;
                running.push(total);
            }
            fill_cdf(&running, total, cdf);
            row_sums.push(total);
        }
        let mut marginal = vec![0.0f32; ny];
        let total = build_cdf(row_sums.iter().copied(), &mut marginal);
        Ok(PiecewiseConstant2D {
            nx,
            ny,
            conditional,
            marginal_guide: marginal_guide(&marginal),
            marginal,
            integral: total / expected as f64,
            scale: GridScale::new(nx, ny),
        })
    }

    /// The number of cells along x (columns).
    pub fn nx(&self) -> usize {
        self.nx
    }

    /// The number of cells along y (rows).
    pub fn ny(&self) -> usize {
        self.ny
    }

    /// The number of cells nx·ny.
    pub fn count(&self) -> usize {
        self.nx * self.ny
    }

    /// The marginal CDF over rows at the top edge of each row:
    /// P(y < (j+1)/ny), the last entry exactly 1.
    pub fn marginal(&self) -> &[f32] {
        &self.marginal
    }

    /// The conditional CDF of x within row `row` at the right edge of each
    /// cell: P(x < (k+1)/nx | row); `None` for a row out of range.
    pub fn conditional(&self, row: usize) -> Option<&[f32]> {
        (row < self.ny).then(|| &self.conditional[row * self.nx..(row + 1) * self.nx])
    }

    /// All conditional CDFs, row-major (`ny` rows of `nx`).
    pub fn cdf(&self) -> &[f32] {
        &self.conditional
    }

    /// The normalised density of cell (column `ix`, row `iy`):
    /// p = ny (M_j - M_{j-1}) · nx (C_k - C_{k-1}); 0 out of range. When both
    /// probabilities are positive the product is at least the smallest
    /// positive `f32`, so a cell that can be drawn never reports 0.
    #[inline(always)]
    pub fn cell_pdf(&self, ix: usize, iy: usize) -> f32 {
        if ix >= self.nx || iy >= self.ny {
            return 0.0;
        }
        let row = &self.conditional[iy * self.nx..(iy + 1) * self.nx];
        joint_pdf(
            cell_mass(&self.marginal, iy) * self.ny as f32,
            cell_mass(row, ix) * self.nx as f32,
        )
    }

    /// The normalised density of every cell, row-major (allocates).
    pub fn func(&self) -> Vec<f32> {
        (0..self.ny)
            .flat_map(|iy| (0..self.nx).map(move |ix| (ix, iy)))
            .map(|(ix, iy)| self.cell_pdf(ix, iy))
            .collect()
    }

    /// The column k of a clamped `u` in row j's conditional CDF: the number
    /// of entries `<= u`. The last entry of a row is 1 > u, so counting the
    /// whole row equals counting all but its last entry.
    ///
    /// A row of up to [`search::WINDOW`] (32) entries is compared all at
    /// once ([`search::count_window`]): its loads and compares are
    /// independent, so a draw waits for one load, one compare and the
    /// mask, where [`count_linear`] chains two loads and two compares. One
    /// call at a time this made the uniform sampler's `sample` 2 to 3%
    /// faster on the built-in nickel (15.8-16.0 to 16.3-16.4 M/s, best of
    /// 10 runs of 10^6 calls, wo changing every call, five alternating
    /// runs on a Zen 5 machine).
    #[inline(always)]
    fn column(&self, j: usize, u: f32) -> usize {
        let nx = self.nx;
        if nx <= search::WINDOW && self.conditional.len() >= search::WINDOW {
            return search::count_window(&self.conditional, j * nx, nx, u);
        }
        let row = &self.conditional[j * nx..(j + 1) * nx];
        if row.len() <= LINEAR_ROW && row.len().is_multiple_of(GUIDE_WINDOW) {
            count_linear(row, u)
        } else if row.len() <= LINEAR_ROW {
            count_all(row, u)
        } else {
            count_at_or_below(&row[..row.len() - 1], u)
        }
    }

    /// The row j drawn by v = u.y in [0, 1): the number of marginal
    /// entries `<= v`, through the guide, whose cell is found with the
    /// constant G ([`MARGINAL_GUIDE_CELLS`]) rather than the stored scale.
    #[inline(always)]
    fn row(&self, v: f32) -> usize {
        let guide = &self.marginal_guide;
        if guide.is_empty() {
            return count_at_or_below(&self.marginal[..self.ny - 1], v);
        }
        debug_assert_eq!(guide.cells, MARGINAL_GUIDE_CELLS);
        guide.count_from_cell(
            &self.marginal,
            v,
            search::Guide::cell(v, MARGINAL_GUIDE_CELLS),
        )
    }

    /// Start loading the conditional row that a draw with this v = u.y
    /// most likely takes: the first row of v's guide interval, which holds
    /// one or two rows on most tables ([`search::prefetch`]). The
    /// uniform sampler's `sample`, one call at a time, ran 2 to 5% faster
    /// with it (built-in nickel, wo changing every call, best of 15 runs of
    /// 10^6, four alternating runs on a Zen 5 machine; prefetching the
    /// interval's last row as well gained nothing more).
    #[inline(always)]
    fn prefetch_likely_row(&self, v: f32) {
        let g = search::Guide::cell(v, MARGINAL_GUIDE_CELLS);
        let row = self.marginal_guide.index.first(g);
        search::prefetch(&self.conditional, row * self.nx, self.nx);
    }

    /// The sample for `u` (clamped into [0, 1)^2) with its row j and
    /// column k.
    #[inline(always)]
    fn draw(&self, u: Vec2) -> (Sample2D, usize, usize) {
        let u = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
        self.prefetch_likely_row(u.y);
        let j = self.row(u.y);
        let k = self.column(j, u.x);
        (self.finish(j, k, u), j, k)
    }

    /// The sample for a clamped `u` once its row j and column k are known.
    #[inline(always)]
    fn finish(&self, j: usize, k: usize, u: Vec2) -> Sample2D {
        let (nx, ny) = (self.nx, self.ny);
        let GridScale {
            nxf,
            nyf,
            inv_nx,
            inv_ny,
        } = self.scale;
        let (dv, row_mass) = within_cell(&self.marginal, j, u.y);
        let row = &self.conditional[j * nx..(j + 1) * nx];
        let (du, col_mass) = within_cell(row, k, u.x);
        Sample2D {
            p: Vec2::new(
                position_in_cell(k, du, nx, nxf, inv_nx),
                position_in_cell(j, dv, ny, nyf, inv_ny),
            ),
            pdf: joint_pdf(row_mass * nyf, col_mass * nxf),
        }
    }

    /// [`sample`](Distribution2D::sample) and
    /// [`same_cell_around`](Self::same_cell_around)`(sample.p, margin)` at
    /// once. The draw knows its cell (k, j), so the box test takes the
    /// fraction of x within the cell as x nx - k instead of truncating x nx
    /// (`inside_drawn_cell`): the same answer, a few instructions fewer
    /// on every draw.
    #[inline(always)]
    pub fn sample_and_same_cell(&self, u: Vec2, margin: Vec2) -> (Sample2D, bool) {
        let (s, j, k) = self.draw(u);
        // `&`: no short-circuit branch.
        let same = inside_drawn_cell(s.p.x, k, self.scale.nxf, margin.x)
            & inside_drawn_cell(s.p.y, j, self.scale.nyf, margin.y);
        (s, same)
    }
}

/// [`inside_cell`] for an x drawn in cell k of a grid of nf cells, whose
/// floor(x nf) is then k (`position_in_cell`): the fraction x nf - k equals
/// x nf - floor(x nf) bit for bit. Where x nf rounds up to the top edge of
/// the last cell both forms give a fraction outside [m nf, 1 - m nf].
#[inline(always)]
fn inside_drawn_cell(x: f32, k: usize, nf: f32, m: f32) -> bool {
    let f = x * nf - k as u32 as f32;
    let m = m * nf;
    (f >= m) & (f <= 1.0 - m)
}

/// The guide of a 2D marginal: [`MARGINAL_GUIDE_CELLS`] intervals.
fn marginal_guide(marginal: &[f32]) -> Guide {
    Guide::with_cells(marginal, MARGINAL_GUIDE_CELLS)
}

/// The product of a marginal and a conditional density, kept from
/// underflowing to 0 when both are positive.
#[inline(always)]
fn joint_pdf(marginal: f32, conditional: f32) -> f32 {
    let p = marginal * conditional;
    if marginal > 0.0 && conditional > 0.0 {
        p.max(f32::from_bits(1))
    } else {
        p
    }
}

impl Distribution2D for PiecewiseConstant2D {
    /// The row j from the marginal with u.y, then the column k from row j's
    /// conditional with u.x; density ny (M_j - M_{j-1}) · nx (C_k - C_{k-1}).
    #[inline(always)]
    fn sample(&self, u: Vec2) -> Sample2D {
        self.draw(u).0
    }

    /// The same densities as [`pdf`](Distribution2D::pdf), bit for bit:
    /// where the CPU has AVX2, eight points at a time in SIMD lanes
    /// (`distribution/gather.rs`), elsewhere one at a time.
    fn pdf_batch(&self, p: &[Vec2], out: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && self.fits_pdf_lanes() {
            // SAFETY: the CPU has just been found to support AVX2, and the
            // table fits the lanes.
            unsafe { self.pdf_batch_gather(p, out) };
            return;
        }
        for (o, &p) in out.iter_mut().zip(p) {
            *o = self.pdf(p);
        }
    }

    /// p(x, y) of the cell (floor(x nx), floor(y ny)); 0 outside [0, 1)^2.
    #[inline(always)]
    fn pdf(&self, p: Vec2) -> f32 {
        if !((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y)) {
            return 0.0;
        }
        self.cell_pdf(
            cell_of(p.x, self.nx, self.nx as f32),
            cell_of(p.y, self.ny, self.ny as f32),
        )
    }

    /// (P(x | row of y), P(y)), each piecewise linear in its cell.
    fn invert(&self, p: Vec2) -> Vec2 {
        let y = p.y.clamp(0.0, 1.0);
        let j = cell_of(y, self.ny, self.ny as f32);
        let row = &self.conditional[j * self.nx..(j + 1) * self.nx];
        Vec2::new(cdf_at(row, p.x), cdf_at(&self.marginal, p.y))
    }

    /// ∫∫ f = (Σ f) / (nx ny), of the values given to [`new`](Self::new).
    fn integral(&self) -> f64 {
        self.integral
    }

    /// The conditional and marginal CDFs and the marginal's guide table.
    fn storage_bytes(&self) -> usize {
        (self.conditional.capacity() + self.marginal.capacity()) * std::mem::size_of::<f32>()
            + self.marginal_guide.bytes()
    }

    /// The same samples as [`sample`](Distribution2D::sample): where the CPU
    /// has AVX2, 32 draws at a time in SIMD lanes (`distribution/gather.rs`),
    /// elsewhere sixteen at a time in scalar stages (`sample_batch_lanes`).
    fn sample_batch(&self, u: &[Vec2], out: &mut [Sample2D]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && self.fits_lanes() {
            // SAFETY: the CPU has just been found to support AVX2, and the
            // table fits the lanes.
            unsafe { self.sample_batch_gather(u, out) };
            return;
        }
        self.sample_batch_lanes(u, out);
    }
}

impl PiecewiseConstant2D {
    /// The same samples as [`sample`](Distribution2D::sample), sixteen draws
    /// at a time in stages (rows, then columns, then positions), so that
    /// the out-of-order core sees sixteen independent chains of loads at each
    /// stage instead of one long chain per draw.
    #[inline(always)]
    fn sample_batch_lanes(&self, u: &[Vec2], out: &mut [Sample2D]) {
        let len = u.len().min(out.len());
        let (u, out) = (&u[..len], &mut out[..len]);
        let mut u_chunks = u.chunks_exact(LANES);
        let mut out_chunks = out.chunks_exact_mut(LANES);
        for (uc, oc) in (&mut u_chunks).zip(&mut out_chunks) {
            let mut ul = [Vec2::ZERO; LANES];
            for (v, u) in ul.iter_mut().zip(uc) {
                *v = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
            }
            let mut j = [0usize; LANES];
            for (j, u) in j.iter_mut().zip(&ul) {
                *j = self.row(u.y);
            }
            let mut k = [0usize; LANES];
            for ((k, &j), u) in k.iter_mut().zip(&j).zip(&ul) {
                *k = self.column(j, u.x);
            }
            self.finish_lanes(&j, &k, &ul, oc);
        }
        for (o, &u) in out_chunks
            .into_remainder()
            .iter_mut()
            .zip(u_chunks.remainder())
        {
            *o = self.sample(u);
        }
    }

    /// [`finish`](Self::finish) for the draws of a stage whose rows `j` and
    /// columns `k` are known: the CDF entries of each draw are gathered
    /// first, then the arithmetic of all of them runs as one branch-free
    /// loop, which the AVX2 build turns into 8-wide operations. The rare
    /// draw whose position rounded onto a cell edge is finished one at a
    /// time, so the samples are those of `finish`, bit for bit.
    #[inline(always)]
    fn finish_lanes(
        &self,
        j: &[usize; LANES],
        k: &[usize; LANES],
        u: &[Vec2; LANES],
        out: &mut [Sample2D],
    ) {
        let (nx, ny) = (self.nx, self.ny);
        let (nxf, nyf) = (nx as f32, ny as f32);
        let (mut row_lo, mut row_hi) = ([0.0f32; LANES], [0.0f32; LANES]);
        let (mut col_lo, mut col_hi) = ([0.0f32; LANES], [0.0f32; LANES]);
        let (mut uj, mut uk) = ([0i32; LANES], [0i32; LANES]);
        for l in 0..LANES {
            row_lo[l] = lower_edge(&self.marginal, j[l]);
            row_hi[l] = self.marginal[j[l]];
            let row = &self.conditional[j[l] * nx..(j[l] + 1) * nx];
            col_lo[l] = lower_edge(row, k[l]);
            col_hi[l] = row[k[l]];
            // Cell indices are below 2^24, so i32 holds them exactly.
            uj[l] = j[l] as i32;
            uk[l] = k[l] as i32;
        }
        let (mut x, mut y, mut pdf) = ([0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES]);
        let mut on_edge = [false; LANES];
        let (last_x, last_y) = (nx as i32 - 1, ny as i32 - 1);
        for l in 0..LANES {
            let row_mass = row_hi[l] - row_lo[l];
            let dv = ((u[l].y - row_lo[l]) / row_mass).clamp(0.0, ONE_MINUS_EPSILON);
            let col_mass = col_hi[l] - col_lo[l];
            let du = ((u[l].x - col_lo[l]) / col_mass).clamp(0.0, ONE_MINUS_EPSILON);
            x[l] = ((uk[l] as f32 + du) * (1.0 / nxf)).min(ONE_MINUS_EPSILON);
            y[l] = ((uj[l] as f32 + dv) * (1.0 / nyf)).min(ONE_MINUS_EPSILON);
            // `cell_of` of each coordinate, for x in [0, 1).
            let cell_x = ((x[l] * nxf) as i32).min(last_x);
            let cell_y = ((y[l] * nyf) as i32).min(last_y);
            on_edge[l] = (cell_x != uk[l]) | (cell_y != uj[l]);
            pdf[l] = joint_pdf(row_mass * nyf, col_mass * nxf);
        }
        for (l, o) in out.iter_mut().enumerate().take(LANES) {
            *o = if on_edge[l] {
                self.finish(j[l], k[l], u[l])
            } else {
                Sample2D {
                    p: Vec2::new(x[l], y[l]),
                    pdf: pdf[l],
                }
            };
        }
    }
}

impl PiecewiseConstant2D {
    /// Draw `u[k]` from `dists[k]` for every k: the slices of a batch of
    /// shading points, each with its own outgoing direction. The same
    /// samples as [`sample`](Distribution2D::sample) of each. Where the CPU
    /// has AVX2, 32 draws at a time in SIMD lanes, each lane reading its own
    /// slice (`distribution/gather.rs`); elsewhere in scalar stages of
    /// sixteen (rows, then columns, then positions). Either way the loads of
    /// different slices, which are rarely in the nearest cache, overlap.
    pub fn sample_each(dists: &[&PiecewiseConstant2D], u: &[Vec2], out: &mut [Sample2D]) {
        let len = dists.len().min(u.len()).min(out.len());
        let (dists, u, out) = (&dists[..len], &u[..len], &mut out[..len]);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has just been found to support AVX2.
            unsafe { Self::sample_each_gather::<false>(dists, u, Vec2::ZERO, out, &mut []) };
            return;
        }
        Self::sample_each_lanes(dists, u, out);
    }

    /// Whether the box of half-width `margin` around p, a point of
    /// [0, 1)^2, lies inside p's cell: p is at least `margin` from the
    /// cell's edges along both axes (no density lookups).
    #[inline(always)]
    pub fn same_cell_around(&self, p: Vec2, margin: Vec2) -> bool {
        inside_cell(p.x, self.nx, margin.x) && inside_cell(p.y, self.ny, margin.y)
    }

    /// [`sample_each`](Self::sample_each) and, into `same`,
    /// [`same_cell_around`](Self::same_cell_around) of every sample in its
    /// own slice. Where the CPU has AVX2 the box tests run in the lanes of
    /// the draws.
    pub fn sample_each_and_same_cell(
        dists: &[&PiecewiseConstant2D],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        let len = dists.len().min(u.len()).min(out.len()).min(same.len());
        let (dists, u, out, same) = (&dists[..len], &u[..len], &mut out[..len], &mut same[..len]);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has just been found to support AVX2.
            unsafe { Self::sample_each_gather::<true>(dists, u, margin, out, same) };
            return;
        }
        Self::sample_each_lanes(dists, u, out);
        Self::same_cells(dists, margin, out, same);
    }

    /// `dists[k].pdf(p[k])` for every k, bit for bit: the slices of a batch
    /// of shading points. Where the CPU has AVX2, eight at a time in SIMD
    /// lanes, each lane reading its own slice; elsewhere one at a time.
    pub fn pdf_each(dists: &[&PiecewiseConstant2D], p: &[Vec2], out: &mut [f32]) {
        let len = dists.len().min(p.len()).min(out.len());
        let (dists, p, out) = (&dists[..len], &p[..len], &mut out[..len]);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has just been found to support AVX2.
            unsafe { Self::pdf_each_gather(dists, p, out) };
            return;
        }
        for ((o, d), &p) in out.iter_mut().zip(dists).zip(p) {
            *o = d.pdf(p);
        }
    }

    /// The box tests of drawn samples, one at a time.
    fn same_cells(
        dists: &[&PiecewiseConstant2D],
        margin: Vec2,
        out: &[Sample2D],
        same: &mut [bool],
    ) {
        for ((same, s), d) in same.iter_mut().zip(out).zip(dists) {
            *same = d.same_cell_around(s.p, margin);
        }
    }

    /// The scalar stages of [`sample_each`](Self::sample_each), for slices
    /// of equal length.
    #[inline(always)]
    fn sample_each_lanes(dists: &[&PiecewiseConstant2D], u: &[Vec2], out: &mut [Sample2D]) {
        let len = dists.len().min(u.len()).min(out.len());
        let (dists, u, out) = (&dists[..len], &u[..len], &mut out[..len]);
        let mut d_chunks = dists.chunks_exact(LANES);
        let mut u_chunks = u.chunks_exact(LANES);
        let mut out_chunks = out.chunks_exact_mut(LANES);
        for ((dc, uc), oc) in (&mut d_chunks).zip(&mut u_chunks).zip(&mut out_chunks) {
            let mut ul = [Vec2::ZERO; LANES];
            for (v, u) in ul.iter_mut().zip(uc) {
                *v = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
            }
            let mut j = [0usize; LANES];
            for ((j, u), d) in j.iter_mut().zip(&ul).zip(dc) {
                *j = d.row(u.y);
            }
            let mut k = [0usize; LANES];
            for (((k, &j), u), d) in k.iter_mut().zip(&j).zip(&ul).zip(dc) {
                *k = d.column(j, u.x);
            }
            for (l, (o, d)) in oc.iter_mut().zip(dc).enumerate() {
                *o = d.finish(j[l], k[l], ul[l]);
            }
        }
        for ((o, d), &u) in out_chunks
            .into_remainder()
            .iter_mut()
            .zip(d_chunks.remainder())
            .zip(u_chunks.remainder())
        {
            *o = d.sample(u);
        }
    }
}

/// Whether x in [0, 1) is at least m from the edges of its cell on a grid
/// of n cells: its fraction within the cell, x n - floor(x n), lies in
/// [m n, 1 - m n]. Truncation is the floor here, without a libm call.
#[inline(always)]
fn inside_cell(x: f32, n: usize, m: f32) -> bool {
    let t = x * n as f32;
    let f = t - acdf_core::fast::truncate_i32(t) as f32;
    let m = m * n as f32;
    f >= m && f <= 1.0 - m
}

/// The number of draws `sample_batch` advances together: sixteen measured
/// about 5% faster than eight on the 256x32 nickel slice (best of 40 runs
/// of 10^6 draws, 65-67 against 63-64 M/s), and 32 no faster.
const LANES: usize = 16;

/// Check that a stored CDF is one [`fill_cdf`] could have produced: finite,
/// within [0, 1], non-decreasing and ending at exactly 1. Sampling relies on
/// each of these (a search that always finds a cell, a positive cell mass).
fn check_stored_cdf(field: &'static str, cdf: &[f32]) -> std::result::Result<(), PersistError> {
    let invalid = |reason: String| PersistError::Invalid { field, reason };
    if cdf.is_empty() || cdf.len() > MAX_CELLS {
        return Err(invalid(format!("{} cells", cdf.len())));
    }
    let mut previous = 0.0f32;
    for (k, &c) in cdf.iter().enumerate() {
        if !(c >= previous && c <= 1.0) {
            return Err(invalid(format!(
                "entry {k} ({c}) breaks monotonicity in [0, 1]"
            )));
        }
        previous = c;
    }
    if previous != 1.0 {
        return Err(invalid(format!("ends at {previous}, not 1")));
    }
    Ok(())
}

fn check_stored_integral(integral: f64) -> std::result::Result<f64, PersistError> {
    if integral.is_finite() && integral >= 0.0 {
        Ok(integral)
    } else {
        Err(PersistError::Invalid {
            field: "integral",
            reason: format!("{integral} is not a finite non-negative number"),
        })
    }
}

/// Stored as the CDF (`f32 array`) and the integral (f64).
impl Persist for PiecewiseConstant1D {
    fn encode(&self, w: &mut ByteWriter) {
        w.f32_array(&self.cdf);
        w.f64(self.integral);
    }

    fn decode(r: &mut ByteReader<'_>) -> std::result::Result<Self, PersistError> {
        let cdf = r.f32_array("PiecewiseConstant1D cdf")?;
        check_stored_cdf("PiecewiseConstant1D cdf", &cdf)?;
        let integral = check_stored_integral(r.f64("integral")?)?;
        Ok(PiecewiseConstant1D {
            guide: Guide::new(&cdf),
            cdf,
            integral,
        })
    }
}

/// Stored as nx, ny (u32), the conditional CDFs (`f32 array`, ny rows of nx),
/// the marginal CDF (`f32 array` of ny) and the integral (f64).
impl Persist for PiecewiseConstant2D {
    fn encode(&self, w: &mut ByteWriter) {
        w.length(self.nx);
        w.length(self.ny);
        w.f32_array(&self.conditional);
        w.f32_array(&self.marginal);
        w.f64(self.integral);
    }

    fn decode(r: &mut ByteReader<'_>) -> std::result::Result<Self, PersistError> {
        let nx = r.u32("nx")? as usize;
        let ny = r.u32("ny")? as usize;
        let conditional = r.f32_array("PiecewiseConstant2D conditional")?;
        if nx == 0 || ny == 0 || nx.checked_mul(ny) != Some(conditional.len()) {
            return Err(PersistError::Invalid {
                field: "PiecewiseConstant2D conditional",
                reason: format!("{} entries for {nx} x {ny}", conditional.len()),
            });
        }
        for row in conditional.chunks_exact(nx) {
            check_stored_cdf("PiecewiseConstant2D conditional", row)?;
        }
        let marginal = r.f32_array("PiecewiseConstant2D marginal")?;
        if marginal.len() != ny {
            return Err(PersistError::Invalid {
                field: "PiecewiseConstant2D marginal",
                reason: format!("{} entries for {ny} rows", marginal.len()),
            });
        }
        check_stored_cdf("PiecewiseConstant2D marginal", &marginal)?;
        let integral = check_stored_integral(r.f64("integral")?)?;
        Ok(PiecewiseConstant2D {
            nx,
            ny,
            conditional,
            marginal_guide: marginal_guide(&marginal),
            marginal,
            integral,
            scale: GridScale::new(nx, ny),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The drawn cell's fraction x n - k gives `inside_cell`'s answer for
    /// every x in cell k, at and within a few ulps of the thresholds m n
    /// and 1 - m n and of the cell's edges.
    #[test]
    fn drawn_cell_fraction_matches_truncation() {
        let mut checked = 0;
        for n in [1usize, 3, 7, 32, 100, 256, 1000] {
            let nf = n as f32;
            for m in [1.0 / 65536.0, 1e-3, 0.3] {
                for k in (0..n).step_by((n / 17).max(1)) {
                    let kf = k as f32;
                    let bases = [kf / nf, (kf + m * nf) / nf, (kf + 1.0 - m * nf) / nf];
                    for base in bases.into_iter().chain([(kf + 1.0) / nf]) {
                        let mut x = base;
                        for _ in 0..8 {
                            x = x.next_down();
                        }
                        for _ in 0..17 {
                            if (0.0..1.0).contains(&x) && cell_of(x, n, nf) == k {
                                assert_eq!(
                                    inside_drawn_cell(x, k, nf, m),
                                    inside_cell(x, n, m),
                                    "x {x} k {k} n {n} m {m}"
                                );
                                checked += 1;
                            }
                            x = x.next_up();
                        }
                    }
                }
            }
        }
        assert!(checked > 1000);
    }

    /// The position of a draw lands in its cell for every grid size,
    /// every cell and fractions up to the largest below 1, and is the
    /// position first computed whenever that one is in the cell (the
    /// shortcut test x n - k in [0, 1) accepts what `cell_of` accepts).
    #[test]
    fn positions_stay_in_their_cells() {
        let mut nudged = 0;
        for n in [1usize, 3, 7, 32, 100, 255, 256, 1000, 4096] {
            let nf = n as f32;
            let inv = 1.0 / nf;
            for k in (0..n).step_by((n / 23).max(1)).chain([n - 1]) {
                let mut fractions = vec![0.0f32, 1e-30, 0.25, 0.5, ONE_MINUS_EPSILON];
                let mut d = ONE_MINUS_EPSILON;
                for _ in 0..40 {
                    d = d.next_down();
                    fractions.push(d);
                }
                for du in fractions {
                    let x = position_in_cell(k, du, n, nf, inv);
                    assert_eq!(cell_of(x, n, nf), k, "n {n} k {k} du {du}");
                    assert!((0.0..1.0).contains(&x));
                    let first = ((k as f32 + du) * inv).min(ONE_MINUS_EPSILON);
                    if cell_of(first, n, nf) == k {
                        assert_eq!(x.to_bits(), first.to_bits(), "n {n} k {k} du {du}");
                    } else {
                        nudged += 1;
                    }
                }
            }
        }
        // Rounding carries some positions out of their cell: the slow
        // path is exercised.
        assert!(nudged > 0);
    }

    #[test]
    fn lower_bound_matches_partition_point() {
        let cdf = [0.1f32, 0.1, 0.3, 0.5, 0.5, 0.9, 1.0];
        for n in 0..=cdf.len() {
            let s = &cdf[..n];
            for u in [0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9, 0.95, 1.0, 2.0] {
                assert_eq!(
                    count_at_or_below(s, u),
                    s.partition_point(|&c| c <= u),
                    "n {n} u {u}"
                );
            }
        }
    }

    #[test]
    fn one_d_samples_follow_the_values() {
        let d = PiecewiseConstant1D::new(&[1.0, 3.0, 0.0, 4.0]).unwrap();
        assert_eq!(d.count(), 4);
        approx::assert_relative_eq!(d.integral(), 2.0);
        assert_eq!(d.cdf(), &[0.125, 0.5, 0.5, 1.0]);
        approx::assert_relative_eq!(d.pdf(0.1), 0.5);
        approx::assert_relative_eq!(d.pdf(0.3), 1.5);
        assert_eq!(d.pdf(0.6), 0.0);
        approx::assert_relative_eq!(d.pdf(0.9), 2.0);
        assert_eq!(d.pdf(1.0), 0.0);
        assert_eq!(d.pdf(-0.1), 0.0);
        assert_eq!(d.pdf(f32::NAN), 0.0);
        let s = d.sample(0.5);
        assert!((0.75..1.0).contains(&s.x), "{s:?}");
        approx::assert_relative_eq!(s.pdf, 2.0);
        assert_eq!(d.func(), vec![0.5, 1.5, 0.0, 2.0]);
    }

    #[test]
    fn u_next_to_one_lands_in_the_last_non_empty_cell() {
        let d = PiecewiseConstant1D::new(&[1.0, 2.0, 0.0, 0.0]).unwrap();
        for u in [ONE_MINUS_EPSILON, 1.0, f32::INFINITY] {
            let s = d.sample(u);
            assert!((0.25..0.5).contains(&s.x), "{s:?}");
            assert!(s.pdf > 0.0 && s.pdf.is_finite());
        }
        let s = d.sample(f32::NAN);
        assert_eq!(s.x, 0.0);
        // Nine cells: x = (8 + du) / 9 can round to 1 without the guard.
        let d = PiecewiseConstant1D::new(&[1.0; 9]).unwrap();
        let s = d.sample(ONE_MINUS_EPSILON);
        assert!(s.x < 1.0 && d.pdf(s.x) == s.pdf);
        let d2 = PiecewiseConstant2D::new(&[1.0, 1.0, 0.0, 2.0, 0.0, 0.0], 2, 3).unwrap();
        let s = d2.sample(Vec2::splat(ONE_MINUS_EPSILON));
        assert!(
            s.p.y >= 1.0 / 3.0 && s.p.y < 2.0 / 3.0 && s.p.x >= 0.5,
            "{s:?}"
        );
        assert!(s.pdf > 0.0 && s.pdf == d2.pdf(s.p));
    }

    #[test]
    fn zero_tables_fall_back_to_uniform() {
        let d = PiecewiseConstant1D::new(&[0.0; 5]).unwrap();
        assert_eq!(d.integral(), 0.0);
        for x in [0.0, 0.3, 0.99] {
            approx::assert_relative_eq!(d.pdf(x), 1.0, max_relative = 1e-6);
        }
        approx::assert_relative_eq!(d.sample(0.3).x, 0.3, max_relative = 1e-6);
        let d2 = PiecewiseConstant2D::new(&[0.0; 6], 3, 2).unwrap();
        assert_eq!(d2.integral(), 0.0);
        let s = d2.sample(Vec2::new(0.4, 0.7));
        approx::assert_relative_eq!(s.pdf, 1.0, max_relative = 1e-6);
        approx::assert_relative_eq!(s.p.x, 0.4, max_relative = 1e-6);
        // A zero row in a non-zero table: uniform conditional, never drawn.
        let d3 = PiecewiseConstant2D::new(&[0.0, 0.0, 1.0, 3.0], 2, 2).unwrap();
        assert_eq!(d3.conditional(0).unwrap(), &[0.5, 1.0]);
        assert_eq!(d3.pdf(Vec2::new(0.2, 0.2)), 0.0);
        for u in [0.0, 0.1, 0.5, ONE_MINUS_EPSILON] {
            let s = d3.sample(Vec2::new(0.3, u));
            assert!(s.p.y >= 0.5 && s.pdf > 0.0);
        }
        approx::assert_relative_eq!(d3.pdf(Vec2::new(0.7, 0.7)), 3.0);
    }

    #[test]
    fn bad_tables_give_the_right_error() {
        assert!(matches!(
            PiecewiseConstant1D::new(&[]),
            Err(Error::EmptyTable { .. })
        ));
        assert!(matches!(
            PiecewiseConstant1D::new(&[1.0, f32::NAN]),
            Err(Error::NonFinite { index: 1, .. })
        ));
        assert!(matches!(
            PiecewiseConstant1D::new(&[f32::INFINITY]),
            Err(Error::NonFinite { index: 0, .. })
        ));
        assert!(matches!(
            PiecewiseConstant1D::new(&[1.0, -1.0]),
            Err(Error::Negative { index: 1, .. })
        ));
        assert!(matches!(
            PiecewiseConstant2D::new(&[1.0; 6], 4, 2),
            Err(Error::SizeMismatch {
                expected: 8,
                got: 6,
                ..
            })
        ));
        assert!(matches!(
            PiecewiseConstant2D::new(&[], 0, 2),
            Err(Error::EmptyTable { .. })
        ));
        assert!(matches!(
            PiecewiseConstant2D::new(&[1.0, 1.0, -0.5, 1.0], 2, 2),
            Err(Error::Negative { index: 2, .. })
        ));
        assert!(matches!(
            PiecewiseConstant2D::new(&[1.0, f32::NAN], 1, 2),
            Err(Error::NonFinite { index: 1, .. })
        ));
        assert!(matches!(
            PiecewiseConstant2D::new(&[1.0], usize::MAX, 2),
            Err(Error::InvalidParameter { .. })
        ));
    }

    #[test]
    fn huge_dynamic_range_stays_monotone_and_ends_at_one() {
        let values: Vec<f32> = (0..61).map(|k| 10f32.powi(k - 30)).collect();
        let d = PiecewiseConstant1D::new(&values).unwrap();
        assert!(d.cdf().windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(*d.cdf().last().unwrap(), 1.0);
        assert!(d.integral().is_finite() && d.integral() > 0.0);
        for u in [0.0, 1e-30, 0.5, 0.9, ONE_MINUS_EPSILON] {
            let s = d.sample(u);
            assert!(s.x < 1.0 && s.pdf > 0.0 && s.pdf.is_finite(), "{u} {s:?}");
            assert_eq!(d.pdf(s.x), s.pdf);
        }
        let mut table = values.clone();
        table.extend(values.iter().rev());
        let d2 = PiecewiseConstant2D::new(&table, 61, 2).unwrap();
        assert_eq!(*d2.marginal().last().unwrap(), 1.0);
        for u in [Vec2::ZERO, Vec2::splat(0.5), Vec2::splat(ONE_MINUS_EPSILON)] {
            let s = d2.sample(u);
            assert!(s.pdf > 0.0 && s.pdf.is_finite() && s.pdf == d2.pdf(s.p));
        }
    }

    #[test]
    fn storage_counts_the_cdfs() {
        let d = PiecewiseConstant2D::new(&vec![1.0; 256 * 32], 32, 256).unwrap();
        // The CDFs plus a u16 guide of 256 + 1 entries over the marginal.
        assert_eq!(d.storage_bytes(), (256 * 32 + 256) * 4 + 257 * 2);
        assert_eq!(
            PiecewiseConstant1D::new(&[1.0; 7]).unwrap().storage_bytes(),
            28 + 8 * 2
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// The branch-free search counts exactly what a binary search does,
        /// for every length.
        #[test]
        fn search_matches_partition_point(
            mut v in prop::collection::vec(prop_oneof![Just(0.5f32), 0.0f32..1.0], 0..300),
            u in prop::collection::vec(0.0f32..1.0, 8),
        ) {
            v.sort_by(f32::total_cmp);
            let lanes: [f32; 8] = std::array::from_fn(|l| if l == 3 { 0.5 } else { u[l] });
            for &u in &lanes {
                let expected = v.partition_point(|&c| c <= u);
                prop_assert_eq!(count_at_or_below(&v, u), expected);
            }
        }

        /// The guided search counts exactly what a binary search does, for
        /// CDFs with long flat runs, steep steps and every u near a guide
        /// boundary.
        #[test]
        fn guided_search_matches_partition_point(values in table(300), u in prop::collection::vec(0.0f32..1.0, 16)) {
            let d = PiecewiseConstant1D::new(&values).unwrap();
            let cdf = d.cdf();
            let n = cdf.len();
            for u in u.iter().copied().chain(near_guide_boundaries(n)).chain(cdf.iter().copied()) {
                let u = clamp_unit(u);
                let expected = cdf[..n - 1].partition_point(|&c| c <= u);
                prop_assert_eq!(d.guide.count_at_or_below(cdf, u), expected, "u {}", u);
            }
        }

        /// The 2D marginal's guide has a fixed number of cells; the row it
        /// finds is that of a binary search whether the table has fewer
        /// rows than guide cells, as many, or more (wide guide intervals),
        /// for u on and beside every guide boundary and marginal entry.
        #[test]
        fn marginal_rows_match_partition_point(values in table(900), nx in 1usize..4, u in prop::collection::vec(0.0f32..1.0, 16)) {
            let ny = values.len().div_ceil(nx);
            let mut v = values.clone();
            v.resize(nx * ny, 0.0);
            let d = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
            let marginal = d.marginal();
            let boundaries = near_guide_boundaries(MARGINAL_GUIDE_CELLS);
            for u in u.iter().copied().chain(boundaries).chain(marginal.iter().copied()) {
                let u = clamp_unit(u);
                let expected = marginal[..ny - 1].partition_point(|&c| c <= u);
                prop_assert_eq!(d.row(u), expected, "u {} ny {}", u, ny);
            }
        }

        /// The draw's own box test equals `same_cell_around` of the sample,
        /// and the sample is `sample`'s, on grids of any size (rounding
        /// carries x to a cell edge more often off powers of two), for u
        /// at and beside every CDF entry, where draws land on cell edges,
        /// and margins from a sliver to more than half a cell.
        #[test]
        fn drawn_cell_box_test_matches_same_cell_around(
            values in table(600),
            nx in 1usize..40,
            u in prop::collection::vec(0.0f32..1.0, 8),
        ) {
            let ny = values.len().div_ceil(nx);
            let mut v = values.clone();
            v.resize(nx * ny, 0.0);
            let d = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
            let edges: Vec<f32> = d
                .cdf()
                .iter()
                .chain(d.marginal())
                .flat_map(|&c| [c, c.next_down(), c.next_up()])
                .collect();
            let points = u.iter().flat_map(|&a| edges.iter().map(move |&b| Vec2::new(b, a)))
                .chain(u.iter().flat_map(|&a| edges.iter().map(move |&b| Vec2::new(a, b))));
            for u in points.take(4000) {
                for m in [1.0 / 65536.0, 1e-3, 0.3] {
                    let margin = Vec2::splat(m);
                    let (s, same) = d.sample_and_same_cell(u, margin);
                    let plain = d.sample(u);
                    prop_assert_eq!(s.p.x.to_bits(), plain.p.x.to_bits());
                    prop_assert_eq!(s.p.y.to_bits(), plain.p.y.to_bits());
                    prop_assert_eq!(s.pdf.to_bits(), plain.pdf.to_bits());
                    prop_assert_eq!(same, d.same_cell_around(s.p, margin), "u {} m {}", u, m);
                }
            }
        }

        /// The short-row count gives the number of entries `<= u` of a
        /// sorted row of 8 to 64 entries, for u below, inside, on and above
        /// its entries, and 0 for NaN.
        #[test]
        fn short_row_counts_match_partition_point(values in prop::collection::vec(0.0f32..1.0, 64), blocks in 1usize..=8, u in prop::collection::vec(-0.5f32..1.5, 8)) {
            let mut row = values[..blocks * GUIDE_WINDOW].to_vec();
            row.sort_by(f32::total_cmp);
            for u in u.iter().copied().chain(row.iter().copied()).chain([f32::MAX]) {
                let expected = row.partition_point(|&c| c <= u);
                prop_assert_eq!(count_linear(&row, u), expected, "u {}", u);
            }
            prop_assert_eq!(count_linear(&row, f32::NAN), 0);
        }

        /// `sample_batch` returns exactly what `sample` does, in full stages
        /// and in the remainder, for u anywhere (CDF entries, 0, 1, NaN and
        /// out of range included) and tables of every shape: rows shorter
        /// than eight, not a power of two, and longer than `LINEAR_ROW`.
        #[test]
        fn batches_equal_single_samples(values in table(600), nx in 1usize..70, n in 0usize..200, seed in 0u64..1000) {
            let ny = values.len().div_ceil(nx);
            let mut v = values.clone();
            v.resize(nx * ny, 0.0);
            let d2 = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
            let d1 = PiecewiseConstant1D::new(&values).unwrap();
            let mut state = seed;
            let mut next = || {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 40) as f32 / (1u64 << 24) as f32
            };
            let specials = [0.0, -0.0, 1.0, -1.0, 2.0, f32::NAN, ONE_MINUS_EPSILON, f32::MIN_POSITIVE];
            let mut coordinate = |cdf: &[f32]| {
                let pick = next();
                if pick < 0.2 {
                    cdf[(next() * cdf.len() as f32) as usize]
                } else if pick < 0.25 {
                    specials[(next() * specials.len() as f32) as usize]
                } else {
                    next()
                }
            };
            let u2: Vec<Vec2> = (0..n)
                .map(|_| Vec2::new(coordinate(d2.cdf()), coordinate(d2.marginal())))
                .collect();
            // Every fourth 1D number exactly on one of its own CDF entries.
            let u1: Vec<f32> = u2
                .iter()
                .enumerate()
                .map(|(k, u)| if k % 4 == 1 { d1.cdf()[k % d1.cdf().len()] } else { u.x })
                .collect();
            let mut out2 = vec![Sample2D::default(); n + 3];
            let mut out1 = vec![Sample1D::default(); n];
            d2.sample_batch(&u2, &mut out2);
            // The staged scalar path, which CPUs without AVX2 take.
            let mut staged = vec![Sample2D::default(); n];
            d2.sample_batch_lanes(&u2, &mut staged);
            prop_assert_eq!(&staged[..], &out2[..n]);
            d1.sample_batch(&u1, &mut out1);
            for k in 0..n {
                prop_assert_eq!(out2[k], d2.sample(u2[k]));
                prop_assert_eq!(out1[k], d1.sample(u1[k]));
            }
            prop_assert!(out2[n..].iter().all(|s| *s == Sample2D::default()));
            // pdf_batch at the samples, beside them, and at the raw u
            // (outside the square and NaN included).
            let mut points: Vec<Vec2> = out2[..n].iter().map(|s| s.p).collect();
            points.extend(out2[..n].iter().map(|s| Vec2::new(s.p.x.next_up(), s.p.y.next_down())));
            points.extend(&u2);
            let mut densities = vec![0.0f32; points.len()];
            d2.pdf_batch(&points, &mut densities);
            for (&b, &p) in densities.iter().zip(&points) {
                prop_assert_eq!(b.to_bits(), d2.pdf(p).to_bits(), "pdf_batch at {}", p);
            }
        }
    }

    /// `sample_each` draws every lane from its own distribution, exactly as
    /// `sample` does: stages of one shape (the lanes path), stages mixing
    /// shapes (the scalar stages) and the tail.
    #[test]
    fn each_lane_draws_from_its_own_table() {
        let table = |seed: usize, nx: usize, ny: usize| -> PiecewiseConstant2D {
            let values: Vec<f32> = (0..nx * ny)
                .map(|k| {
                    if (k * 31 + seed).is_multiple_of(11) {
                        0.0
                    } else {
                        ((k * 7 + seed) % 13) as f32
                    }
                })
                .collect();
            PiecewiseConstant2D::new(&values, nx, ny).unwrap()
        };
        let same_shape: Vec<PiecewiseConstant2D> = (0..5).map(|s| table(s, 32, 64)).collect();
        let odd_shape = table(9, 5, 3);
        let mut state = 99u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let n = 64 * 3 + 17;
        let mut lanes: Vec<&PiecewiseConstant2D> =
            (0..n).map(|k| &same_shape[(k * 3 + k / 7) % 5]).collect();
        // The second stage mixes in another shape.
        lanes[64 + 5] = &odd_shape;
        let mut u: Vec<Vec2> = (0..n).map(|_| Vec2::new(next(), next())).collect();
        u[1] = Vec2::new(f32::NAN, 1.0);
        u[2] = Vec2::new(-3.0, 0.0);
        u[3] = Vec2::new(same_shape[0].cdf()[5], same_shape[0].marginal()[7]);
        let mut out = vec![Sample2D::default(); n + 2];
        PiecewiseConstant2D::sample_each(&lanes, &u, &mut out);
        for k in 0..n {
            assert_eq!(out[k], lanes[k].sample(u[k]), "lane {k}");
        }
        assert_eq!(out[n..], [Sample2D::default(); 2]);
        let mut staged = vec![Sample2D::default(); n];
        PiecewiseConstant2D::sample_each_lanes(&lanes, &u, &mut staged);
        assert_eq!(staged, out[..n]);
        // The box tests in the lanes answer as the scalar test does, inside
        // and outside the cell (a margin of 0.01 is a third of a column).
        for m in [1e-5f32, 0.01, 0.05] {
            let margin = Vec2::splat(m);
            let mut drawn = vec![Sample2D::default(); n];
            let mut same = vec![false; n];
            PiecewiseConstant2D::sample_each_and_same_cell(
                &lanes, &u, margin, &mut drawn, &mut same,
            );
            assert_eq!(drawn, out[..n]);
            let expected: Vec<bool> = (0..n)
                .map(|k| lanes[k].same_cell_around(out[k].p, margin))
                .collect();
            assert_eq!(same, expected, "margin {m}");
            assert!(same.iter().any(|&s| s) && same.iter().any(|&s| !s));
        }
        // Densities bit for bit, at the raw u (outside the square and NaN
        // included) and at draws from other lanes' tables.
        let mut points = u.clone();
        points.extend((0..n).map(|k| out[(k + 3) % n].p));
        let each: Vec<&PiecewiseConstant2D> = lanes.iter().chain(&lanes).copied().collect();
        let mut densities = vec![0.0f32; points.len()];
        PiecewiseConstant2D::pdf_each(&each, &points, &mut densities);
        for k in 0..points.len() {
            assert_eq!(
                densities[k].to_bits(),
                each[k].pdf(points[k]).to_bits(),
                "lane {k}"
            );
        }
        assert!(densities.iter().filter(|&&d| d > 0.0).count() > n);
    }

    /// Tables with zeros and a wide dynamic range.
    /// Each boundary k / g of a guide of g cells and the floats on either
    /// side of it.
    fn near_guide_boundaries(g: usize) -> impl Iterator<Item = f32> {
        (0..g).flat_map(move |k| {
            let b = k as f32 / g as f32;
            [b.next_down().max(0.0), b, b.next_up()]
        })
    }

    fn table(max_len: usize) -> impl Strategy<Value = Vec<f32>> {
        prop::collection::vec(
            prop_oneof![Just(0.0f32), 0.0f32..10.0, 1e-20f32..1e-10, 1e10f32..1e20],
            1..max_len,
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        #[test]
        fn one_d_sample_pdf_invert_agree(values in table(40), u in 0.0f32..1.0) {
            let d = PiecewiseConstant1D::new(&values).unwrap();
            let s = d.sample(u);
            prop_assert!((0.0..1.0).contains(&s.x));
            prop_assert!(s.pdf > 0.0 && s.pdf.is_finite());
            prop_assert_eq!(d.pdf(s.x), s.pdf);
            let back = d.invert(s.x);
            prop_assert!((back - u).abs() <= 1e-4, "u {} -> x {} -> {}", u, s.x, back);
        }

        #[test]
        fn two_d_sample_pdf_invert_agree(
            values in table(60), nx in 1usize..8, ux in 0.0f32..1.0, uy in 0.0f32..1.0
        ) {
            let ny = values.len().div_ceil(nx);
            let mut v = values.clone();
            v.resize(nx * ny, 0.0);
            let d = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
            let u = Vec2::new(ux, uy);
            let s = d.sample(u);
            prop_assert!((0.0..1.0).contains(&s.p.x) && (0.0..1.0).contains(&s.p.y));
            prop_assert!(s.pdf > 0.0 && s.pdf.is_finite());
            prop_assert_eq!(d.pdf(s.p), s.pdf);
            let back = d.invert(s.p);
            prop_assert!((back - u).abs().max_element() <= 1e-4, "u {} -> {} -> {}", u, s.p, back);
        }

        /// The stored density integrates to one (a zero table is uniform).
        #[test]
        fn two_d_density_is_normalised(values in table(60), nx in 1usize..8) {
            let ny = values.len().div_ceil(nx);
            let mut v = values.clone();
            v.resize(nx * ny, 0.0);
            let d = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
            let total: f64 = d.func().iter().map(|&p| p as f64).sum::<f64>() / (nx * ny) as f64;
            prop_assert!((total - 1.0).abs() < 1e-5, "{}", total);
        }
    }
}
