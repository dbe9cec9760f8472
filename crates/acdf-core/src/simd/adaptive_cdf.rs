//! The batch kernels of the adaptive distributions of `acdf-adaptive-cdf`
//! (its `AdaptiveCdf2D` and `AdaptiveCdf1D`) in AVX2 lanes.
//!
//! The kernels read a distribution through a plain view of its arrays:
//! [`AdaptiveTable`] (a 2D table: marginal, offsets, conditionals) and
//! [`AdaptiveCurve`] (a 1D curve). Each kernel draws (or looks up) whole
//! stages of [`STAGE`] entries and returns how many entries it wrote (none
//! for a table whose sizes the lanes cannot read, see below); the caller's
//! plain code does the rest, so every kernel stands for the plain code of
//! the entries it writes:
//! - [`sample_batch`], [`sample_batch_and_same_cell`] and [`pdf_batch`]:
//!   one table for every entry;
//! - [`sample_each_and_same_cell`] and [`pdf_each`]: one stage, each lane
//!   reading its own table (the slices of a wavefront of shading points);
//! - [`sample_batch_1d`]: one curve for every entry.
//!
//! **The searches.** They are those of [`search::lanes`](crate::search::lanes):
//! binary lifting, the same number of steps in every lane, one gather per
//! step. In a batch the marginal is shared by every draw, so its first four
//! steps compare with block ends held in registers; in the `_each` forms
//! every lane reads its own marginal and every step is a gather. Each
//! draw's conditional is its own short list, searched for as many steps
//! as the longest conditional of the stage's tables needs (a number each
//! table carries, so no lane is read to learn it). A search brackets u by
//! the segment's CDF values (x by its positions, for densities), and one
//! paired read per curve fetches the other two ends of the segment.
//!
//! **The arithmetic.** The position and density of a draw are those of
//! `curve::segment_samples` of `acdf-adaptive-cdf` (and a density that of
//! `curve::segment_density`), operation for operation, with the clamps as
//! selects and no fused multiply-add, so every kernel's results are bit
//! for bit those of the distribution's `sample` and `pdf`.
//!
//! **Soundness.** The kernels read the arrays at indices held in registers,
//! which no bounds check guards. What keeps every read inside its array:
//! - before a stage, a kernel checks the sizes of the arrays it was handed
//!   (a marginal of 2m entries, m >= 2, m offsets, at least four
//!   conditional entries, arrays of at most [`MAX_ENTRIES`] entries), and
//!   writes nothing where they fail; the `_each` forms take each lane's
//!   sizes from the same call of `table(l)` as the array they bound;
//! - every index that comes from the values is clamped in the registers:
//!   each segment found by a search to the curve's last segment, each
//!   offset to the vertices the conditionals hold (and the first of a pair
//!   to the second), and the number of search steps to what an `i32` index
//!   can take. For a table whose curves end at 1 (above every number
//!   searched for, all below 1), whose offsets are non-decreasing and end
//!   at the conditionals' end, and whose longest conditional is the one it
//!   carries, as a built or decoded table's are, the clamps change nothing.
//!
//! Checking the values instead would read a whole table for every stage
//! of the `_each` forms, whose lanes each bring their own; a clamp costs
//! one integer minimum per eight draws. The sizes are checked by the
//! kernels rather than by the views, as the `_each` forms read each lane's
//! view in three passes (one per array) and keep nothing of it between
//! them but the sizes they check.
//!
//! Every kernel takes an [`Avx2`] token, proof that the CPU runs AVX2, and
//! is `#[inline(always)]` down to the intrinsics, so that it compiles into
//! the caller's [`dispatch!`](crate::dispatch!) instance built for AVX2.
//! On other targets than x86-64 no token exists, and the kernels write
//! nothing.

use crate::cpu::Avx2;
use crate::{Sample1D, Sample2D, Vec2};

/// The most entries an array a kernel reads may hold (indices are `i32`
/// lanes): [`search::lanes::MAX_ENTRIES`](crate::search::lanes::MAX_ENTRIES)
/// on x86-64.
#[cfg(target_arch = "x86_64")]
pub const MAX_ENTRIES: usize = crate::search::lanes::MAX_ENTRIES;
/// The most entries an array a kernel reads may hold (indices are `i32`
/// lanes).
#[cfg(not(target_arch = "x86_64"))]
pub const MAX_ENTRIES: usize = (i32::MAX / 4) as usize;

/// The entries a kernel draws together:
/// [`search::lanes::STAGE`](crate::search::lanes::STAGE) on x86-64.
#[cfg(target_arch = "x86_64")]
pub const STAGE: usize = crate::search::lanes::STAGE;
/// The entries a kernel draws together.
#[cfg(not(target_arch = "x86_64"))]
pub const STAGE: usize = 32;

/// A 2D adaptive table as the kernels read it: a marginal curve over y
/// and, for each of its segments, a conditional curve over x, each curve
/// stored as its m vertex positions followed by its m CDF values.
///
/// A plain view: any arrays make one, and the kernels check the sizes
/// they read (see the module documentation).
#[derive(Debug, Clone, Copy)]
pub struct AdaptiveTable<'a> {
    /// The marginal's m positions, then its m CDF values.
    pub marginal: &'a [f32],
    /// o_0, ..., o_{m-1}: conditional j occupies
    /// `conditionals[2 o_j .. 2 o_{j+1}]` (fewer than two vertices: the
    /// uniform density).
    pub offsets: &'a [u32],
    /// The conditionals, one after the other.
    pub conditionals: &'a [f32],
    /// The most vertices of any conditional, max o_{j+1} - o_j: the
    /// conditional searches take their number of steps from it.
    pub longest_conditional: usize,
}

/// Whether the lanes can read a table of these sizes: a marginal of 2m
/// entries, m >= 2, m offsets, at least four conditional entries, and
/// arrays of at most [`MAX_ENTRIES`] entries.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
#[inline(always)]
fn fits(marginal: usize, offsets: usize, conditionals: usize) -> bool {
    // Non-short-circuit `&`: a few compares, one branch.
    marginal_fits(marginal) & (offsets == marginal / 2) & conditionals_fit(conditionals)
}

