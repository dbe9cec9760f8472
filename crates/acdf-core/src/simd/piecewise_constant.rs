//! The batch kernels of uniformly tabulated piecewise-constant
//! distributions (those of the `acdf-uniform` plug-in) in AVX2 lanes:
//! draws and densities of a 2D table for many points at once, from one
//! table ([`sample_batch`], [`pdf_batch`]) or from one table per lane
//! ([`sample_each`], [`sample_each_and_same_cell`], [`pdf_each`]), and
//! draws of a 1D table ([`sample_batch_1d`]).
//!
//! The kernels read a table through a plain view of its arrays,
//! [`Table2D`] or [`Table1D`] (or a stage of tables, below), and compute
//! the same IEEE operations in the same order as the plug-in's scalar
//! code, so that every draw and every density is that code's, bit for bit:
//!
//! - a 2D table of `nx` columns and `ny` rows stores a marginal CDF over
//!   the rows, M_0 ..= M_{ny-1} = 1, and row by row a conditional CDF over
//!   the columns, C_0 ..= C_{nx-1} = 1 (the value 0 at the left edge of the
//!   first cell is implicit);
//! - a draw for u in [0, 1)^2 (clamped by
//!   [`clamp_unit`](crate::clamp_unit)) takes the row j with
//!   M_{j-1} <= u.y < M_j and, in that row, the column k with
//!   C_{k-1} <= u.x < C_k; its position is (k + du) / nx and (j + dv) / ny
//!   with du = (u.x - C_{k-1}) / (C_k - C_{k-1}) and dv likewise, each
//!   clamped to [0, 1 - ε/2], and moved back by an ulp or two where
//!   rounding carried it out of its cell; its density is
//!   ny (M_j - M_{j-1}) · nx (C_k - C_{k-1}), raised to the smallest
//!   positive `f32` where both factors are positive;
//! - the density at a point is that of the cell floor(x nx), floor(y ny)
//!   (each clamped to the last cell), and 0 outside [0, 1)^2;
//! - a 1D table is one CDF, drawn as a row of a 2D table.
//!
//! **How.** The cells are found by binary lifting with gathers
//! ([`search::lanes`](crate::search::lanes)): 32 draws per stage, in four
//! groups of eight lanes. In a batch from one table the marginal is a list
//! every lane shares, so its first four search steps come from registers;
//! each draw's conditional row is its own list. The search leaves the
//! drawn cell's two CDF entries in registers, so the arithmetic runs in the
//! same lanes without further loads. A density reads each cell's two
//! entries in one paired load.
//!
//! **Stages.** The kernels of one table per lane take a stage: exactly
//! [`STAGE`] tables, each as the pair `(marginal, conditional)` of its
//! arrays, all of one shape: every marginal as long as the first (ny
//! entries, at least one) and every conditional as long as the first (a
//! multiple nx·ny of ny, at most [`MAX_ENTRIES`]). A kernel checks that
//! before it reads an entry, and refuses (returns false) any other list.
//!
//! **What is checked.** A view checks the sizes of its arrays when it is
//! made (and that a 1D CDF ends at exactly 1), a kernel those of a stage
//! before it reads it; with those, every read of a kernel lies inside the
//! arrays whatever the entries hold. The entries decide the draws, never
//! where the kernels read: a CDF that does not rise or does not end at 1
//! gives draws that mean nothing, but no read outside its table and no
//! endless loop. (The row a 2D search finds is clamped to the table, which
//! changes nothing for a marginal that ends at 1: its last entry is above
//! every clamped u, so no search counts it.)
//!
//! **Where.** The views are plain Rust on every target; the kernels exist
//! on x86-64, take an [`Avx2`](crate::cpu::Avx2) token, and are
//! `#[inline(always)]`, so that they compile into the caller's AVX2
//! instance of [`dispatch!`](crate::dispatch!). Each does the whole stages
//! (or groups of eight) of its input and returns how many items that was,
//! or whether it took the stage; the caller's scalar code does the rest.

#[cfg(target_arch = "x86_64")]
pub use kernels::{
    pdf_batch, pdf_each, sample_batch, sample_batch_1d, sample_each, sample_each_and_same_cell,
};

/// The items a kernel of one table per lane takes at once (its stage):
/// [`sample_each`], [`sample_each_and_same_cell`] and [`pdf_each`] draw or
/// look up exactly this many.
pub const STAGE: usize = 32;

/// The most entries an array of a view may hold: indices into it are
/// `i32` lanes, whose search probes must not overflow (the limit of
/// [`search::lanes::MAX_ENTRIES`](crate::search::lanes::MAX_ENTRIES)).
pub const MAX_ENTRIES: usize = (i32::MAX / 4) as usize;

/// A 2D piecewise-constant table as the kernels read it: `ny` rows of
/// `nx` cells, the marginal CDF over the rows and the conditional CDFs of
/// the rows, row-major.
///
/// Made only by [`new`](Self::new), which checks the sizes the kernels'
/// reads rest on. The draws mean something where the arrays hold CDFs as
/// the module documentation describes them, which is not checked.
#[derive(Debug, Clone, Copy)]
pub struct Table2D<'a> {
    marginal: &'a [f32],
    conditional: &'a [f32],
    nx: usize,
    ny: usize,
}

impl<'a> Table2D<'a> {
    /// The view of `marginal` (`ny` entries) and `conditional` (`nx · ny`
    /// entries), if `nx · ny` is between 1 and [`MAX_ENTRIES`]; `None`
    /// otherwise. The entries are not read: the kernels' reads depend on
    /// the sizes only.
    #[inline(always)]
    pub fn new(marginal: &'a [f32], conditional: &'a [f32], nx: usize, ny: usize) -> Option<Self> {
        // An exact product of 1 or more makes both factors 1 or more.
        let fits = marginal.len() == ny
            && nx.checked_mul(ny) == Some(conditional.len())
            && (1..=MAX_ENTRIES).contains(&conditional.len());
        fits.then_some(Table2D {
            marginal,
            conditional,
            nx,
            ny,
        })
    }
}

