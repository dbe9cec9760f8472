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
//!
//! Every function takes an [`Avx2`] token (or a [`Tables`] holding one),
//! which proves the CPU has AVX2: the `#[target_feature]` entry points are
//! compiled for it and the helpers are `#[inline(always)]` into them. The
//! searches read the curves at indices held in registers, which is
//! `unsafe` (see `acdf_core::search::lanes`); each such read says why its
//! indices lie inside the arrays.

// The loops over groups index several parallel arrays of registers by the
// group number; iterator chains over three or four arrays would hide that.
#![allow(clippy::needless_range_loop)]

use super::{AdaptiveCdf1D, AdaptiveCdf2D};
use acdf_core::cpu::Avx2;
use acdf_core::search::lanes::{
    in_unit, load_i32, load_stage, load_stage_1d, store_lanes, store_samples, store_samples_1d,
    Bracket, PerLane, Shared, SharedList, Source, GROUPS, MAX_ENTRIES, STAGE,
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
fn segment_samples_lanes(_: Avx2, s: SegmentLanes, u: __m256) -> (__m256, __m256) {
    // SAFETY: the token proves the CPU has AVX2.
    unsafe {
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
}

/// `curve::segment_density` for eight lanes.
#[inline(always)]
fn segment_density_lanes(_: Avx2, s: SegmentLanes) -> __m256 {
    // SAFETY: the token proves the CPU has AVX2.
    unsafe { _mm256_div_ps(_mm256_sub_ps(s.c1, s.c0), _mm256_sub_ps(s.x1, s.x0)) }
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
    fn none(_: Avx2) -> ConditionalLanes {
        // SAFETY: the token proves the CPU has AVX2.
        let zero = unsafe { _mm256_setzero_si256() };
        ConditionalLanes {
            xs_start: zero,
            count: zero,
            uniform: zero,
            last: zero,
        }
    }

    /// The conditionals of segments `j` in group g, from the offsets o_j,
    /// o_{j+1}.
    ///
    /// # Safety
    /// In every lane, `0 <= j` and `j + 1` indexes the lane's offsets.
    #[inline(always)]
    unsafe fn of<S: Source>(cpu: Avx2, offsets: &S, g: usize, j: __m256i) -> ConditionalLanes {
        // SAFETY: the token proves the CPU has AVX2; the pair read is
        // inside the offsets by the caller's contract.
        unsafe {
            let (o0, o1) = offsets.gather_pairs(cpu, g, j);
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
    }

    /// The start of its inner CDF values c_1, ... (`inner_cdfs`) or inner
    /// positions x_1, ... (`!inner_cdfs`); 0 where uniform.
    #[inline(always)]
    fn inner(&self, _: Avx2, cdfs: bool) -> __m256i {
        // SAFETY: the token proves the CPU has AVX2.
        unsafe {
            let skip = if cdfs {
                _mm256_add_epi32(self.count, _mm256_set1_epi32(1))
            } else {
                _mm256_set1_epi32(1)
            };
            _mm256_andnot_si256(self.uniform, _mm256_add_epi32(self.xs_start, skip))
        }
    }

    /// The segment ends from a search `found` over its inner list and the
    /// other pair gathered from `paired` (positions after a search of CDF
    /// values, CDF values after a search of positions); the uniform
    /// stand-in's segment (0, 0) to (1, 1) where uniform.
    ///
    /// # Safety
    /// These are the conditionals of a distribution whose offsets lie
    /// inside `conditionals` (a stored conditional of m >= 2 vertices
    /// occupies 2m entries from `xs_start`), and in every lane that is not
    /// uniform the count of `found` is at most m - 2.
    #[inline(always)]
    unsafe fn segment<S: Source>(
        &self,
        cpu: Avx2,
        conditionals: &S,
        g: usize,
        found: (__m256i, __m256, __m256),
        searched_cdfs: bool,
    ) -> SegmentLanes {
        // SAFETY: the token proves the CPU has AVX2. The pair read starts
        // at xs_start + k (positions k, k + 1 <= m - 1) or xs_start + m + k
        // (CDF values), inside the conditional by the caller's contract;
        // uniform lanes read entries 0 and 1 of the array, which holds at
        // least four (`fits_lanes`).
        unsafe {
            let (k, lower, upper) = found;
            let k = _mm256_andnot_si256(self.uniform, k);
            let mut at = _mm256_add_epi32(self.xs_start, k);
            if !searched_cdfs {
                at = _mm256_andnot_si256(self.uniform, _mm256_add_epi32(at, self.count));
            }
            let (a, b) = conditionals.gather_pairs(cpu, g, at);
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
}

/// The box test of `sample_and_same_cell` in lanes: x ± m inside
/// [0, 1) and inside the drawn segment [x_i, x_{i+1}); all ones where it is.
#[inline(always)]
fn inside_lanes(_: Avx2, x: __m256, m: f32, s: SegmentLanes) -> __m256 {
    // SAFETY: the token proves the CPU has AVX2.
    unsafe {
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
}

/// The distributions a stage's lanes use: their three arrays, where the
/// lanes read them from, and each marginal's vertex count m.
///
/// The invariant the searches' bounds rest on: every lane's distribution
/// fits the lanes (`AdaptiveCdf2D::fits_lanes`: a marginal of m >= 2
/// vertices, at least one stored conditional, arrays of at most
/// [`MAX_ENTRIES`]) and is well formed (curves ending at 1, offsets
/// non-decreasing and inside the conditionals, one conditional per
/// marginal segment), as every built or decoded distribution is. Only
/// [`Tables::one`] and [`Tables::each`] make one.
struct Tables<'a, S> {
    cpu: Avx2,
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
    /// stage's lanes had found, it would need a horizontal maximum of their
    /// lengths between the marginal and the conditional searches, which
    /// waits for every lane's marginal search; known up front, it adds
    /// nothing to that chain, at the price of the steps that lanes whose
    /// lists are all shorter would not need.
    marginal_step: usize,
    conditional_step: usize,
}

/// The first lifting step for inner lists of up to `vertices - 1` entries
/// (see [`Bracket::lift`]): their last index `vertices - 2`, plus one,
/// rounded up to a power of two, halved.
fn first_step(vertices: usize) -> usize {
    (vertices.saturating_sub(2) + 1).next_power_of_two() / 2
}

impl<'a> Tables<'a, Shared<'a>> {
    /// Every lane reads `d`.
    ///
    /// # Safety
    /// `d` fits the lanes (`AdaptiveCdf2D::fits_lanes`).
    #[inline(always)]
    unsafe fn one(cpu: Avx2, d: &'a AdaptiveCdf2D) -> Self {
        debug_assert!(d.fits_lanes());
        // SAFETY: the token proves the CPU has AVX2.
        let vertices = unsafe { [_mm256_set1_epi32((d.marginal.len() / 2) as i32); GROUPS] };
        Tables {
            cpu,
            marginal: Shared::new(&d.marginal),
            offsets: Shared::new(&d.offsets),
            conditionals: Shared::new(&d.conditionals),
            vertices,
            shared: Some(d),
            marginal_step: first_step(d.marginal.len() / 2),
            conditional_step: first_step(d.longest_conditional),
        }
    }
}

impl<'a> Tables<'a, PerLane<'a>> {
    /// Lane l reads `dists[l]`.
    ///
    /// # Safety
    /// Every distribution fits the lanes (`AdaptiveCdf2D::fits_lanes`).
    #[inline(always)]
    unsafe fn each(cpu: Avx2, dists: &[&'a AdaptiveCdf2D; STAGE]) -> Self {
        debug_assert!(dists.iter().all(|d| d.fits_lanes()));
        let mut m = [0i32; STAGE];
        let (mut longest_marginal, mut longest_conditional) = (0, 0);
        for (l, d) in dists.iter().enumerate() {
            m[l] = (d.marginal.len() / 2) as i32;
            longest_marginal = longest_marginal.max(d.marginal.len() / 2);
            longest_conditional = longest_conditional.max(d.longest_conditional);
        }
        let vertices = std::array::from_fn(|g| load_i32(cpu, &m[8 * g..]));
        Tables {
            cpu,
            marginal: PerLane::new(cpu, |l| &dists[l].marginal[..]),
            offsets: PerLane::new(cpu, |l| &dists[l].offsets[..]),
            conditionals: PerLane::new(cpu, |l| &dists[l].conditionals[..]),
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
    /// values (`cdfs` true), bracketed by the values on either side: at
    /// most m - 2, the last inner value (1) being above every v searched.
    #[inline(always)]
    fn marginal_segments(&self, v: &[__m256; GROUPS], cdfs: bool) -> Bracket {
        let cpu = self.cpu;
        // SAFETY: the token proves the CPU has AVX2. The lanes search
        // entries `start .. start + m - 1` of their marginal (2m entries,
        // m >= 2 by the invariant of `Tables`): 1 ..= m - 1 or
        // m + 1 ..= 2m - 1, starting from a fresh bracket or `shared_top`
        // over that same inner list.
        unsafe {
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
            let mut rows = Bracket::start(cpu);
            let step = match self.shared {
                Some(d) => {
                    let m = d.marginal.len() / 2;
                    let run = if cdfs {
                        &d.marginal[m + 1..]
                    } else {
                        &d.marginal[1..m]
                    };
                    rows.shared_top(cpu, run, v)
                }
                None => self.marginal_step,
            };
            rows.lift(cpu, &self.marginal, &start, &last, v, step);
            rows
        }
    }

    /// The conditional of every lane's marginal segment, and the segment
    /// of each conditional holding `v` (searched among its CDF values or
    /// positions, as `cdfs` says).
    #[inline(always)]
    fn conditional_segments(
        &self,
        rows: &Bracket,
        v: &[__m256; GROUPS],
        cdfs: bool,
    ) -> ([ConditionalLanes; GROUPS], Bracket) {
        let cpu = self.cpu;
        // SAFETY: the token proves the CPU has AVX2. Segment j = the
        // marginal count is at most m - 2, so offsets j and j + 1 exist
        // (m of them); a stored conditional of c >= 2 vertices occupies
        // entries 2 o_j .. 2 o_j + 2c of the conditionals, and its lanes
        // search the c - 1 inner values from `inner`, whose last (1) is
        // above every v; uniform lanes search entry 0 alone (the array
        // holds at least four).
        unsafe {
            let mut conditional = [ConditionalLanes::none(cpu); GROUPS];
            let (mut start, mut last) = (
                [_mm256_setzero_si256(); GROUPS],
                [_mm256_setzero_si256(); GROUPS],
            );
            for g in 0..GROUPS {
                conditional[g] = ConditionalLanes::of(cpu, &self.offsets, g, rows.count[g]);
                start[g] = conditional[g].inner(cpu, cdfs);
                last[g] = conditional[g].last;
            }
            let mut columns = Bracket::start(cpu);
            columns.lift(
                cpu,
                &self.conditionals,
                &start,
                &last,
                v,
                self.conditional_step,
            );
            (conditional, columns)
        }
    }

    /// The samples of a stage for clamped `ux`, `uy`: positions x and y,
    /// densities, and (with `SAME`) the box-test bits of each group.
    #[inline(always)]
    fn draw<const SAME: bool>(
        &self,
        ux: &[__m256; GROUPS],
        uy: &[__m256; GROUPS],
        margin: Vec2,
    ) -> [(__m256, __m256, __m256, i32); GROUPS] {
        let cpu = self.cpu;
        let rows = self.marginal_segments(uy, true);
        let (conditional, columns) = self.conditional_segments(&rows, ux, true);
        // SAFETY: the token proves the CPU has AVX2. The marginal pair read
        // is positions j, j + 1 <= m - 1 of the marginal (j <= m - 2, see
        // `marginal_segments`); the conditional's is that of
        // `ConditionalLanes::segment`, whose count is at most c - 2 (see
        // `conditional_segments`).
        unsafe {
            let mut drawn = [(
                _mm256_setzero_ps(),
                _mm256_setzero_ps(),
                _mm256_setzero_ps(),
                0,
            ); GROUPS];
            for g in 0..GROUPS {
                let (x0, x1) = self.marginal.gather_pairs(cpu, g, rows.count[g]);
                let row = SegmentLanes {
                    x0,
                    x1,
                    c0: rows.lower[g],
                    c1: rows.upper[g],
                };
                let found = (columns.count[g], columns.lower[g], columns.upper[g]);
                let column = conditional[g].segment(cpu, &self.conditionals, g, found, true);
                let (y, pdf_y) = segment_samples_lanes(cpu, row, uy[g]);
                let (x, pdf_x) = segment_samples_lanes(cpu, column, ux[g]);
                let same = if SAME {
                    _mm256_movemask_ps(_mm256_and_ps(
                        inside_lanes(cpu, y, margin.y, row),
                        inside_lanes(cpu, x, margin.x, column),
                    ))
                } else {
                    0
                };
                drawn[g] = (x, y, _mm256_mul_ps(pdf_y, pdf_x), same);
            }
            drawn
        }
    }

    /// The densities at a stage's points (x, y), 0 outside [0, 1)^2 (NaN
    /// included) and on a zero-mass marginal segment, as `pdf` gives them.
    #[inline(always)]
    fn densities(&self, x: &[__m256; GROUPS], y: &[__m256; GROUPS]) -> [__m256; GROUPS] {
        let cpu = self.cpu;
        // SAFETY: the token proves the CPU has AVX2. The marginal pair read
        // is CDF values m + j, m + j + 1 <= 2m - 1 (j <= m - 2, see
        // `marginal_segments`); the conditional's is that of
        // `ConditionalLanes::segment`, whose count is at most c - 2 (see
        // `conditional_segments`).
        unsafe {
            let mut inside = [_mm256_setzero_ps(); GROUPS];
            let (mut xs, mut ys) = ([_mm256_setzero_ps(); GROUPS], [_mm256_setzero_ps(); GROUPS]);
            for g in 0..GROUPS {
                inside[g] = _mm256_and_ps(in_unit(cpu, x[g]), in_unit(cpu, y[g]));
                // Outside points search at 0 and are zeroed at the end.
                xs[g] = _mm256_and_ps(x[g], inside[g]);
                ys[g] = _mm256_and_ps(y[g], inside[g]);
            }
            let rows = self.marginal_segments(&ys, false);
            let (conditional, columns) = self.conditional_segments(&rows, &xs, false);
            let mut density = [_mm256_setzero_ps(); GROUPS];
            for g in 0..GROUPS {
                let at = _mm256_add_epi32(self.vertices[g], rows.count[g]);
                let (c0, c1) = self.marginal.gather_pairs(cpu, g, at);
                let row = SegmentLanes {
                    x0: rows.lower[g],
                    x1: rows.upper[g],
                    c0,
                    c1,
                };
                let found = (columns.count[g], columns.lower[g], columns.upper[g]);
                let column = conditional[g].segment(cpu, &self.conditionals, g, found, false);
                let py = segment_density_lanes(cpu, row);
                let px = segment_density_lanes(cpu, column);
                // `pdf` returns 0 for a zero-mass marginal segment before
                // looking at its conditional.
                let zero_row = _mm256_cmp_ps::<_CMP_EQ_OQ>(py, _mm256_setzero_ps());
                let p = _mm256_andnot_ps(zero_row, _mm256_mul_ps(py, px));
                density[g] = _mm256_and_ps(p, inside[g]);
            }
            density
        }
    }
}

/// Store a stage's samples and, with `SAME`, its box tests.
#[inline(always)]
fn store_stage<const SAME: bool>(
    cpu: Avx2,
    drawn: &[(__m256, __m256, __m256, i32); GROUPS],
    out: &mut [Sample2D],
    same: &mut [bool],
) {
    for (g, &(x, y, pdf, bits)) in drawn.iter().enumerate() {
        store_samples(cpu, x, y, pdf, &mut out[8 * g..]);
        if SAME {
            for (l, s) in same[8 * g..8 * g + 8].iter_mut().enumerate() {
                *s = bits & (1 << l) != 0;
            }
        }
    }
}

impl AdaptiveCdf2D {
    /// Whether the lanes paths apply: a marginal of at least two vertices,
    /// at least one stored conditional, and arrays the lanes can index
    /// (at most [`MAX_ENTRIES`] entries).
    pub(super) fn fits_lanes(&self) -> bool {
        self.marginal.len() >= 4
            && self.conditionals.len() >= 4
            && self.conditionals.len() <= MAX_ENTRIES
            && self.marginal.len() <= MAX_ENTRIES
    }

    /// The same samples as `sample`, [`STAGE`] at a time in AVX2 lanes (see
    /// the module documentation), and with `SAME` the box test of every
    /// draw into `same` (as long as `out`); the tail goes one by one.
    ///
    /// # Safety
    /// [`fits_lanes`](Self::fits_lanes) must hold (the token proves AVX2).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_batch_gather<const SAME: bool>(
        &self,
        cpu: Avx2,
        u: &[Vec2],
        out: &mut [Sample2D],
        margin: Vec2,
        same: &mut [bool],
    ) {
        let len = u.len().min(out.len());
        // SAFETY: this distribution fits the lanes (the caller's contract).
        let tables = unsafe { Tables::one(cpu, self) };
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (ux, uy) = load_stage(cpu, &u[range.clone()], true);
            let drawn = tables.draw::<SAME>(&ux, &uy, margin);
            let same = if SAME {
                &mut same[range.clone()]
            } else {
                &mut [][..]
            };
            store_stage::<SAME>(cpu, &drawn, &mut out[range], same);
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
    /// [`fits_lanes`](Self::fits_lanes) must hold (the token proves AVX2).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pdf_batch_gather(&self, cpu: Avx2, p: &[Vec2], out: &mut [f32]) {
        let len = p.len().min(out.len());
        // SAFETY: this distribution fits the lanes (the caller's contract).
        let tables = unsafe { Tables::one(cpu, self) };
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (x, y) = load_stage(cpu, &p[range.clone()], false);
            store_densities(cpu, &tables.densities(&x, &y), &mut out[range]);
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
    #[target_feature(enable = "avx2")]
    pub(super) fn sample_each_gather(
        cpu: Avx2,
        dists: &[&AdaptiveCdf2D],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        for (k, stage) in dists.chunks(STAGE).enumerate() {
            let range = k * STAGE..k * STAGE + stage.len();
            let (u, out, same) = (&u[range.clone()], &mut out[range.clone()], &mut same[range]);
            if let Some(full) = fitting_stage(stage) {
                let (ux, uy) = load_stage(cpu, u, true);
                // SAFETY: every distribution of the stage fits the lanes.
                let tables = unsafe { Tables::each(cpu, full) };
                let drawn = tables.draw::<true>(&ux, &uy, margin);
                store_stage::<true>(cpu, &drawn, out, same);
            } else {
                Self::sample_each_lanes(stage, u, margin, out, same);
            }
        }
    }

    /// [`pdf_each`](Self::pdf_each) in AVX2 lanes, for slices of equal
    /// length (see [`sample_each_gather`](Self::sample_each_gather)).
    #[target_feature(enable = "avx2")]
    pub(super) fn pdf_each_gather(
        cpu: Avx2,
        dists: &[&AdaptiveCdf2D],
        p: &[Vec2],
        out: &mut [f32],
    ) {
        for (k, stage) in dists.chunks(STAGE).enumerate() {
            let range = k * STAGE..k * STAGE + stage.len();
            let (p, out) = (&p[range.clone()], &mut out[range]);
            if let Some(full) = fitting_stage(stage) {
                let (x, y) = load_stage(cpu, p, false);
                // SAFETY: every distribution of the stage fits the lanes.
                let tables = unsafe { Tables::each(cpu, full) };
                store_densities(cpu, &tables.densities(&x, &y), out);
            } else {
                Self::pdf_each_lanes(stage, p, out);
            }
        }
    }
}

/// The stage as [`STAGE`] distributions, if it holds that many and all of
/// them fit the lanes.
#[inline(always)]
fn fitting_stage<'s, 'a>(stage: &'s [&'a AdaptiveCdf2D]) -> Option<&'s [&'a AdaptiveCdf2D; STAGE]> {
    if stage.len() == STAGE && stage.iter().all(|d| d.fits_lanes()) {
        stage.try_into().ok()
    } else {
        None
    }
}

/// Write a stage's densities to `out`.
#[inline(always)]
fn store_densities(cpu: Avx2, density: &[__m256; GROUPS], out: &mut [f32]) {
    for (g, d) in density.iter().enumerate() {
        store_lanes(cpu, *d, &mut out[8 * g..8 * g + 8]);
    }
}

impl AdaptiveCdf1D {
    /// The inner CDF values c_1, ..., c_{m-1} (the last is 1) as a list
    /// the lanes can search, when the lanes path applies: two vertices or
    /// more, at most [`MAX_ENTRIES`] entries.
    pub(super) fn lane_list(&self) -> Option<SharedList<'_>> {
        if self.vertices.len() < 4 || self.vertices.len() > MAX_ENTRIES {
            return None;
        }
        SharedList::new(&self.vertices[self.vertices.len() / 2 + 1..])
    }

    /// The same samples as `sample`, [`STAGE`] at a time in AVX2 lanes:
    /// the segment search as the 2D marginal's, then
    /// `curve::segment_samples` in lanes; the tail one by one. `run` is
    /// this curve's [`lane_list`](Self::lane_list).
    #[target_feature(enable = "avx2")]
    pub(super) fn sample_batch_gather(
        &self,
        cpu: Avx2,
        run: SharedList<'_>,
        u: &[f32],
        out: &mut [Sample1D],
    ) {
        let len = u.len().min(out.len());
        let vertices = Shared::new(&self.vertices);
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (u, out) = (&u[range.clone()], &mut out[range]);
            let v = load_stage_1d(cpu, u);
            let segments = Bracket::search_shared(cpu, run, &v);
            for g in 0..GROUPS {
                // SAFETY: the segment i is the count of inner CDF values
                // <= v, at most m - 2 (the last is 1, above every v), so
                // positions i and i + 1 are vertices.
                let (x0, x1) = unsafe { vertices.gather_pairs(cpu, g, segments.count[g]) };
                let segment = SegmentLanes {
                    x0,
                    x1,
                    c0: segments.lower[g],
                    c1: segments.upper[g],
                };
                let (x, pdf) = segment_samples_lanes(cpu, segment, v[g]);
                store_samples_1d(cpu, x, pdf, &mut out[8 * g..8 * g + 8]);
            }
        }
        for k in stages * STAGE..len {
            out[k] = acdf_core::Distribution1D::sample(self, u[k]);
        }
    }
}
