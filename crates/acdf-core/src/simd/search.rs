//! Branch-free searches in sorted lists: the inverse CDF lookups of the
//! distributions, shared by the plug-ins.
//!
//! Every search here returns the number of entries `<= v` of a
//! non-decreasing list, which is exactly what `partition_point(|&e| e <= v)`
//! returns, so the cell or segment a sample or a density lookup lands in
//! does not depend on which search found it. What differs is the cost: a
//! binary search over ~100 entries takes seven branches that follow the
//! random `v` and mispredict about half the time (some 15 cycles each),
//! whereas these searches compare without data-dependent branches: a list of
//! up to [`WINDOW`] entries (a conditional over 32 φ_h columns) is compared
//! all at once, a longer one (a marginal over 256 θ_h rows) is first cut
//! down to such a window by a four-way search.
//!
//! The searches read the lists as they are; a [`Guide`], the one index
//! here, is derived from its list when a distribution is built or loaded,
//! never written with it.
//!
//! [`lanes`] (x86-64) searches for many draws at once in AVX2 lanes, for the
//! batch paths; [`narrow`] does the same over lists of 8- and 16-bit
//! entries.

#[cfg(target_arch = "x86_64")]
pub mod lanes;
#[cfg(target_arch = "x86_64")]
pub mod narrow;

/// The number of entries compared at once; a conditional over 32 φ_h
/// columns has at most 33 vertices, whose inner 31 fit.
pub const WINDOW: usize = 32;

/// An entry of the sorted lists searched here: `f32` positions and CDF
/// values, `u32` packed vertices, 16- and 8-bit quantised CDF values. The
/// searches below are written once for all of them; an entry type brings
/// only its compare of one window.
pub trait Key: Copy + PartialOrd {
    /// Bit k set where `window[k] <= key`.
    fn window_mask(window: &[Self; WINDOW], key: Self) -> u32;
}

impl Key for f32 {
    #[inline(always)]
    fn window_mask(window: &[f32; WINDOW], key: f32) -> u32 {
        at_or_below_mask(window, key)
    }
}

impl Key for u32 {
    #[inline(always)]
    fn window_mask(window: &[u32; WINDOW], key: u32) -> u32 {
        window_at_or_below_u32(window, key)
    }
}

impl Key for u16 {
    #[inline(always)]
    fn window_mask(window: &[u16; WINDOW], key: u16) -> u32 {
        window_at_or_below_u16(window, key)
    }
}

impl Key for u8 {
    #[inline(always)]
    fn window_mask(window: &[u8; WINDOW], key: u8) -> u32 {
        window_at_or_below_u8(window, key)
    }
}

/// For each lane l, the number of entries of the non-decreasing list
/// `data[start..start + len]` that are `<= keys[l]` (all lanes share the
/// list): the one search of every piecewise CDF in the workspace.
///
/// A four-way search cuts the list down to at most [`WINDOW`] candidates,
/// which [`count_window`] then compares at once. The candidates for the
/// answer are kept as an interval [lo, lo + n]: three probes split it into
/// quarters of q = floor(n / 4) entries, and the number of probes at or
/// below the key (added as integers, so no branch) says which quarter holds
/// the answer; the interval keeps the last quarter's length n - 3q in every
/// case, which is never shorter than the others, so the number of steps
/// depends on `len` only. The lanes thus step together, and their
/// independent loads overlap. A list of at most [`WINDOW`] entries (a
/// conditional over 32 φ_h columns, every curve of a slice at the default
/// tolerance) takes no step: one window compare is the whole search.
#[inline(always)]
pub fn count_at_or_below<K: Key, const L: usize>(
    data: &[K],
    start: usize,
    len: usize,
    keys: [K; L],
) -> [usize; L] {
    let mut lo = [start; L];
    let mut n = len;
    // Below WINDOW entries in all, a window cannot be read: search to the end.
    let stop = if data.len() >= WINDOW { WINDOW } else { 3 };
    while n > stop {
        let q = n / 4;
        for (lo, &key) in lo.iter_mut().zip(&keys) {
            let probe = |k: usize| (data[*lo + k * q - 1] <= key) as usize;
            let quarters = probe(1) + probe(2) + probe(3);
            *lo += q * quarters;
        }
        n -= 3 * q;
    }
    for (lo, &key) in lo.iter_mut().zip(&keys) {
        *lo = *lo - start
            + if stop == WINDOW {
                count_window(data, *lo, n, key)
            } else {
                count_few(data, *lo, n, key)
            };
    }
    lo
}

