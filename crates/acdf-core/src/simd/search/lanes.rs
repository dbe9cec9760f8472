//! The inverse-CDF search for many draws at once, in 8-wide AVX2 lanes:
//! the batch paths of the distributions (and through them the samplers')
//! use it.
//!
//! A scalar draw is a chain of dependent loads with bookkeeping between
//! them. Here eight draws share every instruction, and [`GROUPS`] groups of
//! eight advance together, step by step, so that the loads of one group
//! hide the latency of the others'. The search is binary lifting: its steps
//! are fixed by the length of the list, not by the data, so it needs no
//! branch, every step of every lane is one gather, and different lanes can
//! search different lists (each draw's own conditional).
//!
//! The count found is exactly that of a plain search (the number of entries
//! `<= u`), so the cell or segment a batch lands in is the one `sample`
//! finds. The search also returns the entries on both sides of it, which
//! are the edges of the drawn cell, so no further loads are needed for them.
//!
//! **What is checked, and where.** Every function here takes an
//! [`Avx2`] token, which only [`cpu::avx2`](crate::cpu::avx2) hands out, so
//! the AVX2 precondition is proven by the type. The functions are
//! `#[inline(always)]` so that they compile into the caller's
//! `#[target_feature(enable = "avx2")]` code. The lists are read through
//! [`Shared`] and [`PerLane`], built from slices that must outlive them.
//! What stays `unsafe` is reading at indices held in registers
//! ([`Source::gather`], [`Source::gather_pairs`], [`Bracket::lift`]): the
//! indices are data, different in every lane, and checking each one
//! against its list's length would add a compare per lane to every step of
//! the search, which is what the lanes exist to keep short. Their callers
//! derive the indices from a distribution's own invariants (a stored CDF
//! ends at 1, a conditional's offsets lie inside its array) and say so
//! where they call.

// The loops over groups index several parallel arrays of registers by the
// group number; iterator chains over three or four arrays would hide that.
#![allow(clippy::needless_range_loop)]

use crate::cpu::Avx2;
use crate::{Sample1D, Sample2D, Vec2, ONE_MINUS_EPSILON};
use std::arch::x86_64::*;
use std::marker::PhantomData;

/// Groups of eight lanes advanced together: thirty-two draws per stage.
/// More groups hide more latency but hold more registers; past four, a
/// stage's state spills. Four is therefore the most groups that stay in
/// registers, one count shared by the uniform and the adaptive batches
/// (how it was chosen: `docs/performance.md`).
pub const GROUPS: usize = 4;

/// Draws per stage, [`GROUPS`] × 8.
pub const STAGE: usize = 8 * GROUPS;

/// The most entries an array read by the lanes may hold: indices are
/// `i32` lanes, and a search's probes run up to about three times the
/// length of a list before they are clamped, which must not overflow.
pub const MAX_ENTRIES: usize = (i32::MAX / 4) as usize;

/// Block ends of a shared list held in registers by `Bracket::shared_top`.
const TOP: usize = 16;

/// A search in progress for every lane: the count of entries `<= u` found
/// so far, and the entries on either side of it that the steps compared.
#[derive(Clone, Copy)]
pub struct Bracket {
    /// The number of entries `<= u` (so far).
    pub count: [__m256i; GROUPS],
    /// The largest compared entry `<= u`: 0 until one is found, which is
    /// the CDF at the left edge of the first cell.
    pub lower: [__m256; GROUPS],
    /// The smallest compared entry `> u`: 1 until one is found, which is
    /// the last entry of every stored CDF.
    pub upper: [__m256; GROUPS],
}

impl Bracket {
    /// Nothing counted yet.
    #[inline(always)]
    pub fn start(_: Avx2) -> Bracket {
        // SAFETY: the token proves the CPU has AVX2.
        unsafe {
            Bracket {
                count: [_mm256_setzero_si256(); GROUPS],
                lower: [_mm256_setzero_ps(); GROUPS],
                upper: [_mm256_set1_ps(1.0); GROUPS],
            }
        }
    }

