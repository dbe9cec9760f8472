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

// The loops over groups index several parallel arrays of registers by the
// group number; iterator chains over three or four arrays would hide that.
#![allow(clippy::needless_range_loop)]

use super::{PiecewiseConstant1D, PiecewiseConstant2D};
use acdf_core::search::lanes::{
    in_unit, lanes_f32, lanes_i32, load_pairs, load_stage, load_stage_1d, store_samples,
    store_samples_1d, Bracket, PerLane, Shared, Source, GROUPS, STAGE,
};
use acdf_core::{Sample1D, Sample2D, Vec2, ONE_MINUS_EPSILON};
use acdf_tabulated::SliceDistribution;
use std::arch::x86_64::*;

/// `f32::clamp(d, 0, 1 - ε/2)` in lanes, for d not NaN.
#[inline(always)]
unsafe fn clamp_fraction(d: __m256) -> __m256 {
    _mm256_min_ps(
        _mm256_max_ps(d, _mm256_setzero_ps()),
        _mm256_set1_ps(ONE_MINUS_EPSILON),
    )
}

/// One coordinate of the draw: the position (cell + fraction) / n, capped
/// below 1, and whether it rounded out of its cell (all ones where it did).
#[inline(always)]
unsafe fn position(cell: __m256i, fraction: __m256, n: usize) -> (__m256, __m256i) {
    let nf = n as f32;
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

/// `joint_pdf` in lanes: the product, raised to the smallest positive
/// `f32` where both factors are positive.
#[inline(always)]
unsafe fn joint_pdf_lanes(marginal: __m256, conditional: __m256) -> __m256 {
    let zero = _mm256_setzero_ps();
    let p = _mm256_mul_ps(marginal, conditional);
    let both = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GT_OQ>(marginal, zero),
        _mm256_cmp_ps::<_CMP_GT_OQ>(conditional, zero),
    );
    _mm256_blendv_ps(p, _mm256_max_ps(p, _mm256_set1_ps(f32::from_bits(1))), both)
}

/// The tables a stage's lanes draw from: all of one shape (nx, ny), read
/// from one distribution or one per lane.
struct Tables<'a, S> {
    marginal: S,
    conditional: S,
    nx: usize,
    ny: usize,
    /// The marginal every lane shares (a batch), whose first search steps
    /// can then come from registers.
    shared: Option<&'a [f32]>,
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
    unsafe fn draw(&self, ux: &[__m256; GROUPS], uy: &[__m256; GROUPS]) -> Drawn {
        let (nx, ny) = (self.nx, self.ny);
        let (nxf, nyf) = (_mm256_set1_ps(nx as f32), _mm256_set1_ps(ny as f32));
        let zero = [_mm256_setzero_si256(); GROUPS];
        let last_row = [_mm256_set1_epi32(ny as i32 - 1); GROUPS];
        let last_column = [_mm256_set1_epi32(nx as i32 - 1); GROUPS];
        let mut rows = Bracket::start();
        let step = match self.shared {
            Some(marginal) => rows.shared_top(marginal, uy),
            None => ny.next_power_of_two() / 2,
        };
        rows.lift(&self.marginal, &zero, &last_row, uy, step);
        let mut row_start = zero;
        for g in 0..GROUPS {
            row_start[g] = _mm256_mullo_epi32(rows.count[g], _mm256_set1_epi32(nx as i32));
        }
        let mut columns = Bracket::start();
        let step = nx.next_power_of_two() / 2;
        columns.lift(&self.conditional, &row_start, &last_column, ux, step);
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
            let (x, x_off) = position(k, clamp_fraction(du), nx);
            let (y, y_off) = position(j, clamp_fraction(dv), ny);
            drawn.x[g] = x;
            drawn.y[g] = y;
            drawn.pdf[g] =
                joint_pdf_lanes(_mm256_mul_ps(row_mass, nyf), _mm256_mul_ps(col_mass, nxf));
            drawn.on_edge[g] =
                _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_or_si256(x_off, y_off)));
        }
        drawn
    }
}