/// The number of entries of the non-decreasing `data[start..start + len]`
/// that are `<= key`: [`count_at_or_below`] for one key, with the short
/// list (one window, the common case) tested first, ahead of the four-way
/// search's set-up.
#[inline(always)]
pub fn count_one<K: Key>(data: &[K], start: usize, len: usize, key: K) -> usize {
    if len <= WINDOW && data.len() >= WINDOW {
        count_window(data, start, len, key)
    } else {
        count_at_or_below(data, start, len, [key])[0]
    }
}

/// The number of entries of the non-decreasing `list` that are `<= key`.
#[inline(always)]
pub fn count_sorted<K: Key>(list: &[K], key: K) -> usize {
    count_one(list, 0, list.len(), key)
}

/// The number of entries of `data[start..start + n]`, n <= 3, that are
/// `<= v` (n depends on the list's length only, so its branches are
/// predicted).
#[inline(always)]
fn count_few<K: Key>(data: &[K], start: usize, n: usize, key: K) -> usize {
    let at_or_below = |k: usize| (data[start + k] <= key) as usize;
    let mut count = 0;
    if n >= 1 {
        count += at_or_below(0);
    }
    if n >= 2 {
        count += at_or_below(1);
    }
    if n >= 3 {
        count += at_or_below(2);
    }
    count
}

/// The number of entries of the non-decreasing `data[start..start + len]`
/// that are `<= v`, for `len <= WINDOW <= data.len()`.
///
/// It compares a fixed window of [`WINDOW`] entries holding the list at once
/// and reads the answer off the bit mask of the comparisons: the list's
/// entries at or below v come first, so the count is the run of ones from
/// the list's first bit, cut at `len` (the entries around the list may be
/// anything). The window starts at the list, or ends at the end of `data`
/// when it would run past it. No loop whose trip count changes from draw to
/// draw, no data-dependent branch.
#[inline(always)]
pub fn count_window<K: Key>(data: &[K], start: usize, len: usize, key: K) -> usize {
    let first = start.min(data.len() - WINDOW);
    let window: &[K; WINDOW] = data[first..first + WINDOW]
        .try_into()
        .expect("a window of WINDOW entries");
    // A u64 so that the shift (at most WINDOW, for an empty list at the very
    // end) is defined.
    let mask = u64::from(K::window_mask(window, key)) >> (start - first);
    (mask.trailing_ones() as usize).min(len)
}

/// Bit k set where `window[k] <= v`.
///
/// Where the CPU has AVX-512 (F, VL and BW) the 32 comparisons go straight
/// into mask registers ([`at_or_below_mask_evex`]); otherwise four-wide SSE
/// compares are narrowed to bytes and gathered into one mask per 16
/// entries (x86-64 always has SSE2). The check ([`crate::cpu::mask_compares`])
/// is one load of a cached flag and a branch that always goes the same way.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn at_or_below_mask(window: &[f32; WINDOW], v: f32) -> u32 {
    if crate::cpu::mask_compares() {
        // SAFETY: the CPU has been found to support AVX-512 F, VL and BW.
        return unsafe { at_or_below_mask_evex(window, v) };
    }
    at_or_below_mask_sse(window, v)
}

/// [`at_or_below_mask`] by SSE2 compares (the x86-64 baseline).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn at_or_below_mask_sse(window: &[f32; WINDOW], v: f32) -> u32 {
    use std::arch::x86_64::{
        _mm_castps_si128, _mm_cmple_ps, _mm_loadu_ps, _mm_movemask_epi8, _mm_packs_epi16,
        _mm_packs_epi32, _mm_set1_ps,
    };
    // SAFETY: SSE2 is part of the x86-64 baseline, and every load reads four
    // floats inside `window` (offsets 0, 4, ..., 28 of a 32-float array).
    unsafe {
        let v = _mm_set1_ps(v);
        let at = |k: usize| _mm_castps_si128(_mm_cmple_ps(_mm_loadu_ps(window[k..].as_ptr()), v));
        // Each comparison lane is 0 or -1, which the saturating packs keep,
        // in order: 16 byte lanes for entries k..k + 16.
        let sixteen = |k: usize| {
            let low = _mm_packs_epi32(at(k), at(k + 4));
            let high = _mm_packs_epi32(at(k + 8), at(k + 12));
            _mm_movemask_epi8(_mm_packs_epi16(low, high)) as u32
        };
        sixteen(0) | sixteen(16) << 16
    }
}

