//! The AVX2 batch paths of the piecewise-constant distributions:
//! `PiecewiseConstant2D::sample_batch`, `sample_each` (with or without the
//! box test of each draw), `pdf_batch` and `pdf_each`, and
//! `PiecewiseConstant1D::sample_batch`. The searches are those of
//! [`acdf_core::search::lanes`], the final arithmetic runs in the same lanes.
//!
//! In a batch the marginal is one list shared by every draw, so its first
//! four search steps come from registers; each draw's conditional is its own
//! list, searched with gathers. log2(ny) - 4 + log2(nx) gathers find both
//! cells and their edges (four and five at 256x32). In `sample_each` every
//! lane reads its own slice, and the marginal is searched with gathers too.
//!
//! The arithmetic is the same IEEE operations in the same order as
//! `PiecewiseConstant2D::finish`, so the samples are bit-identical to
//! `sample`; a draw whose position rounds onto a cell edge is finished by
//! the scalar code, as everywhere else.
//!
//! Every function takes an [`Avx2`] token (or a [`Tables`] holding one),
//! which proves the CPU has AVX2: the `#[target_feature]` entry points are
//! compiled for it and the helpers are `#[inline(always)]` into them. The
//! searches read the tables at indices held in registers, which is
//! `unsafe` (see `acdf_core::search::lanes`); each such read says why its
//! indices lie inside the tables.

// The loops over groups index several parallel arrays of registers by the
// group number; iterator chains over three or four arrays would hide that.
#![allow(clippy::needless_range_loop)]

use super::{PiecewiseConstant1D, PiecewiseConstant2D};
use acdf_core::cpu::Avx2;
use acdf_core::search::lanes::{
    in_unit, lanes_f32, lanes_i32, load_pairs, load_stage, load_stage_1d, store_lanes,
    store_samples, store_samples_1d, Bracket, PerLane, Shared, SharedList, Source, GROUPS,
    MAX_ENTRIES, STAGE,
};
use acdf_core::{Sample1D, Sample2D, Vec2, ONE_MINUS_EPSILON};
use acdf_tabulated::SliceDistribution;
use std::arch::x86_64::*;

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

/// One coordinate of the draw: the position (cell + fraction) / n, capped
/// below 1, and whether it rounded out of its cell (all ones where it did).
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

/// `joint_pdf` in lanes: the product, raised to the smallest positive
/// `f32` where both factors are positive.
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

/// The tables a stage's lanes draw from: all of one shape (nx, ny), read
/// from one distribution or one per lane.
///
/// The invariant the searches' bounds rest on: every lane's marginal holds
/// `ny` entries and its conditional `nx · ny`, at most
/// [`MAX_ENTRIES`], and every CDF ends at exactly 1. Only [`Tables::one`]
/// and [`Tables::each`] make one, from distributions that fit the lanes
/// (`PiecewiseConstant2D::fits_lanes`) and share one shape.
struct Tables<'a, S> {
    cpu: Avx2,
    marginal: S,
    conditional: S,
    nx: usize,
    ny: usize,
    /// The marginal every lane shares (a batch), whose first search steps
    /// can then come from registers.
    shared: Option<&'a [f32]>,
}

impl<'a> Tables<'a, Shared<'a>> {
    /// Every lane reads `d`.
    ///
    /// # Safety
    /// `d` fits the lanes (`PiecewiseConstant2D::fits_lanes`).
    #[inline(always)]
    unsafe fn one(cpu: Avx2, d: &'a PiecewiseConstant2D) -> Self {
        debug_assert!(d.fits_lanes());
        Tables {
            cpu,
            marginal: Shared::new(&d.marginal),
            conditional: Shared::new(&d.conditional),
            nx: d.nx,
            ny: d.ny,
            shared: Some(&d.marginal),
        }
    }
}

impl<'a> Tables<'a, PerLane<'a>> {
    /// Lane l reads `stage[l]`.
    ///
    /// # Safety
    /// Each distribution fits the lanes and has the shape of the first
    /// (as [`same_shape_stage`] finds them).
    #[inline(always)]
    unsafe fn each(cpu: Avx2, stage: &[&'a PiecewiseConstant2D; STAGE]) -> Self {
        let (nx, ny) = (stage[0].nx, stage[0].ny);
        debug_assert!(stage
            .iter()
            .all(|d| d.fits_lanes() && d.nx == nx && d.ny == ny));
        let (marginal, conditional) = per_lane_tables(cpu, stage);
        Tables {
            cpu,
            marginal,
            conditional,
            nx,
            ny,
            shared: None,
        }
    }
}