/// Whether the lanes can read a curve of `len` entries: 2m, m >= 2, at
/// most [`MAX_ENTRIES`].
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
#[inline(always)]
fn marginal_fits(len: usize) -> bool {
    len.is_multiple_of(2) & (4..=MAX_ENTRIES).contains(&len)
}

/// Whether the lanes can read conditionals of `len` entries: at least
/// four (the uniform stand-in reads entries 0 and 1), at most
/// [`MAX_ENTRIES`].
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
#[inline(always)]
fn conditionals_fit(len: usize) -> bool {
    (4..=MAX_ENTRIES).contains(&len)
}

/// A 1D adaptive curve as the kernels read it: its m vertex positions
/// followed by its m CDF values. A plain view, as [`AdaptiveTable`].
#[derive(Debug, Clone, Copy)]
pub struct AdaptiveCurve<'a> {
    /// The m positions, then the m CDF values.
    pub vertices: &'a [f32],
}

/// The same samples as `AdaptiveCdf2D::sample` of the table `table`
/// views, bit for bit, for `u[k]` into `out[k]`, for the entries of the
/// whole stages of `min(u.len(), out.len())`; returns how many it wrote
/// (none for a table the lanes cannot read).
#[inline(always)]
pub fn sample_batch(
    cpu: Avx2,
    table: &AdaptiveTable<'_>,
    u: &[Vec2],
    out: &mut [Sample2D],
) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        avx2::sample_batch::<false>(cpu, table, u, out, Vec2::ZERO, &mut [])
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (cpu, table, u, out);
        0
    }
}

/// The same samples and box tests as `AdaptiveCdf2D::sample_and_same_cell`
/// of the table `table` views with `margin`, bit for bit, for `u[k]` into
/// `out[k]` and `same[k]`, for the entries of the whole stages of the
/// shortest of the three slices; returns how many it wrote (none for a
/// table the lanes cannot read).
#[inline(always)]
pub fn sample_batch_and_same_cell(
    cpu: Avx2,
    table: &AdaptiveTable<'_>,
    u: &[Vec2],
    margin: Vec2,
    out: &mut [Sample2D],
    same: &mut [bool],
) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        avx2::sample_batch::<true>(cpu, table, u, out, margin, same)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (cpu, table, u, margin, out, same);
        0
    }
}

/// The same densities as `AdaptiveCdf2D::pdf` of the table `table` views,
/// bit for bit, at `p[k]` into `out[k]`, for the entries of the whole
/// stages of `min(p.len(), out.len())`; returns how many it wrote (none
/// for a table the lanes cannot read).
#[inline(always)]
pub fn pdf_batch(cpu: Avx2, table: &AdaptiveTable<'_>, p: &[Vec2], out: &mut [f32]) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        avx2::pdf_batch(cpu, table, p, out)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (cpu, table, p, out);
        0
    }
}

/// The same samples and box tests as `sample_and_same_cell(u[l], margin)`
/// of the table `table(l)` views, bit for bit, into `out[l]` and
/// `same[l]`, for the [`STAGE`] lanes l of one stage; returns [`STAGE`],
/// or 0 with nothing written when a lane's table is one the lanes cannot
/// read or a slice holds fewer than [`STAGE`] entries. `table` is called
/// three times per lane.
#[inline(always)]
pub fn sample_each_and_same_cell<'a>(
    cpu: Avx2,
    table: impl Fn(usize) -> AdaptiveTable<'a>,
    u: &[Vec2],
    margin: Vec2,
    out: &mut [Sample2D],
    same: &mut [bool],
) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        avx2::sample_each(cpu, table, u, margin, out, same)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (cpu, table, u, margin, out, same);
        0
    }
}

/// The same densities as `pdf(p[l])` of the table `table(l)` views, bit
/// for bit, into `out[l]`, for the [`STAGE`] lanes l of one stage;
/// returns [`STAGE`], or 0 with nothing written when a lane's table is
/// one the lanes cannot read or a slice holds fewer than [`STAGE`]
/// entries. `table` is called three times per lane.
#[inline(always)]
pub fn pdf_each<'a>(
    cpu: Avx2,
    table: impl Fn(usize) -> AdaptiveTable<'a>,
    p: &[Vec2],
    out: &mut [f32],
) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        avx2::pdf_each(cpu, table, p, out)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (cpu, table, p, out);
        0
    }
}

/// The same samples as `AdaptiveCdf1D::sample` of the curve `curve` views,
/// bit for bit, for `u[k]` into `out[k]`, for the entries of the whole
/// stages of `min(u.len(), out.len())`; returns how many it wrote (none
/// for a curve of fewer than two vertices, an odd length or more than
/// [`MAX_ENTRIES`] entries).
#[inline(always)]
pub fn sample_batch_1d(
    cpu: Avx2,
    curve: &AdaptiveCurve<'_>,
    u: &[f32],
    out: &mut [Sample1D],
) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        avx2::sample_batch_1d(cpu, curve, u, out)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (cpu, curve, u, out);
        0
    }
}