    /// The first four steps of [`lift`](Self::lift) over one sorted list
    /// `run` shared by every lane, whose last entry is 1 (above every u),
    /// without a load per lane: the sixteen block ends
    /// E_i = run[min((i + 1) P/16 - 1, n - 1)], P = n rounded up to a power
    /// of two, sit in two registers, and the count of those `<= u` times
    /// P/16 is the count those steps find. Returns the step to continue
    /// lifting with (from a fresh [`start`](Self::start)); for a list of
    /// fewer than sixteen entries (an empty one included) nothing is done
    /// and the step is the whole search's first.
    ///
    /// Sixteen block ends rather than eight: one more compare per group
    /// saves a gather, a load per lane whose latency every lane of the
    /// group waits for.
    #[inline(always)]
    pub fn shared_top(&mut self, _: Avx2, run: &[f32], u: &[__m256; GROUPS]) -> usize {
        let n = run.len();
        let p = n.next_power_of_two();
        if p < TOP {
            return p / 2;
        }
        let block = p / TOP;
        let mut ends = [0.0f32; TOP];
        for (i, e) in ends.iter_mut().enumerate() {
            *e = run[((i + 1) * block - 1).min(n - 1)];
        }
        // SAFETY: the token proves the CPU has AVX2; the two loads read
        // the sixteen floats of `ends`.
        unsafe {
            let first = _mm256_loadu_ps(ends.as_ptr());
            let second = _mm256_loadu_ps(ends[8..].as_ptr());
            let shift = _mm_cvtsi32_si128(block.trailing_zeros() as i32);
            for g in 0..GROUPS {
                let mut blocks = _mm256_setzero_si256();
                // The last block end is the run's last entry, above every u.
                for &e in &ends[..TOP - 1] {
                    let below = _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_set1_ps(e), u[g]);
                    blocks = _mm256_sub_epi32(blocks, _mm256_castps_si256(below));
                }
                let before = _mm256_sub_epi32(blocks, _mm256_set1_epi32(1));
                let any = _mm256_cmpgt_epi32(blocks, _mm256_setzero_si256());
                self.lower[g] =
                    _mm256_and_ps(select16(first, second, before), _mm256_castsi256_ps(any));
                self.upper[g] = select16(first, second, blocks);
                self.count[g] = _mm256_sll_epi32(blocks, shift);
            }
        }
        block / 2
    }

    /// Binary lifting over each lane's sorted list
    /// `data[base .. base + last + 1]`, whose last entry `data[base + last]`
    /// is above every u (a stored CDF ends at exactly 1 and u < 1), from the
    /// power of two `step` down to 1: the count gains each step s whose
    /// entry `count + s - 1` is `<= u`.
    ///
    /// Lifting runs over the list's length rounded up to a power of two;
    /// indices past the list are clamped to its last entry, which acts as
    /// +infinity, so the virtual list stays sorted and the count is exact
    /// once `step` is at least half the longest list (or continues a
    /// [`shared_top`](Self::shared_top)). The last entry found `<= u` is the
    /// one just below the final count and the last found `> u` the one at
    /// it, so [`lower`](Self::lower) and [`upper`](Self::upper) end as the
    /// drawn cell's edges.
    ///
    /// # Safety
    /// In every lane, `last >= 0`, `base + last` indexes that lane's array
    /// of `data`, that array holds at most [`MAX_ENTRIES`] entries, and
    /// `base + count` (the count this bracket holds) is at least 0 and at
    /// most `base + last` (true of a fresh [`start`](Self::start) and after
    /// [`shared_top`](Self::shared_top) over the same list): every probe,
    /// computed without overflow, is then clamped into `[0, base + last]`.
    #[inline(always)]
    pub unsafe fn lift<S: Source>(
        &mut self,
        cpu: Avx2,
        data: &S,
        base: &[__m256i; GROUPS],
        last: &[__m256i; GROUPS],
        u: &[__m256; GROUPS],
        mut step: usize,
    ) {
        // SAFETY: the token proves the CPU has AVX2; every gather reads
        // index `min(at + step - 1, end)` with `at >= base` and `end =
        // base + last`, inside the lane's array by the caller's contract.
        unsafe {
            // The lanes step through absolute indices, base + count, against
            // the absolute index of their last entry: one add fewer per step.
            let mut at = [_mm256_setzero_si256(); GROUPS];
            let mut end = [_mm256_setzero_si256(); GROUPS];
            for g in 0..GROUPS {
                at[g] = _mm256_add_epi32(base[g], self.count[g]);
                end[g] = _mm256_add_epi32(base[g], last[g]);
            }
            while step > 0 {
                let s = _mm256_set1_epi32(step as i32);
                let offset = _mm256_set1_epi32(step as i32 - 1);
                for g in 0..GROUPS {
                    let probe = _mm256_min_epi32(_mm256_add_epi32(at[g], offset), end[g]);
                    let entry = data.gather(cpu, g, probe);
                    let below = _mm256_cmp_ps::<_CMP_LE_OQ>(entry, u[g]);
                    at[g] =
                        _mm256_add_epi32(at[g], _mm256_and_si256(_mm256_castps_si256(below), s));
                    self.lower[g] = _mm256_blendv_ps(self.lower[g], entry, below);
                    self.upper[g] = _mm256_blendv_ps(entry, self.upper[g], below);
                }
                step /= 2;
            }
            for g in 0..GROUPS {
                self.count[g] = _mm256_sub_epi32(at[g], base[g]);
            }
        }
    }

    /// The whole search of one sorted list shared by every lane, whose last
    /// entry is above every u: [`shared_top`](Self::shared_top), then
    /// [`lift`](Self::lift) from the step it leaves.
    #[inline(always)]
    pub fn search_shared(cpu: Avx2, run: SharedList<'_>, u: &[__m256; GROUPS]) -> Bracket {
        let run = run.list;
        let mut found = Bracket::start(cpu);
        // SAFETY: the token proves the CPU has AVX2 (for the two
        // constants).
        let (zero, last) = unsafe {
            (
                [_mm256_setzero_si256(); GROUPS],
                [_mm256_set1_epi32(run.len() as i32 - 1); GROUPS],
            )
        };
        let step = found.shared_top(cpu, run, u);
        // SAFETY: `SharedList` holds between 1 and MAX_ENTRIES entries,
        // so `last = len - 1` is a valid index of `run` in every lane, and
        // the count after `shared_top` over `run` is at most `last`.
        unsafe { found.lift(cpu, &Shared::new(run), &zero, &last, u, step) };
        found
    }
}