/// A stage's draws: positions, densities, cells, and the lanes (bits of
/// each group) whose position rounded out of its cell.
struct Drawn {
    x: [__m256; GROUPS],
    y: [__m256; GROUPS],
    pdf: [__m256; GROUPS],
    row: [__m256i; GROUPS],
    column: [__m256i; GROUPS],
    on_edge: [i32; GROUPS],
}

impl<S: Source> Tables<'_, S> {
    /// The draws for clamped `ux`, `uy`.
    #[inline(always)]
    fn draw(&self, ux: &[__m256; GROUPS], uy: &[__m256; GROUPS]) -> Drawn {
        let cpu = self.cpu;
        let (nx, ny) = (self.nx, self.ny);
        // SAFETY: the token proves the CPU has AVX2 (for every intrinsic
        // here). The two searches read inside the tables (the invariant of
        // `Tables`): the marginal's lanes search its `ny` entries from 0 to
        // `ny - 1` (a fresh bracket, or `shared_top` over that same list);
        // the conditional's lanes search row j = the marginal count, which
        // is at most `ny - 1` because the marginal's last entry, 1, is above
        // every clamped u: entries `j nx` to `j nx + nx - 1` of the
        // conditional's `nx ny`.
        unsafe {
            let (nxf, nyf) = (_mm256_set1_ps(nx as f32), _mm256_set1_ps(ny as f32));
            let zero = [_mm256_setzero_si256(); GROUPS];
            let last_row = [_mm256_set1_epi32(ny as i32 - 1); GROUPS];
            let last_column = [_mm256_set1_epi32(nx as i32 - 1); GROUPS];
            let mut rows = Bracket::start(cpu);
            let step = match self.shared {
                Some(marginal) => rows.shared_top(cpu, marginal, uy),
                None => ny.next_power_of_two() / 2,
            };
            rows.lift(cpu, &self.marginal, &zero, &last_row, uy, step);
            let mut row_start = zero;
            for g in 0..GROUPS {
                row_start[g] = _mm256_mullo_epi32(rows.count[g], _mm256_set1_epi32(nx as i32));
            }
            let mut columns = Bracket::start(cpu);
            let step = nx.next_power_of_two() / 2;
            columns.lift(cpu, &self.conditional, &row_start, &last_column, ux, step);
            let mut drawn = Drawn {
                x: [_mm256_setzero_ps(); GROUPS],
                y: [_mm256_setzero_ps(); GROUPS],
                pdf: [_mm256_setzero_ps(); GROUPS],
                row: rows.count,
                column: columns.count,
                on_edge: [0; GROUPS],
            };
            for g in 0..GROUPS {
                let (j, k) = (rows.count[g], columns.count[g]);
                let row_mass = _mm256_sub_ps(rows.upper[g], rows.lower[g]);
                let col_mass = _mm256_sub_ps(columns.upper[g], columns.lower[g]);
                let dv = _mm256_div_ps(_mm256_sub_ps(uy[g], rows.lower[g]), row_mass);
                let du = _mm256_div_ps(_mm256_sub_ps(ux[g], columns.lower[g]), col_mass);
                let (x, x_off) = position(cpu, k, clamp_fraction(cpu, du), nx);
                let (y, y_off) = position(cpu, j, clamp_fraction(cpu, dv), ny);
                drawn.x[g] = x;
                drawn.y[g] = y;
                drawn.pdf[g] = joint_pdf_lanes(
                    cpu,
                    _mm256_mul_ps(row_mass, nyf),
                    _mm256_mul_ps(col_mass, nxf),
                );
                drawn.on_edge[g] =
                    _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_or_si256(x_off, y_off)));
            }
            drawn
        }
    }
}