/// [`at_or_below_mask`] by four eight-wide AVX-512 compares into mask
/// registers (v >= entry, ordered, so a NaN on either side clears its bit
/// as `<=` does), joined into one 32-bit mask: nine instructions where the
/// SSE form takes 25 (a broadcast, eight loads, eight compares, six packs,
/// an insert and a byte mask; counted in the sampler's AVX2 copy).
///
/// Written as inline assembly so that it inlines into code compiled for any
/// target features (the sampler's AVX2 copy, the baseline): an intrinsic
/// needing AVX-512 would stay an out-of-line call there. It uses ymm16 and
/// k1 to k4, which code compiled without AVX-512 never holds values in: a
/// register numbered 16 or more leaves the upper halves of registers 0 to
/// 15 clean for SSE code around it, and 256 bits rather than 512 keep
/// clear of the lower clock some processors run 512-bit work at.
///
/// A tabulated sampler's `sample` compares three such windows on every
/// call (the θ_o cell and, for the uniform tabulation, the φ_h row; for the
/// adaptive one, both curves' guide windows), all on the chain of dependent
/// steps, so where the processor has AVX-512 the shorter form takes
/// instructions off that chain three times in every call of `sample`.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and BW.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn at_or_below_mask_evex(window: &[f32; WINDOW], v: f32) -> u32 {
    let mask: u32;
    // SAFETY: the caller guarantees the instructions exist; the four loads
    // read the 128 bytes of `window`; no memory is written, no stack used.
    unsafe {
        std::arch::asm!(
            "vbroadcastss ymm16, {v}",
            "vcmpps k1, ymm16, ymmword ptr [{p}], 29",
            "vcmpps k2, ymm16, ymmword ptr [{p} + 32], 29",
            "vcmpps k3, ymm16, ymmword ptr [{p} + 64], 29",
            "vcmpps k4, ymm16, ymmword ptr [{p} + 96], 29",
            "kunpckbw k1, k2, k1",
            "kunpckbw k3, k4, k3",
            "kunpckwd k1, k3, k1",
            "kmovd {mask:e}, k1",
            v = in(xmm_reg) v,
            p = in(reg) window.as_ptr(),
            mask = lateout(reg) mask,
            out("zmm16") _,
            out("k1") _,
            out("k2") _,
            out("k3") _,
            out("k4") _,
            options(pure, readonly, nostack, preserves_flags),
        );
    }
    mask
}

/// Bit k set where `window[k] <= v`.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn at_or_below_mask(window: &[f32; WINDOW], v: f32) -> u32 {
    mask_at_or_below(window, v)
}

/// Bit k set where `entries[k] <= key`, one entry at a time, for at most
/// 32 entries: every window compare's form for CPUs other than x86-64, and
/// the reference the tests hold the vector forms to.
#[inline(always)]
pub fn mask_at_or_below<K: Copy + PartialOrd>(entries: &[K], key: K) -> u32 {
    entries
        .iter()
        .enumerate()
        .fold(0, |mask, (k, &e)| mask | ((e <= key) as u32) << k)
}

/// The width of a short window: one eight-wide compare.
pub const SHORT_WINDOW: usize = 8;

/// The longest row counted by [`count_linear`].
pub const LINEAR_ROW: usize = 64;

/// The [`SHORT_WINDOW`] entries of `list` from `start` (which must leave
/// room for them).
#[inline(always)]
pub fn short_window(list: &[f32], start: usize) -> &[f32; SHORT_WINDOW] {
    list[start..start + SHORT_WINDOW]
        .try_into()
        .expect("the caller leaves room for a window")
}

/// The number of entries of a non-decreasing window of eight that are
/// `<= v`, for v not NaN.
///
/// On x86-64 this is two four-wide compares (SSE2, part of the baseline)
/// whose sign bits form a mask; the window is sorted, so the mask is a run
/// of ones from bit 0 and the count is the position of its first zero.
/// Elsewhere the entries are compared one by one.
#[inline(always)]
pub fn count_short_window(w: &[f32; SHORT_WINDOW], v: f32) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_cmple_ps, _mm_loadu_ps, _mm_movemask_ps, _mm_set1_ps};
        // SAFETY: SSE2 is part of the x86-64 baseline, and both loads read
        // four floats inside the eight of `w`.
        let mask = unsafe {
            let vv = _mm_set1_ps(v);
            let lo = _mm_cmple_ps(_mm_loadu_ps(w.as_ptr()), vv);
            let hi = _mm_cmple_ps(_mm_loadu_ps(w.as_ptr().add(4)), vv);
            (_mm_movemask_ps(lo) | (_mm_movemask_ps(hi) << 4)) as u32
        };
        (!mask).trailing_zeros() as usize
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        w.iter().map(|&c| (c <= v) as usize).sum()
    }
}