/// A sorted list of `f32` every lane searches, checked when it is made:
/// not empty, and at most [`MAX_ENTRIES`] long.
#[derive(Clone, Copy)]
pub struct SharedList<'a> {
    list: &'a [f32],
}

impl<'a> SharedList<'a> {
    /// `list`, if it holds between 1 and [`MAX_ENTRIES`] entries.
    #[inline(always)]
    pub fn new(list: &'a [f32]) -> Option<Self> {
        (!list.is_empty() && list.len() <= MAX_ENTRIES).then_some(SharedList { list })
    }
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for u32 {}
    impl Sealed for super::Shared<'_> {}
    impl Sealed for super::PerLane<'_> {}
}

/// The types of 4-byte entries the lanes read: `f32`, and `u32` read as
/// its bits.
pub trait Entry: sealed::Sealed + Copy + 'static {}
impl Entry for f32 {}
impl Entry for u32 {}

/// Where the lanes read their entries from: one array shared by every lane
/// ([`Shared`]: a batch from one distribution) or one array per lane
/// ([`PerLane`]: the slices of a wavefront of shading points). Entries are
/// 4 bytes (`f32`, or `u32` read as their bits). Implemented here only.
pub trait Source: sealed::Sealed + Copy {
    /// Entry `index` of each lane's array in group `g` (lanes 8g..8g + 8).
    ///
    /// # Safety
    /// Every index is at least 0 and below the length of its lane's array.
    unsafe fn gather(&self, cpu: Avx2, g: usize, index: __m256i) -> __m256;

    /// Entries `index` and `index + 1` of each lane's array in group `g`
    /// (a segment's two ends, a conditional's two offsets).
    ///
    /// # Safety
    /// Every index is at least 0, and `index + 1` below the length of its
    /// lane's array.
    unsafe fn gather_pairs(&self, cpu: Avx2, g: usize, index: __m256i) -> (__m256, __m256);
}

/// One array read by every lane.
#[derive(Clone, Copy)]
pub struct Shared<'a> {
    entries: *const f32,
    _array: PhantomData<&'a [u32]>,
}

impl<'a> Shared<'a> {
    /// Every lane reads `array`.
    #[inline(always)]
    pub fn new<T: Entry>(array: &'a [T]) -> Self {
        Shared {
            entries: array.as_ptr() as *const f32,
            _array: PhantomData,
        }
    }
}

impl Source for Shared<'_> {
    /// # Safety
    /// As [`Source::gather`]: every index inside its lane's array.
    #[inline(always)]
    unsafe fn gather(&self, _: Avx2, _g: usize, index: __m256i) -> __m256 {
        // SAFETY: the token proves the CPU has AVX2; every index is inside
        // the array (the caller's contract), whose 4-byte entries the
        // scale 4 steps over.
        unsafe { _mm256_i32gather_ps::<4>(self.entries, index) }
    }

    /// # Safety
    /// As [`Source::gather_pairs`]: every index inside its lane's array.
    #[inline(always)]
    unsafe fn gather_pairs(&self, _: Avx2, _g: usize, index: __m256i) -> (__m256, __m256) {
        // Unsigned: the indices are never negative, and a u32 widens to an
        // address for free where an i32 takes a sign extension per lane.
        let mut at = [0u32; 8];
        let entries = self.entries;
        // SAFETY: the token proves the CPU has AVX2; the store writes the
        // eight lanes of `at`; each pair `index`, `index + 1` is inside the
        // array (the caller's contract), so each address and the next
        // entry are readable.
        unsafe {
            _mm256_storeu_si256(at.as_mut_ptr() as *mut __m256i, index);
            load_pairs_at(|l| entries.add(at[l] as usize))
        }
    }
}

/// One array per lane, for the [`STAGE`] lanes of a stage: the addresses
/// of the arrays as 64-bit lanes, four per register. Each gather is then
/// two 64-bit-indexed gathers of four lanes, whose base is 0 and whose
/// indices are the lanes' own addresses plus the entry offsets.
#[derive(Clone, Copy)]
pub struct PerLane<'a> {
    /// Lanes 0..4 and 4..8 of each group.
    low: [__m256i; GROUPS],
    high: [__m256i; GROUPS],
    _arrays: PhantomData<&'a [u32]>,
}

impl<'a> PerLane<'a> {
    /// Lane l reads `array(l)`, for l in 0..[`STAGE`].
    #[inline(always)]
    pub fn new<T: Entry + 'a>(_: Avx2, array: impl Fn(usize) -> &'a [T]) -> PerLane<'a> {
        let address = |l: usize| array(l).as_ptr() as usize as i64;
        // SAFETY: the token proves the CPU has AVX2.
        unsafe {
            let mut lanes = PerLane {
                low: [_mm256_setzero_si256(); GROUPS],
                high: [_mm256_setzero_si256(); GROUPS],
                _arrays: PhantomData,
            };
            for g in 0..GROUPS {
                let l = 8 * g;
                lanes.low[g] =
                    _mm256_setr_epi64x(address(l), address(l + 1), address(l + 2), address(l + 3));
                lanes.high[g] = _mm256_setr_epi64x(
                    address(l + 4),
                    address(l + 5),
                    address(l + 6),
                    address(l + 7),
                );
            }
            lanes
        }
    }

    /// The byte addresses of entries `index` (4-byte entries) of lanes
    /// 0..4 and 4..8 of group g.
    #[inline(always)]
    fn addresses(&self, _: Avx2, g: usize, index: __m256i) -> (__m256i, __m256i) {
        // SAFETY: the token proves the CPU has AVX2; this is arithmetic on
        // registers, nothing is read.
        unsafe {
            let bytes = |i: __m128i| _mm256_slli_epi64::<2>(_mm256_cvtepi32_epi64(i));
            (
                _mm256_add_epi64(self.low[g], bytes(_mm256_castsi256_si128(index))),
                _mm256_add_epi64(self.high[g], bytes(_mm256_extracti128_si256::<1>(index))),
            )
        }
    }
}

