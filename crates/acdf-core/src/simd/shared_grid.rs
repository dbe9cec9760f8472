//! The batch draws and densities of the outgoing sampler's slices on a
//! shared grid (`acdf_adaptive_cdf::quantised::SharedSlices`), a stage of
//! [`STAGE`](super::search::lanes::STAGE) lanes at a time in AVX2: what
//! `SharedSlices::sample` and `SharedSlices::locate` with
//! `SharedSlices::density` compute one at a time.
//!
//! Each lane searches its own slice's CDF values (a draw) or the shared
//! positions (a density) by the binary lifting of
//! [`search::narrow`](super::search::narrow), whose counts are those of a
//! search one draw at a time, and reads the two ends of each segment in
//! one gather. The floating-point operations are those of the scalar path
//! in the same order, without fused multiply-adds, so every result is bit
//! for bit the scalar one (`lane_draws_and_densities_equal_single_ones` in
//! the outgoing plug-in's tests).
//!
//! The slices arrive as a [`SharedGrid`]: plain slices of the stored
//! arrays, whose shape [`SharedGrid::new`] checks, so that every gather's
//! index lies inside its array whatever the stored values are.

#![allow(clippy::needless_range_loop)]

use super::cpu::Avx2;
use super::search::lanes::GROUPS;
use super::search::narrow::{first_step, lift_at_or_below, Pairs};
use crate::ONE_MINUS_EPSILON;
use std::arch::x86_64::*;

/// The stored arrays of the slices on one grid, as the lanes read them.
///
/// - `grid`: the m marginal positions (quantised θ_h), then m offsets:
///   where each marginal segment's conditional starts among the
///   conditional positions (the last offset, where they end);
/// - `positions`: the conditional positions (quantised φ_h) one after
///   another, and 3 entries of padding;
/// - `cdf`: per slice `m + c` quantised CDF values (its marginal's, then
///   its conditionals'), c the number of conditional positions, and 1
///   entry of padding;
/// - `quantum`: the value a CDF ends at, which a u in [0, 1) is scaled to.
#[derive(Clone, Copy)]
pub struct SharedGrid<'a> {
    grid: &'a [u16],
    m: usize,
    positions: &'a [u8],
    cdf: &'a [u16],
    stride: usize,
    count: usize,
    longest_conditional: usize,
    quantum: f32,
}

impl<'a> SharedGrid<'a> {
    /// The arrays of `count` slices, whose longest conditional has
    /// `longest_conditional + 1` vertices, or `None` where their shape
    /// does not allow the lanes to read them: fewer than 2 marginal
    /// positions or 1 slice, an offset past the conditional positions,
    /// lengths that do not match [`SharedGrid`]'s layout, or arrays too long
    /// for 32-bit lanes. Values are not checked, nor is
    /// `longest_conditional`: arrays that do not hold valid slices give
    /// meaningless draws, never a read outside them.
    #[inline(always)]
    pub fn new(
        grid: &'a [u16],
        positions: &'a [u8],
        cdf: &'a [u16],
        count: usize,
        longest_conditional: usize,
        quantum: f32,
    ) -> Option<Self> {
        let m = grid.len() / 2;
        if m < 2 || grid.len() != 2 * m || count == 0 || positions.len() < 3 {
            return None;
        }
        let c = positions.len() - 3;
        // The largest offset by a fold without an early exit, which
        // compiles to a few vector compares.
        let largest = grid[m..]
            .iter()
            .fold(0, |largest, &offset| largest.max(offset));
        if usize::from(largest) > c {
            return None;
        }
        let stride = m + c;
        if cdf.len() != count.checked_mul(stride)?.checked_add(1)? {
            return None;
        }
        Some(SharedGrid {
            grid,
            m,
            positions,
            cdf,
            stride,
            count,
            longest_conditional,
            quantum,
        })
    }
}

/// What a stage of draws starts from, one entry per lane: the blend of
/// wo, (1 - t) slice k + t slice k + 1, and u in [0, 1)^2, whose u.x
/// also picks the slice drawn from as `pick_slice` does (slice k where
/// u.x < 1 - t).
pub struct DrawInputs<'a> {
    pub k: &'a [i32],
    pub t: &'a [f32],
    pub u_x: &'a [f32],
    pub u_y: &'a [f32],
}

