//! The AVX2 batch paths of the adaptive distributions:
//! `AdaptiveCdf2D::sample_batch` (with or without the drawn-segment box
//! test), `pdf_batch`, `sample_each_and_same_cell` and `pdf_each`, and
//! `AdaptiveCdf1D::sample_batch`. The segment searches are those of
//! [`acdf_core::search::lanes`], the positions and densities run in the same
//! lanes.
//!
//! In a batch the marginal curve is shared by every draw, so its first four
//! search steps come from registers; in the `_each` forms every lane reads
//! its own distribution and all steps are gathers. Each draw's conditional
//! is its own short list, searched for as many steps as the longest
//! conditional of the stage's distributions needs (a number each
//! distribution keeps, so no lane has to be read to know it). The searches
//! bracket u by the segment's CDF values (or x by its positions, for
//! densities); one paired gather per curve reads the other two ends.
//!
//! The arithmetic is that of `curve::segment_samples` and
//! `curve::segment_density`, operation for operation (the clamps as
//! selects), so the results are bit-identical to `sample` and `pdf`.

// The loops over groups index several parallel arrays of registers by the
// group number; iterator chains over three or four arrays would hide that.
#![allow(clippy::needless_range_loop)]

use super::{AdaptiveCdf1D, AdaptiveCdf2D};
use acdf_core::search::lanes::{
    in_unit, load_stage, load_stage_1d, store_samples, store_samples_1d, Bracket, PerLane, Shared,
    Source, GROUPS, STAGE,
};
use acdf_core::{Sample1D, Sample2D, Vec2, ONE_MINUS_EPSILON};
use acdf_tabulated::SliceDistribution;
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

/// `curve::segment_samples` for eight lanes: the position
/// x_i + t (x_{i+1} - x_i) with t = (u - c_i) / (c_{i+1} - c_i) clamped to
/// [0, 1], then clamped below x_{i+1} and below 1, and the density
/// (c_{i+1} - c_i) / (x_{i+1} - x_i). Returns (positions, densities).
#[inline(always)]
unsafe fn segment_samples_lanes(s: SegmentLanes, u: __m256) -> (__m256, __m256) {
    let zero = _mm256_setzero_ps();
    let one = _mm256_set1_ps(1.0);
    let mass = _mm256_sub_ps(s.c1, s.c0);
    let width = _mm256_sub_ps(s.x1, s.x0);
    let mut t = _mm256_div_ps(_mm256_sub_ps(u, s.c0), mass);
    t = _mm256_blendv_ps(t, zero, _mm256_cmp_ps::<_CMP_LT_OQ>(t, zero));
    t = _mm256_blendv_ps(t, one, _mm256_cmp_ps::<_CMP_GT_OQ>(t, one));
    // A separate multiply and add, as the scalar code rounds them.
    let mut x = _mm256_add_ps(s.x0, _mm256_mul_ps(t, width));
    let below_x1 = _mm256_castsi256_ps(_mm256_sub_epi32(
        _mm256_castps_si256(s.x1),
        _mm256_set1_epi32(1),
    ));
    let cap = _mm256_set1_ps(ONE_MINUS_EPSILON);
    let top = _mm256_blendv_ps(below_x1, cap, _mm256_cmp_ps::<_CMP_GT_OQ>(below_x1, cap));
    x = _mm256_blendv_ps(x, top, _mm256_cmp_ps::<_CMP_GT_OQ>(x, top));
    (x, _mm256_div_ps(mass, width))
}