impl Source for PerLane<'_> {
    /// # Safety
    /// As [`Source::gather`]: every index inside its lane's array.
    #[inline(always)]
    unsafe fn gather(&self, cpu: Avx2, g: usize, index: __m256i) -> __m256 {
        let (low, high) = self.addresses(cpu, g, index);
        // Base 0: the indices are the addresses themselves, each inside the
        // array its lane was given (the caller's contract), so every load
        // reads memory the caller owns; the gather instruction takes its
        // addresses from the index lanes whatever pointer is passed.
        let base = std::ptr::null::<f32>();
        // SAFETY: the token proves the CPU has AVX2; as just said, every
        // address is that of an entry of its lane's array.
        unsafe {
            join_halves(
                cpu,
                _mm256_i64gather_ps::<1>(base, low),
                _mm256_i64gather_ps::<1>(base, high),
            )
        }
    }

    /// # Safety
    /// As [`Source::gather_pairs`]: every index inside its lane's array.
    #[inline(always)]
    unsafe fn gather_pairs(&self, cpu: Avx2, g: usize, index: __m256i) -> (__m256, __m256) {
        let (low, high) = self.addresses(cpu, g, index);
        let mut at = [0u64; 8];
        // SAFETY: the token proves the CPU has AVX2; the stores write the
        // eight lanes of `at`; each address is that of entry `index` of its
        // lane's array, and `index + 1` is inside it too (the caller's
        // contract).
        unsafe {
            _mm256_storeu_si256(at.as_mut_ptr() as *mut __m256i, low);
            _mm256_storeu_si256(at.as_mut_ptr().add(4) as *mut __m256i, high);
            load_pairs_at(|l| at[l] as usize as *const f32)
        }
    }
}

/// The pairs of 4-byte entries at `entry(0)`, ..., `entry(7)` as the eight
/// first and the eight second entries, in lane order.
///
/// Eight 8-byte loads and four shuffles, where two gathers per eight pairs
/// would do: for the pairs of the adaptive 2D `sample_batch` (three pair
/// reads per draw) the independent loads beat both two 32-bit and two
/// 64-bit gathers per eight pairs; for single entries they gain nothing,
/// so single entries keep the gather instruction.
///
/// # Safety
/// AVX2; each `entry(l)` and the entry after it are readable.
#[inline(always)]
unsafe fn load_pairs_at(entry: impl Fn(usize) -> *const f32) -> (__m256, __m256) {
    // SAFETY: the caller's contract: AVX2, and 8 readable bytes at each
    // `entry(l)`.
    unsafe {
        let two = |l: usize| {
            let first = _mm_load_sd(entry(l) as *const f64);
            _mm_castpd_ps(_mm_loadh_pd(first, entry(l + 1) as *const f64))
        };
        // low = a0 b0 a1 b1 | a4 b4 a5 b5, high = a2 b2 a3 b3 | a6 b6 a7 b7.
        let low = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(two(0)), two(4));
        let high = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(two(2)), two(6));
        (
            _mm256_shuffle_ps::<0b10_00_10_00>(low, high),
            _mm256_shuffle_ps::<0b11_01_11_01>(low, high),
        )
    }
}

/// Two registers of four lanes as one of eight.
#[inline(always)]
fn join_halves(_: Avx2, low: __m128, high: __m128) -> __m256 {
    // SAFETY: the token proves the CPU has AVX2.
    unsafe { _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(low), high) }
}

/// Entry b (0..16) of the sixteen lanes of `first` and `second`: the
/// permutation reads the low three bits, the block number's fourth bit
/// picks the register.
///
/// # Safety
/// AVX2 (a helper of [`Bracket::shared_top`], inside its token's proof).
#[inline(always)]
unsafe fn select16(first: __m256, second: __m256, b: __m256i) -> __m256 {
    // SAFETY: the caller's contract: AVX2.
    unsafe {
        let high = _mm256_castsi256_ps(_mm256_cmpgt_epi32(b, _mm256_set1_epi32(7)));
        _mm256_blendv_ps(
            _mm256_permutevar8x32_ps(first, b),
            _mm256_permutevar8x32_ps(second, b),
            high,
        )
    }
}

/// [`clamp_unit`](crate::clamp_unit) in lanes: u > 0 (false for NaN) keeps
/// min(u, 1 - ε/2), everything else becomes +0.
#[inline(always)]
pub fn clamp_unit_lanes(_: Avx2, u: __m256) -> __m256 {
    // SAFETY: the token proves the CPU has AVX2.
    unsafe {
        let positive = _mm256_cmp_ps::<_CMP_GT_OQ>(u, _mm256_setzero_ps());
        _mm256_and_ps(
            positive,
            _mm256_min_ps(u, _mm256_set1_ps(ONE_MINUS_EPSILON)),
        )
    }
}