/// The number of entries of a non-decreasing `row` that are `<= v`, for a
/// row whose length is a multiple of [`SHORT_WINDOW`], at most
/// [`LINEAR_ROW`].
///
/// The last entry of each block of eight is compared first: the blocks
/// whose last entry is `<= v` are wholly counted, and only the next block
/// is counted entry by entry ([`count_short_window`]). Both steps are fixed
/// sequences of compares with no data-dependent branch, so a row of 32
/// costs three scalar and two four-wide compares.
#[inline(always)]
pub fn count_linear(row: &[f32], v: f32) -> usize {
    let blocks = row.len() / SHORT_WINDOW;
    let mut full = 0;
    for b in 0..blocks - 1 {
        full += (row[b * SHORT_WINDOW + SHORT_WINDOW - 1] <= v) as usize;
    }
    let start = full * SHORT_WINDOW;
    start + count_short_window(short_window(row, start), v)
}

/// Ask the CPU to bring `data[start..start + len]` into the first-level
/// cache without waiting for it: its first, middle and last cache lines
/// (all of a list of up to 48 entries). A hint with no effect on any
/// result: addresses past the end of `data` are allowed (a prefetch never
/// faults), so none are clamped.
///
/// A draw reads its conditional only after searching the marginal, one
/// cache miss after another on the chain of dependent steps; asking for the
/// conditional that the guide makes most likely as soon as u is known puts
/// that read in flight during the search.
#[inline(always)]
pub fn prefetch(data: &[f32], start: usize, len: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let first = data.as_ptr().wrapping_add(start);
        for offset in [0, len / 2, len.wrapping_sub(1)] {
            // SAFETY: SSE is part of the x86-64 baseline, and a prefetch
            // reads nothing the program sees: it may name any address.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(first.wrapping_add(offset) as *const i8) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (data, start, len);
    }
}

/// A cutpoint index (guide table) of a non-decreasing list of values in
/// [0, 1]: for each of G equal intervals of v, the range of entries that a
/// count for a v in that interval has still to compare.
///
/// With cell(v) = min(floor(v G), G - 1) (a monotone function of v, the
/// same in `f32` whatever the rounding), `lo[g]` is the number of entries e
/// with cell(e) < g. For v in cell g every entry counted by `lo[g]` is below
/// v and every entry from `lo[g + 1]` on is above it, so the count of
/// entries `<= v` is `lo[g]` plus the count within [`lo[g]`, `lo[g + 1]`):
/// exactly what a plain search returns. It is derived from the list (never
/// stored with it) and held as `u16`, so a list of more than 2^16 entries
/// gets no guide.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Guide {
    /// G + 1 counts; empty when there is no guide.
    lo: Box<[u16]>,
}

impl Guide {
    /// The guide of `list` with `cells` intervals (none for an empty list,
    /// zero cells or more than 2^16 entries).
    pub fn new(list: &[f32], cells: usize) -> Guide {
        if list.is_empty() || cells == 0 || list.len() > u16::MAX as usize {
            return Guide::default();
        }
        let mut lo = vec![0u16; cells + 1];
        let mut k = 0;
        for (g, lo) in lo.iter_mut().enumerate() {
            while k < list.len() && Self::cell(list[k], cells) < g {
                k += 1;
            }
            *lo = k as u16;
        }
        Guide { lo: lo.into() }
    }

    /// cell(v) = min(floor(v G), G - 1) for G = `cells`; negative values
    /// and NaN give 0. With a constant G the cell of a random number is
    /// known before the list is.
    #[inline(always)]
    pub fn cell(v: f32, cells: usize) -> usize {
        crate::fast::grid_cell(v * cells as f32, (cells - 1) as f32)
    }