/// `curve::segment_density` for eight lanes.
#[inline(always)]
unsafe fn segment_density_lanes(s: SegmentLanes) -> __m256 {
    _mm256_div_ps(_mm256_sub_ps(s.c1, s.c0), _mm256_sub_ps(s.x1, s.x0))
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

    /// The conditionals of segments `j` in group g, from the offsets o_j,
    /// o_{j+1}.
    #[inline(always)]
    unsafe fn of<S: Source>(offsets: &S, g: usize, j: __m256i) -> ConditionalLanes {
        let (o0, o1) = offsets.gather_pairs(g, j);
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
    unsafe fn segment<S: Source>(
        &self,
        conditionals: &S,
        g: usize,
        found: (__m256i, __m256, __m256),
        searched_cdfs: bool,
    ) -> SegmentLanes {
        let (k, lower, upper) = found;
        let k = _mm256_andnot_si256(self.uniform, k);
        let mut at = _mm256_add_epi32(self.xs_start, k);
        if !searched_cdfs {
            at = _mm256_andnot_si256(self.uniform, _mm256_add_epi32(at, self.count));
        }
        let (a, b) = conditionals.gather_pairs(g, at);
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

/// The box test of `sample_and_same_cell` in lanes: x ± m inside
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

/// The distributions a stage's lanes use: their three arrays, where the
/// lanes read them from, and each marginal's vertex count m.
struct Tables<'a, S> {
    marginal: S,
    offsets: S,
    conditionals: S,
    /// m of each lane.
    vertices: [__m256i; GROUPS],
    /// The one distribution of every lane (a batch), whose marginal's
    /// first search steps can then come from registers.
    shared: Option<&'a AdaptiveCdf2D>,
    /// The first lifting step of the marginal searches (without `shared`)
    /// and of the conditional searches: half the longest list of the
    /// stage's distributions, rounded up to a power of two, known before
    /// any lane's list is read. Taken instead from the longest list the
    /// stage's lanes had found (a horizontal maximum of their lengths
    /// between the marginal and the conditional searches), it left the
    /// adaptive 2D `sample_batch` 3 to 4% slower: 180.5 against 187.8 M/s
    /// (built-in nickel's middle slice, best of 30 runs of 10^6, mean of
    /// the best three of five alternating runs, a Zen 5 machine).
    marginal_step: usize,
    conditional_step: usize,
}

/// The first lifting step for inner lists of up to `vertices - 1` entries
/// (see [`Bracket::lift`]): their last index `vertices - 2`, plus one,
/// rounded up to a power of two, halved.
fn first_step(vertices: usize) -> usize {
    (vertices.saturating_sub(2) + 1).next_power_of_two() / 2
}

impl<'a> Tables<'a, Shared<f32>> {
    /// Every lane reads `d`.
    #[inline(always)]
    unsafe fn one(d: &'a AdaptiveCdf2D) -> Self {
        Tables {
            marginal: Shared(d.marginal.as_ptr()),
            offsets: Shared(d.offsets.as_ptr() as *const f32),
            conditionals: Shared(d.conditionals.as_ptr()),
            vertices: [_mm256_set1_epi32((d.marginal.len() / 2) as i32); GROUPS],
            shared: Some(d),
            marginal_step: first_step(d.marginal.len() / 2),
            conditional_step: first_step(d.longest_conditional),
        }
    }
}

impl<'a> Tables<'a, PerLane> {
    /// Lane l reads `dists[l]`.
    #[inline(always)]
    unsafe fn each(dists: &[&'a AdaptiveCdf2D]) -> Self {
        let mut marginal = [std::ptr::null::<f32>(); STAGE];
        let mut offsets = [std::ptr::null::<f32>(); STAGE];
        let mut conditionals = [std::ptr::null::<f32>(); STAGE];
        let mut m = [0i32; STAGE];
        let (mut longest_marginal, mut longest_conditional) = (0, 0);
        for (l, d) in dists.iter().take(STAGE).enumerate() {
            marginal[l] = d.marginal.as_ptr();
            offsets[l] = d.offsets.as_ptr() as *const f32;
            conditionals[l] = d.conditionals.as_ptr();
            m[l] = (d.marginal.len() / 2) as i32;
            longest_marginal = longest_marginal.max(d.marginal.len() / 2);
            longest_conditional = longest_conditional.max(d.longest_conditional);
        }
        let mut vertices = [_mm256_setzero_si256(); GROUPS];
        for (g, v) in vertices.iter_mut().enumerate() {
            *v = _mm256_loadu_si256(m[8 * g..].as_ptr() as *const __m256i);
        }
        Tables {
            marginal: PerLane::new(&marginal),
            offsets: PerLane::new(&offsets),
            conditionals: PerLane::new(&conditionals),
            vertices,
            shared: None,
            marginal_step: first_step(longest_marginal),
            conditional_step: first_step(longest_conditional),
        }
    }
}

impl<S: Source> Tables<'_, S> {
    /// The marginal segment of every lane: the count of inner vertex
    /// values `<= v` among the marginal's positions (`cdfs` false) or CDF
    /// values (`cdfs` true), bracketed by the values on either side.
    #[inline(always)]
    unsafe fn marginal_segments(&self, v: &[__m256; GROUPS], cdfs: bool) -> Bracket {
        let one = _mm256_set1_epi32(1);
        // The inner list starts at index 1 (positions) or m + 1 (CDF
        // values) and holds m - 1 entries, the last being 1.
        let mut start = [one; GROUPS];
        let mut last = [one; GROUPS];
        for g in 0..GROUPS {
            if cdfs {
                start[g] = _mm256_add_epi32(self.vertices[g], one);
            }
            last[g] = _mm256_sub_epi32(self.vertices[g], _mm256_set1_epi32(2));
        }
        let mut rows = Bracket::start();
        let step = match self.shared {
            Some(d) => {
                let m = d.marginal.len() / 2;
                let run = if cdfs {
                    &d.marginal[m + 1..]
                } else {
                    &d.marginal[1..m]
                };
                rows.shared_top(run, v)
            }
            None => self.marginal_step,
        };
        rows.lift(&self.marginal, &start, &last, v, step);
        rows
    }

    /// The conditional of every lane's marginal segment, and the segment
    /// of each conditional holding `v` (searched among its CDF values or
    /// positions, as `cdfs` says).
    #[inline(always)]
    unsafe fn conditional_segments(
        &self,
        rows: &Bracket,
        v: &[__m256; GROUPS],
        cdfs: bool,
    ) -> ([ConditionalLanes; GROUPS], Bracket) {
        let mut conditional = [ConditionalLanes::none(); GROUPS];
        let (mut start, mut last) = (
            [_mm256_setzero_si256(); GROUPS],
            [_mm256_setzero_si256(); GROUPS],
        );
        for g in 0..GROUPS {
            conditional[g] = ConditionalLanes::of(&self.offsets, g, rows.count[g]);
            start[g] = conditional[g].inner(cdfs);
            last[g] = conditional[g].last;
        }
        let mut columns = Bracket::start();
        columns.lift(&self.conditionals, &start, &last, v, self.conditional_step);
        (conditional, columns)
    }

    /// The samples of a stage for clamped `ux`, `uy`: positions x and y,
    /// densities, and (with `SAME`) the box-test bits of each group.
    #[inline(always)]
    unsafe fn draw<const SAME: bool>(
        &self,
        ux: &[__m256; GROUPS],
        uy: &[__m256; GROUPS],
        margin: Vec2,
    ) -> [(__m256, __m256, __m256, i32); GROUPS] {
        let rows = self.marginal_segments(uy, true);
        let (conditional, columns) = self.conditional_segments(&rows, ux, true);
        let mut drawn = [(
            _mm256_setzero_ps(),
            _mm256_setzero_ps(),
            _mm256_setzero_ps(),
            0,
        ); GROUPS];
        for g in 0..GROUPS {
            let (x0, x1) = self.marginal.gather_pairs(g, rows.count[g]);
            let row = SegmentLanes {
                x0,
                x1,
                c0: rows.lower[g],
                c1: rows.upper[g],
            };
            let found = (columns.count[g], columns.lower[g], columns.upper[g]);
            let column = conditional[g].segment(&self.conditionals, g, found, true);
            let (y, pdf_y) = segment_samples_lanes(row, uy[g]);
            let (x, pdf_x) = segment_samples_lanes(column, ux[g]);
            let same = if SAME {
                _mm256_movemask_ps(_mm256_and_ps(
                    inside_lanes(y, margin.y, row),
                    inside_lanes(x, margin.x, column),
                ))
            } else {
                0
            };
            drawn[g] = (x, y, _mm256_mul_ps(pdf_y, pdf_x), same);
        }
        drawn
    }

    /// The densities at a stage's points (x, y), 0 outside [0, 1)^2 (NaN
    /// included) and on a zero-mass marginal segment, as `pdf` gives them.
    #[inline(always)]
    unsafe fn densities(&self, x: &[__m256; GROUPS], y: &[__m256; GROUPS]) -> [__m256; GROUPS] {
        let mut inside = [_mm256_setzero_ps(); GROUPS];
        let (mut xs, mut ys) = ([_mm256_setzero_ps(); GROUPS], [_mm256_setzero_ps(); GROUPS]);
        for g in 0..GROUPS {
            inside[g] = _mm256_and_ps(in_unit(x[g]), in_unit(y[g]));
            // Outside points search at 0 and are zeroed at the end.
            xs[g] = _mm256_and_ps(x[g], inside[g]);
            ys[g] = _mm256_and_ps(y[g], inside[g]);
        }
        let rows = self.marginal_segments(&ys, false);
        let (conditional, columns) = self.conditional_segments(&rows, &xs, false);
        let mut density = [_mm256_setzero_ps(); GROUPS];
        for g in 0..GROUPS {
            let at = _mm256_add_epi32(self.vertices[g], rows.count[g]);
            let (c0, c1) = self.marginal.gather_pairs(g, at);
            let row = SegmentLanes {
                x0: rows.lower[g],
                x1: rows.upper[g],
                c0,
                c1,
            };
            let found = (columns.count[g], columns.lower[g], columns.upper[g]);
            let column = conditional[g].segment(&self.conditionals, g, found, false);
            let py = segment_density_lanes(row);
            let px = segment_density_lanes(column);
            // `pdf` returns 0 for a zero-mass marginal segment before
            // looking at its conditional.
            let zero_row = _mm256_cmp_ps::<_CMP_EQ_OQ>(py, _mm256_setzero_ps());
            let p = _mm256_andnot_ps(zero_row, _mm256_mul_ps(py, px));
            density[g] = _mm256_and_ps(p, inside[g]);
        }
        density
    }
}

/// Store a stage's samples and, with `SAME`, its box tests.
#[inline(always)]
unsafe fn store_stage<const SAME: bool>(
    drawn: &[(__m256, __m256, __m256, i32); GROUPS],
    out: &mut [Sample2D],
    same: &mut [bool],
) {
    for (g, &(x, y, pdf, bits)) in drawn.iter().enumerate() {
        store_samples(x, y, pdf, &mut out[8 * g..]);
        if SAME {
            for (l, s) in same[8 * g..8 * g + 8].iter_mut().enumerate() {
                *s = bits & (1 << l) != 0;
            }
        }
    }
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
        let tables = Tables::one(self);
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (ux, uy) = load_stage(&u[range.clone()], true);
            let drawn = tables.draw::<SAME>(&ux, &uy, margin);
            let same = if SAME {
                &mut same[range.clone()]
            } else {
                &mut [][..]
            };
            store_stage::<SAME>(&drawn, &mut out[range], same);
        }
        for k in stages * STAGE..len {
            if SAME {
                (out[k], same[k]) = self.sample_and_same_cell(u[k], margin);
            } else {
                out[k] = self.sample_inline(u[k]);
            }
        }
    }

    /// The same densities as `pdf`, [`STAGE`] points at a time in AVX2
    /// lanes: the segments are found by searching the vertex positions,
    /// their CDF values gathered in pairs, and the densities computed as
    /// `curve::segment_density` does.
    ///
    /// # Safety
    /// The CPU must support AVX2, and [`fits_lanes`](Self::fits_lanes)
    /// must hold.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pdf_batch_gather(&self, p: &[Vec2], out: &mut [f32]) {
        let len = p.len().min(out.len());
        let tables = Tables::one(self);
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (x, y) = load_stage(&p[range.clone()], false);
            store_densities(&tables.densities(&x, &y), &mut out[range]);
        }
        for k in stages * STAGE..len {
            out[k] = acdf_core::Distribution2D::pdf(self, p[k]);
        }
    }

    /// [`sample_each_and_same_cell`](Self::sample_each_and_same_cell)
    /// in AVX2 lanes, for slices of equal length: a stage whose
    /// distributions all fit the lanes is drawn as in
    /// [`sample_batch_gather`](Self::sample_batch_gather), each lane
    /// reading its own distribution; other stages and the tail go through
    /// the scalar stages.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_each_gather(
        dists: &[&AdaptiveCdf2D],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        for (k, stage) in dists.chunks(STAGE).enumerate() {
            let range = k * STAGE..k * STAGE + stage.len();
            let (u, out, same) = (&u[range.clone()], &mut out[range.clone()], &mut same[range]);
            if stage.len() == STAGE && stage.iter().all(|d| d.fits_lanes()) {
                let (ux, uy) = load_stage(u, true);
                let drawn = Tables::each(stage).draw::<true>(&ux, &uy, margin);
                store_stage::<true>(&drawn, out, same);
            } else {
                Self::sample_each_lanes(stage, u, margin, out, same);
            }
        }
    }

    /// [`pdf_each`](Self::pdf_each) in AVX2 lanes, for slices of equal
    /// length (see [`sample_each_gather`](Self::sample_each_gather)).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pdf_each_gather(dists: &[&AdaptiveCdf2D], p: &[Vec2], out: &mut [f32]) {
        for (k, stage) in dists.chunks(STAGE).enumerate() {
            let range = k * STAGE..k * STAGE + stage.len();
            let (p, out) = (&p[range.clone()], &mut out[range]);
            if stage.len() == STAGE && stage.iter().all(|d| d.fits_lanes()) {
                let (x, y) = load_stage(p, false);
                store_densities(&Tables::each(stage).densities(&x, &y), out);
            } else {
                Self::pdf_each_lanes(stage, p, out);
            }
        }
    }
}