/// What a stage of draws gives: the point (x, y), its blended density
/// and whether every slice's density is the same over the box around it
/// (`same`: all bits set where it is, 0 elsewhere, as a vector compare
/// leaves it).
pub struct DrawnPoints<'a> {
    pub x: &'a mut [f32],
    pub y: &'a mut [f32],
    pub p: &'a mut [f32],
    pub same: &'a mut [i32],
}

/// The arrays as the lanes read them; `None` when one is too short for a
/// gather (which the padding rules out).
struct Sources<'a> {
    cpu: Avx2,
    grid: Pairs<'a, u16>,
    positions: Pairs<'a, u8>,
    cdf: Pairs<'a, u16>,
    /// The stride between slices' values and m, in every lane.
    stride: __m256i,
    m: __m256i,
    /// The last slice's index, in every lane.
    last_slice: __m256i,
}

/// Lanes 8g..8g + 8 of `v`; panics if `v` is shorter.
#[inline(always)]
fn load_f(_: Avx2, g: usize, v: &[f32]) -> __m256 {
    let v = &v[8 * g..8 * g + 8];
    // SAFETY: the token proves the CPU has AVX2; the load reads the eight
    // floats of `v`.
    unsafe { _mm256_loadu_ps(v.as_ptr()) }
}

/// [`load_f`] of integers.
#[inline(always)]
fn load_i(_: Avx2, g: usize, v: &[i32]) -> __m256i {
    let v = &v[8 * g..8 * g + 8];
    // SAFETY: as `load_f`.
    unsafe { _mm256_loadu_si256(v.as_ptr() as *const __m256i) }
}

/// Store `v` to lanes 8g..8g + 8 of `out`; panics if `out` is shorter.
#[inline(always)]
fn store_f(_: Avx2, g: usize, v: __m256, out: &mut [f32]) {
    let out = &mut out[8 * g..8 * g + 8];
    // SAFETY: the token proves the CPU has AVX2; the store writes the
    // eight floats of `out`.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), v) }
}

/// [`store_f`] of integers.
#[inline(always)]
fn store_i(_: Avx2, g: usize, v: __m256i, out: &mut [i32]) {
    let out = &mut out[8 * g..8 * g + 8];
    // SAFETY: as `store_f`.
    unsafe { _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, v) }
}