/// Store a stage's draws into `out`; a lane whose position rounded onto a
/// cell edge is finished by the scalar code of its distribution.
#[inline(always)]
unsafe fn store_stage<'a>(
    drawn: &Drawn,
    ux: &[__m256; GROUPS],
    uy: &[__m256; GROUPS],
    dist_of: impl Fn(usize) -> &'a PiecewiseConstant2D,
    out: &mut [Sample2D],
) {
    for g in 0..GROUPS {
        let o = &mut out[8 * g..8 * g + 8];
        store_samples(drawn.x[g], drawn.y[g], drawn.pdf[g], o);
        let on_edge = drawn.on_edge[g];
        if on_edge != 0 {
            let (jl, kl) = (lanes_i32(drawn.row[g]), lanes_i32(drawn.column[g]));
            let (uxl, uyl) = (lanes_f32(ux[g]), lanes_f32(uy[g]));
            for l in (0..8).filter(|l| on_edge & (1 << l) != 0) {
                let u = Vec2::new(uxl[l], uyl[l]);
                o[l] = dist_of(8 * g + l).finish(jl[l] as usize, kl[l] as usize, u);
            }
        }
    }
}

impl PiecewiseConstant2D {
    /// Whether the lanes can index this table with `i32`.
    pub(super) fn fits_lanes(&self) -> bool {
        self.conditional.len() <= i32::MAX as usize
    }