    /// Whether there is no guide (see [`new`](Self::new)).
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.lo.is_empty()
    }

    /// The entries of the index: G + 1 counts, or none.
    pub fn counts(&self) -> &[u16] {
        &self.lo
    }

    /// The number of entries below every v of cell g, `lo[g]` (0 without a
    /// guide): where a count for such a v starts, and the count itself
    /// when the interval holds one entry or none.
    #[inline(always)]
    pub fn first(&self, g: usize) -> usize {
        self.lo.get(g).map_or(0, |&c| c as usize)
    }

    /// Heap bytes of the index.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(&*self.lo)
    }

    /// The number of entries of `data[start..start + n]`, the list the
    /// guide was built from, that are `<= v`, given g = [`cell`](Self::cell)
    /// of v (a guide must exist). A range of up to [`WINDOW`] entries, the
    /// common case, is compared in one window ([`count_window`]); a longer
    /// one (entries crowded into one interval) is searched.
    #[inline(always)]
    pub fn count(&self, data: &[f32], start: usize, v: f32, g: usize) -> usize {
        let (a, b) = (self.lo[g] as usize, self.lo[g + 1] as usize);
        a + count_one(data, start + a, b - a, v)
    }
}

/// Bit l set where `window[l] <= key`, for 16-bit values.
#[inline(always)]
pub fn window_at_or_below_u16(window: &[u16; WINDOW], key: u16) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        mask_u16_sse2(window, key)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        mask_at_or_below(window, key)
    }
}

/// Bit l set where `window[l] <= key`, for 8-bit values.
#[inline(always)]
pub fn window_at_or_below_u8(window: &[u8; WINDOW], key: u8) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        mask_u8_sse2(window, key)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        mask_at_or_below(window, key)
    }
}

/// [`window_at_or_below_u16`] by SSE2 (the x86-64
/// baseline): p <= key exactly when the saturating difference p - key is
/// zero; the word compares are narrowed to bytes and read as bit masks.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn mask_u16_sse2(window: &[u16; WINDOW], key: u16) -> u32 {
    use std::arch::x86_64::{
        __m128i, _mm_cmpeq_epi16, _mm_loadu_si128, _mm_movemask_epi8, _mm_packs_epi16,
        _mm_set1_epi16, _mm_setzero_si128, _mm_subs_epu16,
    };
    // SAFETY: SSE2 is part of the x86-64 baseline, and every load reads
    // eight values inside `window` (offsets 0, 8, 16 and 24 of 32).
    unsafe {
        let k = _mm_set1_epi16(key as i16);
        let zero = _mm_setzero_si128();
        let at = |l: usize| {
            let p = _mm_loadu_si128(window.as_ptr().add(l) as *const __m128i);
            _mm_cmpeq_epi16(_mm_subs_epu16(p, k), zero)
        };
        // Each word lane is 0 or -1, which the saturating pack keeps.
        let low = _mm_movemask_epi8(_mm_packs_epi16(at(0), at(8))) as u32;
        let high = _mm_movemask_epi8(_mm_packs_epi16(at(16), at(24))) as u32;
        low | high << 16
    }
}

/// [`window_at_or_below_u8`] by SSE2, as [`mask_u16_sse2`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn mask_u8_sse2(window: &[u8; WINDOW], key: u8) -> u32 {
    use std::arch::x86_64::{
        __m128i, _mm_cmpeq_epi8, _mm_loadu_si128, _mm_movemask_epi8, _mm_set1_epi8,
        _mm_setzero_si128, _mm_subs_epu8,
    };
    // SAFETY: SSE2 is part of the x86-64 baseline, and both loads read
    // sixteen values inside `window` (offsets 0 and 16 of 32).
    unsafe {
        let k = _mm_set1_epi8(key as i8);
        let zero = _mm_setzero_si128();
        let at = |l: usize| {
            let p = _mm_loadu_si128(window.as_ptr().add(l) as *const __m128i);
            _mm_movemask_epi8(_mm_cmpeq_epi8(_mm_subs_epu8(p, k), zero)) as u32
        };
        at(0) | at(16) << 16
    }
}