impl<'a> SharedGrid<'a> {
    #[inline(always)]
    fn sources(&self, cpu: Avx2) -> Option<Sources<'a>> {
        // SAFETY: the token proves the CPU has AVX2.
        let (stride, m, last_slice) = unsafe {
            (
                _mm256_set1_epi32(self.stride as i32),
                _mm256_set1_epi32(self.m as i32),
                _mm256_set1_epi32(self.count as i32 - 1),
            )
        };
        Some(Sources {
            cpu,
            grid: Pairs::new(self.grid)?,
            positions: Pairs::new(self.positions)?,
            cdf: Pairs::new(self.cdf)?,
            stride,
            m,
            last_slice,
        })
    }

    /// The table draws of the outgoing sampler (its `table_point`) for
    /// the [`STAGE`](super::search::lanes::STAGE) lanes of `input`: the
    /// slice picked from the blend, its draw (`SharedSlices::sample`), and
    /// the blended density w_drawn d_drawn + (1 - w_drawn) d_other of the
    /// drawn cell (the other term only where its weight is positive).
    /// Returns false, writing nothing, if the arrays cannot be read by
    /// lanes. Slice indices are clamped into [0, count). Panics if
    /// a slice of `input` or `out` holds fewer than
    /// [`STAGE`](super::search::lanes::STAGE) lanes.
    #[inline(always)]
    pub fn sample_lanes(
        &self,
        cpu: Avx2,
        input: &DrawInputs<'_>,
        n: (f32, f32),
        margin: (f32, f32),
        out: DrawnPoints<'_>,
    ) -> bool {
        let Some(src) = self.sources(cpu) else {
            return false;
        };
        let (n_x, n_y) = n;
        let m = self.m as i32;
        // SAFETY: the token proves the CPU has AVX2. Every gather index
        // is derived from the shape `SharedGrid::new` checked (every offset
        // at most the count c of conditional positions): a slice's values start
        // at s * stride with s clamped into [0, count), its marginal
        // search reads its values 1..m - 1, the pair at j <= m - 2 ends at
        // m - 1; the offsets pair at m + j ends at 2m - 1, inside the
        // grid; a conditional's search reads its values a + 1 ..= b - 1
        // and its pair at a + i <= b - 2 ends at b - 1 < c, where the CDF
        // padding keeps the last pair of the last slice readable and the
        // positions' padding the last position. A lane whose marginal
        // segment has no conditional (never drawn from valid slices) is
        // pointed at its slice's first conditional value instead.
        unsafe {
            let stride = src.stride;
            let one = _mm256_set1_epi32(1);
            let zero_i = _mm256_setzero_si256();
            let m_v = src.m;
            let qf = _mm256_set1_ps(self.quantum);
            let zero = _mm256_setzero_ps();
            let one_f = _mm256_set1_ps(1.0);
            let half = _mm256_set1_ps(0.5);
            let mut base = [zero_i; GROUPS];
            let mut other = [zero_i; GROUPS];
            let mut w_drawn = [zero; GROUPS];
            let mut key = [zero_i; GROUPS];
            let mut us_y = [zero; GROUPS];
            let mut us_x = [zero; GROUPS];
            for g in 0..GROUPS {
                // The slice drawn from, chosen by selects where one lane
                // at a time would branch on a coin toss: slice k with u.x
                // / (1 - t) where u.x < 1 - t, else slice k + 1 with
                // (u.x - (1 - t)) / t, clamped to [0, 1) as `clamp_unit`.
                let (k, t) = (load_i(cpu, g, input.k), load_f(cpu, g, input.t));
                let u_x = load_f(cpu, g, input.u_x);
                let w_first = _mm256_sub_ps(one_f, t);
                let first = _mm256_cmp_ps::<_CMP_LT_OQ>(u_x, w_first);
                let numerator = _mm256_blendv_ps(_mm256_sub_ps(u_x, w_first), u_x, first);
                w_drawn[g] = _mm256_blendv_ps(t, w_first, first);
                let u_x = _mm256_div_ps(numerator, w_drawn[g]);
                let u_x = _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GT_OQ>(u_x, zero),
                    _mm256_min_ps(u_x, _mm256_set1_ps(ONE_MINUS_EPSILON)),
                );
                // `first` is -1 in a lane that draws from slice k.
                let first = _mm256_castps_si256(first);
                let drawn = _mm256_add_epi32(_mm256_add_epi32(k, one), first);
                other[g] = slice_index(&src, _mm256_sub_epi32(k, first));
                base[g] = _mm256_mullo_epi32(slice_index(&src, drawn), stride);
                us_y[g] = _mm256_mul_ps(load_f(cpu, g, input.u_y), qf);
                us_x[g] = _mm256_mul_ps(u_x, qf);
                key[g] = search_key(us_y[g], u16::MAX);
            }
            // The marginal: each lane's values 1..=m - 1.
            let mut from = [zero_i; GROUPS];
            for g in 0..GROUPS {
                from[g] = _mm256_add_epi32(base[g], one);
            }
            let j = lift_at_or_below(
                cpu,
                &src.cdf,
                &from,
                &[_mm256_set1_epi32(m - 2); GROUPS],
                &key,
                first_step(self.m - 1),
            );
            let mut last = [zero_i; GROUPS];
            let mut a = [zero_i; GROUPS];
            let mut y = [zero; GROUPS];
            let mut segment_y = [(zero, zero); GROUPS];
            let mut mass_y = [zero; GROUPS];
            for g in 0..GROUPS {
                let (c0, c1) = src.cdf.gather(cpu, _mm256_add_epi32(base[g], j[g]));
                let (p0, p1) = src.grid.gather(cpu, j[g]);
                let (p0, p1) = (_mm256_cvtepi32_ps(p0), _mm256_cvtepi32_ps(p1));
                y[g] = invert(us_y[g], (c0, c1), (p0, p1), n_y, (zero, one_f, half));
                segment_y[g] = (p0, p1);
                mass_y[g] = _mm256_cvtepi32_ps(_mm256_sub_epi32(c1, c0));
                let c = conditional_of(&src, j[g]);
                (a[g], last[g]) = (c.first, c.last);
                from[g] = _mm256_add_epi32(_mm256_add_epi32(base[g], m_v), c.inner);
                key[g] = search_key(us_x[g], u16::MAX);
            }
            // The conditional of each lane's marginal segment.
            let i = lift_at_or_below(
                cpu,
                &src.cdf,
                &from,
                &last,
                &key,
                first_step(self.longest_conditional),
            );
            let nn = _mm256_set1_ps(n_x * n_y);
            let qq = _mm256_set1_ps(self.quantum * self.quantum);
            let (mx, my) = (
                _mm256_set1_ps(margin.0 * n_x),
                _mm256_set1_ps(margin.1 * n_y),
            );
            let (nx_v, ny_v) = (_mm256_set1_ps(n_x), _mm256_set1_ps(n_y));
            for g in 0..GROUPS {
                let at = _mm256_add_epi32(a[g], i[g]);
                let (c0, c1) = src
                    .cdf
                    .gather(cpu, _mm256_add_epi32(_mm256_add_epi32(base[g], m_v), at));
                let (q0, q1) = src.positions.gather(cpu, at);
                let (q0, q1) = (_mm256_cvtepi32_ps(q0), _mm256_cvtepi32_ps(q1));
                let x = invert(us_x[g], (c0, c1), (q0, q1), n_x, (zero, one_f, half));
                let width = _mm256_mul_ps(
                    _mm256_sub_ps(segment_y[g].1, segment_y[g].0),
                    _mm256_sub_ps(q1, q0),
                );
                let scale = _mm256_div_ps(nn, _mm256_mul_ps(width, qq));
                let mass = _mm256_mul_ps(mass_y[g], _mm256_cvtepi32_ps(_mm256_sub_epi32(c1, c0)));
                let drawn = _mm256_mul_ps(mass, scale);
                // The other slice at the same cell.
                let other_density = density(&src, other[g], j[g], at, scale);
                let w_drawn = w_drawn[g];
                let w_other = _mm256_sub_ps(one_f, w_drawn);
                let p = _mm256_mul_ps(w_drawn, drawn);
                let with_other = _mm256_add_ps(p, _mm256_mul_ps(w_other, other_density));
                let p = _mm256_blendv_ps(p, with_other, _mm256_cmp_ps::<_CMP_GT_OQ>(w_other, zero));
                let same = _mm256_and_ps(
                    inside(_mm256_mul_ps(y[g], ny_v), my, segment_y[g]),
                    inside(_mm256_mul_ps(x, nx_v), mx, (q0, q1)),
                );
                store_f(cpu, g, x, out.x);
                store_f(cpu, g, y[g], out.y);
                store_f(cpu, g, p, out.p);
                store_i(cpu, g, _mm256_castps_si256(same), out.same);
            }
        }
        true
    }

    /// For the [`STAGE`](super::search::lanes::STAGE) lanes of points (x, y) in [0, 1)^2 (or anything,
    /// for lanes whose result is dropped), the blended density
    /// (1 - t) d_k + t d_{k+1} (each term only where its weight is
    /// positive; 0 where no slice has mass), as
    /// `SharedSlices::locate` and `SharedSlices::density` find it one
    /// at a time. `k + 1` is read only where `t > 0`; slice indices are
    /// clamped into [0, count).
    /// Panics if a slice holds fewer than [`STAGE`](super::search::lanes::STAGE) lanes. Returns
    /// false, writing nothing, if the arrays cannot be read by lanes.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn density_lanes(
        &self,
        cpu: Avx2,
        k: &[i32],
        t: &[f32],
        x: &[f32],
        y: &[f32],
        n: (f32, f32),
        out: &mut [f32],
    ) -> bool {
        let Some(src) = self.sources(cpu) else {
            return false;
        };
        let (n_x, n_y) = n;
        let m = self.m as i32;
        // SAFETY: the token proves the CPU has AVX2. The indices: the
        // marginal search reads positions 1..=m - 1 and its pair at
        // j <= m - 2 ends at m - 1; the offsets pair at m + j ends at
        // 2m - 1, inside the grid; a conditional's search reads positions
        // a + 1 ..= b - 1 and its pair at a + i <= b - 2 ends at b - 1,
        // the positions' padding keeping the last readable; a lane whose
        // segment has no conditional reads position 0 and value 0 of its
        // slices instead, and its density is 0. Slice k is below count
        // and k + 1 (read only where t > 0, k again elsewhere) are
        // clamped into [0, count).
        unsafe {
            let one = _mm256_set1_epi32(1);
            let zero_i = _mm256_setzero_si256();
            let zero = _mm256_setzero_ps();
            let one_f = _mm256_set1_ps(1.0);
            let mut key = [zero_i; GROUPS];
            for g in 0..GROUPS {
                key[g] = search_key(
                    _mm256_mul_ps(load_f(cpu, g, y), _mm256_set1_ps(n_y)),
                    u16::MAX,
                );
            }
            let j = lift_at_or_below(
                cpu,
                &src.grid,
                &[one; GROUPS],
                &[_mm256_set1_epi32(m - 2); GROUPS],
                &key,
                first_step(self.m - 1),
            );
            let (mut a, mut has) = ([zero_i; GROUPS], [zero_i; GROUPS]);
            let (mut from, mut last) = ([zero_i; GROUPS], [zero_i; GROUPS]);
            for g in 0..GROUPS {
                let c = conditional_of(&src, j[g]);
                (a[g], from[g], last[g], has[g]) = (c.first, c.inner, c.last, c.has);
                let tx = _mm256_mul_ps(load_f(cpu, g, x), _mm256_set1_ps(n_x));
                key[g] = search_key(tx, u8::MAX.into());
            }
            let i = lift_at_or_below(
                cpu,
                &src.positions,
                &from,
                &last,
                &key,
                first_step(self.longest_conditional),
            );
            let nn = _mm256_set1_ps(n_x * n_y);
            let qq = _mm256_set1_ps(self.quantum * self.quantum);
            for g in 0..GROUPS {
                let at = _mm256_add_epi32(a[g], i[g]);
                let (p0, p1) = src.grid.gather(cpu, j[g]);
                let (q0, q1) = src.positions.gather(cpu, at);
                let width = _mm256_mul_ps(
                    _mm256_cvtepi32_ps(_mm256_sub_epi32(p1, p0)),
                    _mm256_cvtepi32_ps(_mm256_sub_epi32(q1, q0)),
                );
                let scale = _mm256_div_ps(nn, _mm256_mul_ps(width, qq));
                let t = load_f(cpu, g, t);
                let later = _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero);
                let k = load_i(cpu, g, k);
                let k1 = _mm256_add_epi32(k, _mm256_and_si256(one, _mm256_castps_si256(later)));
                let (k, k1) = (slice_index(&src, k), slice_index(&src, k1));
                let mut p = zero;
                let first = _mm256_add_ps(
                    p,
                    _mm256_mul_ps(_mm256_sub_ps(one_f, t), density(&src, k, j[g], at, scale)),
                );
                p = _mm256_blendv_ps(p, first, _mm256_cmp_ps::<_CMP_LT_OQ>(t, one_f));
                let second = _mm256_add_ps(p, _mm256_mul_ps(t, density(&src, k1, j[g], at, scale)));
                p = _mm256_blendv_ps(p, second, later);
                p = _mm256_and_ps(p, _mm256_castsi256_ps(has[g]));
                store_f(cpu, g, p, out);
            }
        }
        true
    }
}