/// Store a stage's draws into `out`; a lane whose position rounded onto a
/// cell edge is finished by the scalar code of its distribution.
#[inline(always)]
fn store_stage<'a>(
    cpu: Avx2,
    drawn: &Drawn,
    ux: &[__m256; GROUPS],
    uy: &[__m256; GROUPS],
    dist_of: impl Fn(usize) -> &'a PiecewiseConstant2D,
    out: &mut [Sample2D],
) {
    for g in 0..GROUPS {
        let o = &mut out[8 * g..8 * g + 8];
        store_samples(cpu, drawn.x[g], drawn.y[g], drawn.pdf[g], o);
        let on_edge = drawn.on_edge[g];
        if on_edge != 0 {
            let (jl, kl) = (
                lanes_i32(cpu, drawn.row[g]),
                lanes_i32(cpu, drawn.column[g]),
            );
            let (uxl, uyl) = (lanes_f32(cpu, ux[g]), lanes_f32(cpu, uy[g]));
            for l in (0..8).filter(|l| on_edge & (1 << l) != 0) {
                let u = Vec2::new(uxl[l], uyl[l]);
                o[l] = dist_of(8 * g + l).finish(jl[l] as usize, kl[l] as usize, u);
            }
        }
    }
}

impl PiecewiseConstant2D {
    /// Whether the lanes can index this table: at most
    /// [`MAX_ENTRIES`] entries.
    pub(super) fn fits_lanes(&self) -> bool {
        self.conditional.len() <= MAX_ENTRIES
    }

    /// The same samples as `sample`, [`STAGE`] at a time in AVX2 lanes
    /// (see the module documentation); the tail is drawn one by one.
    ///
    /// # Safety
    /// [`fits_lanes`](Self::fits_lanes) must hold (the token proves AVX2).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_batch_gather(&self, cpu: Avx2, u: &[Vec2], out: &mut [Sample2D]) {
        let len = u.len().min(out.len());
        // SAFETY: this distribution fits the lanes (the caller's contract).
        let tables = unsafe { Tables::one(cpu, self) };
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (ux, uy) = load_stage(cpu, &u[range.clone()], true);
            let drawn = tables.draw(&ux, &uy);
            store_stage(cpu, &drawn, &ux, &uy, |_| self, &mut out[range]);
        }
        for k in stages * STAGE..len {
            out[k] = acdf_core::Distribution2D::sample(self, u[k]);
        }
    }

    /// [`sample_each`](Self::sample_each) in AVX2 lanes, for slices of
    /// equal length: a stage whose distributions all fit the lanes and
    /// share one shape is drawn as in
    /// [`sample_batch_gather`](Self::sample_batch_gather), each lane reading
    /// its own distribution; other stages and the tail go through the
    /// scalar stages. With `SAME`, also the box test of every draw into
    /// `same` (as long as `out`), in the same lanes.
    #[target_feature(enable = "avx2")]
    pub(super) fn sample_each_gather<const SAME: bool>(
        cpu: Avx2,
        dists: &[&PiecewiseConstant2D],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        for (k, stage) in dists.chunks(STAGE).enumerate() {
            let range = k * STAGE..k * STAGE + stage.len();
            let (u, out) = (&u[range.clone()], &mut out[range.clone()]);
            let same = if SAME { &mut same[range] } else { &mut [][..] };
            let Some(full) = same_shape_stage(stage, PiecewiseConstant2D::fits_lanes) else {
                Self::sample_each_lanes(stage, u, out);
                if SAME {
                    Self::same_cells(stage, margin, out, same);
                }
                continue;
            };
            // SAFETY: `same_shape_stage` found every distribution fitting
            // the lanes and of one shape.
            let tables = unsafe { Tables::each(cpu, full) };
            let (nx, ny) = (tables.nx, tables.ny);
            let (ux, uy) = load_stage(cpu, u, true);
            let drawn = tables.draw(&ux, &uy);
            store_stage(cpu, &drawn, &ux, &uy, |l| stage[l], out);
            if SAME {
                for g in 0..GROUPS {
                    let inside = _mm256_and_ps(
                        inside_cell_lanes(cpu, drawn.x[g], nx, margin.x),
                        inside_cell_lanes(cpu, drawn.y[g], ny, margin.y),
                    );
                    let bits = _mm256_movemask_ps(inside);
                    for l in 0..8 {
                        let i = 8 * g + l;
                        // A draw finished by the scalar code is tested as stored.
                        same[i] = if drawn.on_edge[g] & (1 << l) != 0 {
                            stage[i].same_cell_around(out[i].p, margin)
                        } else {
                            bits & (1 << l) != 0
                        };
                    }
                }
            }
        }
    }
}

