//! `AdaptiveCdf2D::sample_batch`, the batch with the drawn-segment box test,
//! and `pdf_batch`, in AVX2 lanes: both segment searches by
//! [`acdf_core::search::lanes`], the position and density in the same lanes.
//!
//! The marginal curve is shared by every draw, so its first four search
//! steps come from registers. Each draw's conditional is its own short
//! list, searched with gathers for as many steps as the longest conditional
//! in the stage needs. The searches bracket u by the segment's CDF values;
//! two more gathers per curve read its positions.
//!
//! The arithmetic is that of `curve::segment_samples`, operation for
//! operation (the differences and the quotient in f64, the clamps as
//! selects), so the samples are bit-identical to `sample`.

// The loops over groups index several parallel arrays of registers by the
// group number; iterator chains over three or four arrays would hide that.
#![allow(clippy::needless_range_loop)]

use super::AdaptiveCdf2D;
use acdf_core::search::lanes::{
    gather_pairs, in_unit, lanes_i32, load_pairs, load_unit_pairs, store_samples, Bracket, GROUPS,
    STAGE,
};
use acdf_core::{Sample2D, Vec2, ONE_MINUS_EPSILON};
use std::arch::x86_64::*;

/// The ends of the drawn segment of every lane: positions x_i, x_{i+1} and
/// CDF values c_i, c_{i+1}.
#[derive(Clone, Copy)]
struct SegmentLanes {
    x0: __m256,
    x1: __m256,
    c0: __m256,
    c1: __m256,
}

/// The low and high four lanes, widened to f64.
#[inline(always)]
unsafe fn widen(v: __m256) -> (__m256d, __m256d) {
    (
        _mm256_cvtps_pd(_mm256_castps256_ps128(v)),
        _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(v)),
    )
}

/// Two halves of four lanes back in one register.
#[inline(always)]
unsafe fn join(low: __m128, high: __m128) -> __m256 {
    _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(low), high)
}

/// The f64 part of `curve::segment_samples` for four lanes: the position
/// x_i + t (x_{i+1} - x_i) with t = (u - c_i) / (c_{i+1} - c_i) clamped to
/// [0, 1], and the density (c_{i+1} - c_i) / (x_{i+1} - x_i), each rounded
/// once to f32.
#[inline(always)]
unsafe fn segment_half(
    x0: __m256d,
    x1: __m256d,
    c0: __m256d,
    c1: __m256d,
    u: __m256d,
) -> (__m128, __m128) {
    let zero = _mm256_setzero_pd();
    let one = _mm256_set1_pd(1.0);
    let mass = _mm256_sub_pd(c1, c0);
    let width = _mm256_sub_pd(x1, x0);
    let mut t = _mm256_div_pd(_mm256_sub_pd(u, c0), mass);
    t = _mm256_blendv_pd(t, zero, _mm256_cmp_pd::<_CMP_LT_OQ>(t, zero));
    t = _mm256_blendv_pd(t, one, _mm256_cmp_pd::<_CMP_GT_OQ>(t, one));
    let x = _mm256_cvtpd_ps(_mm256_add_pd(x0, _mm256_mul_pd(t, width)));
    (x, _mm256_cvtpd_ps(_mm256_div_pd(mass, width)))
}

/// `curve::segment_samples` for eight lanes, four at a time in f64
/// ([`segment_half`]), then the position clamped into [x_i, x_{i+1}) and
/// below 1 in f32. Returns (positions, densities).
#[inline(always)]
unsafe fn segment_samples_lanes(s: SegmentLanes, u: __m256) -> (__m256, __m256) {
    let (x0, x1, c0, c1, uu) = (widen(s.x0), widen(s.x1), widen(s.c0), widen(s.c1), widen(u));
    let (x_lo, pdf_lo) = segment_half(x0.0, x1.0, c0.0, c1.0, uu.0);
    let (x_hi, pdf_hi) = segment_half(x0.1, x1.1, c0.1, c1.1, uu.1);
    let mut x = join(x_lo, x_hi);
    let below_x1 = _mm256_castsi256_ps(_mm256_sub_epi32(
        _mm256_castps_si256(s.x1),
        _mm256_set1_epi32(1),
    ));
    x = _mm256_blendv_ps(x, s.x0, _mm256_cmp_ps::<_CMP_LT_OQ>(x, s.x0));
    x = _mm256_blendv_ps(x, below_x1, _mm256_cmp_ps::<_CMP_GT_OQ>(x, below_x1));
    let cap = _mm256_set1_ps(ONE_MINUS_EPSILON);
    x = _mm256_blendv_ps(x, cap, _mm256_cmp_ps::<_CMP_GT_OQ>(x, cap));
    (x, join(pdf_lo, pdf_hi))
}