/// Slice indices clamped into [0, count): what makes every gather of a
/// slice's values safe whatever the caller passes (a valid index is kept).
///
/// # Safety
/// AVX2.
#[inline(always)]
unsafe fn slice_index(src: &Sources<'_>, s: __m256i) -> __m256i {
    // SAFETY: the caller's contract: AVX2.
    unsafe { _mm256_max_epi32(_mm256_min_epi32(s, src.last_slice), _mm256_setzero_si256()) }
}

/// The conditional of a marginal segment on the grid, as the lanes
/// search it ([`conditional_of`]).
struct Conditional {
    /// The index of its first vertex among the conditional positions.
    first: __m256i,
    /// `first + 1`, the first inner vertex, where the search starts.
    inner: __m256i,
    /// The last index the search may count to: its vertices less 2.
    last: __m256i,
    /// All bits set where it has at least two vertices (mass).
    has: __m256i,
}

/// The conditional of marginal segment j. A segment whose conditional
/// has fewer than two vertices gives 0 for `first`, `inner` and `last`,
/// so that its lanes read position 0 and count nothing.
///
/// # Safety
/// AVX2, and m + j + 1 inside the grid.
#[inline(always)]
unsafe fn conditional_of(src: &Sources<'_>, j: __m256i) -> Conditional {
    // SAFETY: the caller's contract.
    unsafe {
        let (first, end) = src.grid.gather(src.cpu, _mm256_add_epi32(src.m, j));
        let length = _mm256_sub_epi32(end, first);
        let one = _mm256_set1_epi32(1);
        let has = _mm256_cmpgt_epi32(length, one);
        let first = _mm256_and_si256(first, has);
        Conditional {
            first,
            inner: _mm256_add_epi32(first, _mm256_and_si256(one, has)),
            last: _mm256_and_si256(_mm256_sub_epi32(length, _mm256_set1_epi32(2)), has),
            has,
        }
    }
}

