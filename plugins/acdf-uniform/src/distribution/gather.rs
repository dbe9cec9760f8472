//! `PiecewiseConstant2D::sample_batch` in AVX2 lanes: both searches by
//! [`acdf_core::search::lanes`], the final arithmetic in the same lanes.
//!
//! The marginal is one list shared by every draw, so its first four search
//! steps come from registers; each draw's conditional is its own list,
//! searched with gathers. log2(ny) - 4 + log2(nx) gathers find both cells
//! and their edges (four and five at 256x32).
//!
//! The arithmetic is the same IEEE operations in the same order as
//! `PiecewiseConstant2D::finish`, so the samples are bit-identical to
//! `sample`; a draw whose position rounds onto a cell edge is finished by
//! the scalar code, as everywhere else.

// The loops over groups index several parallel arrays of registers by the
// group number; iterator chains over three or four arrays would hide that.
#![allow(clippy::needless_range_loop)]

use super::PiecewiseConstant2D;
use acdf_core::search::lanes::{
    gather_pairs, in_unit, lanes_f32, lanes_i32, load_pairs, load_unit_pairs, store_samples,
    Bracket, GROUPS, STAGE,
};
use acdf_core::{Sample2D, Vec2, ONE_MINUS_EPSILON};
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
        let (u, out) = (&u[..len], &mut out[..len]);
        let (nx, ny) = (self.nx, self.ny);
        let (nxf, nyf) = (_mm256_set1_ps(nx as f32), _mm256_set1_ps(ny as f32));
        let zero = [_mm256_setzero_si256(); GROUPS];
        let last_row = [_mm256_set1_epi32(ny as i32 - 1); GROUPS];
        let last_column = [_mm256_set1_epi32(nx as i32 - 1); GROUPS];
        let mut u_chunks = u.chunks_exact(STAGE);
        let mut out_chunks = out.chunks_exact_mut(STAGE);
        for (uc, oc) in (&mut u_chunks).zip(&mut out_chunks) {
            let (mut ux, mut uy) = ([_mm256_setzero_ps(); GROUPS], [_mm256_setzero_ps(); GROUPS]);
            for g in 0..GROUPS {
                (ux[g], uy[g]) = load_unit_pairs(&uc[8 * g..]);
            }
            let mut rows = Bracket::start();
            let step = rows.shared_top(&self.marginal, &uy);
            rows.lift(self.marginal.as_ptr(), &zero, &last_row, &uy, step);
            let mut row_start = zero;
            for g in 0..GROUPS {
                row_start[g] = _mm256_mullo_epi32(rows.count[g], _mm256_set1_epi32(nx as i32));
            }
            let mut columns = Bracket::start();
            let step = nx.next_power_of_two() / 2;
            columns.lift(
                self.conditional.as_ptr(),
                &row_start,
                &last_column,
                &ux,
                step,
            );
            for g in 0..GROUPS {
                let (j, k) = (rows.count[g], columns.count[g]);
                let row_mass = _mm256_sub_ps(rows.upper[g], rows.lower[g]);
                let col_mass = _mm256_sub_ps(columns.upper[g], columns.lower[g]);
                let dv = _mm256_div_ps(_mm256_sub_ps(uy[g], rows.lower[g]), row_mass);
                let du = _mm256_div_ps(_mm256_sub_ps(ux[g], columns.lower[g]), col_mass);
                let (x, x_off) = position(k, clamp_fraction(du), nx);
                let (y, y_off) = position(j, clamp_fraction(dv), ny);
                let pdf =
                    joint_pdf_lanes(_mm256_mul_ps(row_mass, nyf), _mm256_mul_ps(col_mass, nxf));
                let o = &mut oc[8 * g..8 * g + 8];
                store_samples(x, y, pdf, o);
                let on_edge =
                    _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_or_si256(x_off, y_off)));
                if on_edge != 0 {
                    let (jl, kl) = (lanes_i32(j), lanes_i32(k));
                    let (uxl, uyl) = (lanes_f32(ux[g]), lanes_f32(uy[g]));
                    for l in (0..8).filter(|l| on_edge & (1 << l) != 0) {
                        let u = Vec2::new(uxl[l], uyl[l]);
                        o[l] = self.finish(jl[l] as usize, kl[l] as usize, u);
                    }
                }
            }
        }
        for (o, &u) in out_chunks
            .into_remainder()
            .iter_mut()
            .zip(u_chunks.remainder())
        {
            *o = acdf_core::Distribution2D::sample(self, u);
        }
    }
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
/// beginning at `start`, as `cell_mass` computes it: P_k - P_{k-1}, with
/// P_{-1} = 0. The run must hold at least two entries.
#[inline(always)]
unsafe fn cell_mass_lanes(cdf: *const f32, start: __m256i, k: __m256i) -> __m256 {
    let zero = _mm256_setzero_si256();
    let first = _mm256_cmpeq_epi32(k, zero);
    // Entries k - 1 and k, or 0 and 1 for k = 0.
    let from = _mm256_add_epi32(
        start,
        _mm256_max_epi32(_mm256_sub_epi32(k, _mm256_set1_epi32(1)), zero),
    );
    let (a, b) = gather_pairs(cdf, from);
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
        let (nxf, nyf) = (_mm256_set1_ps(nx as f32), _mm256_set1_ps(ny as f32));
        let mut p_chunks = p.chunks_exact(8);
        let mut out_chunks = out.chunks_exact_mut(8);
        for (pc, oc) in (&mut p_chunks).zip(&mut out_chunks) {
            let (x, y) = load_pairs(pc);
            let inside = _mm256_and_ps(in_unit(x), in_unit(y));
            // Outside points look up cell (0, 0) and are zeroed at the end.
            let (x, y) = (_mm256_and_ps(x, inside), _mm256_and_ps(y, inside));
            let (ix, iy) = (cell_lanes(x, nx), cell_lanes(y, ny));
            let zero = _mm256_setzero_si256();
            let row_mass = cell_mass_lanes(self.marginal.as_ptr(), zero, iy);
            let row = _mm256_mullo_epi32(iy, _mm256_set1_epi32(nx as i32));
            let col_mass = cell_mass_lanes(self.conditional.as_ptr(), row, ix);
            let pdf = joint_pdf_lanes(_mm256_mul_ps(row_mass, nyf), _mm256_mul_ps(col_mass, nxf));
            _mm256_storeu_ps(oc.as_mut_ptr(), _mm256_and_ps(pdf, inside));
        }
        for (o, &p) in out_chunks
            .into_remainder()
            .iter_mut()
            .zip(p_chunks.remainder())
        {
            *o = acdf_core::Distribution2D::pdf(self, p);
        }
    }
}