/// Bit k set where `window[k] <= key`, for unsigned 32-bit values: the
/// packed conditionals of the orientation-aware environment sampler, whose
/// entries are a quantised CDF value and a column in one `u32`.
///
/// On x86-64 eight four-wide SSE2 compares (the x86-64 baseline) of the
/// entries above the key, signed after flipping the sign bit of both sides
/// (which orders unsigned values as signed ones), narrowed to bytes by
/// saturating packs (which keep lanes of all ones or zeros) and read as
/// two 16-bit masks, inverted; elsewhere one entry at a time.
#[inline(always)]
pub fn window_at_or_below_u32(window: &[u32; WINDOW], key: u32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            __m128i, _mm_cmpgt_epi32, _mm_loadu_si128, _mm_movemask_epi8, _mm_packs_epi16,
            _mm_packs_epi32, _mm_set1_epi32, _mm_xor_si128,
        };
        let p = window.as_ptr() as *const __m128i;
        // SAFETY: SSE2 is part of the x86-64 baseline; the eight unaligned
        // loads read four u32 each, the 32 entries of `window`.
        unsafe {
            let sign = _mm_set1_epi32(i32::MIN);
            let k = _mm_xor_si128(_mm_set1_epi32(key as i32), sign);
            // All ones where the entry is above the key.
            let above =
                |i: usize| _mm_cmpgt_epi32(_mm_xor_si128(_mm_loadu_si128(p.add(i)), sign), k);
            let half = |i: usize| {
                let lo = _mm_packs_epi32(above(i), above(i + 1));
                let hi = _mm_packs_epi32(above(i + 2), above(i + 3));
                _mm_movemask_epi8(_mm_packs_epi16(lo, hi)) as u32
            };
            !(half(0) | (half(4) << 16))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        mask_at_or_below(window, key)
    }
}

