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
//! x stays monotone. Where the CPU has AVX2, the batch forms run in SIMD
//! lanes instead, by the kernels of [`acdf_core::simd::piecewise_constant`]
//! (32 draws per stage, both searches by binary lifting with gathers), which
//! read the same CDFs through a plain view of them; elsewhere
//! `sample_batch` runs sixteen draws in scalar stages. Both return exactly
//! what `sample` and `pdf` return.
//!
//! **All-zero input.** A table (or a row of a 2D table) that sums to zero
//! falls back to the uniform density; `integral()` then reports 0. In a 2D
//! table a zero row gets a uniform conditional, but its marginal probability
//! is 0 unless the whole table is zero, so it is never drawn.

use acdf_core::fast::grid_cell;
use acdf_core::search::{self, count_linear, count_sorted, LINEAR_ROW, SHORT_WINDOW};
#[cfg(target_arch = "x86_64")]
use acdf_core::simd::piecewise_constant;
use acdf_core::simd::piecewise_constant::{Table1D, Table2D, STAGE};
use acdf_core::simd::Avx2;
use acdf_core::{
    clamp_unit, validate_table, Distribution1D, Distribution2D, Error, Result, Sample1D, Sample2D,
    Vec2, ONE_MINUS_EPSILON,
};
use acdf_tabulated::SliceDistribution;

/// The largest number of cells along one axis: beyond 2^24 neighbouring
/// cell boundaries k/n are no longer distinct `f32` values.
pub const MAX_CELLS: usize = 1 << 24;

/// The cutpoint index (guide table) of a stored CDF: the shared
/// [`search::Guide`] over its searched entries (all but the last, which is
/// 1), with G equal intervals of u (G = n for a 1D distribution, a fixed
/// [`MARGINAL_GUIDE_CELLS`] for a 2D marginal), so that the search inspects
/// a handful of entries instead of log n and returns exactly the cell of a
/// plain search. Derived from the CDF (rebuilt when a distribution is read
/// back, never stored); a CDF of more than 2^16 searched entries is
/// searched without it. The count within an interval compares a window of
/// [`SHORT_WINDOW`] entries, narrower than the shared guide's: here G is
/// at least the number of cells, so intervals hold few entries.
#[derive(Debug, Clone, PartialEq, Default)]
struct CdfGuide {
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
/// multiply, clamps and conversion after that lookup on every draw's chain;
/// with the constant they run beside the lookup. (A row count passed in by
/// the sampler and checked against the slice's gains less than the
/// constant.) 256 is the default θ_h resolution, so at the default the
/// guide is the same as with G = n; marginals with many more rows get
/// wider guide intervals, and those wider than [`SHORT_WINDOW`] are
/// searched, which costs a draw about as much as G = n does.
pub(crate) const MARGINAL_GUIDE_CELLS: usize = 256;

impl CdfGuide {
    /// The guide of a stored CDF (all n entries, the last being 1; the
    /// searched entries are the first n - 1) with G = n intervals.
    fn new(cdf: &[f32]) -> CdfGuide {
        Self::with_cells(cdf, cdf.len())
    }