/// All ones where 0 <= v < 1 (so not for NaN): the domain of a density
/// over the unit square.
#[inline(always)]
pub fn in_unit(_: Avx2, v: __m256) -> __m256 {
    // SAFETY: the token proves the CPU has AVX2.
    unsafe {
        _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GE_OQ>(v, _mm256_setzero_ps()),
            _mm256_cmp_ps::<_CMP_LT_OQ>(v, _mm256_set1_ps(1.0)),
        )
    }
}

/// Eight points `p[0..8]` as x and y lanes, lane l holding point l; panics
/// if `p` holds fewer than eight.
#[inline(always)]
pub fn load_pairs(cpu: Avx2, p: &[Vec2]) -> (__m256, __m256) {
    assert!(p.len() >= 8);
    // Vec2 is two consecutive f32 (glam's `repr(C)` scalar layout).
    let f = p.as_ptr() as *const f32;
    // SAFETY: the token proves the CPU has AVX2; the two loads read the
    // sixteen floats of `p[0..8]`, checked above.
    let (a, b) = unsafe { (_mm256_loadu_ps(f), _mm256_loadu_ps(f.add(8))) };
    // SAFETY: the token proves the CPU has AVX2.
    unsafe {
        // The shuffles give x0 x1 x4 x5 | x2 x3 x6 x7 (and the same for y);
        // the permutation of 64-bit pairs puts them back in order.
        let x = _mm256_shuffle_ps::<0b10_00_10_00>(a, b);
        let y = _mm256_shuffle_ps::<0b11_01_11_01>(a, b);
        (pair_order(cpu, x), pair_order(cpu, y))
    }
}

/// A stage's [`STAGE`] uniform numbers as lanes, group by group, clamped
/// with [`clamp_unit_lanes`]; panics if `u` holds fewer.
#[inline(always)]
pub fn load_stage_1d(cpu: Avx2, u: &[f32]) -> [__m256; GROUPS] {
    assert!(u.len() >= STAGE);
    // SAFETY: the token proves the CPU has AVX2; each load reads eight
    // floats of `u[..STAGE]`, checked above.
    unsafe {
        let mut v = [_mm256_setzero_ps(); GROUPS];
        for g in 0..GROUPS {
            v[g] = clamp_unit_lanes(cpu, _mm256_loadu_ps(u[8 * g..].as_ptr()));
        }
        v
    }
}

/// A stage's [`STAGE`] pairs as x and y lanes, group by group: clamped
/// with [`clamp_unit_lanes`] when they are uniform numbers (`clamp`), as
/// they are when they are points. Panics if `p` holds fewer.
#[inline(always)]
pub fn load_stage(cpu: Avx2, p: &[Vec2], clamp: bool) -> ([__m256; GROUPS], [__m256; GROUPS]) {
    // SAFETY: the token proves the CPU has AVX2.
    let (mut x, mut y) = unsafe { ([_mm256_setzero_ps(); GROUPS], [_mm256_setzero_ps(); GROUPS]) };
    for g in 0..GROUPS {
        let (xg, yg) = load_pairs(cpu, &p[8 * g..]);
        (x[g], y[g]) = if clamp {
            (clamp_unit_lanes(cpu, xg), clamp_unit_lanes(cpu, yg))
        } else {
            (xg, yg)
        };
    }
    (x, y)
}

/// Lanes 0 1 4 5 2 3 6 7 of `v` (its 64-bit quarters 0, 2, 1, 3).
#[inline(always)]
fn pair_order(_: Avx2, v: __m256) -> __m256 {
    // SAFETY: the token proves the CPU has AVX2.
    unsafe { _mm256_castpd_ps(_mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_castps_pd(v))) }
}

/// Write eight samples (x, y, pdf) to `out[0..8]` as three 8-float stores:
/// each store's floats come from the three registers by one shared
/// permutation and two blends. Panics if `out` holds fewer than eight.
#[inline(always)]
pub fn store_samples(cpu: Avx2, x: __m256, y: __m256, pdf: __m256, out: &mut [Sample2D]) {
    assert!(out.len() >= 8);
    // Sample2D is `repr(C)`: three consecutive f32.
    let p = out.as_mut_ptr() as *mut f32;
    // out[0..8] = x0 y0 p0 x1 y1 p1 x2 y2, then p2 x3 y3 p3 x4 y4 p4 x5,
    // then y5 p5 x6 y6 p6 x7 y7 p7.
    // SAFETY: the token proves the CPU has AVX2; the three stores write
    // the 24 floats of `out[0..8]`, checked above.
    unsafe {
        let (a, b, c) = permute3(cpu, x, y, pdf, [0, 0, 0, 1, 1, 1, 2, 2]);
        _mm256_storeu_ps(p, _mm256_blend_ps::<0x24>(_mm256_blend_ps::<0x92>(a, b), c));
        let (a, b, c) = permute3(cpu, x, y, pdf, [2, 3, 3, 3, 4, 4, 4, 5]);
        _mm256_storeu_ps(
            p.add(8),
            _mm256_blend_ps::<0x49>(_mm256_blend_ps::<0x24>(a, b), c),
        );
        let (a, b, c) = permute3(cpu, x, y, pdf, [5, 5, 6, 6, 6, 7, 7, 7]);
        _mm256_storeu_ps(
            p.add(16),
            _mm256_blend_ps::<0x92>(_mm256_blend_ps::<0x49>(a, b), c),
        );
    }
}