/// The stage as [`STAGE`] distributions, if it holds that many, all of
/// them `fit`, and all share the shape of the first; `None` otherwise.
#[inline(always)]
fn same_shape_stage<'s, 'a>(
    stage: &'s [&'a PiecewiseConstant2D],
    fit: impl Fn(&PiecewiseConstant2D) -> bool,
) -> Option<&'s [&'a PiecewiseConstant2D; STAGE]> {
    let full: &[&PiecewiseConstant2D; STAGE] = stage.try_into().ok()?;
    let (nx, ny) = (full[0].nx, full[0].ny);
    full.iter()
        .all(|d| fit(d) && d.nx == nx && d.ny == ny)
        .then_some(full)
}

/// The marginal and conditional CDFs of a stage's [`STAGE`] distributions,
/// lane l reading `stage[l]`'s.
#[inline(always)]
fn per_lane_tables<'a>(
    cpu: Avx2,
    stage: &[&'a PiecewiseConstant2D; STAGE],
) -> (PerLane<'a>, PerLane<'a>) {
    (
        PerLane::new(cpu, |l| &stage[l].marginal[..]),
        PerLane::new(cpu, |l| &stage[l].conditional[..]),
    )
}

/// `inside_cell` in lanes: the same operations (the truncation of x n,
/// in [0, n), by one conversion), all ones where the lane is inside.
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

/// The cell of each lane's coordinate v in [0, 1) on a grid of n cells,
/// as `cell_of` computes it: in [0, n - 1] for every v in [0, 1).
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
/// beginning at `start` (in group g of `cdf`), as `cell_mass` computes it:
/// P_k - P_{k-1}, with P_{-1} = 0.
///
/// # Safety
/// In every lane, `start >= 0`, `k >= 0`, and entries `start + max(k - 1,
/// 0)` and the one after it lie inside the lane's array (a run of at least
/// two entries holding cell k).
#[inline(always)]
unsafe fn cell_mass_lanes<S: Source>(
    cpu: Avx2,
    cdf: &S,
    g: usize,
    start: __m256i,
    k: __m256i,
) -> __m256 {
    // SAFETY: the token proves the CPU has AVX2; the pair read is inside
    // the array by the caller's contract.
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

impl PiecewiseConstant2D {
    /// Whether [`pdf_batch_gather`](Self::pdf_batch_gather) applies: at
    /// least two cells along each axis (its pair loads read two entries).
    pub(super) fn fits_pdf_lanes(&self) -> bool {
        self.fits_lanes() && self.nx >= 2 && self.ny >= 2
    }

    /// The same densities as `pdf`, [`STAGE`] points at a time in AVX2
    /// lanes: the cells from the coordinates, each cell's two CDF entries
    /// in one paired load, `joint_pdf` of the masses; 0 outside [0, 1)^2.
    ///
    /// # Safety
    /// [`fits_pdf_lanes`](Self::fits_pdf_lanes) must hold (the token proves
    /// AVX2).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pdf_batch_gather(&self, cpu: Avx2, p: &[Vec2], out: &mut [f32]) {
        let len = p.len().min(out.len());
        let (p, out) = (&p[..len], &mut out[..len]);
        let (nx, ny) = (self.nx, self.ny);
        let (marginal, conditional) = (Shared::new(&self.marginal), Shared::new(&self.conditional));
        let mut p_chunks = p.chunks_exact(8);
        let mut out_chunks = out.chunks_exact_mut(8);
        for (pc, oc) in (&mut p_chunks).zip(&mut out_chunks) {
            let (x, y) = load_pairs(cpu, pc);
            // SAFETY: the tables are of shape (nx, ny), both at least 2
            // (the caller's contract).
            let pdf = unsafe { densities_lanes(cpu, &marginal, &conditional, 0, (nx, ny), x, y) };
            store_lanes(cpu, pdf, oc);
        }
        for (o, &p) in out_chunks
            .into_remainder()
            .iter_mut()
            .zip(p_chunks.remainder())
        {
            *o = acdf_core::Distribution2D::pdf(self, p);
        }
    }

    /// [`pdf_each`](Self::pdf_each) in AVX2 lanes: a stage of [`STAGE`]
    /// points whose distributions all fit the lanes and share one shape is
    /// looked up as in [`pdf_batch_gather`](Self::pdf_batch_gather), each
    /// lane reading its own distribution; other stages and the tail go one
    /// by one.
    #[target_feature(enable = "avx2")]
    pub(super) fn pdf_each_gather(
        cpu: Avx2,
        dists: &[&PiecewiseConstant2D],
        p: &[Vec2],
        out: &mut [f32],
    ) {
        for (k, stage) in dists.chunks(STAGE).enumerate() {
            let range = k * STAGE..k * STAGE + stage.len();
            let (p, out) = (&p[range.clone()], &mut out[range]);
            let Some(full) = same_shape_stage(stage, PiecewiseConstant2D::fits_pdf_lanes) else {
                for ((o, d), &p) in out.iter_mut().zip(stage).zip(p) {
                    *o = acdf_core::Distribution2D::pdf(*d, p);
                }
                continue;
            };
            let (nx, ny) = (full[0].nx, full[0].ny);
            let (marginal, conditional) = per_lane_tables(cpu, full);
            for g in 0..GROUPS {
                let (x, y) = load_pairs(cpu, &p[8 * g..]);
                // SAFETY: every lane's tables are of shape (nx, ny), both at
                // least 2 (`fits_pdf_lanes`, checked for the whole stage).
                let pdf =
                    unsafe { densities_lanes(cpu, &marginal, &conditional, g, (nx, ny), x, y) };
                store_lanes(cpu, pdf, &mut out[8 * g..]);
            }
        }
    }
}