/// `curve::segment_density` for four lanes: (c_{i+1} - c_i) /
/// (x_{i+1} - x_i) in f64, rounded once to f32.
#[inline(always)]
unsafe fn density_half(x0: __m256d, x1: __m256d, c0: __m256d, c1: __m256d) -> __m128 {
    _mm256_cvtpd_ps(_mm256_div_pd(_mm256_sub_pd(c1, c0), _mm256_sub_pd(x1, x0)))
}

/// `curve::segment_density` for eight lanes.
#[inline(always)]
unsafe fn segment_density_lanes(s: SegmentLanes) -> __m256 {
    let (x0, x1, c0, c1) = (widen(s.x0), widen(s.x1), widen(s.c0), widen(s.c1));
    join(
        density_half(x0.0, x1.0, c0.0, c1.0),
        density_half(x0.1, x1.1, c0.1, c1.1),
    )
}

/// Where each lane's conditional (that of marginal segment j) is stored.
#[derive(Clone, Copy)]
struct ConditionalLanes {
    /// The index of its first vertex position, 2 o_j; 0 where uniform.
    xs_start: __m256i,
    /// Its number of vertices, o_{j+1} - o_j.
    count: __m256i,
    /// All ones where it has fewer than two vertices: the uniform stand-in,
    /// whose lanes search entry 0 (any valid index) and are replaced.
    uniform: __m256i,
    /// The index of the last entry of its inner list (x_1.. or c_1..,
    /// m - 1 entries, the last being 1): m - 2; 0 where uniform.
    last: __m256i,
}

impl ConditionalLanes {
    /// A placeholder, overwritten before use.
    #[inline(always)]
    unsafe fn none() -> ConditionalLanes {
        let zero = _mm256_setzero_si256();
        ConditionalLanes {
            xs_start: zero,
            count: zero,
            uniform: zero,
            last: zero,
        }
    }

    /// The conditionals of segments `j`, from the offsets o_j, o_{j+1}.
    #[inline(always)]
    unsafe fn of(offsets: *const u32, j: __m256i) -> ConditionalLanes {
        let (o0, o1) = gather_pairs(offsets, j);
        let (o0, o1) = (_mm256_castps_si256(o0), _mm256_castps_si256(o1));
        let count = _mm256_sub_epi32(o1, o0);
        let uniform = _mm256_cmpgt_epi32(_mm256_set1_epi32(2), count);
        ConditionalLanes {
            xs_start: _mm256_andnot_si256(uniform, _mm256_add_epi32(o0, o0)),
            count,
            uniform,
            last: _mm256_andnot_si256(uniform, _mm256_sub_epi32(count, _mm256_set1_epi32(2))),
        }
    }

    /// The start of its inner CDF values c_1, ... (`inner_cdfs`) or inner
    /// positions x_1, ... (`!inner_cdfs`); 0 where uniform.
    #[inline(always)]
    unsafe fn inner(&self, cdfs: bool) -> __m256i {
        let skip = if cdfs {
            _mm256_add_epi32(self.count, _mm256_set1_epi32(1))
        } else {
            _mm256_set1_epi32(1)
        };
        _mm256_andnot_si256(self.uniform, _mm256_add_epi32(self.xs_start, skip))
    }

    /// The segment ends from a search `found` over its inner list and the
    /// other pair gathered from `paired` (positions after a search of CDF
    /// values, CDF values after a search of positions); the uniform
    /// stand-in's segment (0, 0) to (1, 1) where uniform.
    #[inline(always)]
    unsafe fn segment(
        &self,
        data: *const f32,
        found: (__m256i, __m256, __m256),
        searched_cdfs: bool,
    ) -> SegmentLanes {
        let (k, lower, upper) = found;
        let k = _mm256_andnot_si256(self.uniform, k);
        let mut at = _mm256_add_epi32(self.xs_start, k);
        if !searched_cdfs {
            at = _mm256_andnot_si256(self.uniform, _mm256_add_epi32(at, self.count));
        }
        let (a, b) = gather_pairs(data, at);
        let flat = _mm256_castsi256_ps(self.uniform);
        let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
        let (x0, x1, c0, c1) = if searched_cdfs {
            (a, b, lower, upper)
        } else {
            (lower, upper, a, b)
        };
        SegmentLanes {
            x0: _mm256_blendv_ps(x0, zero, flat),
            x1: _mm256_blendv_ps(x1, one, flat),
            c0: _mm256_blendv_ps(c0, zero, flat),
            c1: _mm256_blendv_ps(c1, one, flat),
        }
    }
}