    /// The same samples as `sample`, [`STAGE`] at a time in AVX2 lanes
    /// (see the module documentation); the tail is drawn one by one.
    ///
    /// # Safety
    /// The CPU must support AVX2, and [`fits_lanes`](Self::fits_lanes)
    /// must hold.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_batch_gather(&self, u: &[Vec2], out: &mut [Sample2D]) {
        let len = u.len().min(out.len());
        let tables = Tables {
            marginal: Shared(self.marginal.as_ptr()),
            conditional: Shared(self.conditional.as_ptr()),
            nx: self.nx,
            ny: self.ny,
            shared: Some(&self.marginal),
        };
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (ux, uy) = load_stage(&u[range.clone()], true);
            let drawn = tables.draw(&ux, &uy);
            store_stage(&drawn, &ux, &uy, |_| self, &mut out[range]);
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
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_each_gather<const SAME: bool>(
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
            let (nx, ny) = (stage[0].nx, stage[0].ny);
            let fits = |d: &&PiecewiseConstant2D| d.fits_lanes() && d.nx == nx && d.ny == ny;
            if stage.len() < STAGE || !stage.iter().all(fits) {
                Self::sample_each_lanes(stage, u, out);
                if SAME {
                    Self::same_cells(stage, margin, out, same);
                }
                continue;
            }
            let (marginal, conditional) = per_lane_tables(stage);
            let tables = Tables {
                marginal,
                conditional,
                nx,
                ny,
                shared: None,
            };
            let (ux, uy) = load_stage(u, true);
            let drawn = tables.draw(&ux, &uy);
            store_stage(&drawn, &ux, &uy, |l| stage[l], out);
            if SAME {
                for g in 0..GROUPS {
                    let inside = _mm256_and_ps(
                        inside_cell_lanes(drawn.x[g], nx, margin.x),
                        inside_cell_lanes(drawn.y[g], ny, margin.y),
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

/// The marginal and conditional CDFs of a stage's [`STAGE`] distributions,
/// lane l reading `stage[l]`'s.
///
/// # Safety
/// AVX2; `stage` holds [`STAGE`] distributions.
#[inline(always)]
unsafe fn per_lane_tables(stage: &[&PiecewiseConstant2D]) -> (PerLane, PerLane) {
    let mut marginal = [std::ptr::null::<f32>(); STAGE];
    let mut conditional = [std::ptr::null::<f32>(); STAGE];
    for (l, d) in stage.iter().take(STAGE).enumerate() {
        marginal[l] = d.marginal.as_ptr();
        conditional[l] = d.conditional.as_ptr();
    }
    (PerLane::new(&marginal), PerLane::new(&conditional))
}

/// `inside_cell` in lanes: the same operations (the truncation of x n,
/// in [0, n), by one conversion), all ones where the lane is inside.
#[inline(always)]
unsafe fn inside_cell_lanes(x: __m256, n: usize, m: f32) -> __m256 {
    let nf = n as f32;
    let t = _mm256_mul_ps(x, _mm256_set1_ps(nf));
    let f = _mm256_sub_ps(t, _mm256_cvtepi32_ps(_mm256_cvttps_epi32(t)));
    let m = m * nf;
    _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GE_OQ>(f, _mm256_set1_ps(m)),
        _mm256_cmp_ps::<_CMP_LE_OQ>(f, _mm256_set1_ps(1.0 - m)),
    )
}

/// The cell of each lane's coordinate v in [0, 1) on a grid of n cells,
/// as `cell_of` computes it.
#[inline(always)]
unsafe fn cell_lanes(v: __m256, n: usize) -> __m256i {
    _mm256_min_epi32(
        _mm256_cvttps_epi32(_mm256_mul_ps(v, _mm256_set1_ps(n as f32))),
        _mm256_set1_epi32(n as i32 - 1),
    )
}

/// The probability of each lane's cell `start + k` of a stored CDF
/// beginning at `start` (in group g of `cdf`), as `cell_mass` computes it:
/// P_k - P_{k-1}, with P_{-1} = 0. The run must hold at least two entries.
#[inline(always)]
unsafe fn cell_mass_lanes<S: Source>(cdf: &S, g: usize, start: __m256i, k: __m256i) -> __m256 {
    let zero = _mm256_setzero_si256();
    let first = _mm256_cmpeq_epi32(k, zero);
    // Entries k - 1 and k, or 0 and 1 for k = 0.
    let from = _mm256_add_epi32(
        start,
        _mm256_max_epi32(_mm256_sub_epi32(k, _mm256_set1_epi32(1)), zero),
    );
    let (a, b) = cdf.gather_pairs(g, from);
    let first = _mm256_castsi256_ps(first);
    let upper = _mm256_blendv_ps(b, a, first);
    let lower = _mm256_andnot_ps(first, a);
    _mm256_sub_ps(upper, lower)
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
    /// The CPU must support AVX2, and
    /// [`fits_pdf_lanes`](Self::fits_pdf_lanes) must hold.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pdf_batch_gather(&self, p: &[Vec2], out: &mut [f32]) {
        let len = p.len().min(out.len());
        let (p, out) = (&p[..len], &mut out[..len]);
        let (nx, ny) = (self.nx, self.ny);
        let (marginal, conditional) = (
            Shared(self.marginal.as_ptr()),
            Shared(self.conditional.as_ptr()),
        );
        let mut p_chunks = p.chunks_exact(8);
        let mut out_chunks = out.chunks_exact_mut(8);
        for (pc, oc) in (&mut p_chunks).zip(&mut out_chunks) {
            let (x, y) = load_pairs(pc);
            let pdf = densities_lanes(&marginal, &conditional, 0, (nx, ny), x, y);
            _mm256_storeu_ps(oc.as_mut_ptr(), pdf);
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
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pdf_each_gather(
        dists: &[&PiecewiseConstant2D],
        p: &[Vec2],
        out: &mut [f32],
    ) {
        for (k, stage) in dists.chunks(STAGE).enumerate() {
            let range = k * STAGE..k * STAGE + stage.len();
            let (p, out) = (&p[range.clone()], &mut out[range]);
            let (nx, ny) = (stage[0].nx, stage[0].ny);
            let fits = |d: &&PiecewiseConstant2D| d.fits_pdf_lanes() && d.nx == nx && d.ny == ny;
            if stage.len() < STAGE || !stage.iter().all(fits) {
                for ((o, d), &p) in out.iter_mut().zip(stage).zip(p) {
                    *o = acdf_core::Distribution2D::pdf(*d, p);
                }
                continue;
            }
            let (marginal, conditional) = per_lane_tables(stage);
            for g in 0..GROUPS {
                let (x, y) = load_pairs(&p[8 * g..]);
                let pdf = densities_lanes(&marginal, &conditional, g, (nx, ny), x, y);
                _mm256_storeu_ps(out[8 * g..].as_mut_ptr(), pdf);
            }
        }
    }
}

/// The densities `pdf` gives at eight points (x, y) of tables of shape
/// (nx, ny) (group g of the sources): the cells from the coordinates, each
/// cell's two CDF entries in one paired read, `joint_pdf` of the masses;
/// 0 outside [0, 1)^2 (NaN included).
#[inline(always)]
unsafe fn densities_lanes<S: Source>(
    marginal: &S,
    conditional: &S,
    g: usize,
    (nx, ny): (usize, usize),
    x: __m256,
    y: __m256,
) -> __m256 {
    let inside = _mm256_and_ps(in_unit(x), in_unit(y));
    // Outside points look up cell (0, 0) and are zeroed at the end.
    let (x, y) = (_mm256_and_ps(x, inside), _mm256_and_ps(y, inside));
    let (ix, iy) = (cell_lanes(x, nx), cell_lanes(y, ny));
    let row_mass = cell_mass_lanes(marginal, g, _mm256_setzero_si256(), iy);
    let row = _mm256_mullo_epi32(iy, _mm256_set1_epi32(nx as i32));
    let col_mass = cell_mass_lanes(conditional, g, row, ix);
    let (nxf, nyf) = (_mm256_set1_ps(nx as f32), _mm256_set1_ps(ny as f32));
    let pdf = joint_pdf_lanes(_mm256_mul_ps(row_mass, nyf), _mm256_mul_ps(col_mass, nxf));
    _mm256_and_ps(pdf, inside)
}

impl PiecewiseConstant1D {
    /// Whether the lanes can index this CDF with `i32`.
    pub(super) fn fits_lanes(&self) -> bool {
        self.cdf.len() <= i32::MAX as usize
    }

    /// The same samples as `sample`, [`STAGE`] at a time in AVX2 lanes:
    /// the search as the 2D marginal's (first four steps from registers,
    /// the rest gathers, the cell's edges with the count), then the
    /// arithmetic of `finish` in the same lanes; a draw that rounds onto a
    /// cell edge is finished by the scalar code, and the tail drawn one by
    /// one.
    ///
    /// # Safety
    /// The CPU must support AVX2, and [`fits_lanes`](Self::fits_lanes)
    /// must hold.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_batch_gather(&self, u: &[f32], out: &mut [Sample1D]) {
        let len = u.len().min(out.len());
        let n = self.cdf.len();
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (u, out) = (&u[range.clone()], &mut out[range]);
            let v = load_stage_1d(u);
            let cells = Bracket::search_shared(&self.cdf, &v);
            for g in 0..GROUPS {
                let mass = _mm256_sub_ps(cells.upper[g], cells.lower[g]);
                let du = _mm256_div_ps(_mm256_sub_ps(v[g], cells.lower[g]), mass);
                let (x, off) = position(cells.count[g], clamp_fraction(du), n);
                let pdf = _mm256_mul_ps(mass, _mm256_set1_ps(n as f32));
                let o = &mut out[8 * g..8 * g + 8];
                store_samples_1d(x, pdf, o);
                let on_edge = _mm256_movemask_ps(_mm256_castsi256_ps(off));
                if on_edge != 0 {
                    let (kl, vl) = (lanes_i32(cells.count[g]), lanes_f32(v[g]));
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