/// A 1D piecewise-constant table as [`sample_batch_1d`] reads it: the CDF
/// at the right edge of each of its `n` cells.
///
/// Made only by [`new`](Self::new), which checks what the kernel's reads
/// rest on: the size, and the last entry, 1, above every clamped u, which
/// keeps the count of the list's whole search (its first steps from
/// registers) within the list.
#[derive(Debug, Clone, Copy)]
pub struct Table1D<'a> {
    cdf: &'a [f32],
}

impl<'a> Table1D<'a> {
    /// The view of `cdf`, if it holds between 1 and [`MAX_ENTRIES`]
    /// entries and the last is exactly 1 (the one entry read here).
    #[inline(always)]
    pub fn new(cdf: &'a [f32]) -> Option<Self> {
        let fits = (1..=MAX_ENTRIES).contains(&cdf.len()) && cdf[cdf.len() - 1] == 1.0;
        fits.then_some(Table1D { cdf })
    }
}

#[cfg(target_arch = "x86_64")]
mod kernels {
    // The loops over groups index several parallel arrays of registers by
    // the group number; iterator chains over three or four arrays would
    // hide that.
    #![allow(clippy::needless_range_loop)]

    use super::{Table1D, Table2D, MAX_ENTRIES, STAGE};
    use crate::cpu::Avx2;
    use crate::search::lanes::{
        in_unit, lanes_f32, lanes_i32, load_pairs, load_stage, load_stage_1d, store_lanes,
        store_samples, store_samples_1d, Bracket, PerLane, Shared, SharedList, Source, GROUPS,
    };
    use crate::{Sample1D, Sample2D, Vec2, ONE_MINUS_EPSILON};
    use std::arch::x86_64::*;

    const _: () = assert!(STAGE == crate::search::lanes::STAGE);
    const _: () = assert!(super::MAX_ENTRIES == crate::search::lanes::MAX_ENTRIES);

    /// The same draws as `PiecewiseConstant2D::sample` of `acdf-uniform`
    /// (the draw of the module documentation) for the table, bit for bit,
    /// for the whole stages of `u`: `out[i]` for every i below the returned
    /// count, the largest multiple of [`STAGE`] within both lengths; the
    /// rest is the caller's.
    #[inline(always)]
    pub fn sample_batch(cpu: Avx2, table: &Table2D<'_>, u: &[Vec2], out: &mut [Sample2D]) -> usize {
        let done = u.len().min(out.len()) / STAGE * STAGE;
        let tables = Tables::one(table);
        for (u, out) in u[..done]
            .chunks_exact(STAGE)
            .zip(out[..done].chunks_exact_mut(STAGE))
        {
            let (ux, uy) = load_stage(cpu, u, true);
            let drawn = tables.draw(cpu, &ux, &uy);
            for g in 0..GROUPS {
                store_samples(cpu, drawn.x[g], drawn.y[g], drawn.pdf[g], &mut out[8 * g..]);
            }
        }
        done
    }