/// The box test of `sample_and_same_segment` in lanes: x ± m inside
/// [0, 1) and inside the drawn segment [x_i, x_{i+1}); all ones where it is.
#[inline(always)]
unsafe fn inside_lanes(x: __m256, m: f32, s: SegmentLanes) -> __m256 {
    let m = _mm256_set1_ps(m);
    let (low, high) = (_mm256_sub_ps(x, m), _mm256_add_ps(x, m));
    let zero = _mm256_setzero_ps();
    _mm256_and_ps(
        _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GE_OQ>(low, zero),
            _mm256_cmp_ps::<_CMP_LT_OQ>(high, _mm256_set1_ps(1.0)),
        ),
        _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GE_OQ>(low, s.x0),
            _mm256_cmp_ps::<_CMP_LT_OQ>(high, s.x1),
        ),
    )
}

/// The largest lane of the registers (at least 0).
#[inline(always)]
unsafe fn largest(v: &[__m256i; GROUPS]) -> usize {
    let mut m = _mm256_setzero_si256();
    for v in v {
        m = _mm256_max_epi32(m, *v);
    }
    lanes_i32(m).into_iter().max().unwrap_or(0) as usize
}

impl AdaptiveCdf2D {
    /// Whether the lanes paths apply: a marginal of at least two vertices,
    /// at least one stored conditional, and buffers that `i32` lanes index.
    pub(super) fn fits_lanes(&self) -> bool {
        self.marginal.len() >= 4
            && self.conditionals.len() >= 4
            && self.conditionals.len() <= i32::MAX as usize
            && self.marginal.len() <= i32::MAX as usize
    }