    /// The guide of a stored CDF with G = `g_count` intervals (at least 1).
    fn with_cells(cdf: &[f32], g_count: usize) -> CdfGuide {
        CdfGuide {
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
    fn guided_count(&self, cdf: &[f32], u: f32) -> usize {
        if self.is_empty() {
            return count_sorted(&cdf[..cdf.len() - 1], u);
        }
        self.count_from_cell(cdf, u, self.cell(u))
    }

    /// [`guided_count`](Self::guided_count) for a guide that
    /// exists, given g = [`cell`](Self::cell)`(u)`.
    #[inline(always)]
    fn count_from_cell(&self, cdf: &[f32], u: f32, g: usize) -> usize {
        let n = cdf.len();
        let lo = self.index.counts();
        let (a, b) = (lo[g] as usize, lo[g + 1] as usize);
        if b - a <= SHORT_WINDOW && n >= SHORT_WINDOW {
            // Count a fixed window of entries from a (moved left to stay
            // inside the table): entries before a are below u and entries
            // from b on (the last entry, 1, included) above it, so the count
            // is exact; a fixed-size window compiles to SIMD compares.
            let start = a.min(n - SHORT_WINDOW);
            start + search::count_short_window(search::short_window(cdf, start), u)
        } else {
            a + count_sorted(&cdf[a..b], u)
        }
    }
}

/// The number of entries of `row` that are `<= u`, comparing them all:
/// for short rows of other lengths.
#[inline(always)]
fn count_all(row: &[f32], u: f32) -> usize {
    row.iter().map(|&c| (c <= u) as usize).sum()
}

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
    let mut positive = Vec::with_capacity(n);
    let mut total = 0.0f64;
    for v in values {
        total += v;
        running.push(total);
        positive.push(v > 0.0);
    }
    fill_cdf(&running, total, cdf, |k| positive[k]);
    total
}

/// Normalise the running sums (the last of which is `total`) into `cdf`.
///
/// The result is what sampling relies on: non-decreasing, ending at exactly
/// 1, and *strictly* increasing across every cell whose value is positive,
/// flat across every cell whose value is 0. Rounding to `f32` would
/// otherwise merge a cell holding less than about 6e-8 of its row into its
/// neighbour, giving it density 0 where the integrand is positive (a
/// near-mirror lobe's far cells, a grazing cell the horizon barely lights);
/// such a cell keeps one ulp of the CDF instead, so it is drawn rarely but
/// is drawn, and its pdf is positive.
///
/// `positive(k)` says whether cell k's value is positive: a difference of
/// running sums cannot tell, since a cell below 1e-16 of the sum before it
/// leaves the `f64` sum unchanged.
fn fill_cdf(running: &[f64], total: f64, cdf: &mut [f32], positive: impl Fn(usize) -> bool) {
    let n = cdf.len();
    if !(total > 0.0 && total.is_finite()) {
        for (k, c) in cdf.iter_mut().enumerate() {
            *c = ((k + 1) as f64 / n as f64) as f32;
        }
        cdf[n - 1] = 1.0;
        return;
    }
    // Forward: round, then lift each positive cell's top one ulp above the
    // entry before it where rounding made them equal.
    let mut previous = 0.0f32;
    for (k, c) in cdf.iter_mut().enumerate() {
        let rounded = ((running[k] / total) as f32).min(1.0);
        *c = if positive(k) {
            rounded.max(previous.next_up())
        } else {
            previous
        };
        previous = *c;
    }
    // Backward: the top is exactly 1 (so that every u < 1 finds a cell);
    // where the lifting above pushed entries to 1 or past the next one,
    // step them down so that each positive cell keeps at least one ulp.
    // Only a row of more than 2^23 cells could run out of room below 1.
    cdf[n - 1] = 1.0;
    for k in (0..n - 1).rev() {
        let above = cdf[k + 1];
        cdf[k] = if positive(k + 1) {
            cdf[k].min(above.next_down())
        } else {
            above
        };
    }
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
    guide: CdfGuide,
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
            guide: CdfGuide::new(&cdf),
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

    /// The CDF as the SIMD kernels read it.
    #[inline(always)]
    fn table(&self) -> Option<Table1D<'_>> {
        Table1D::new(&self.cdf)
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
        let k = self.guide.guided_count(&self.cdf, u);
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
    /// has AVX2, 32 at a time in SIMD lanes
    /// ([`piecewise_constant::sample_batch_1d`]); the rest one at a time
    /// (the guided search has no loop-carried dependence, so the
    /// out-of-order core overlaps consecutive draws).
    fn sample_batch(&self, u: &[f32], out: &mut [Sample1D]) {
        acdf_core::dispatch!(Self::sample_batch_one, self, u, out)
    }
}

impl PiecewiseConstant1D {
    /// [`Distribution1D::sample_batch`] itself.
    #[inline(always)]
    fn sample_batch_one(&self, u: &[f32], out: &mut [Sample1D], cpu: Option<Avx2>) {
        let done = match (cpu, self.table()) {
            #[cfg(target_arch = "x86_64")]
            (Some(cpu), Some(t)) => piecewise_constant::sample_batch_1d(cpu, &t, u, out),
            _ => 0,
        };
        for (o, &u) in out[done..].iter_mut().zip(&u[done..]) {
            *o = self.sample(u);
        }
    }
}

/// A piecewise-constant density over [0, 1)^2 from a row-major table of
/// `ny` rows of `nx` cells: a marginal CDF over the rows (y) and one
/// conditional CDF over x per row, stored flat for locality.
///
/// # Examples
///
/// ```
/// use acdf_core::{Distribution2D, Sample2D, Vec2};
/// use acdf_uniform::PiecewiseConstant2D;
///
/// // Two rows of three cells: the second row holds three quarters of the
/// // mass, and its last cell half of that.
/// let table = [1.0, 1.0, 0.0, 1.0, 1.0, 4.0];
/// let d = PiecewiseConstant2D::new(&table, 3, 2)?;
/// // The density of a cell is its value over the mean of the table (4/3).
/// assert!((d.pdf(Vec2::new(0.9, 0.9)) - 3.0).abs() < 1e-6);
/// assert_eq!(d.pdf(Vec2::new(0.9, 0.1)), 0.0);
/// // A draw lands in a cell of positive density and reports it.
/// let s = d.sample(Vec2::new(0.9, 0.9));
/// assert!(s.p.x >= 2.0 / 3.0 && s.p.y >= 0.5);
/// assert_eq!(s.pdf, d.pdf(s.p));
/// // Many draws at once give the same samples, bit for bit.
/// let u = [Vec2::new(0.1, 0.2), Vec2::new(0.9, 0.9), Vec2::new(0.5, 0.5)];
/// let mut out = [Sample2D::default(); 3];
/// d.sample_batch(&u, &mut out);
/// assert_eq!(out[1], s);
/// # Ok::<(), acdf_core::Error>(())
/// ```
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
    marginal_guide: CdfGuide,
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
            fill_cdf(&running, total, cdf, |k| row[k] > 0.0);
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
    /// mask, where [`count_linear`] chains two loads and two compares.
    #[inline(always)]
    fn column(&self, j: usize, u: f32) -> usize {
        let nx = self.nx;
        if nx <= search::WINDOW && self.conditional.len() >= search::WINDOW {
            return search::count_window(&self.conditional, j * nx, nx, u);
        }
        let row = &self.conditional[j * nx..(j + 1) * nx];
        if row.len() <= LINEAR_ROW && row.len().is_multiple_of(SHORT_WINDOW) {
            count_linear(row, u)
        } else if row.len() <= LINEAR_ROW {
            count_all(row, u)
        } else {
            count_sorted(&row[..row.len() - 1], u)
        }
    }