/// Write eight 1D samples (x, pdf) to `out[0..8]` as two 8-float stores;
/// panics if `out` holds fewer than eight.
#[inline(always)]
pub fn store_samples_1d(_: Avx2, x: __m256, pdf: __m256, out: &mut [Sample1D]) {
    assert!(out.len() >= 8);
    // Sample1D is `repr(C)`: two consecutive f32.
    let p = out.as_mut_ptr() as *mut f32;
    // SAFETY: the token proves the CPU has AVX2; the two stores write the
    // 16 floats of `out[0..8]`, checked above.
    unsafe {
        // Unpacking gives the pairs of lanes 0 1 | 4 5 and 2 3 | 6 7; the
        // 128-bit halves are then put in order.
        let (low, high) = (_mm256_unpacklo_ps(x, pdf), _mm256_unpackhi_ps(x, pdf));
        _mm256_storeu_ps(p, _mm256_permute2f128_ps::<0x20>(low, high));
        _mm256_storeu_ps(p.add(8), _mm256_permute2f128_ps::<0x31>(low, high));
    }
}

/// Write eight `f32` lanes to `out[0..8]`; panics if `out` holds fewer.
#[inline(always)]
pub fn store_lanes(_: Avx2, v: __m256, out: &mut [f32]) {
    assert!(out.len() >= 8);
    // SAFETY: the token proves the CPU has AVX2; the store writes the
    // eight floats of `out[0..8]`, checked above.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), v) }
}

/// The lanes `order` of each of three registers.
#[inline(always)]
fn permute3(_: Avx2, x: __m256, y: __m256, z: __m256, order: [i32; 8]) -> (__m256, __m256, __m256) {
    // SAFETY: the token proves the CPU has AVX2; the load reads the eight
    // integers of `order`.
    unsafe {
        let i = _mm256_loadu_si256(order.as_ptr() as *const __m256i);
        (
            _mm256_permutevar8x32_ps(x, i),
            _mm256_permutevar8x32_ps(y, i),
            _mm256_permutevar8x32_ps(z, i),
        )
    }
}

/// The eight lanes of a register, for the scalar clean-up of rare lanes.
#[inline(always)]
pub fn lanes_f32(_: Avx2, v: __m256) -> [f32; 8] {
    let mut out = [0.0f32; 8];
    // SAFETY: the token proves the CPU has AVX2; the store writes the
    // eight floats of `out`.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), v) };
    out
}

/// The eight lanes of an integer register.
#[inline(always)]
pub fn lanes_i32(_: Avx2, v: __m256i) -> [i32; 8] {
    let mut out = [0i32; 8];
    // SAFETY: the token proves the CPU has AVX2; the store writes the
    // eight integers of `out`.
    unsafe { _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, v) };
    out
}

/// Eight `i32` lanes loaded from `v[0..8]`; panics if `v` holds fewer.
#[inline(always)]
pub fn load_i32(_: Avx2, v: &[i32]) -> __m256i {
    assert!(v.len() >= 8);
    // SAFETY: the token proves the CPU has AVX2; the load reads the eight
    // integers of `v[0..8]`, checked above.
    unsafe { _mm256_loadu_si256(v.as_ptr() as *const __m256i) }
}