/// [`window_at_or_below_u32`] for a window of [`SHORT_WINDOW`] entries:
/// two four-wide SSE2 compares on x86-64, as there, and their sign bits.
/// A fixed-size window lets the compare be straight-line code, where a
/// slice of unknown length would take a loop and its remainder.
#[inline(always)]
pub fn short_window_at_or_below_u32(window: &[u32; SHORT_WINDOW], key: u32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            __m128i, _mm_castsi128_ps, _mm_cmpgt_epi32, _mm_loadu_si128, _mm_movemask_ps,
            _mm_set1_epi32, _mm_xor_si128,
        };
        let p = window.as_ptr() as *const __m128i;
        // SAFETY: SSE2 is part of the x86-64 baseline; the two unaligned
        // loads read four u32 each, the eight entries of `window`.
        let above = unsafe {
            let sign = _mm_set1_epi32(i32::MIN);
            let k = _mm_xor_si128(_mm_set1_epi32(key as i32), sign);
            let above = |i: usize| {
                let v = _mm_xor_si128(_mm_loadu_si128(p.add(i)), sign);
                _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(v, k))) as u32
            };
            above(0) | above(1) << 4
        };
        !above & 0xff
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        mask_at_or_below(window, key)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every form of the compare gives the mask of `<=` on every pattern of
    /// one window, bit for bit: the portable fold, the SSE form always, the
    /// AVX-512 form where the CPU has it (the chosen one is tested either
    /// way). A CPU without AVX-512 says so.
    #[test]
    fn compares_agree() {
        #[cfg(target_arch = "x86_64")]
        let evex = crate::cpu::detected().mask_compares;
        #[cfg(target_arch = "x86_64")]
        if !evex {
            println!("no AVX-512 F+VL+BW here: its mask compare is not tested");
        }
        let mut state = 3u64;
        for _ in 0..2000 {
            let window: [f32; WINDOW] = std::array::from_fn(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
                [
                    0.0,
                    0.5,
                    1.0,
                    f32::NAN,
                    -0.0,
                    f32::INFINITY,
                    f32::NEG_INFINITY,
                    1e-40,
                ][(state >> 61) as usize]
            });
            for v in [0.0, 0.5, 1.0, f32::NAN, 0.25, -0.0, f32::INFINITY, 1e-40] {
                let expected = mask_at_or_below(&window, v);
                let plain = window
                    .iter()
                    .enumerate()
                    .filter(|(_, &e)| e <= v)
                    .fold(0u32, |m, (k, _)| m | 1 << k);
                assert_eq!(expected, plain);
                assert_eq!(at_or_below_mask(&window, v), expected);
                #[cfg(target_arch = "x86_64")]
                {
                    assert_eq!(at_or_below_mask_sse(&window, v), expected);
                    if evex {
                        // SAFETY: the CPU has been found to support
                        // AVX-512 F, VL and BW.
                        assert_eq!(unsafe { at_or_below_mask_evex(&window, v) }, expected);
                    }
                }
            }
        }
    }

    fn plain(list: &[f32], v: f32) -> usize {
        list.partition_point(|&e| e <= v)
    }

    /// A sorted list from arbitrary values, with runs of equal entries when
    /// `repeat` says so (flat CDF segments give those).
    fn sorted(mut values: Vec<f32>, repeat: &[bool]) -> Vec<f32> {
        values.sort_by(f32::total_cmp);
        for k in 1..values.len() {
            if repeat.get(k).copied().unwrap_or(false) {
                values[k] = values[k - 1];
            }
        }
        values
    }

    /// The search counts `expected`, for one key and in a lane of four.
    fn check(data: &[f32], start: usize, len: usize, v: f32, expected: usize) {
        let list = &data[start..start + len];
        let counts = [
            count_one(data, start, len, v),
            count_at_or_below(data, start, len, [0.5, v, -1.0, 2.0])[1],
        ];
        assert_eq!(counts, [expected; 2], "list {list:?} v {v}");
    }

    /// The count of `key` in `data[start..start + len]` equals the
    /// partition point, for an integer entry type.
    fn check_integers<K: Key + std::fmt::Debug>(data: &[K], start: usize, len: usize, key: K) {
        let list = &data[start..start + len];
        let expected = list.partition_point(|&e| e <= key);
        assert_eq!(
            count_one(data, start, len, key),
            expected,
            "list {list:?} key {key:?}"
        );
    }

    /// The one search counts like a partition point on lists of every
    /// integer entry type, of every length from empty to past two windows,
    /// inside buffers shorter and longer than a window, at every key from
    /// below the first entry to the type's largest value.
    #[test]
    fn integer_searches_equal_partition_point() {
        let mut state = 11u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            state >> 33
        };
        for total in [5usize, 31, 32, 40, 100] {
            let mut v: Vec<u32> = (0..total).map(|_| (next() % 300) as u32).collect();
            v.sort();
            let wide: Vec<u32> = v.iter().map(|&e| e * 14_000_000).collect();
            let w16: Vec<u16> = v.iter().map(|&e| (e * 200) as u16).collect();
            let w8: Vec<u8> = v.iter().map(|&e| (e * 255 / 299) as u8).collect();
            for start in [0, 1, total / 2] {
                for len in 0..=total - start {
                    for k in [0u32, 1, 77, 150, 299, 300] {
                        check_integers(&wide, start, len, k * 14_000_000);
                        check_integers(&wide, start, len, u32::MAX);
                        check_integers(&w16, start, len, (k * 200).min(65535) as u16);
                        check_integers(&w16, start, len, u16::MAX);
                        check_integers(&w8, start, len, (k * 255 / 299).min(255) as u8);
                    }
                }
            }
        }
    }

    /// The probes to compare at: every entry, its neighbours, the ends, NaN.
    fn probes(list: &[f32]) -> Vec<f32> {
        let mut v = vec![-1.0, 0.0, 0.5, 1.0, 2.0, f32::NAN, f32::INFINITY];
        for &e in list {
            v.extend([e, e.next_down(), e.next_up()]);
        }
        v
    }

    /// A prefetch of any range, empty, past the end or of an empty list,
    /// is only a hint: nothing is read and nothing panics.
    #[test]
    fn prefetch_takes_any_range() {
        let data = [0.5f32; 40];
        for (start, len) in [
            (0, 0),
            (0, 40),
            (39, 1),
            (38, 100),
            (1000, 5),
            (usize::MAX, usize::MAX),
        ] {
            prefetch(&data, start, len);
            prefetch(&[], start, len);
        }
    }

    /// Every search equals `partition_point` on every length up to 300, on
    /// lists with long runs of equal entries (adversarial for a search that
    /// assumed distinct vertices), at every entry and its neighbours.
    #[test]
    fn searches_equal_partition_point_on_runs_and_every_length() {
        for len in 0..300usize {
            for pattern in 0..3 {
                let list: Vec<f32> = (0..len)
                    .map(|k| match pattern {
                        0 => k as f32 / 300.0,
                        1 => (k / 7) as f32 / 64.0,
                        _ => {
                            if k < len / 2 {
                                0.0
                            } else {
                                1.0
                            }
                        }
                    })
                    .collect();
                // Embedded in a larger buffer, as the conditionals are,
                // with a window running past the end or not.
                let mut data = vec![9.0f32; 5];
                data.extend(&list);
                if len % 2 == 0 {
                    data.extend([-3.0; WINDOW]);
                }
                for v in probes(&list) {
                    let expected = plain(&list, v);
                    check(&data, 5, len, v, expected);
                    let lanes = count_at_or_below(&data, 5, len, [v, 0.25, -1.0, 7.0]);
                    assert_eq!(lanes, [expected, plain(&list, 0.25), 0, len]);
                }
            }
        }
    }

    proptest! {
        /// On random sorted lists with repeats, placed anywhere in a buffer
        /// (the window may run to its very end), every search equals
        /// `partition_point`.
        #[test]
        fn searches_equal_partition_point(
            values in prop::collection::vec(0.0f32..1.0, 0..80),
            repeat in prop::collection::vec(any::<bool>(), 80),
            before in 0usize..40,
            after in 0usize..40,
            v in prop::sample::select(vec![0.0f32, 0.3, 0.999, 1.0, -0.0]),
        ) {
            let list = sorted(values, &repeat);
            let mut data = vec![0.5f32; before];
            data.extend(&list);
            data.extend(std::iter::repeat_n(-1.0, after));
            for v in probes(&list).into_iter().chain([v]) {
                let expected = plain(&list, v);
                check(&data, before, list.len(), v, expected);
            }
        }

        /// A guide's count equals `partition_point` for lists whose entries
        /// crowd into few intervals (more than a window's worth in one, so
        /// the fallback search runs) or spread over many, whatever G, with
        /// the list anywhere in a buffer.
        #[test]
        fn guided_counts_equal_partition_point(
            values in prop::collection::vec(0.0f32..1.0, 1..120),
            crowd in prop::sample::select(vec![1.0f32, 0.05, 0.001]),
            repeat in prop::collection::vec(any::<bool>(), 120),
            cells in prop::sample::select(vec![1usize, 3, 32, 256]),
            before in 0usize..40,
            after in 0usize..40,
        ) {
            // `crowd` squeezes the values towards 1, as the flat tail of a
            // peaked CDF does.
            let squeezed = values.iter().map(|&v| 1.0 - crowd * (1.0 - v)).collect();
            let list = sorted(squeezed, &repeat);
            let guide = Guide::new(&list, cells);
            prop_assert_eq!(guide.counts().len(), cells + 1);
            let mut data = vec![0.5f32; before];
            data.extend(&list);
            data.extend(std::iter::repeat_n(-1.0, after));
            for v in probes(&list) {
                let count = guide.count(&data, before, v, Guide::cell(v, cells));
                prop_assert_eq!(count, plain(&list, v), "v {}", v);
            }
        }
    }

    /// The SSE2 masks of narrow windows are those of one compare per entry,
    /// for sorted windows and keys at, just below and just above each entry
    /// and at the ends of the type's range.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn narrow_masks_equal_the_portable_masks() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..20 {
            let mut v: Vec<u32> = (0..WINDOW)
                .map(|_| {
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
                    ((state >> 33) % 65536) as u32
                })
                .collect();
            v.sort_unstable();
            let w16: [u16; WINDOW] = std::array::from_fn(|l| v[l] as u16);
            let w8: [u8; WINDOW] = std::array::from_fn(|l| (v[l] >> 8) as u8);
            let mut keys16: Vec<u16> = vec![0, 1, 0x7fff, 0x8000, 0xfffe, 0xffff];
            let mut keys8: Vec<u8> = vec![0, 1, 0x7f, 0x80, 0xfe, 0xff];
            for l in 0..WINDOW {
                keys16.extend([w16[l], w16[l].wrapping_sub(1), w16[l].wrapping_add(1)]);
                keys8.extend([w8[l], w8[l].wrapping_sub(1), w8[l].wrapping_add(1)]);
            }
            for k in keys16 {
                assert_eq!(mask_u16_sse2(&w16, k), mask_at_or_below(&w16, k), "{k}");
            }
            for k in keys8 {
                assert_eq!(mask_u8_sse2(&w8, k), mask_at_or_below(&w8, k), "{k}");
            }
        }
    }

    /// The SSE2 masks of 32-bit windows are those of one compare per entry,
    /// for random windows and keys at the edges of the signed and unsigned
    /// ranges.
    #[test]
    fn u32_masks_equal_the_portable_masks() {
        let mut state = 5u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 32) as u32
        };
        for _ in 0..2000 {
            let w: [u32; WINDOW] = std::array::from_fn(|_| next());
            let short: &[u32; SHORT_WINDOW] = w[..SHORT_WINDOW].try_into().unwrap();
            let keys = [
                0,
                1,
                i32::MAX as u32,
                1 << 31,
                u32::MAX - 1,
                u32::MAX,
                next(),
                w[3],
                w[20],
            ];
            for key in keys {
                assert_eq!(window_at_or_below_u32(&w, key), mask_at_or_below(&w, key));
                assert_eq!(
                    short_window_at_or_below_u32(short, key),
                    mask_at_or_below(short, key)
                );
            }
        }
    }
}