/// Write a stage's densities to `out`.
#[inline(always)]
unsafe fn store_densities(density: &[__m256; GROUPS], out: &mut [f32]) {
    for (g, d) in density.iter().enumerate() {
        _mm256_storeu_ps(out[8 * g..8 * g + 8].as_mut_ptr(), *d);
    }
}

impl AdaptiveCdf1D {
    /// Whether the lanes path applies: two vertices or more, indexable by
    /// `i32` lanes.
    pub(super) fn fits_lanes(&self) -> bool {
        self.vertices.len() >= 4 && self.vertices.len() <= i32::MAX as usize
    }

    /// The same samples as `sample`, [`STAGE`] at a time in AVX2 lanes:
    /// the segment search as the 2D marginal's, then
    /// `curve::segment_samples` in lanes; the tail one by one.
    ///
    /// # Safety
    /// The CPU must support AVX2, and [`fits_lanes`](Self::fits_lanes)
    /// must hold.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_batch_gather(&self, u: &[f32], out: &mut [Sample1D]) {
        let len = u.len().min(out.len());
        let m = self.vertices.len() / 2;
        // The CDF values c_1, ..., c_{m-1} (the last is 1).
        let run = &self.vertices[m + 1..];
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (u, out) = (&u[range.clone()], &mut out[range]);
            let v = load_stage_1d(u);
            let segments = Bracket::search_shared(run, &v);
            for g in 0..GROUPS {
                let (x0, x1) = Shared(self.vertices.as_ptr()).gather_pairs(g, segments.count[g]);
                let segment = SegmentLanes {
                    x0,
                    x1,
                    c0: segments.lower[g],
                    c1: segments.upper[g],
                };
                let (x, pdf) = segment_samples_lanes(segment, v[g]);
                store_samples_1d(x, pdf, &mut out[8 * g..8 * g + 8]);
            }
        }
        for k in stages * STAGE..len {
            out[k] = acdf_core::Distribution1D::sample(self, u[k]);
        }
    }
}