/// The densities `pdf` gives at eight points (x, y) of tables of shape
/// (nx, ny) (group g of the sources): the cells from the coordinates, each
/// cell's two CDF entries in one paired read, `joint_pdf` of the masses;
/// 0 outside [0, 1)^2 (NaN included).
///
/// # Safety
/// Every lane's marginal holds `ny` entries and its conditional `nx · ny`,
/// with `nx`, `ny` >= 2 and `nx · ny` at most [`MAX_ENTRIES`].
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
    // SAFETY: the token proves the CPU has AVX2. Outside points look up
    // cell (0, 0), inside ones cells (ix, iy) in [0, nx - 1] x [0, ny - 1]
    // (`cell_lanes`): the marginal pair read starts at max(iy - 1, 0) <=
    // ny - 2, the conditional's at iy nx + max(ix - 1, 0) <= nx ny - 2,
    // inside the tables by the caller's contract.
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

impl PiecewiseConstant1D {
    /// The CDF as a list the lanes can search: at most [`MAX_ENTRIES`]
    /// entries (it is never empty).
    pub(super) fn lane_list(&self) -> Option<SharedList<'_>> {
        SharedList::new(&self.cdf)
    }

    /// The same samples as `sample`, [`STAGE`] at a time in AVX2 lanes:
    /// the search as the 2D marginal's (first four steps from registers,
    /// the rest gathers, the cell's edges with the count), then the
    /// arithmetic of `finish` in the same lanes; a draw that rounds onto a
    /// cell edge is finished by the scalar code, and the tail drawn one by
    /// one. `cdf` is this distribution's [`lane_list`](Self::lane_list).
    #[target_feature(enable = "avx2")]
    pub(super) fn sample_batch_gather(
        &self,
        cpu: Avx2,
        cdf: SharedList<'_>,
        u: &[f32],
        out: &mut [Sample1D],
    ) {
        let len = u.len().min(out.len());
        let n = self.cdf.len();
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (u, out) = (&u[range.clone()], &mut out[range]);
            let v = load_stage_1d(cpu, u);
            let cells = Bracket::search_shared(cpu, cdf, &v);
            for g in 0..GROUPS {
                let mass = _mm256_sub_ps(cells.upper[g], cells.lower[g]);
                let du = _mm256_div_ps(_mm256_sub_ps(v[g], cells.lower[g]), mass);
                let (x, off) = position(cpu, cells.count[g], clamp_fraction(cpu, du), n);
                let pdf = _mm256_mul_ps(mass, _mm256_set1_ps(n as f32));
                let o = &mut out[8 * g..8 * g + 8];
                store_samples_1d(cpu, x, pdf, o);
                let on_edge = _mm256_movemask_ps(_mm256_castsi256_ps(off));
                if on_edge != 0 {
                    let (kl, vl) = (lanes_i32(cpu, cells.count[g]), lanes_f32(cpu, v[g]));
                    for l in (0..8).filter(|l| on_edge & (1 << l) != 0) {
                        o[l] = self.finish(kl[l] as usize, vl[l]);
                    }
                }
            }
        }
        for k in stages * STAGE..len {
            out[k] = acdf_core::Distribution1D::sample(self, u[k]);
        }
    }
}