/// The integer key of a search among quantised values up to `top`: `v`
/// (already scaled to them) clamped to [0, top] and truncated, as the
/// scalar searches' keys are.
///
/// # Safety
/// AVX2.
#[inline(always)]
unsafe fn search_key(v: __m256, top: u16) -> __m256i {
    // SAFETY: the caller's contract: AVX2.
    unsafe {
        let clamped = _mm256_min_ps(
            _mm256_max_ps(v, _mm256_setzero_ps()),
            _mm256_set1_ps(f32::from(top)),
        );
        _mm256_cvttps_epi32(clamped)
    }
}

/// Whether [t - margin, t + margin] lies inside the segment (p0, p1), as
/// `Segment::inside`.
///
/// # Safety
/// AVX2.
#[inline(always)]
unsafe fn inside(t: __m256, margin: __m256, (p0, p1): (__m256, __m256)) -> __m256 {
    // SAFETY: the caller's contract: AVX2.
    unsafe {
        _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_LE_OQ>(p0, _mm256_sub_ps(t, margin)),
            _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_add_ps(t, margin), p1),
        )
    }
}

/// Slice s's density in the cell of marginal segment j and conditional
/// vertex `at`, whose scale is `scale`, as `SharedSlices::density`.
///
/// # Safety
/// AVX2; every s is below the slices' count and (j, at) a cell of the
/// grid (or 0, 0), so that every gather reads inside the CDF values.
#[inline(always)]
unsafe fn density(src: &Sources<'_>, s: __m256i, j: __m256i, at: __m256i, scale: __m256) -> __m256 {
    // SAFETY: the caller's contract.
    unsafe {
        let s = _mm256_mullo_epi32(s, src.stride);
        let (c0, c1) = src.cdf.gather(src.cpu, _mm256_add_epi32(s, j));
        let (d0, d1) = src
            .cdf
            .gather(src.cpu, _mm256_add_epi32(_mm256_add_epi32(s, src.m), at));
        let mass = _mm256_mul_ps(
            _mm256_cvtepi32_ps(_mm256_sub_epi32(c1, c0)),
            _mm256_cvtepi32_ps(_mm256_sub_epi32(d1, d0)),
        );
        _mm256_mul_ps(mass, scale)
    }
}