    /// The row j drawn by v = u.y in [0, 1): the number of marginal
    /// entries `<= v`, through the guide, whose cell is found with the
    /// constant G ([`MARGINAL_GUIDE_CELLS`]) rather than the stored scale.
    #[inline(always)]
    fn row(&self, v: f32) -> usize {
        let guide = &self.marginal_guide;
        if guide.is_empty() {
            return count_sorted(&self.marginal[..self.ny - 1], v);
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
    /// one or two rows on most tables ([`search::prefetch`]), so that the
    /// row's read is in flight while the marginal is searched; prefetching
    /// the interval's last row as well gains nothing more.
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
fn marginal_guide(marginal: &[f32]) -> CdfGuide {
    CdfGuide::with_cells(marginal, MARGINAL_GUIDE_CELLS)
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
    /// ([`piecewise_constant::pdf_batch`]); the rest one at a time.
    fn pdf_batch(&self, p: &[Vec2], out: &mut [f32]) {
        acdf_core::dispatch!(Self::pdf_batch_one, self, p, out)
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
    /// has AVX2, 32 draws at a time in SIMD lanes
    /// ([`piecewise_constant::sample_batch`]); the rest sixteen at a time
    /// in scalar stages (`sample_batch_lanes`).
    fn sample_batch(&self, u: &[Vec2], out: &mut [Sample2D]) {
        acdf_core::dispatch!(Self::sample_batch_one, self, u, out)
    }
}

impl PiecewiseConstant2D {
    /// [`Distribution2D::sample_batch`] itself.
    #[inline(always)]
    fn sample_batch_one(&self, u: &[Vec2], out: &mut [Sample2D], cpu: Option<Avx2>) {
        let done = match (cpu, self.table()) {
            #[cfg(target_arch = "x86_64")]
            (Some(cpu), Some(t)) => piecewise_constant::sample_batch(cpu, &t, u, out),
            _ => 0,
        };
        self.sample_batch_lanes(&u[done..], &mut out[done..]);
    }

    /// [`Distribution2D::pdf_batch`] itself.
    #[inline(always)]
    fn pdf_batch_one(&self, p: &[Vec2], out: &mut [f32], cpu: Option<Avx2>) {
        let done = match (cpu, self.table()) {
            #[cfg(target_arch = "x86_64")]
            (Some(cpu), Some(t)) => piecewise_constant::pdf_batch(cpu, &t, p, out),
            _ => 0,
        };
        for (o, &p) in out[done..].iter_mut().zip(&p[done..]) {
            *o = self.pdf(p);
        }
    }

    /// The CDFs as the SIMD kernels read them.
    #[inline(always)]
    fn table(&self) -> Option<Table2D<'_>> {
        Table2D::new(&self.marginal, &self.conditional, self.nx, self.ny)
    }

    /// The marginal and the conditional CDFs, a lane's table in the SIMD
    /// kernels of one table per lane.
    #[inline(always)]
    fn cdfs(&self) -> (&[f32], &[f32]) {
        (&self.marginal, &self.conditional)
    }

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

impl SliceDistribution for PiecewiseConstant2D {
    /// A slice's table is `n_x` columns by `n_y` rows.
    fn fits_grid(&self, n_x: usize, n_y: usize) -> bool {
        (self.nx, self.ny) == (n_x, n_y)
    }

    /// [`sample`](Distribution2D::sample) and
    /// [`same_cell_around`](Self::same_cell_around)`(sample.p, margin)` at
    /// once. The draw knows its cell (k, j), so the box test takes the
    /// fraction of x within the cell as x nx - k instead of truncating x nx
    /// (`inside_drawn_cell`): the same answer, a few instructions fewer
    /// on every draw.
    #[inline(always)]
    fn sample_and_same_cell(&self, u: Vec2, margin: Vec2) -> (Sample2D, bool) {
        let (s, j, k) = self.draw(u);
        // `&`: no short-circuit branch.
        let same = inside_drawn_cell(s.p.x, k, self.scale.nxf, margin.x)
            & inside_drawn_cell(s.p.y, j, self.scale.nyf, margin.y);
        (s, same)
    }

    /// Draw `u[k]` from `dists[k]` for every k: the slices of a batch of
    /// shading points, each with its own outgoing direction. The same
    /// samples as [`sample`](Distribution2D::sample) of each. Where the CPU
    /// has AVX2, a stage of 32 slices of one shape is drawn in SIMD lanes,
    /// each lane reading its own slice ([`piecewise_constant::sample_each`]);
    /// other stages in scalar stages of sixteen (rows, then columns, then
    /// positions). Either way the loads of different slices, which are
    /// rarely in the nearest cache, overlap.
    fn sample_each(dists: &[&Self], u: &[Vec2], out: &mut [Sample2D]) {
        let len = dists.len().min(u.len()).min(out.len());
        let (dists, u, out) = (&dists[..len], &u[..len], &mut out[..len]);
        acdf_core::dispatch!(Self::sample_each_one, dists, u, out)
    }

    /// Whether the box of half-width `margin` around p, a point of
    /// [0, 1)^2, lies inside p's cell: p is at least `margin` from the
    /// cell's edges along both axes (no density lookups).
    #[inline(always)]
    fn same_cell_around(&self, p: Vec2, margin: Vec2) -> bool {
        inside_cell(p.x, self.nx, margin.x) && inside_cell(p.y, self.ny, margin.y)
    }

    /// [`sample_each`](Self::sample_each) and, into `same`,
    /// [`same_cell_around`](Self::same_cell_around) of every sample in its
    /// own slice. Where the CPU has AVX2 the box tests run in the lanes of
    /// the draws ([`piecewise_constant::sample_each_and_same_cell`]).
    fn sample_each_and_same_cell(
        dists: &[&Self],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        let len = dists.len().min(u.len()).min(out.len()).min(same.len());
        let (dists, u, out, same) = (&dists[..len], &u[..len], &mut out[..len], &mut same[..len]);
        acdf_core::dispatch!(
            Self::sample_each_and_same_cell_one,
            dists,
            u,
            margin,
            out,
            same
        )
    }

    /// `dists[k].pdf(p[k])` for every k, bit for bit: the slices of a batch
    /// of shading points. Where the CPU has AVX2, a stage of 32 slices of
    /// one shape is looked up in SIMD lanes, each lane reading its own slice
    /// ([`piecewise_constant::pdf_each`]); other stages one at a time.
    fn pdf_each(dists: &[&Self], p: &[Vec2], out: &mut [f32]) {
        let len = dists.len().min(p.len()).min(out.len());
        let (dists, p, out) = (&dists[..len], &p[..len], &mut out[..len]);
        acdf_core::dispatch!(Self::pdf_each_one, dists, p, out)
    }
}

impl PiecewiseConstant2D {
    /// [`SliceDistribution::sample_each`] itself, a stage of [`STAGE`]
    /// draws at a time.
    #[inline(always)]
    fn sample_each_one(dists: &[&Self], u: &[Vec2], out: &mut [Sample2D], cpu: Option<Avx2>) {
        let stages = dists.chunks(STAGE).zip(u.chunks(STAGE));
        for ((dists, u), out) in stages.zip(out.chunks_mut(STAGE)) {
            let tables = dists.iter().map(|d| d.cdfs());
            let in_lanes = match cpu {
                #[cfg(target_arch = "x86_64")]
                Some(cpu) => piecewise_constant::sample_each(cpu, tables, u, out),
                _ => false,
            };
            if !in_lanes {
                Self::sample_each_lanes(dists, u, out);
            }
        }
    }

    /// [`SliceDistribution::sample_each_and_same_cell`] itself, a stage of
    /// [`STAGE`] draws at a time.
    #[inline(always)]
    fn sample_each_and_same_cell_one(
        dists: &[&Self],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
        cpu: Option<Avx2>,
    ) {
        let stages = dists.chunks(STAGE).zip(u.chunks(STAGE));
        let outputs = out.chunks_mut(STAGE).zip(same.chunks_mut(STAGE));
        for ((dists, u), (out, same)) in stages.zip(outputs) {
            let tables = dists.iter().map(|d| d.cdfs());
            let in_lanes = match cpu {
                #[cfg(target_arch = "x86_64")]
                Some(cpu) => {
                    piecewise_constant::sample_each_and_same_cell(cpu, tables, u, margin, out, same)
                }
                _ => false,
            };
            if !in_lanes {
                Self::sample_each_lanes(dists, u, out);
                Self::same_cells(dists, margin, out, same);
            }
        }
    }

    /// [`SliceDistribution::pdf_each`] itself, a stage of [`STAGE`]
    /// densities at a time.
    #[inline(always)]
    fn pdf_each_one(dists: &[&Self], p: &[Vec2], out: &mut [f32], cpu: Option<Avx2>) {
        let stages = dists.chunks(STAGE).zip(p.chunks(STAGE));
        for ((dists, p), out) in stages.zip(out.chunks_mut(STAGE)) {
            let tables = dists.iter().map(|d| d.cdfs());
            let in_lanes = match cpu {
                #[cfg(target_arch = "x86_64")]
                Some(cpu) => piecewise_constant::pdf_each(cpu, tables, p, out),
                _ => false,
            };
            if !in_lanes {
                for ((o, d), &p) in out.iter_mut().zip(dists).zip(p) {
                    *o = d.pdf(p);
                }
            }
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

/// The number of draws the scalar `sample_batch` advances together: enough
/// independent draws for their loads to overlap, few enough for their
/// state to stay in registers. Sixteen beat eight on the `sample_batch`
/// throughput of the 256x32 slice, and 32 gained nothing more.
const LANES: usize = 16;

mod persist;
#[cfg(test)]
mod tests;