/// The AVX2 kernels behind the public functions.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    // The loops over groups index several parallel arrays of registers by
    // the group number; iterator chains over three or four arrays would
    // hide that.
    #![allow(clippy::needless_range_loop)]

    use super::{conditionals_fit, fits, marginal_fits, AdaptiveCurve, AdaptiveTable, MAX_ENTRIES};
    use crate::cpu::Avx2;
    use crate::search::lanes::{
        in_unit, load_i32, load_stage, load_stage_1d, store_lanes, store_samples, store_samples_1d,
        Bracket, PerLane, Shared, SharedList, Source, GROUPS, STAGE,
    };
    use crate::{Sample1D, Sample2D, Vec2, ONE_MINUS_EPSILON};
    use std::arch::x86_64::*;
    use std::cell::Cell;

    /// The ends of the drawn segment of every lane: positions x_i, x_{i+1}
    /// and CDF values c_i, c_{i+1}.
    #[derive(Clone, Copy)]
    struct SegmentLanes {
        x0: __m256,
        x1: __m256,
        c0: __m256,
        c1: __m256,
    }

    /// `curve::segment_samples` for eight lanes: the position
    /// x_i + t (x_{i+1} - x_i) with t = (u - c_i) / (c_{i+1} - c_i) clamped
    /// to [0, 1], then clamped below x_{i+1} and below 1, and the density
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
            // A separate multiply and add, as the plain code rounds them.
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

    /// Where each lane's conditional (that of marginal segment j) is
    /// stored, its offsets clamped into the conditionals: with
    /// o_j <= o_{j+1} <= (the vertices the conditionals hold), every index
    /// below stays inside them.
    #[derive(Clone, Copy)]
    struct ConditionalLanes {
        /// The index of its first vertex position, 2 o_j; 0 where uniform.
        xs_start: __m256i,
        /// Its number of vertices, c = o_{j+1} - o_j.
        count: __m256i,
        /// All ones where it has fewer than two vertices: the uniform
        /// stand-in, whose lanes search entry 0 (any valid index) and are
        /// replaced.
        uniform: __m256i,
        /// The index of the last entry of its inner list (x_1.. or c_1..,
        /// c - 1 entries, the last being 1): c - 2; 0 where uniform.
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

        /// The conditionals of segments `j` in group g, from the offsets
        /// o_j, o_{j+1} clamped to `stored` (the vertices each lane's
        /// conditionals hold, half their entries), o_j then to o_{j+1}.
        ///
        /// # Safety
        /// In every lane, `0 <= j` and `j + 1` indexes the lane's offsets.
        #[inline(always)]
        unsafe fn of<S: Source>(
            cpu: Avx2,
            offsets: &S,
            g: usize,
            j: __m256i,
            stored: __m256i,
        ) -> ConditionalLanes {
            // SAFETY: the token proves the CPU has AVX2; the pair read is
            // inside the offsets by the caller's contract.
            unsafe {
                let (o0, o1) = offsets.gather_pairs(cpu, g, j);
                let (o0, o1) = (_mm256_castps_si256(o0), _mm256_castps_si256(o1));
                // Unsigned, as the offsets are stored.
                let o1 = _mm256_min_epu32(o1, stored);
                let o0 = _mm256_min_epu32(o0, o1);
                let count = _mm256_sub_epi32(o1, o0);
                let uniform = _mm256_cmpgt_epi32(_mm256_set1_epi32(2), count);
                ConditionalLanes {
                    xs_start: _mm256_andnot_si256(uniform, _mm256_add_epi32(o0, o0)),
                    count,
                    uniform,
                    last: _mm256_andnot_si256(
                        uniform,
                        _mm256_sub_epi32(count, _mm256_set1_epi32(2)),
                    ),
                }
            }
        }

        /// The start of its inner CDF values c_1, ... (`cdfs`) or inner
        /// positions x_1, ... (`!cdfs`); 0 where uniform.
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

        /// The segment ends from a search `found` over its inner list
        /// (the count clamped to `last`, which is also 0 where uniform) and
        /// the other pair read from `conditionals` (positions after a
        /// search of CDF values, CDF values after a search of positions);
        /// the uniform stand-in's segment (0, 0) to (1, 1) where uniform.
        ///
        /// # Safety
        /// These are conditionals from [`of`](Self::of) over the offsets
        /// of tables whose `conditionals` hold at least four entries, and
        /// the count of `found` is at least 0 in every lane.
        #[inline(always)]
        unsafe fn segment<S: Source>(
            &self,
            cpu: Avx2,
            conditionals: &S,
            g: usize,
            found: (__m256i, __m256, __m256),
            searched_cdfs: bool,
        ) -> SegmentLanes {
            // SAFETY: the token proves the CPU has AVX2. With k clamped to
            // c - 2, the pair read starts at xs_start + k (positions k,
            // k + 1 <= c - 1) or xs_start + c + k (CDF values k, k + 1),
            // inside the conditional's 2c entries from 2 o_j, which end by
            // 2 o_{j+1} <= the array's length (see `of`); uniform lanes
            // read entries 0 and 1 (the array holds at least four).
            unsafe {
                let (k, lower, upper) = found;
                let k = _mm256_min_epi32(k, self.last);
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
    /// [0, 1) and inside the drawn segment [x_i, x_{i+1}); all ones where
    /// it is.
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

    /// The tables a stage's lanes read: their three arrays, where the
    /// lanes read them from, each marginal's vertex count m and each
    /// table's stored conditional vertices.
    ///
    /// Only [`Tables::one`] and [`Tables::each`] make one, after checking
    /// the sizes of every lane's arrays: a marginal of m >= 2 vertices,
    /// m offsets, at least four conditional entries, arrays of at most
    /// `MAX_ENTRIES`. The searches clamp what they find from the values
    /// into these sizes (see the module documentation).
    struct Tables<'a, S> {
        cpu: Avx2,
        marginal: S,
        offsets: S,
        conditionals: S,
        /// m of each lane.
        vertices: [__m256i; GROUPS],
        /// Half the conditional entries of each lane: the clamp of its
        /// offsets.
        stored: [__m256i; GROUPS],
        /// The one marginal of every lane (a batch), whose first search
        /// steps can then come from registers.
        shared: Option<&'a [f32]>,
        /// The first lifting step of the marginal searches (without
        /// `shared`) and of the conditional searches: half the longest
        /// list of the stage's tables, rounded up to a power of two, known
        /// before any lane's list is read. Taken instead from the longest
        /// list the stage's lanes had found, it would need a horizontal
        /// maximum of their lengths between the marginal and the
        /// conditional searches, which waits for every lane's marginal
        /// search; known up front, it adds nothing to that chain, at the
        /// price of the steps that lanes whose lists are all shorter would
        /// not need.
        marginal_step: usize,
        conditional_step: usize,
    }

    /// The first lifting step for inner lists of up to `vertices - 1`
    /// entries (see [`Bracket::lift`]): their last index `vertices - 2`,
    /// plus one, rounded up to a power of two, halved; 0 below two
    /// vertices. `vertices` is taken at most `MAX_ENTRIES / 2` (no array
    /// holds longer curves), so that no probe index overflows an `i32`
    /// whatever number a table carries.
    fn first_step(vertices: usize) -> usize {
        (vertices.clamp(2, MAX_ENTRIES / 2) - 1).next_power_of_two() / 2
    }

    impl<'a> Tables<'a, Shared<'a>> {
        /// Every lane reads `t`; `None` if the lanes cannot read it.
        #[inline(always)]
        fn one(cpu: Avx2, t: &AdaptiveTable<'a>) -> Option<Self> {
            if !fits(t.marginal.len(), t.offsets.len(), t.conditionals.len()) {
                return None;
            }
            let m = t.marginal.len() / 2;
            // SAFETY: the token proves the CPU has AVX2.
            let (vertices, stored) = unsafe {
                (
                    [_mm256_set1_epi32(m as i32); GROUPS],
                    [_mm256_set1_epi32((t.conditionals.len() / 2) as i32); GROUPS],
                )
            };
            Some(Tables {
                cpu,
                marginal: Shared::new(t.marginal),
                offsets: Shared::new(t.offsets),
                conditionals: Shared::new(t.conditionals),
                vertices,
                stored,
                shared: Some(t.marginal),
                marginal_step: first_step(m),
                conditional_step: first_step(t.longest_conditional),
            })
        }
    }

    impl<'a> Tables<'a, PerLane<'a>> {
        /// Lane l reads `table(l)`; `None` if the lanes cannot read a
        /// lane's table.
        ///
        /// Each array's lanes are made by one pass over the lanes, which
        /// calls `table(l)` and keeps the array and the sizes that bound
        /// its reads, from that same call: the marginal's m, the offsets'
        /// length (which must be m), the conditionals' stored vertices.
        /// Nothing else is kept between the passes, so that a stage needs
        /// no copy of its lanes' views.
        #[inline(always)]
        fn each(cpu: Avx2, table: impl Fn(usize) -> AdaptiveTable<'a>) -> Option<Self> {
            let fits = Cell::new(true);
            let (mut m, mut stored) = ([0i32; STAGE], [0i32; STAGE]);
            let (m_of, stored_of) = (
                Cell::from_mut(&mut m[..]).as_slice_of_cells(),
                Cell::from_mut(&mut stored[..]).as_slice_of_cells(),
            );
            let longest_conditional = Cell::new(0);
            let marginal = PerLane::new(cpu, |l| {
                let t = table(l);
                let len = t.marginal.len();
                fits.set(fits.get() & marginal_fits(len));
                m_of[l].set((len / 2) as i32);
                longest_conditional.set(longest_conditional.get().max(t.longest_conditional));
                t.marginal
            });
            let offsets = PerLane::new(cpu, |l| {
                let offsets = table(l).offsets;
                fits.set(fits.get() & (offsets.len() == m_of[l].get() as usize));
                offsets
            });
            let conditionals = PerLane::new(cpu, |l| {
                let conditionals = table(l).conditionals;
                fits.set(fits.get() & conditionals_fit(conditionals.len()));
                stored_of[l].set((conditionals.len() / 2) as i32);
                conditionals
            });
            if !fits.get() {
                return None;
            }
            let longest_marginal = m.iter().fold(0, |a, &b| a.max(b)) as usize;
            Some(Tables {
                cpu,
                marginal,
                offsets,
                conditionals,
                vertices: std::array::from_fn(|g| load_i32(cpu, &m[8 * g..])),
                stored: std::array::from_fn(|g| load_i32(cpu, &stored[8 * g..])),
                shared: None,
                marginal_step: first_step(longest_marginal),
                conditional_step: first_step(longest_conditional.get()),
            })
        }
    }

    impl<S: Source> Tables<'_, S> {
        /// The marginal segment of every lane: the count of inner vertex
        /// values `<= v` among the marginal's positions (`cdfs` false) or
        /// CDF values (`cdfs` true), bracketed by the values on either
        /// side, clamped to m - 2 (which a marginal ending at 1, above
        /// every v searched, never exceeds).
        #[inline(always)]
        fn marginal_segments(&self, v: &[__m256; GROUPS], cdfs: bool) -> Bracket {
            let cpu = self.cpu;
            // SAFETY: the token proves the CPU has AVX2. The lanes search
            // entries `start .. start + m - 1` of their marginal (2m
            // entries, m >= 2, see `Tables`): 1 ..= m - 1 or
            // m + 1 ..= 2m - 1, starting from a fresh bracket or
            // `shared_top` over that same inner list.
            unsafe {
                let one = _mm256_set1_epi32(1);
                // The inner list starts at index 1 (positions) or m + 1
                // (CDF values) and holds m - 1 entries, the last being 1.
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
                    Some(marginal) => {
                        let m = marginal.len() / 2;
                        let run = if cdfs {
                            &marginal[m + 1..]
                        } else {
                            &marginal[1..m]
                        };
                        rows.shared_top(cpu, run, v)
                    }
                    None => self.marginal_step,
                };
                rows.lift(cpu, &self.marginal, &start, &last, v, step);
                for g in 0..GROUPS {
                    rows.count[g] = _mm256_min_epi32(rows.count[g], last[g]);
                }
                rows
            }
        }

        /// The conditional of every lane's marginal segment, and the
        /// segment of each conditional holding `v` (searched among its CDF
        /// values or positions, as `cdfs` says).
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
            // (m of them). A conditional of c >= 2 vertices, its offsets
            // clamped by `ConditionalLanes::of`, occupies entries
            // 2 o_j .. 2 o_j + 2c inside the conditionals, and its lanes
            // search the c - 1 inner values from `inner`; uniform lanes
            // search entry 0 alone (the array holds at least four).
            unsafe {
                let mut conditional = [ConditionalLanes::none(cpu); GROUPS];
                let (mut start, mut last) = (
                    [_mm256_setzero_si256(); GROUPS],
                    [_mm256_setzero_si256(); GROUPS],
                );
                for g in 0..GROUPS {
                    conditional[g] =
                        ConditionalLanes::of(cpu, &self.offsets, g, rows.count[g], self.stored[g]);
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

        /// The samples of a stage for clamped `ux`, `uy`: positions x and
        /// y, densities, and (with `SAME`) the box tests, all ones in the
        /// lanes where the box lies in the drawn cell.
        #[inline(always)]
        fn draw<const SAME: bool>(
            &self,
            ux: &[__m256; GROUPS],
            uy: &[__m256; GROUPS],
            margin: Vec2,
        ) -> [(__m256, __m256, __m256, __m256); GROUPS] {
            let cpu = self.cpu;
            let rows = self.marginal_segments(uy, true);
            let (conditional, columns) = self.conditional_segments(&rows, ux, true);
            // SAFETY: the token proves the CPU has AVX2. The marginal pair
            // read is positions j, j + 1 <= m - 1 of the marginal
            // (j <= m - 2, see `marginal_segments`); the conditional's is
            // that of `ConditionalLanes::segment`, whose counts a lifting
            // search leaves at least 0.
            unsafe {
                let zero = _mm256_setzero_ps();
                let mut drawn = [(zero, zero, zero, zero); GROUPS];
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
                        _mm256_and_ps(
                            inside_lanes(cpu, y, margin.y, row),
                            inside_lanes(cpu, x, margin.x, column),
                        )
                    } else {
                        zero
                    };
                    drawn[g] = (x, y, _mm256_mul_ps(pdf_y, pdf_x), same);
                }
                drawn
            }
        }

        /// The densities at a stage's points (x, y), 0 outside [0, 1)^2
        /// (NaN included) and on a zero-mass marginal segment, as `pdf`
        /// gives them.
        #[inline(always)]
        fn densities(&self, x: &[__m256; GROUPS], y: &[__m256; GROUPS]) -> [__m256; GROUPS] {
            let cpu = self.cpu;
            // SAFETY: the token proves the CPU has AVX2.
            let (inside, xs, ys) = unsafe {
                let mut inside = [_mm256_setzero_ps(); GROUPS];
                let (mut xs, mut ys) =
                    ([_mm256_setzero_ps(); GROUPS], [_mm256_setzero_ps(); GROUPS]);
                for g in 0..GROUPS {
                    inside[g] = _mm256_and_ps(in_unit(cpu, x[g]), in_unit(cpu, y[g]));
                    // Outside points search at 0 and are zeroed at the end.
                    xs[g] = _mm256_and_ps(x[g], inside[g]);
                    ys[g] = _mm256_and_ps(y[g], inside[g]);
                }
                (inside, xs, ys)
            };
            let rows = self.marginal_segments(&ys, false);
            let (conditional, columns) = self.conditional_segments(&rows, &xs, false);
            // SAFETY: the token proves the CPU has AVX2. The marginal pair
            // read is CDF values m + j, m + j + 1 <= 2m - 1 (j <= m - 2,
            // see `marginal_segments`); the conditional's is that of
            // `ConditionalLanes::segment`, whose counts a lifting search
            // leaves at least 0.
            unsafe {
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
                    // `pdf` returns 0 for a zero-mass marginal segment
                    // before looking at its conditional.
                    let zero_row = _mm256_cmp_ps::<_CMP_EQ_OQ>(py, _mm256_setzero_ps());
                    let p = _mm256_andnot_ps(zero_row, _mm256_mul_ps(py, px));
                    density[g] = _mm256_and_ps(p, inside[g]);
                }
                density
            }
        }
    }

    /// Store a stage's samples and, with `SAME`, its box tests into
    /// `same[..STAGE]` (which must hold them).
    #[inline(always)]
    fn store_stage<const SAME: bool>(
        cpu: Avx2,
        drawn: &[(__m256, __m256, __m256, __m256); GROUPS],
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        for (g, &(x, y, pdf, _)) in drawn.iter().enumerate() {
            store_samples(cpu, x, y, pdf, &mut out[8 * g..]);
        }
        if SAME {
            let masks = drawn.map(|d| d.3);
            store_bools(cpu, &masks, &mut same[..STAGE]);
        }
    }

    /// The [`STAGE`] lanes of `masks` (all ones or all zeros each) as
    /// bools into `out`, in lane order; panics if `out` holds fewer.
    #[inline(always)]
    fn store_bools(_: Avx2, masks: &[__m256; GROUPS], out: &mut [bool]) {
        const _: () = assert!(GROUPS == 4);
        assert!(out.len() >= STAGE);
        // SAFETY: the token proves the CPU has AVX2; the store writes the
        // 32 bytes of `out[..STAGE]`, checked above, each 0 or 1, which
        // are the bytes of `false` and `true`.
        unsafe {
            let m = |g: usize| _mm256_castps_si256(masks[g]);
            // The saturating packs keep 0 and -1; per 128-bit half they
            // give the four lanes of groups 0, 1, 2, 3 from the low halves
            // of the registers, then from the high halves.
            let bytes = _mm256_packs_epi16(
                _mm256_packs_epi32(m(0), m(1)),
                _mm256_packs_epi32(m(2), m(3)),
            );
            let order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
            let bytes = _mm256_permutevar8x32_epi32(bytes, order);
            let bools = _mm256_and_si256(bytes, _mm256_set1_epi8(1));
            _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, bools);
        }
    }

    /// Write a stage's densities to `out`.
    #[inline(always)]
    fn store_densities(cpu: Avx2, density: &[__m256; GROUPS], out: &mut [f32]) {
        for (g, d) in density.iter().enumerate() {
            store_lanes(cpu, *d, &mut out[8 * g..8 * g + 8]);
        }
    }

    /// [`super::sample_batch`] (`!SAME`) and
    /// [`super::sample_batch_and_same_cell`] (`SAME`).
    #[inline(always)]
    pub(super) fn sample_batch<const SAME: bool>(
        cpu: Avx2,
        table: &AdaptiveTable<'_>,
        u: &[Vec2],
        out: &mut [Sample2D],
        margin: Vec2,
        same: &mut [bool],
    ) -> usize {
        let mut len = u.len().min(out.len());
        if SAME {
            len = len.min(same.len());
        }
        let Some(tables) = Tables::one(cpu, table) else {
            return 0;
        };
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
        stages * STAGE
    }

    /// [`super::pdf_batch`].
    #[inline(always)]
    pub(super) fn pdf_batch(
        cpu: Avx2,
        table: &AdaptiveTable<'_>,
        p: &[Vec2],
        out: &mut [f32],
    ) -> usize {
        let len = p.len().min(out.len());
        let Some(tables) = Tables::one(cpu, table) else {
            return 0;
        };
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (x, y) = load_stage(cpu, &p[range.clone()], false);
            store_densities(cpu, &tables.densities(&x, &y), &mut out[range]);
        }
        stages * STAGE
    }

    /// [`super::sample_each_and_same_cell`].
    #[inline(always)]
    pub(super) fn sample_each<'a>(
        cpu: Avx2,
        table: impl Fn(usize) -> AdaptiveTable<'a>,
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) -> usize {
        if u.len().min(out.len()).min(same.len()) < STAGE {
            return 0;
        }
        let Some(tables) = Tables::each(cpu, table) else {
            return 0;
        };
        let (ux, uy) = load_stage(cpu, u, true);
        let drawn = tables.draw::<true>(&ux, &uy, margin);
        store_stage::<true>(cpu, &drawn, out, same);
        STAGE
    }

    /// [`super::pdf_each`].
    #[inline(always)]
    pub(super) fn pdf_each<'a>(
        cpu: Avx2,
        table: impl Fn(usize) -> AdaptiveTable<'a>,
        p: &[Vec2],
        out: &mut [f32],
    ) -> usize {
        if p.len().min(out.len()) < STAGE {
            return 0;
        }
        let Some(tables) = Tables::each(cpu, table) else {
            return 0;
        };
        let (x, y) = load_stage(cpu, p, false);
        store_densities(cpu, &tables.densities(&x, &y), out);
        STAGE
    }

    /// [`super::sample_batch_1d`]: the segment search as the 2D
    /// marginal's, then `curve::segment_samples` in lanes.
    #[inline(always)]
    pub(super) fn sample_batch_1d(
        cpu: Avx2,
        curve: &AdaptiveCurve<'_>,
        u: &[f32],
        out: &mut [Sample1D],
    ) -> usize {
        let vertices = curve.vertices;
        if !marginal_fits(vertices.len()) {
            return 0;
        }
        // The inner CDF values c_1, ..., c_{m-1}: at least one entry
        // (m >= 2) and at most MAX_ENTRIES.
        let Some(run) = SharedList::new(&vertices[vertices.len() / 2 + 1..]) else {
            return 0;
        };
        let len = u.len().min(out.len());
        let positions = Shared::new(vertices);
        // SAFETY: the token proves the CPU has AVX2.
        let last = unsafe { _mm256_set1_epi32((vertices.len() / 2 - 2) as i32) };
        let stages = len / STAGE;
        for k in 0..stages {
            let range = k * STAGE..(k + 1) * STAGE;
            let (u, out) = (&u[range.clone()], &mut out[range]);
            let v = load_stage_1d(cpu, u);
            let segments = Bracket::search_shared(cpu, run, &v);
            for g in 0..GROUPS {
                // SAFETY: the token proves the CPU has AVX2; the segment i
                // is clamped to m - 2 (a no-op where the last inner CDF
                // value is 1, above every clamped v), so positions i and
                // i + 1 are vertices.
                let (x0, x1) = unsafe {
                    let i = _mm256_min_epi32(segments.count[g], last);
                    positions.gather_pairs(cpu, g, i)
                };
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
        stages * STAGE
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{clamp_unit, ONE_MINUS_EPSILON};

    /// A stream of numbers in [0, 1).
    fn stream(mut state: u64) -> impl FnMut() -> f32 {
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// A curve of `m` vertices from 0 to 1 as its positions then its CDF
    /// values: positions increasing, CDF values non-decreasing with flat
    /// runs (zero-mass segments) where `next` says so.
    fn curve(m: usize, next: &mut impl FnMut() -> f32) -> Vec<f32> {
        let mut xs: Vec<f32> = (0..m - 2).map(|_| next()).collect();
        xs.sort_by(f32::total_cmp);
        xs.dedup();
        xs.retain(|&x| x > 0.0);
        let m = xs.len() + 2;
        let mut cs: Vec<f32> = (0..m - 2).map(|_| next()).collect();
        cs.sort_by(f32::total_cmp);
        for k in 1..cs.len() {
            if next() < 0.3 {
                cs[k] = cs[k - 1];
            }
        }
        let mut v = vec![0.0];
        v.extend(xs);
        v.push(1.0);
        v.push(0.0);
        v.extend(cs);
        v.push(1.0);
        v
    }

    /// A well-formed table: the marginal, the offsets, the conditionals
    /// (some empty or of one vertex: the uniform stand-in) and the longest
    /// conditional.
    struct Table {
        marginal: Vec<f32>,
        offsets: Vec<u32>,
        conditionals: Vec<f32>,
        longest: usize,
    }

    impl Table {
        fn random(next: &mut impl FnMut() -> f32) -> Table {
            let marginal = curve(2 + (next() * 40.0) as usize, next);
            let m = marginal.len() / 2;
            let (mut offsets, mut conditionals, mut longest) = (vec![0u32], Vec::new(), 0);
            for _ in 0..m - 1 {
                let pick = next();
                if pick < 0.15 {
                    // Empty, or a single vertex: the uniform stand-in.
                    if pick < 0.05 {
                        conditionals.extend([0.0, 0.0]);
                    }
                } else {
                    let c = curve(2 + (next() * 45.0) as usize, next);
                    conditionals.extend(&c);
                }
                offsets.push((conditionals.len() / 2) as u32);
            }
            for w in offsets.windows(2) {
                longest = longest.max((w[1] - w[0]) as usize);
            }
            if conditionals.len() < 4 {
                conditionals.extend(curve(2, next));
            }
            Table {
                marginal,
                offsets,
                conditionals,
                longest,
            }
        }

        fn view(&self) -> AdaptiveTable<'_> {
            AdaptiveTable {
                marginal: &self.marginal,
                offsets: &self.offsets,
                conditionals: &self.conditionals,
                longest_conditional: self.longest,
            }
        }

        /// Conditional j as positions then CDF values (empty for the
        /// uniform stand-in).
        fn conditional(&self, j: usize) -> &[f32] {
            let (a, b) = (self.offsets[j] as usize, self.offsets[j + 1] as usize);
            if b - a < 2 {
                &[]
            } else {
                &self.conditionals[2 * a..2 * b]
            }
        }

        /// `sample_and_same_cell`, written out plainly.
        fn sample(&self, u: Vec2, margin: Vec2) -> (Sample2D, bool) {
            let (y, py, j, row) = plain_sample(&self.marginal, u.y);
            let (x, px, _, column) = plain_sample(self.conditional(j), u.x);
            let inside = |x: f32, m: f32, (x0, x1): (f32, f32)| {
                x - m >= 0.0 && x + m < 1.0 && x - m >= x0 && x + m < x1
            };
            let same = inside(y, margin.y, row) && inside(x, margin.x, column);
            let s = Sample2D {
                p: Vec2::new(x, y),
                pdf: py * px,
            };
            (s, same)
        }

        /// `pdf`, written out plainly.
        fn pdf(&self, p: Vec2) -> f32 {
            if !((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y)) {
                return 0.0;
            }
            let (j, py) = plain_density(&self.marginal, p.y);
            if py == 0.0 {
                return 0.0;
            }
            py * plain_density(self.conditional(j), p.x).1
        }
    }

    /// The draw of a curve (positions then CDF values; empty: uniform):
    /// position, density, segment and its ends.
    fn plain_sample(curve: &[f32], u: f32) -> (f32, f32, usize, (f32, f32)) {
        let u = clamp_unit(u);
        if curve.is_empty() {
            return (u, 1.0, 0, (0.0, 1.0));
        }
        let m = curve.len() / 2;
        let (xs, cs) = curve.split_at(m);
        let i = cs[1..].partition_point(|&c| c <= u);
        let (x0, x1, c0, c1) = (xs[i], xs[i + 1], cs[i], cs[i + 1]);
        let mut t = (u - c0) / (c1 - c0);
        t = if t < 0.0 { 0.0 } else { t };
        t = if t > 1.0 { 1.0 } else { t };
        let x = x0 + t * (x1 - x0);
        let below = f32::from_bits(x1.to_bits() - 1);
        let top = if below > ONE_MINUS_EPSILON {
            ONE_MINUS_EPSILON
        } else {
            below
        };
        let x = if x > top { top } else { x };
        (x, (c1 - c0) / (x1 - x0), i, (x0, x1))
    }

    /// The segment of a curve holding x in [0, 1), and its density.
    fn plain_density(curve: &[f32], x: f32) -> (usize, f32) {
        if curve.is_empty() {
            return (0, 1.0);
        }
        let m = curve.len() / 2;
        let (xs, cs) = curve.split_at(m);
        let i = xs[1..].partition_point(|&e| e <= x);
        (i, (cs[i + 1] - cs[i]) / (xs[i + 1] - xs[i]))
    }

    /// The numbers to draw with: random ones, the ends, and some beyond.
    fn numbers(n: usize, next: &mut impl FnMut() -> f32) -> Vec<Vec2> {
        let specials = [0.0, -0.0, ONE_MINUS_EPSILON, 1.0, -1.0, 2.0, f32::NAN];
        (0..n)
            .map(|k| {
                let special = |k: usize| specials[k % specials.len()];
                match k % 11 {
                    3 => Vec2::new(special(k / 11), next()),
                    7 => Vec2::new(next(), special(k / 11)),
                    _ => Vec2::new(next(), next()),
                }
            })
            .collect()
    }

    /// The token, or a printed line saying the test is skipped.
    fn avx2() -> Option<Avx2> {
        let cpu = crate::cpu::avx2();
        if cpu.is_none() {
            println!("skipped: this CPU has no AVX2 and FMA (or ACDF_CPU=portable)");
        }
        cpu
    }

    /// The kernels draw nothing from tables whose sizes the lanes cannot
    /// read, and leave their outputs alone.
    #[test]
    fn kernels_refuse_tables_of_the_wrong_sizes() {
        let Some(cpu) = avx2() else { return };
        let marginal = [0.0, 0.5, 1.0, 0.0, 0.25, 1.0];
        let conditionals = [0.0, 1.0, 0.0, 1.0];
        let table = |marginal, offsets, conditionals| AdaptiveTable {
            marginal,
            offsets,
            conditionals,
            longest_conditional: 2,
        };
        let good = table(&marginal[..], &[0, 0, 2][..], &conditionals[..]);
        let bad = [
            // Too few offsets, too many.
            table(&marginal[..], &[0, 2][..], &conditionals[..]),
            table(&marginal[..], &[0, 0, 2, 2][..], &conditionals[..]),
            // A marginal of one vertex, of an odd length.
            table(&marginal[..2], &[0][..], &conditionals[..]),
            table(&marginal[..5], &[0, 2][..], &conditionals[..]),
            // Fewer than four conditional entries.
            table(&marginal[..], &[0, 0, 1][..], &conditionals[..2]),
        ];
        let u = vec![Vec2::splat(0.5); STAGE];
        let margin = Vec2::splat(1e-3);
        let (mut out, mut same) = (vec![Sample2D::default(); STAGE], vec![false; STAGE]);
        let mut density = vec![0.0f32; STAGE];
        assert_eq!(sample_batch(cpu, &good, &u, &mut out), STAGE);
        for t in &bad {
            let (mut out, mut same) = (vec![Sample2D::default(); STAGE], vec![false; STAGE]);
            assert_eq!(sample_batch(cpu, t, &u, &mut out), 0);
            assert_eq!(
                sample_batch_and_same_cell(cpu, t, &u, margin, &mut out, &mut same),
                0
            );
            assert_eq!(pdf_batch(cpu, t, &u, &mut density), 0);
            // One lane of a stage with the bad table.
            let lane = |l: usize| if l == 20 { *t } else { good };
            assert_eq!(
                sample_each_and_same_cell(cpu, lane, &u, margin, &mut out, &mut same),
                0
            );
            assert_eq!(pdf_each(cpu, lane, &u, &mut density), 0);
            assert_eq!(out, vec![Sample2D::default(); STAGE]);
            assert_eq!(same, vec![false; STAGE]);
        }
        let each = |_: usize| good;
        assert_eq!(
            sample_each_and_same_cell(cpu, each, &u, margin, &mut out, &mut same),
            STAGE
        );
        let u1 = vec![0.5f32; STAGE];
        let mut out1 = vec![Sample1D::default(); STAGE];
        for (vertices, drawn) in [
            (&marginal[..], STAGE),
            (&marginal[..2], 0),
            (&marginal[..5], 0),
        ] {
            let curve = AdaptiveCurve { vertices };
            assert_eq!(sample_batch_1d(cpu, &curve, &u1, &mut out1), drawn);
        }
    }

    /// Every kernel gives the plain draws, box tests and densities bit for
    /// bit, writes whole stages only, and leaves the rest alone.
    #[test]
    fn kernels_give_the_plain_results() {
        let Some(cpu) = avx2() else { return };
        let mut next = stream(17);
        let tables: Vec<Table> = (0..40).map(|_| Table::random(&mut next)).collect();
        let margin = Vec2::splat(1e-3);
        let n = 3 * STAGE + 5;
        for t in &tables {
            let view = t.view();
            let u = numbers(n, &mut next);
            let mut out = vec![Sample2D::default(); n];
            let mut same = vec![false; n];
            assert_eq!(sample_batch(cpu, &view, &u, &mut out), 3 * STAGE);
            for k in 0..3 * STAGE {
                assert_eq!(out[k], t.sample(u[k], margin).0, "u {}", u[k]);
            }
            assert_eq!(out[3 * STAGE..], [Sample2D::default(); 5]);
            out.fill(Sample2D::default());
            let done = sample_batch_and_same_cell(cpu, &view, &u, margin, &mut out, &mut same);
            assert_eq!(done, 3 * STAGE);
            for k in 0..done {
                assert_eq!((out[k], same[k]), t.sample(u[k], margin), "u {}", u[k]);
            }
            // Points on the vertices, at the draws, outside and NaN.
            let mut p: Vec<Vec2> = out[..done].iter().map(|s| s.p).collect();
            p.extend(u[..done].iter().copied());
            let m = t.marginal.len() / 2;
            p.extend(t.marginal[..m].iter().map(|&y| Vec2::new(0.5, y)));
            p.extend(t.conditionals.iter().map(|&x| Vec2::new(x, 0.3)));
            let mut density = vec![0.0f32; p.len()];
            let done = pdf_batch(cpu, &view, &p, &mut density);
            assert_eq!(done, p.len() / STAGE * STAGE);
            for k in 0..done {
                assert_eq!(density[k].to_bits(), t.pdf(p[k]).to_bits(), "p {}", p[k]);
            }
        }
        // A table per lane.
        let u = numbers(STAGE, &mut next);
        let lanes: Vec<&Table> = (0..STAGE)
            .map(|l| &tables[(l * 7) % tables.len()])
            .collect();
        let (mut out, mut same) = (vec![Sample2D::default(); STAGE], vec![false; STAGE]);
        let view = |l: usize| lanes[l].view();
        assert_eq!(
            sample_each_and_same_cell(cpu, view, &u, margin, &mut out, &mut same),
            STAGE
        );
        for l in 0..STAGE {
            assert_eq!((out[l], same[l]), lanes[l].sample(u[l], margin), "lane {l}");
        }
        let p: Vec<Vec2> = (0..STAGE).map(|l| out[(l + 3) % STAGE].p).collect();
        let mut density = vec![0.0f32; STAGE];
        assert_eq!(pdf_each(cpu, view, &p, &mut density), STAGE);
        for l in 0..STAGE {
            assert_eq!(
                density[l].to_bits(),
                lanes[l].pdf(p[l]).to_bits(),
                "lane {l}"
            );
        }
        // A stage too short: nothing written.
        let (mut out, mut same) = (vec![Sample2D::default(); STAGE], vec![false; STAGE]);
        assert_eq!(
            sample_each_and_same_cell(cpu, view, &u[1..], margin, &mut out, &mut same),
            0
        );
        assert_eq!(pdf_each(cpu, view, &p[1..], &mut density[1..]), 0);
        assert_eq!(out, vec![Sample2D::default(); STAGE]);
        // The 1D kernel on the marginals.
        for t in &tables {
            let curve = AdaptiveCurve {
                vertices: &t.marginal,
            };
            let u: Vec<f32> = numbers(n, &mut next).iter().map(|p| p.y).collect();
            let mut out = vec![Sample1D::default(); n];
            assert_eq!(sample_batch_1d(cpu, &curve, &u, &mut out), 3 * STAGE);
            for k in 0..3 * STAGE {
                let (x, pdf, _, _) = plain_sample(&t.marginal, u[k]);
                assert_eq!(out[k], Sample1D { x, pdf }, "u {}", u[k]);
            }
        }
    }

    /// Tables that are not well formed (offsets out of order or past the
    /// conditionals, curves that do not end at 1, NaN, a wrong longest
    /// conditional) keep every read inside their arrays: the kernels run
    /// through them (their results are not the point).
    #[test]
    fn malformed_tables_are_read_inside_their_arrays() {
        let Some(cpu) = avx2() else { return };
        let mut next = stream(29);
        let margin = Vec2::splat(1e-3);
        for round in 0..200 {
            let m = 2 + (next() * 30.0) as usize;
            let c = 4 + (next() * 60.0) as usize;
            let mut garbage = |n: usize| -> Vec<f32> {
                (0..n)
                    .map(|k| match (k + round) % 7 {
                        0 => f32::NAN,
                        1 => -1.0,
                        2 => 0.5,
                        _ => next() * 3.0 - 1.0,
                    })
                    .collect()
            };
            let marginal = garbage(2 * m);
            let conditionals = garbage(c);
            let offsets: Vec<u32> = (0..m)
                .map(|k| match (k + round) % 5 {
                    0 => u32::MAX,
                    1 => (next() * 1e9) as u32,
                    2 => (next() * 40.0) as u32,
                    _ => 1 << 31,
                })
                .collect();
            let longest = [0, 1, 7, 1 << 20, usize::MAX][round % 5];
            let view = AdaptiveTable {
                marginal: &marginal,
                offsets: &offsets,
                conditionals: &conditionals,
                longest_conditional: longest,
            };
            let u = numbers(2 * STAGE, &mut next);
            let mut out = vec![Sample2D::default(); 2 * STAGE];
            let mut same = vec![false; 2 * STAGE];
            let mut density = vec![0.0f32; 2 * STAGE];
            sample_batch(cpu, &view, &u, &mut out);
            sample_batch_and_same_cell(cpu, &view, &u, margin, &mut out, &mut same);
            pdf_batch(cpu, &view, &u, &mut density);
            let each = |_: usize| view;
            sample_each_and_same_cell(cpu, each, &u, margin, &mut out, &mut same);
            pdf_each(cpu, each, &u, &mut density);
            let curve = AdaptiveCurve {
                vertices: &marginal,
            };
            let u1: Vec<f32> = u.iter().map(|p| p.x).collect();
            let mut out1 = vec![Sample1D::default(); 2 * STAGE];
            sample_batch_1d(cpu, &curve, &u1, &mut out1);
        }
    }
}