/// The number of entries of `ascending` (non-decreasing, no NaN) at or
/// below `key`, eight entries to a compare; entries past the last multiple
/// of eight are not counted, so a list is padded with +∞ to a whole
/// number of eights. A NaN key counts none.
///
/// In a list that ascends, the entries at or below the key are a prefix,
/// so each compare's mask is a run of ones from bit 0, and its length is
/// the trailing zeros of mask + 1: one mask move and one bit scan per
/// eight entries, with no sum across lanes at the end. A list that does
/// not ascend gets, per eight, the length of the run from the first
/// entry, which is not its count.
#[inline(always)]
pub fn count_ascending_at_or_below(_: Avx2, ascending: &[f32], key: f32) -> usize {
    let mut count = 0;
    // SAFETY: the token proves the CPU has AVX2; each load reads the eight
    // floats of one chunk.
    unsafe {
        let k = _mm256_set1_ps(key);
        for chunk in ascending.chunks_exact(8) {
            let v = _mm256_loadu_ps(chunk.as_ptr());
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(v, k)) as u32;
            // mask + 1 <= 256; the bit above tells the compiler it is not 0.
            count += ((mask + 1) | 0x200).trailing_zeros() as usize;
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The token, or a printed line saying the test is skipped.
    fn avx2() -> Option<Avx2> {
        let cpu = crate::cpu::avx2();
        if cpu.is_none() {
            println!("skipped: this CPU has no AVX2 and FMA (or ACDF_CPU=portable)");
        }
        cpu
    }

    /// A sorted run ending at 1 from arbitrary non-negative steps.
    fn sorted_run(steps: &[f32]) -> Vec<f32> {
        let total: f32 = steps.iter().sum::<f32>() + 1.0;
        let mut run: Vec<f32> = steps
            .iter()
            .scan(0.0f32, |acc, &s| {
                *acc += s;
                Some((*acc / total).min(1.0))
            })
            .collect();
        run.push(1.0);
        run
    }

    /// Every lane searches `run` (not empty), with or without the
    /// register top.
    fn search_shared(cpu: Avx2, run: &[f32], u: &[f32; STAGE], top: bool) -> Bracket {
        let lanes: [__m256; GROUPS] = std::array::from_fn(|g| {
            let v: [f32; 8] = std::array::from_fn(|l| u[8 * g + l]);
            // SAFETY: AVX2 (the token); the load reads the eight floats of `v`.
            unsafe { _mm256_loadu_ps(v.as_ptr()) }
        });
        let mut b = Bracket::start(cpu);
        let step = if top {
            b.shared_top(cpu, run, &lanes)
        } else {
            run.len().next_power_of_two() / 2
        };
        let lengths = [run.len() as i32 - 1; 8];
        let last = [load_i32(cpu, &lengths); GROUPS];
        let zero = [load_i32(cpu, &[0; 8]); GROUPS];
        // SAFETY: `run` is not empty, so its last index is valid, and the
        // count is that of `shared_top` over it (or 0).
        unsafe { b.lift(cpu, &Shared::new(run), &zero, &last, &lanes, step) };
        b
    }

    proptest! {
        /// The count of an ascending list padded with +∞ is the plain count,
        /// for keys between, on and beside its entries and NaN.
        #[test]
        fn ascending_count_is_the_plain_count(
            mut list in prop::collection::vec(-2.0f32..2.0, 0..70),
            keys in prop::collection::vec(-2.5f32..2.5, 8),
        ) {
            let Some(cpu) = avx2() else { return Ok(()) };
            list.sort_by(f32::total_cmp);
            let mut padded = list.clone();
            padded.resize(list.len().div_ceil(8).max(1) * 8, f32::INFINITY);
            let mut all_keys = keys.clone();
            all_keys.extend(list.iter().copied());
            all_keys.extend([f32::NAN, f32::NEG_INFINITY, f32::MAX]);
            for key in all_keys {
                let want = list.iter().filter(|&&e| e <= key).count();
                prop_assert_eq!(count_ascending_at_or_below(cpu, &padded, key), want);
            }
        }
    }

    proptest! {
        /// Lifting, with and without the register top, counts what
        /// `partition_point` counts and brackets u by the neighbouring
        /// entries, on runs of every length (ties, zero steps included).
        #[test]
        fn shared_search_counts_and_brackets(
            steps in prop::collection::vec(prop_oneof![Just(0.0f32), 0.0f32..1.0], 0..300),
            us in prop::collection::vec(0.0f32..1.0, STAGE),
            picks in prop::collection::vec(any::<prop::sample::Index>(), STAGE / 4),
        ) {
            let Some(cpu) = avx2() else {
                return Ok(());
            };
            let run = sorted_run(&steps);
            let mut u = [0.0f32; STAGE];
            u.copy_from_slice(&us);
            // Some u exactly on entries, where ties decide the count.
            if run.len() > 1 {
                for (k, p) in picks.iter().enumerate() {
                    u[4 * k] = run[p.index(run.len() - 1)];
                }
            }
            for top in [false, true] {
                let b = search_shared(cpu, &run, &u, top);
                if top && run.len() > 1 {
                    // The whole search as the batch paths run it.
                    let lanes = std::array::from_fn(|g| load_f32(cpu, &u[8 * g..]));
                    let list = SharedList::new(&run).expect("a list");
                    let whole = Bracket::search_shared(cpu, list, &lanes);
                    for g in 0..GROUPS {
                        prop_assert_eq!(lanes_i32(cpu, whole.count[g]), lanes_i32(cpu, b.count[g]));
                    }
                }
                for g in 0..GROUPS {
                    let (count, lower, upper) = (
                        lanes_i32(cpu, b.count[g]),
                        lanes_f32(cpu, b.lower[g]),
                        lanes_f32(cpu, b.upper[g]),
                    );
                    for l in 0..8 {
                        let v = u[8 * g + l];
                        let expected = run.partition_point(|&e| e <= v);
                        prop_assert_eq!(count[l] as usize, expected, "u {} top {}", v, top);
                        let below = if expected == 0 { 0.0 } else { run[expected - 1] };
                        prop_assert_eq!(lower[l], below);
                        prop_assert_eq!(upper[l], run[expected]);
                    }
                }
            }
        }
    }

    /// Lanes searching different lists of different lengths, all in one
    /// buffer ([`Shared`] with a start per lane) and each in its own
    /// allocation ([`PerLane`]): the same counts and brackets, and the same
    /// pairs of neighbouring entries.
    #[test]
    fn per_lane_lists_of_different_lengths() {
        let Some(cpu) = avx2() else {
            return;
        };
        let lists: Vec<Vec<f32>> = (0..STAGE)
            .map(|k| {
                sorted_run(
                    &(0..1 + (k * 7) % 41)
                        .map(|i| ((i * 13) % 5) as f32)
                        .collect::<Vec<_>>(),
                )
            })
            .collect();
        let mut data = Vec::new();
        let (mut base, mut last) = ([0i32; STAGE], [0i32; STAGE]);
        for (k, list) in lists.iter().enumerate() {
            base[k] = data.len() as i32;
            last[k] = list.len() as i32 - 1;
            data.extend_from_slice(list);
        }
        let u: Vec<f32> = (0..STAGE).map(|k| ((k * 37) % 64) as f32 / 64.0).collect();
        let longest = lists.iter().map(Vec::len).max().unwrap();
        let bases: [__m256i; GROUPS] = std::array::from_fn(|g| load_i32(cpu, &base[8 * g..]));
        let lasts: [__m256i; GROUPS] = std::array::from_fn(|g| load_i32(cpu, &last[8 * g..]));
        let us: [__m256; GROUPS] = std::array::from_fn(|g| load_f32(cpu, &u[8 * g..]));
        let zero = [load_i32(cpu, &[0; 8]); GROUPS];
        let step = longest.next_power_of_two() / 2;
        let mut shared = Bracket::start(cpu);
        // SAFETY: every base + last indexes `data`, where each list ends.
        unsafe { shared.lift(cpu, &Shared::new(&data), &bases, &lasts, &us, step) };
        let per_lane = PerLane::new(cpu, |l| &lists[l][..]);
        let mut own = Bracket::start(cpu);
        // SAFETY: every last indexes its own list.
        unsafe { own.lift(cpu, &per_lane, &zero, &lasts, &us, step) };
        // Entries (0, 1) of every list (each has two or more).
        let pairs: Vec<([f32; 8], [f32; 8])> = (0..GROUPS)
            .map(|g| {
                // SAFETY: every list holds entries 0 and 1.
                let (a, b) = unsafe { per_lane.gather_pairs(cpu, g, zero[g]) };
                (lanes_f32(cpu, a), lanes_f32(cpu, b))
            })
            .collect();
        for (k, list) in lists.iter().enumerate() {
            let (g, l) = (k / 8, k % 8);
            let expected = list.partition_point(|&e| e <= u[k]);
            let below = if expected == 0 {
                0.0
            } else {
                list[expected - 1]
            };
            for b in [&shared, &own] {
                let (count, lower, upper) = (
                    lanes_i32(cpu, b.count[g]),
                    lanes_f32(cpu, b.lower[g]),
                    lanes_f32(cpu, b.upper[g]),
                );
                assert_eq!(count[l] as usize, expected, "list {k}");
                assert_eq!((lower[l], upper[l]), (below, list[expected]), "list {k}");
            }
            {
                assert_eq!(
                    (pairs[g].0[l], pairs[g].1[l]),
                    (list[0], list[1]),
                    "list {k}"
                );
            }
        }
    }

    /// The lane clamp is `clamp_unit`, bit for bit, and pairs load in order.
    #[test]
    fn clamp_and_pairs_match_the_scalar_rules() {
        let Some(cpu) = avx2() else {
            return;
        };
        let specials = [
            0.0,
            -0.0,
            0.5,
            1.0,
            -1.0,
            2.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            ONE_MINUS_EPSILON,
            f32::MIN_POSITIVE,
            1e-45,
            0.999_999_9,
            -1e-30,
        ];
        let pairs: Vec<Vec2> = (0..8)
            .map(|k| Vec2::new(specials[k], specials[(k + 6) % specials.len()]))
            .collect();
        let (x, y) = load_pairs(cpu, &pairs);
        let (x, y) = (clamp_unit_lanes(cpu, x), clamp_unit_lanes(cpu, y));
        let (x, y) = (lanes_f32(cpu, x), lanes_f32(cpu, y));
        for (l, p) in pairs.iter().enumerate() {
            assert_eq!(x[l].to_bits(), crate::clamp_unit(p.x).to_bits(), "x of {p}");
            assert_eq!(y[l].to_bits(), crate::clamp_unit(p.y).to_bits(), "y of {p}");
        }
    }

    /// Eight lanes loaded from `v[0..8]`.
    fn load_f32(cpu: Avx2, v: &[f32]) -> __m256 {
        let mut lanes = [0.0; 8];
        lanes.copy_from_slice(&v[..8]);
        let _ = cpu;
        // SAFETY: AVX2 (the token); the load reads the eight floats of
        // `lanes`.
        unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
    }

    /// Lanes holding base, base + 1, ..., base + 7.
    fn lane(cpu: Avx2, base: f32) -> __m256 {
        load_f32(cpu, &std::array::from_fn::<f32, 8, _>(|l| base + l as f32))
    }

    /// Samples stored from lanes land in their own slots, in order.
    #[test]
    fn stored_samples_are_in_lane_order() {
        let Some(cpu) = avx2() else {
            return;
        };
        let mut out = vec![Sample2D::default(); 9];
        store_samples(
            cpu,
            lane(cpu, 0.0),
            lane(cpu, 10.0),
            lane(cpu, 20.0),
            &mut out,
        );
        for (l, s) in out.iter().take(8).enumerate() {
            let l = l as f32;
            assert_eq!(
                *s,
                Sample2D {
                    p: Vec2::new(l, 10.0 + l),
                    pdf: 20.0 + l
                }
            );
        }
        assert_eq!(out[8], Sample2D::default());
        let mut out = vec![Sample1D::default(); 9];
        store_samples_1d(cpu, lane(cpu, 0.0), lane(cpu, 10.0), &mut out);
        for (l, s) in out.iter().take(8).enumerate() {
            let l = l as f32;
            assert_eq!(
                *s,
                Sample1D {
                    x: l,
                    pdf: 10.0 + l
                }
            );
        }
        assert_eq!(out[8], Sample1D::default());
    }
}