    /// The same samples as `sample`, [`STAGE`] at a time in AVX2 lanes (see
    /// the module documentation), and with `SAME` the box test of every
    /// draw into `same` (as long as `out`); the tail goes one by one.
    ///
    /// # Safety
    /// The CPU must support AVX2, and [`fits_lanes`](Self::fits_lanes)
    /// must hold.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_batch_gather<const SAME: bool>(
        &self,
        u: &[Vec2],
        out: &mut [Sample2D],
        margin: Vec2,
        same: &mut [bool],
    ) {
        let len = u.len().min(out.len());
        let (u, out) = (&u[..len], &mut out[..len]);
        let m = self.marginal.len() / 2;
        // The marginal's CDF values c_1, ..., c_{m-1} (the last is 1).
        let marginal_run = &self.marginal[m + 1..];
        let zero = [_mm256_setzero_si256(); GROUPS];
        let last_marginal = [_mm256_set1_epi32(m as i32 - 2); GROUPS];
        let mut u_chunks = u.chunks_exact(STAGE);
        let mut out_chunks = out.chunks_exact_mut(STAGE);
        for (stage, (uc, oc)) in (&mut u_chunks).zip(&mut out_chunks).enumerate() {
            let (mut ux, mut uy) = ([_mm256_setzero_ps(); GROUPS], [_mm256_setzero_ps(); GROUPS]);
            for g in 0..GROUPS {
                (ux[g], uy[g]) = load_unit_pairs(&uc[8 * g..]);
            }
            let mut rows = Bracket::start();
            let step = rows.shared_top(marginal_run, &uy);
            rows.lift(marginal_run.as_ptr(), &zero, &last_marginal, &uy, step);

            let mut conditional = [ConditionalLanes::none(); GROUPS];
            let (mut start, mut last) = (zero, zero);
            for g in 0..GROUPS {
                conditional[g] = ConditionalLanes::of(self.offsets.as_ptr(), rows.count[g]);
                start[g] = conditional[g].inner(true);
                last[g] = conditional[g].last;
            }
            let mut columns = Bracket::start();
            let step = (largest(&last) + 1).next_power_of_two() / 2;
            columns.lift(self.conditionals.as_ptr(), &start, &last, &ux, step);

            for g in 0..GROUPS {
                let (x0, x1) = gather_pairs(self.marginal.as_ptr(), rows.count[g]);
                let row = SegmentLanes {
                    x0,
                    x1,
                    c0: rows.lower[g],
                    c1: rows.upper[g],
                };
                let found = (columns.count[g], columns.lower[g], columns.upper[g]);
                let column = conditional[g].segment(self.conditionals.as_ptr(), found, true);
                let (y, pdf_y) = segment_samples_lanes(row, uy[g]);
                let (x, pdf_x) = segment_samples_lanes(column, ux[g]);
                store_samples(x, y, _mm256_mul_ps(pdf_y, pdf_x), &mut oc[8 * g..]);
                if SAME {
                    let inside = _mm256_and_ps(
                        inside_lanes(y, margin.y, row),
                        inside_lanes(x, margin.x, column),
                    );
                    let bits = _mm256_movemask_ps(inside);
                    let first = stage * STAGE + 8 * g;
                    for (l, s) in same[first..first + 8].iter_mut().enumerate() {
                        *s = bits & (1 << l) != 0;
                    }
                }
            }
        }
        let tail = len / STAGE * STAGE;
        for (k, (o, &u)) in out_chunks
            .into_remainder()
            .iter_mut()
            .zip(u_chunks.remainder())
            .enumerate()
        {
            if SAME {
                let (sample, inside) = self.sample_and_same_segment(u, margin);
                *o = sample;
                same[tail + k] = inside;
            } else {
                *o = self.sample_inline(u);
            }
        }
    }

    /// The same densities as `pdf`, [`STAGE`] points at a time in AVX2
    /// lanes: the segments are found by searching the vertex positions
    /// (the marginal's first four steps from registers), their CDF values
    /// gathered in pairs, and the densities computed as
    /// `curve::segment_density` does. Points outside [0, 1)^2 (NaN
    /// included) get 0, as does a zero-mass marginal segment.
    ///
    /// # Safety
    /// The CPU must support AVX2, and [`fits_lanes`](Self::fits_lanes)
    /// must hold.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pdf_batch_gather(&self, p: &[Vec2], out: &mut [f32]) {
        let len = p.len().min(out.len());
        let (p, out) = (&p[..len], &mut out[..len]);
        let m = self.marginal.len() / 2;
        // The marginal's positions x_1, ..., x_{m-1} (the last is 1).
        let marginal_run = &self.marginal[1..m];
        let zero = [_mm256_setzero_si256(); GROUPS];
        let last_marginal = [_mm256_set1_epi32(m as i32 - 2); GROUPS];
        let mut p_chunks = p.chunks_exact(STAGE);
        let mut out_chunks = out.chunks_exact_mut(STAGE);
        for (pc, oc) in (&mut p_chunks).zip(&mut out_chunks) {
            let (mut x, mut y) = ([_mm256_setzero_ps(); GROUPS], [_mm256_setzero_ps(); GROUPS]);
            let mut inside = [_mm256_setzero_ps(); GROUPS];
            for g in 0..GROUPS {
                let (px, py) = load_pairs(&pc[8 * g..]);
                inside[g] = _mm256_and_ps(in_unit(px), in_unit(py));
                // Outside points search at 0 and are zeroed at the end.
                x[g] = _mm256_and_ps(px, inside[g]);
                y[g] = _mm256_and_ps(py, inside[g]);
            }
            let mut rows = Bracket::start();
            let step = rows.shared_top(marginal_run, &y);
            rows.lift(marginal_run.as_ptr(), &zero, &last_marginal, &y, step);

            let mut conditional = [ConditionalLanes::none(); GROUPS];
            let (mut start, mut last) = (zero, zero);
            for g in 0..GROUPS {
                conditional[g] = ConditionalLanes::of(self.offsets.as_ptr(), rows.count[g]);
                start[g] = conditional[g].inner(false);
                last[g] = conditional[g].last;
            }
            let mut columns = Bracket::start();
            let step = (largest(&last) + 1).next_power_of_two() / 2;
            columns.lift(self.conditionals.as_ptr(), &start, &last, &x, step);

            for g in 0..GROUPS {
                let (c0, c1) = gather_pairs(self.marginal.as_ptr().add(m), rows.count[g]);
                let row = SegmentLanes {
                    x0: rows.lower[g],
                    x1: rows.upper[g],
                    c0,
                    c1,
                };
                let found = (columns.count[g], columns.lower[g], columns.upper[g]);
                let column = conditional[g].segment(self.conditionals.as_ptr(), found, false);
                let py = segment_density_lanes(row);
                let px = segment_density_lanes(column);
                // `pdf` returns 0 for a zero-mass marginal segment before
                // looking at its conditional.
                let zero_row = _mm256_cmp_ps::<_CMP_EQ_OQ>(py, _mm256_setzero_ps());
                let density = _mm256_andnot_ps(zero_row, _mm256_mul_ps(py, px));
                _mm256_storeu_ps(
                    oc[8 * g..8 * g + 8].as_mut_ptr(),
                    _mm256_and_ps(density, inside[g]),
                );
            }
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