/// A curve's inversion at `us` = u Q in its segment of CDF values
/// (c0, c1) and positions (p0, p1), over `n` cells: as `Curve::sample`
/// computes it, operation for operation.
///
/// # Safety
/// AVX2.
#[inline(always)]
unsafe fn invert(
    us: __m256,
    (c0, c1): (__m256i, __m256i),
    (p0, p1): (__m256, __m256),
    n: f32,
    (zero, one, half): (__m256, __m256, __m256),
) -> __m256 {
    // SAFETY: the caller's contract: AVX2.
    unsafe {
        let (c0, c1) = (_mm256_cvtepi32_ps(c0), _mm256_cvtepi32_ps(c1));
        let ratio = _mm256_div_ps(_mm256_sub_ps(us, c0), _mm256_sub_ps(c1, c0));
        let clamped = _mm256_min_ps(_mm256_max_ps(ratio, zero), one);
        let frac = _mm256_blendv_ps(half, clamped, _mm256_cmp_ps::<_CMP_GT_OQ>(c1, c0));
        let x = _mm256_div_ps(
            _mm256_add_ps(p0, _mm256_mul_ps(frac, _mm256_sub_ps(p1, p0))),
            _mm256_set1_ps(n),
        );
        _mm256_min_ps(x, _mm256_set1_ps(ONE_MINUS_EPSILON))
    }
}