    /// The same draws as [`sample_batch`] (as `PiecewiseConstant2D::sample`)
    /// for one stage in which lane i draws `u[i]` from the i-th of `tables`
    /// (its marginal and its conditionals), into `out[..STAGE]`: true if it
    /// drew them, false (nothing written) unless `tables` are a stage (see
    /// the module documentation) and `u` and `out` hold at least [`STAGE`]
    /// items.
    #[inline(always)]
    pub fn sample_each<'a>(
        cpu: Avx2,
        tables: impl IntoIterator<Item = (&'a [f32], &'a [f32])>,
        u: &[Vec2],
        out: &mut [Sample2D],
    ) -> bool {
        sample_stage::<false>(cpu, tables, u, Vec2::ZERO, out, &mut [])
    }

    /// [`sample_each`], and into `same[i]` the same answer as
    /// `PiecewiseConstant2D::same_cell_around(out[i].p, margin)`: whether
    /// the point is at least `margin` from its cell's edges along both
    /// axes, its fraction t - trunc(t) of t = x nx (and of y ny) lying in
    /// [m nx, 1 - m nx]. False (nothing written) where [`sample_each`]
    /// would be, or where `same` holds fewer than [`STAGE`] items.
    #[inline(always)]
    pub fn sample_each_and_same_cell<'a>(
        cpu: Avx2,
        tables: impl IntoIterator<Item = (&'a [f32], &'a [f32])>,
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) -> bool {
        sample_stage::<true>(cpu, tables, u, margin, out, same)
    }

    /// [`sample_each`], with the box tests into `same` when `SAME`.
    #[inline(always)]
    fn sample_stage<'a, const SAME: bool>(
        cpu: Avx2,
        tables: impl IntoIterator<Item = (&'a [f32], &'a [f32])>,
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) -> bool {
        if u.len() < STAGE || out.len() < STAGE || (SAME && same.len() < STAGE) {
            return false;
        }
        let Some(stage) = Stage::new(tables, 1) else {
            return false;
        };
        let lanes = Tables::each(cpu, &stage);
        let (ux, uy) = load_stage(cpu, u, true);
        let drawn = lanes.draw(cpu, &ux, &uy);
        for g in 0..GROUPS {
            store_samples(cpu, drawn.x[g], drawn.y[g], drawn.pdf[g], &mut out[8 * g..]);
            if SAME {
                let inside_x = inside_cell_lanes(cpu, drawn.x[g], stage.nx, margin.x);
                let inside_y = inside_cell_lanes(cpu, drawn.y[g], stage.ny, margin.y);
                // SAFETY: the token proves the CPU has AVX2.
                let bits = unsafe { _mm256_movemask_ps(_mm256_and_ps(inside_x, inside_y)) };
                for l in 0..8 {
                    same[8 * g + l] = bits & (1 << l) != 0;
                }
            }
        }
        true
    }

    /// The same densities as `PiecewiseConstant2D::pdf` of `acdf-uniform`
    /// (the density of the module documentation) for the table, bit for
    /// bit, for the whole groups of eight points of `p`: `out[i]` for every
    /// i below the returned count, the largest multiple of eight within
    /// both lengths; the rest is the caller's. A table of a single row or
    /// column is left to the caller whole (count 0): each cell's two
    /// entries are read as one pair.
    #[inline(always)]
    pub fn pdf_batch(cpu: Avx2, table: &Table2D<'_>, p: &[Vec2], out: &mut [f32]) -> usize {
        if table.nx < 2 || table.ny < 2 {
            return 0;
        }
        let done = p.len().min(out.len()) / 8 * 8;
        let (marginal, conditional) = (Shared::new(table.marginal), Shared::new(table.conditional));
        let shape = (table.nx, table.ny);
        for (p, out) in p[..done]
            .chunks_exact(8)
            .zip(out[..done].chunks_exact_mut(8))
        {
            let (x, y) = load_pairs(cpu, p);
            // SAFETY: the marginal holds `ny` entries and the conditional
            // `nx ny`, with nx, ny >= 2 (checked above) and nx ny at most
            // MAX_ENTRIES (`Table2D::new`).
            let pdf = unsafe { densities_lanes(cpu, &marginal, &conditional, 0, shape, x, y) };
            store_lanes(cpu, pdf, out);
        }
        done
    }

    /// The same densities as [`pdf_batch`] (as `PiecewiseConstant2D::pdf`)
    /// for one stage in which lane i looks up `p[i]` in the i-th of
    /// `tables` (its marginal and its conditionals), into `out[..STAGE]`:
    /// true if it did, false (nothing written) unless `tables` are a stage
    /// (see the module documentation) of at least two rows and two columns
    /// and `p` and `out` hold at least [`STAGE`] items.
    #[inline(always)]
    pub fn pdf_each<'a>(
        cpu: Avx2,
        tables: impl IntoIterator<Item = (&'a [f32], &'a [f32])>,
        p: &[Vec2],
        out: &mut [f32],
    ) -> bool {
        if p.len() < STAGE || out.len() < STAGE {
            return false;
        }
        let Some(stage) = Stage::new(tables, 2) else {
            return false;
        };
        let (marginal, conditional) = stage.per_lane(cpu);
        for g in 0..GROUPS {
            let (x, y) = load_pairs(cpu, &p[8 * g..]);
            // SAFETY: every lane's marginal holds `ny` entries and its
            // conditional `nx ny`, with nx, ny >= 2 and nx ny at most
            // MAX_ENTRIES (`Stage::new` checked it for every lane).
            let pdf = unsafe {
                densities_lanes(cpu, &marginal, &conditional, g, (stage.nx, stage.ny), x, y)
            };
            store_lanes(cpu, pdf, &mut out[8 * g..]);
        }
        true
    }

    /// The same draws as `PiecewiseConstant1D::sample` of `acdf-uniform`
    /// for the table (drawn as a row of a 2D table: the cell k with
    /// P_{k-1} <= u < P_k, x = (k + du) / n moved back into its cell if
    /// rounding carried it out, density n (P_k - P_{k-1})), bit for bit,
    /// for the whole stages of `u`: `out[i]` for every i below the returned
    /// count, the largest multiple of [`STAGE`] within both lengths; the
    /// rest is the caller's.
    #[inline(always)]
    pub fn sample_batch_1d(
        cpu: Avx2,
        table: &Table1D<'_>,
        u: &[f32],
        out: &mut [Sample1D],
    ) -> usize {
        let Some(cdf) = SharedList::new(table.cdf) else {
            // Not reached: a view holds as many entries as a list may.
            return 0;
        };
        let n = table.cdf.len();
        let done = u.len().min(out.len()) / STAGE * STAGE;
        for (u, out) in u[..done]
            .chunks_exact(STAGE)
            .zip(out[..done].chunks_exact_mut(STAGE))
        {
            let v = load_stage_1d(cpu, u);
            let cells = Bracket::search_shared(cpu, cdf, &v);
            for g in 0..GROUPS {
                let k = cells.count[g];
                // SAFETY: the token proves the CPU has AVX2.
                let (mass, du) = unsafe {
                    let mass = _mm256_sub_ps(cells.upper[g], cells.lower[g]);
                    (
                        mass,
                        _mm256_div_ps(_mm256_sub_ps(v[g], cells.lower[g]), mass),
                    )
                };
                let (mut x, off) = position(cpu, k, clamp_fraction(cpu, du), n);
                // SAFETY: the token proves the CPU has AVX2.
                let (on_edge, pdf) = unsafe {
                    (
                        _mm256_movemask_ps(_mm256_castsi256_ps(off)),
                        _mm256_mul_ps(mass, _mm256_set1_ps(n as f32)),
                    )
                };
                if on_edge != 0 {
                    // Rare: a position rounded onto a cell edge.
                    x = into_cells(cpu, x, k, on_edge, n);
                }
                store_samples_1d(cpu, x, pdf, &mut out[8 * g..]);
            }
        }
        done
    }

    /// `f32::clamp(d, 0, 1 - ε/2)` in lanes, for d not NaN.
    #[inline(always)]
    fn clamp_fraction(_: Avx2, d: __m256) -> __m256 {
        // SAFETY: the token proves the CPU has AVX2.
        unsafe {
            _mm256_min_ps(
                _mm256_max_ps(d, _mm256_setzero_ps()),
                _mm256_set1_ps(ONE_MINUS_EPSILON),
            )
        }
    }

    /// One coordinate of the draw: the position (cell + fraction) / n,
    /// capped below 1, and whether it rounded out of its cell (all ones
    /// where it did).
    #[inline(always)]
    fn position(_: Avx2, cell: __m256i, fraction: __m256, n: usize) -> (__m256, __m256i) {
        let nf = n as f32;
        // SAFETY: the token proves the CPU has AVX2.
        unsafe {
            let p = _mm256_min_ps(
                _mm256_mul_ps(
                    _mm256_add_ps(_mm256_cvtepi32_ps(cell), fraction),
                    _mm256_set1_ps(1.0 / nf),
                ),
                _mm256_set1_ps(ONE_MINUS_EPSILON),
            );
            let back = _mm256_min_epi32(
                _mm256_cvttps_epi32(_mm256_mul_ps(p, _mm256_set1_ps(nf))),
                _mm256_set1_epi32(n as i32 - 1),
            );
            (
                p,
                _mm256_xor_si256(_mm256_cmpeq_epi32(back, cell), _mm256_set1_epi32(-1)),
            )
        }
    }

    /// The positions `v` with the lanes flagged in `on_edge` (bit l for
    /// lane l) moved into their cells `cell` of a grid of n cells, as the
    /// scalar draw moves them ([`into_cell`]).
    #[inline(always)]
    fn into_cells(cpu: Avx2, v: __m256, cell: __m256i, on_edge: i32, n: usize) -> __m256 {
        let (mut lanes, cells) = (lanes_f32(cpu, v), lanes_i32(cpu, cell));
        for l in (0..8).filter(|l| on_edge & (1 << l) != 0) {
            lanes[l] = into_cell(lanes[l], cells[l] as usize, n);
        }
        // SAFETY: the token proves the CPU has AVX2; the load reads the
        // eight floats of `lanes`.
        unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
    }

    /// x, a position in [0, 1), moved by ulps into cell k of a grid of n
    /// cells, the cell of x being min(floor(x n), n - 1) as the scalar draw
    /// finds it: the rare draw whose position rounded onto a cell edge.
    /// A couple of ulps suffice; the upward steps stop at 1, which they
    /// reach only for a cell past the grid (a conditional row not ending
    /// at 1), so that the loops end whatever the table.
    ///
    /// Scalar and out of line: it runs for a handful of draws in a million.
    #[cold]
    #[inline(never)]
    fn into_cell(mut x: f32, k: usize, n: usize) -> f32 {
        let nf = n as f32;
        let cell = |x: f32| crate::fast::grid_cell(x * nf, nf - 1.0);
        while cell(x) > k {
            x = x.next_down();
        }
        while cell(x) < k && x < 1.0 {
            x = x.next_up();
        }
        x
    }

    /// The scalar `joint_pdf` in lanes: the product, raised to the
    /// smallest positive `f32` where both factors are positive.
    #[inline(always)]
    fn joint_pdf_lanes(_: Avx2, marginal: __m256, conditional: __m256) -> __m256 {
        // SAFETY: the token proves the CPU has AVX2.
        unsafe {
            let zero = _mm256_setzero_ps();
            let p = _mm256_mul_ps(marginal, conditional);
            let both = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GT_OQ>(marginal, zero),
                _mm256_cmp_ps::<_CMP_GT_OQ>(conditional, zero),
            );
            _mm256_blendv_ps(p, _mm256_max_ps(p, _mm256_set1_ps(f32::from_bits(1))), both)
        }
    }

    /// The tables of [`sample_each`] or [`pdf_each`], checked to be a stage
    /// (the module documentation): lane l's marginal and conditionals, and
    /// their shape.
    struct Stage<'a> {
        tables: [(&'a [f32], &'a [f32]); STAGE],
        nx: usize,
        ny: usize,
    }

    impl<'a> Stage<'a> {
        /// The stage, if `tables` are one with at least `least` rows and
        /// columns.
        #[inline(always)]
        fn new(
            tables: impl IntoIterator<Item = (&'a [f32], &'a [f32])>,
            least: usize,
        ) -> Option<Self> {
            let mut tables = tables.into_iter();
            let first = tables.next()?;
            let (ny, cells) = (first.0.len(), first.1.len());
            if ny == 0 || !(1..=MAX_ENTRIES).contains(&cells) {
                return None;
            }
            // Both below 2^31 (ny <= cells is kept for the division), so a
            // 32-bit division; nx ny <= cells cannot overflow.
            let nx = (cells as u32 / ny.min(cells) as u32) as usize;
            if nx * ny != cells || nx < least || ny < least {
                return None;
            }
            let mut fits = true;
            // Each lane is written once; one of other lengths is replaced by
            // the first table and rejects the stage below.
            let all = std::array::from_fn(|l| {
                if l == 0 {
                    return first;
                }
                match tables.next() {
                    Some(t) if t.0.len() == ny && t.1.len() == cells => t,
                    _ => {
                        fits = false;
                        first
                    }
                }
            });
            (fits && tables.next().is_none()).then_some(Stage {
                tables: all,
                nx,
                ny,
            })
        }

        /// The marginals and the conditionals, lane l reading lane l's.
        #[inline(always)]
        fn per_lane(&self, cpu: Avx2) -> (PerLane<'a>, PerLane<'a>) {
            (
                PerLane::new(cpu, |l| self.tables[l].0),
                PerLane::new(cpu, |l| self.tables[l].1),
            )
        }
    }

    /// The tables a stage's lanes draw from: all of one shape (nx, ny),
    /// read from one table or one per lane.
    ///
    /// The invariant the searches' reads rest on: every lane's marginal
    /// holds `ny` entries and its conditional `nx · ny`, at most
    /// [`MAX_ENTRIES`]. Only [`Tables::one`] and [`Tables::each`] make one,
    /// from tables that [`Table2D::new`] or [`Stage::new`] checked.
    struct Tables<'a, S> {
        marginal: S,
        conditional: S,
        nx: usize,
        ny: usize,
        /// The marginal every lane shares (a batch), whose first search
        /// steps can then come from registers.
        shared: Option<&'a [f32]>,
    }

    impl<'a> Tables<'a, Shared<'a>> {
        /// Every lane reads `table`.
        #[inline(always)]
        fn one(table: &Table2D<'a>) -> Self {
            Tables {
                marginal: Shared::new(table.marginal),
                conditional: Shared::new(table.conditional),
                nx: table.nx,
                ny: table.ny,
                shared: Some(table.marginal),
            }
        }
    }

    impl<'a> Tables<'a, PerLane<'a>> {
        /// Lane l reads the stage's l-th table.
        #[inline(always)]
        fn each(cpu: Avx2, stage: &Stage<'a>) -> Self {
            let (marginal, conditional) = stage.per_lane(cpu);
            Tables {
                marginal,
                conditional,
                nx: stage.nx,
                ny: stage.ny,
                shared: None,
            }
        }
    }

    /// A stage's draws: positions and densities.
    struct Drawn {
        x: [__m256; GROUPS],
        y: [__m256; GROUPS],
        pdf: [__m256; GROUPS],
    }

    impl<S: Source> Tables<'_, S> {
        /// The draws for clamped `ux`, `uy`.
        #[inline(always)]
        fn draw(&self, cpu: Avx2, ux: &[__m256; GROUPS], uy: &[__m256; GROUPS]) -> Drawn {
            let (nx, ny) = (self.nx, self.ny);
            // SAFETY: the token proves the CPU has AVX2 (for every
            // intrinsic here). The two searches read inside the tables
            // (the invariant of `Tables`): the marginal's lanes search its
            // `ny` entries from 0 to `ny - 1`, from a count of 0 (a fresh
            // bracket) or of at most `ny - 1` (`shared_top` over that same
            // list, clamped); the conditional's lanes search row j, the
            // marginal count clamped to `ny - 1`: entries `j nx` to
            // `j nx + nx - 1` of the conditional's `nx ny`.
            unsafe {
                let (nxf, nyf) = (_mm256_set1_ps(nx as f32), _mm256_set1_ps(ny as f32));
                let zero = [_mm256_setzero_si256(); GROUPS];
                let last_row = [_mm256_set1_epi32(ny as i32 - 1); GROUPS];
                let last_column = [_mm256_set1_epi32(nx as i32 - 1); GROUPS];
                let mut rows = Bracket::start(cpu);
                let step = match self.shared {
                    Some(marginal) => {
                        let step = rows.shared_top(cpu, marginal, uy);
                        for g in 0..GROUPS {
                            rows.count[g] = _mm256_min_epi32(rows.count[g], last_row[g]);
                        }
                        step
                    }
                    None => ny.next_power_of_two() / 2,
                };
                rows.lift(cpu, &self.marginal, &zero, &last_row, uy, step);
                let mut row_start = zero;
                for g in 0..GROUPS {
                    rows.count[g] = _mm256_min_epi32(rows.count[g], last_row[g]);
                    row_start[g] = _mm256_mullo_epi32(rows.count[g], _mm256_set1_epi32(nx as i32));
                }
                let mut columns = Bracket::start(cpu);
                let step = nx.next_power_of_two() / 2;
                columns.lift(cpu, &self.conditional, &row_start, &last_column, ux, step);
                let mut drawn = Drawn {
                    x: [_mm256_setzero_ps(); GROUPS],
                    y: [_mm256_setzero_ps(); GROUPS],
                    pdf: [_mm256_setzero_ps(); GROUPS],
                };
                for g in 0..GROUPS {
                    let (j, k) = (rows.count[g], columns.count[g]);
                    let row_mass = _mm256_sub_ps(rows.upper[g], rows.lower[g]);
                    let col_mass = _mm256_sub_ps(columns.upper[g], columns.lower[g]);
                    let dv = _mm256_div_ps(_mm256_sub_ps(uy[g], rows.lower[g]), row_mass);
                    let du = _mm256_div_ps(_mm256_sub_ps(ux[g], columns.lower[g]), col_mass);
                    let (mut x, x_off) = position(cpu, k, clamp_fraction(cpu, du), nx);
                    let (mut y, y_off) = position(cpu, j, clamp_fraction(cpu, dv), ny);
                    let on_edge =
                        _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_or_si256(x_off, y_off)));
                    if on_edge != 0 {
                        // Rare: a position rounded onto a cell edge.
                        x = into_cells(cpu, x, k, on_edge, nx);
                        y = into_cells(cpu, y, j, on_edge, ny);
                    }
                    drawn.x[g] = x;
                    drawn.y[g] = y;
                    drawn.pdf[g] = joint_pdf_lanes(
                        cpu,
                        _mm256_mul_ps(row_mass, nyf),
                        _mm256_mul_ps(col_mass, nxf),
                    );
                }
                drawn
            }
        }
    }

    /// The box test of the scalar `same_cell_around` in lanes, per axis:
    /// the fraction t - trunc(t) of t = x n (in [0, n), so one conversion
    /// truncates it) lies in [m n, 1 - m n]; all ones where it does.
    #[inline(always)]
    fn inside_cell_lanes(_: Avx2, x: __m256, n: usize, m: f32) -> __m256 {
        let nf = n as f32;
        let m = m * nf;
        // SAFETY: the token proves the CPU has AVX2.
        unsafe {
            let t = _mm256_mul_ps(x, _mm256_set1_ps(nf));
            let f = _mm256_sub_ps(t, _mm256_cvtepi32_ps(_mm256_cvttps_epi32(t)));
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(f, _mm256_set1_ps(m)),
                _mm256_cmp_ps::<_CMP_LE_OQ>(f, _mm256_set1_ps(1.0 - m)),
            )
        }
    }

    /// The cell of each lane's coordinate v in [0, 1) on a grid of n
    /// cells, as the scalar `pdf` finds it: in [0, n - 1] for every v in
    /// [0, 1).
    #[inline(always)]
    fn cell_lanes(_: Avx2, v: __m256, n: usize) -> __m256i {
        // SAFETY: the token proves the CPU has AVX2.
        unsafe {
            _mm256_min_epi32(
                _mm256_cvttps_epi32(_mm256_mul_ps(v, _mm256_set1_ps(n as f32))),
                _mm256_set1_epi32(n as i32 - 1),
            )
        }
    }

    /// The probability of each lane's cell `start + k` of a stored CDF
    /// beginning at `start` (in group g of `cdf`): P_k - P_{k-1}, with
    /// P_{-1} = 0.
    ///
    /// # Safety
    /// In every lane, `start >= 0`, `k >= 0`, and entries
    /// `start + max(k - 1, 0)` and the one after it lie inside the lane's
    /// array (a run of at least two entries holding cell k).
    #[inline(always)]
    unsafe fn cell_mass_lanes<S: Source>(
        cpu: Avx2,
        cdf: &S,
        g: usize,
        start: __m256i,
        k: __m256i,
    ) -> __m256 {
        // SAFETY: the token proves the CPU has AVX2; the pair read is
        // inside the array by the caller's contract.
        unsafe {
            let zero = _mm256_setzero_si256();
            let first = _mm256_cmpeq_epi32(k, zero);
            // Entries k - 1 and k, or 0 and 1 for k = 0.
            let from = _mm256_add_epi32(
                start,
                _mm256_max_epi32(_mm256_sub_epi32(k, _mm256_set1_epi32(1)), zero),
            );
            let (a, b) = cdf.gather_pairs(cpu, g, from);
            let first = _mm256_castsi256_ps(first);
            let upper = _mm256_blendv_ps(b, a, first);
            let lower = _mm256_andnot_ps(first, a);
            _mm256_sub_ps(upper, lower)
        }
    }

    /// The densities at eight points (x, y) of tables of shape (nx, ny)
    /// (group g of the sources): the cells from the coordinates, each
    /// cell's two CDF entries in one paired read, `joint_pdf` of the
    /// masses; 0 outside [0, 1)^2 (NaN included).
    ///
    /// # Safety
    /// Every lane's marginal holds `ny` entries and its conditional
    /// `nx · ny`, with `nx`, `ny` >= 2 and `nx · ny` at most
    /// [`MAX_ENTRIES`].
    #[inline(always)]
    unsafe fn densities_lanes<S: Source>(
        cpu: Avx2,
        marginal: &S,
        conditional: &S,
        g: usize,
        (nx, ny): (usize, usize),
        x: __m256,
        y: __m256,
    ) -> __m256 {
        // SAFETY: the token proves the CPU has AVX2. Outside points look
        // up cell (0, 0), inside ones cells (ix, iy) in [0, nx - 1] x
        // [0, ny - 1] (`cell_lanes`): the marginal pair read starts at
        // max(iy - 1, 0) <= ny - 2, the conditional's at
        // iy nx + max(ix - 1, 0) <= nx ny - 2, inside the tables by the
        // caller's contract.
        unsafe {
            let inside = _mm256_and_ps(in_unit(cpu, x), in_unit(cpu, y));
            // Outside points look up cell (0, 0) and are zeroed at the end.
            let (x, y) = (_mm256_and_ps(x, inside), _mm256_and_ps(y, inside));
            let (ix, iy) = (cell_lanes(cpu, x, nx), cell_lanes(cpu, y, ny));
            let row_mass = cell_mass_lanes(cpu, marginal, g, _mm256_setzero_si256(), iy);
            let row = _mm256_mullo_epi32(iy, _mm256_set1_epi32(nx as i32));
            let col_mass = cell_mass_lanes(cpu, conditional, g, row, ix);
            let (nxf, nyf) = (_mm256_set1_ps(nx as f32), _mm256_set1_ps(ny as f32));
            let pdf = joint_pdf_lanes(
                cpu,
                _mm256_mul_ps(row_mass, nyf),
                _mm256_mul_ps(col_mass, nxf),
            );
            _mm256_and_ps(pdf, inside)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator of numbers in [0, 1).
    struct Numbers(u64);

    impl Numbers {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// A stored CDF of `values` (running sums over the total, the last
    /// exactly 1; the uniform one for a zero total).
    fn cdf_of(values: &[f32]) -> Vec<f32> {
        let total: f64 = values.iter().map(|&v| v as f64).sum();
        let n = values.len();
        let mut running = 0.0f64;
        let mut cdf: Vec<f32> = values
            .iter()
            .enumerate()
            .map(|(k, &v)| {
                running += v as f64;
                if total > 0.0 {
                    (running / total) as f32
                } else {
                    ((k + 1) as f64 / n as f64) as f32
                }
            })
            .collect();
        cdf[n - 1] = 1.0;
        cdf
    }

    /// Cell values with zeros, tiny values and a zero row now and then.
    fn values(numbers: &mut Numbers, count: usize) -> Vec<f32> {
        (0..count)
            .map(|_| match (numbers.next() * 8.0) as u32 {
                0 | 1 => 0.0,
                2 => numbers.next() * 1e-9,
                _ => numbers.next() * numbers.next() * 100.0,
            })
            .collect()
    }

    /// A 2D table's marginal and conditionals, row-major.
    struct Owned {
        marginal: Vec<f32>,
        conditional: Vec<f32>,
        nx: usize,
        ny: usize,
    }

    impl Owned {
        fn new(numbers: &mut Numbers, nx: usize, ny: usize) -> Owned {
            let mut conditional = Vec::with_capacity(nx * ny);
            let mut rows = Vec::with_capacity(ny);
            for j in 0..ny {
                let row = if j % 5 == 3 {
                    vec![0.0; nx]
                } else {
                    values(numbers, nx)
                };
                rows.push(row.iter().sum::<f32>());
                conditional.extend(cdf_of(&row));
            }
            Owned {
                marginal: cdf_of(&rows),
                conditional,
                nx,
                ny,
            }
        }

        fn cdfs(&self) -> (&[f32], &[f32]) {
            (&self.marginal, &self.conditional)
        }

        fn view(&self) -> Table2D<'_> {
            Table2D::new(&self.marginal, &self.conditional, self.nx, self.ny).expect("a view")
        }

        fn row(&self, j: usize) -> &[f32] {
            &self.conditional[j * self.nx..(j + 1) * self.nx]
        }

        /// The draw, written out plainly.
        fn sample(&self, u: Vec2) -> Sample2D {
            let (ux, uy) = (clamp_unit(u.x), clamp_unit(u.y));
            let (y, row_mass) = draw_1d(&self.marginal, uy);
            let j = cell(y, self.ny);
            let (x, col_mass) = draw_1d(self.row(j), ux);
            Sample2D {
                p: Vec2::new(x, y),
                pdf: joint(row_mass * self.ny as f32, col_mass * self.nx as f32),
            }
        }

        /// The density, written out plainly.
        fn pdf(&self, p: Vec2) -> f32 {
            if !((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y)) {
                return 0.0;
            }
            let (i, j) = (cell(p.x, self.nx), cell(p.y, self.ny));
            joint(
                mass(&self.marginal, j) * self.ny as f32,
                mass(self.row(j), i) * self.nx as f32,
            )
        }
    }

    use crate::{clamp_unit, Sample1D, Sample2D, Vec2, ONE_MINUS_EPSILON};

    /// min(floor(x n), n - 1) for x in [0, 1).
    fn cell(x: f32, n: usize) -> usize {
        ((x * n as f32) as usize).min(n - 1)
    }

    fn mass(cdf: &[f32], k: usize) -> f32 {
        cdf[k] - if k == 0 { 0.0 } else { cdf[k - 1] }
    }

    fn joint(a: f32, b: f32) -> f32 {
        let p = a * b;
        if a > 0.0 && b > 0.0 {
            p.max(f32::from_bits(1))
        } else {
            p
        }
    }

    /// Draws whose position rounded out of its cell, in [`draw_1d`].
    static NUDGED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

    /// The position drawn by a clamped u from a CDF, and its cell's mass.
    fn draw_1d(cdf: &[f32], u: f32) -> (f32, f32) {
        let n = cdf.len();
        let k = cdf[..n - 1].partition_point(|&c| c <= u);
        let lower = if k == 0 { 0.0 } else { cdf[k - 1] };
        let m = cdf[k] - lower;
        let du = ((u - lower) / m).clamp(0.0, ONE_MINUS_EPSILON);
        let nf = n as f32;
        let mut x = ((k as f32 + du) * (1.0 / nf)).min(ONE_MINUS_EPSILON);
        if cell(x, n) != k {
            NUDGED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        while cell(x, n) > k {
            x = x.next_down();
        }
        while cell(x, n) < k {
            x = x.next_up();
        }
        (x, m)
    }

    fn inside(x: f32, n: usize, m: f32) -> bool {
        let t = x * n as f32;
        let f = t - (t as i32) as f32;
        let m = m * n as f32;
        f >= m && f <= 1.0 - m
    }

    /// Uniform numbers with the edges: 0, -0, 1, past 1, NaN, negative,
    /// the largest below 1, entries of `cdf` (where ties decide) and the
    /// numbers just below them (whose positions may round onto an edge).
    fn inputs(numbers: &mut Numbers, count: usize, cdf: &[f32]) -> Vec<f32> {
        let edges = [
            0.0,
            -0.0,
            1.0,
            1.5,
            f32::NAN,
            -0.25,
            ONE_MINUS_EPSILON,
            f32::INFINITY,
        ];
        (0..count)
            .map(|i| match i % 7 {
                0 => edges[(i / 7) % edges.len()],
                1 => cdf[(numbers.next() * cdf.len() as f32) as usize],
                2 | 3 => cdf[(numbers.next() * cdf.len() as f32) as usize].next_down(),
                _ => numbers.next(),
            })
            .collect()
    }

    fn same_bits(a: &Sample2D, b: &Sample2D) -> bool {
        (a.p.x.to_bits(), a.p.y.to_bits(), a.pdf.to_bits())
            == (b.p.x.to_bits(), b.p.y.to_bits(), b.pdf.to_bits())
    }

    #[test]
    fn views_check_their_sizes() {
        let (m, c) = ([0.5, 1.0], [0.25, 0.5, 1.0, 0.1, 0.2, 1.0]);
        assert!(Table2D::new(&m, &c, 3, 2).is_some());
        assert!(Table2D::new(&m, &c, 2, 3).is_none());
        assert!(Table2D::new(&m, &c[..5], 3, 2).is_none());
        assert!(Table2D::new(&m[..1], &c, 3, 2).is_none());
        assert!(Table2D::new(&[], &[], 0, 0).is_none());
        assert!(Table2D::new(&[], &[], 5, 0).is_none());
        assert!(Table2D::new(&m, &c, usize::MAX / 2 + 2, 2).is_none());
        assert!(Table1D::new(&c[..3]).is_some());
        assert!(Table1D::new(&c[..2]).is_none());
        assert!(Table1D::new(&[]).is_none());
    }

    /// The draws, densities and box tests of every kernel are those
    /// written out plainly above, bit for bit, on tables of many shapes.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn kernels_match_the_plain_draws() {
        let Some(cpu) = crate::cpu::avx2() else {
            println!("skipped: this CPU has no AVX2 and FMA (or ACDF_CPU=portable)");
            return;
        };
        let mut numbers = Numbers(7);
        let margin = Vec2::new(1e-3, 2e-3);
        for (nx, ny) in [
            (1, 1),
            (1, 9),
            (9, 1),
            (2, 2),
            (3, 17),
            (32, 256),
            (5, 40),
            (64, 3),
        ] {
            let tables: Vec<Owned> = (0..3).map(|_| Owned::new(&mut numbers, nx, ny)).collect();
            let n = 12 * STAGE + 5;
            let xs = inputs(&mut numbers, n, &tables[0].conditional);
            let ys = inputs(&mut numbers, n, &tables[0].marginal);
            let u: Vec<Vec2> = xs.iter().zip(&ys).map(|(&x, &y)| Vec2::new(x, y)).collect();

            // One table.
            let t = &tables[0];
            let mut out = vec![Sample2D::default(); n];
            let done = sample_batch(cpu, &t.view(), &u, &mut out);
            assert_eq!(done, 12 * STAGE);
            for (s, &u) in out[..done].iter().zip(&u) {
                assert!(same_bits(s, &t.sample(u)), "{nx}x{ny} at {u}: {s:?}");
            }
            let points: Vec<Vec2> = u
                .iter()
                .zip(&out)
                .enumerate()
                .map(|(i, (&u, s))| if i % 2 == 0 { s.p } else { u })
                .collect();
            let mut densities = vec![0.0; n];
            let done = pdf_batch(cpu, &t.view(), &points, &mut densities);
            assert_eq!(done, if nx < 2 || ny < 2 { 0 } else { n / 8 * 8 });
            for (d, &p) in densities[..done].iter().zip(&points) {
                assert_eq!(d.to_bits(), t.pdf(p).to_bits(), "{nx}x{ny} at {p}");
            }

            // One table per lane, over whole stages.
            let pick = |i: usize| &tables[(i * 7 + i / 3) % tables.len()];
            for stage in 0..12 {
                let range = stage * STAGE..(stage + 1) * STAGE;
                let views = range.clone().map(|i| pick(i).cdfs());
                let mut drawn = [Sample2D::default(); STAGE];
                let mut same = [false; STAGE];
                assert!(sample_each_and_same_cell(
                    cpu,
                    views.clone(),
                    &u[range.clone()],
                    margin,
                    &mut drawn,
                    &mut same
                ));
                let mut plain = [Sample2D::default(); STAGE];
                assert!(sample_each(
                    cpu,
                    views.clone(),
                    &u[range.clone()],
                    &mut plain
                ));
                let mut densities = [0.0; STAGE];
                let looked_up = pdf_each(cpu, views, &points[range.clone()], &mut densities);
                assert_eq!(looked_up, nx >= 2 && ny >= 2);
                for (l, i) in range.enumerate() {
                    let want = pick(i).sample(u[i]);
                    assert!(same_bits(&drawn[l], &want), "{nx}x{ny} lane {l}");
                    assert!(same_bits(&plain[l], &want), "{nx}x{ny} lane {l}");
                    let box_inside =
                        inside(want.p.x, nx, margin.x) && inside(want.p.y, ny, margin.y);
                    assert_eq!(same[l], box_inside, "{nx}x{ny} lane {l}");
                    if looked_up {
                        assert_eq!(densities[l].to_bits(), pick(i).pdf(points[i]).to_bits());
                    }
                }
            }

            // 1D: the first row's CDF.
            let cdf = t.row(0);
            let v = inputs(&mut numbers, n, cdf);
            let mut out = vec![Sample1D::default(); n];
            let done = sample_batch_1d(cpu, &Table1D::new(cdf).unwrap(), &v, &mut out);
            assert_eq!(done, 12 * STAGE);
            for (s, &v) in out[..done].iter().zip(&v) {
                let (x, m) = draw_1d(cdf, clamp_unit(v));
                assert_eq!(
                    (s.x.to_bits(), s.pdf.to_bits()),
                    (x.to_bits(), (m * nx as f32).to_bits())
                );
            }
        }
        // Some positions rounded onto a cell edge: the scalar clean-up ran.
        assert!(NUDGED.load(std::sync::atomic::Ordering::Relaxed) > 0);
    }

    /// A stage that is not [`STAGE`] views of one shape is left alone.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn stages_of_other_tables_are_refused() {
        let Some(cpu) = crate::cpu::avx2() else {
            return;
        };
        let mut numbers = Numbers(3);
        let (a, b) = (
            Owned::new(&mut numbers, 4, 6),
            Owned::new(&mut numbers, 6, 4),
        );
        let u = vec![Vec2::splat(0.5); STAGE + 1];
        let mut out = [Sample2D::default(); STAGE + 1];
        let mut densities = [0.0; STAGE + 1];
        let untouched = Sample2D::default();
        let refuse = |views: Vec<(&[f32], &[f32])>, out: &mut [Sample2D], d: &mut [f32]| {
            assert!(!sample_each(cpu, views.clone(), &u, out));
            assert!(!pdf_each(cpu, views, &u, d));
        };
        let fewer = vec![a.cdfs(); STAGE - 1];
        refuse(fewer, &mut out, &mut densities);
        let more = vec![a.cdfs(); STAGE + 1];
        refuse(more, &mut out, &mut densities);
        let mut mixed = vec![a.cdfs(); STAGE];
        mixed[17] = b.cdfs();
        refuse(mixed, &mut out, &mut densities);
        let mut short = vec![a.cdfs(); STAGE];
        short[31].1 = &a.conditional[..23];
        refuse(short, &mut out, &mut densities);
        let mut ragged = vec![(&a.marginal[..5], &a.conditional[..23]); STAGE];
        refuse(ragged.clone(), &mut out, &mut densities);
        ragged[0] = (&[], &[]);
        refuse(ragged, &mut out, &mut densities);
        assert!(out.iter().all(|s| same_bits(s, &untouched)));
        assert!(densities.iter().all(|&d| d == 0.0));
        // Short inputs.
        let full = vec![a.cdfs(); STAGE];
        assert!(!sample_each(cpu, full.clone(), &u[..STAGE - 1], &mut out));
        assert!(!pdf_each(cpu, full, &u, &mut densities[..STAGE - 1]));
        // Tables of one column or row are drawn, but not looked up.
        let thin = Owned::new(&mut numbers, 1, 9);
        let views = vec![thin.cdfs(); STAGE];
        assert!(sample_each(cpu, views.clone(), &u, &mut out));
        assert!(!pdf_each(cpu, views, &u, &mut densities));
    }

    /// Tables whose entries are not CDFs (falling, NaN, rows not ending at
    /// 1) give meaningless draws, but every kernel returns.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn any_entries_are_read_safely() {
        let Some(cpu) = crate::cpu::avx2() else {
            return;
        };
        let mut numbers = Numbers(11);
        let (nx, ny) = (7, 13);
        for round in 0..4 {
            let mut junk = |count: usize| -> Vec<f32> {
                (0..count)
                    .map(|_| match round {
                        0 => 0.0,
                        1 => f32::NAN,
                        2 => 2.0 - numbers.next() * 4.0,
                        _ => f32::INFINITY,
                    })
                    .collect()
            };
            let conditional = junk(nx * ny);
            let mut marginal = junk(ny);
            let table = Table2D::new(&marginal, &conditional, nx, ny).unwrap();
            let u: Vec<Vec2> = (0..STAGE)
                .map(|_| Vec2::new(numbers.next(), numbers.next()))
                .collect();
            let mut out = [Sample2D::default(); STAGE];
            let mut densities = [0.0; STAGE];
            let mut same = [false; STAGE];
            sample_batch(cpu, &table, &u, &mut out);
            pdf_batch(cpu, &table, &u, &mut densities);
            let views = vec![(&marginal[..], &conditional[..]); STAGE];
            sample_each_and_same_cell(cpu, views.clone(), &u, Vec2::ZERO, &mut out, &mut same);
            pdf_each(cpu, views, &u, &mut densities);
            *marginal.last_mut().unwrap() = 1.0;
            let v: Vec<f32> = u.iter().map(|u| u.x).collect();
            let mut drawn = [Sample1D::default(); STAGE];
            sample_batch_1d(cpu, &Table1D::new(&marginal).unwrap(), &v, &mut drawn);
        }
    }
}
