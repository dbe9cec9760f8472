//! The lane searches of [`lanes`](super::lanes) over lists of 8- and
//! 16-bit entries: the quantised CDF values and grid positions of the
//! packed samplers, which keep a curve's vertex in 2 or 3 bytes instead of
//! the 8 of two `f32`.
//!
//! One 32-bit gather at an entry's address reads that entry and the next
//! (two for 16-bit entries, four bytes for 8-bit ones), so the two ends of
//! a segment, or a conditional's two offsets, come in one gather. The
//! search is the same binary lifting as [`Bracket::lift`](super::lanes::Bracket::lift):
//! steps fixed by the longest list, probes clamped to each lane's last
//! entry, and the count found is exactly that of a plain search (the
//! number of entries `<= key`), clamped to the lane's last index, so the
//! segment a batch lands in is the one a draw at a time finds.
//!
//! The reads at indices held in registers stay `unsafe`
//! ([`Pairs::gather`], [`lift_at_or_below`]); [`Pairs`] says up to which index a
//! gather may read, and the callers derive their indices from what a
//! decoder checked (offsets inside their arrays, a CDF ending at its
//! largest value) and pad their arrays so that the last pair is readable.

// The loops over groups index several parallel arrays of registers by the
// group number, as in `lanes`.
#![allow(clippy::needless_range_loop)]

use super::lanes::GROUPS;
use crate::cpu::Avx2;
use std::arch::x86_64::*;
use std::marker::PhantomData;

/// The entry types [`Pairs`] reads: `u8` and `u16`.
pub trait Narrow: sealed::Sealed + Copy + 'static {
    /// Bytes per entry.
    const BYTES: usize;
}

impl Narrow for u8 {
    const BYTES: usize = 1;
}

impl Narrow for u16 {
    const BYTES: usize = 2;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for u8 {}
    impl Sealed for u16 {}
}

/// An array of narrow entries read by the lanes, two consecutive entries
/// per gather (as `i32` lanes, zero-extended).
#[derive(Clone, Copy)]
pub struct Pairs<'a, T: Narrow> {
    bytes: *const u8,
    /// The largest index whose gather stays inside the array: a gather
    /// reads four bytes.
    max_index: usize,
    _array: PhantomData<&'a [T]>,
}

impl<'a, T: Narrow> Pairs<'a, T> {
    /// Lanes read `array`, which must hold at least four bytes (two 16-bit
    /// or four 8-bit entries) and at most [`MAX_ENTRIES`](super::lanes::MAX_ENTRIES)
    /// entries.
    #[inline(always)]
    pub fn new(array: &'a [T]) -> Option<Self> {
        let bytes = array.len() * T::BYTES;
        (bytes >= 4 && array.len() <= super::lanes::MAX_ENTRIES).then(|| Pairs {
            bytes: array.as_ptr() as *const u8,
            max_index: (bytes - 4) / T::BYTES,
            _array: PhantomData,
        })
    }

    /// The largest index [`gather`](Self::gather) may read at: the array's
    /// length less 2 for 16-bit entries, less 4 for 8-bit ones.
    #[inline(always)]
    pub fn max_index(&self) -> usize {
        self.max_index
    }

    /// Entries `index` and `index + 1` of the array in every lane.
    ///
    /// # Safety
    /// Every index is at least 0 and at most [`max_index`](Self::max_index).
    #[inline(always)]
    pub unsafe fn gather(&self, _: Avx2, index: __m256i) -> (__m256i, __m256i) {
        // SAFETY: the token proves the CPU has AVX2; each lane reads the
        // four bytes at `index * BYTES`, inside the array by the caller's
        // contract and the definition of `max_index`.
        unsafe {
            let (word, second) = if T::BYTES == 1 {
                let w = _mm256_i32gather_epi32::<1>(self.bytes as *const i32, index);
                (w, _mm256_srli_epi32::<8>(w))
            } else {
                let w = _mm256_i32gather_epi32::<2>(self.bytes as *const i32, index);
                (w, _mm256_srli_epi32::<16>(w))
            };
            let mask = _mm256_set1_epi32(if T::BYTES == 1 { 0xff } else { 0xffff });
            (_mm256_and_si256(word, mask), _mm256_and_si256(second, mask))
        }
    }
}

/// For each lane, the number of entries `<= key` of its non-decreasing
/// list `data[base ..= base + last]`, clamped to `last`: the search of a
/// curve's inner vertices (the list then holds them and the curve's last
/// vertex, which bounds the count), by binary lifting from the power of
/// two `step`, which must be at least half of every lane's `last + 1`
/// rounded up to a power of two. Keys and entries compare as `i32`.
///
/// # Safety
/// In every lane `base >= 0`, `last >= 0` and `base + last <=
/// data.max_index()`: every probe is clamped into `[base, base + last]`,
/// and the count returned is at most `last`.
#[inline(always)]
pub unsafe fn lift_at_or_below<T: Narrow>(
    cpu: Avx2,
    data: &Pairs<'_, T>,
    base: &[__m256i; GROUPS],
    last: &[__m256i; GROUPS],
    key: &[__m256i; GROUPS],
    mut step: usize,
) -> [__m256i; GROUPS] {
    // SAFETY: the token proves the CPU has AVX2; every gather reads at
    // `min(at + step - 1, base + last)` with `at >= base`, inside the
    // array by the caller's contract.
    unsafe {
        let mut at = [_mm256_setzero_si256(); GROUPS];
        let mut end = [_mm256_setzero_si256(); GROUPS];
        for g in 0..GROUPS {
            at[g] = base[g];
            end[g] = _mm256_add_epi32(base[g], last[g]);
        }
        while step > 0 {
            let s = _mm256_set1_epi32(step as i32);
            let offset = _mm256_set1_epi32(step as i32 - 1);
            for g in 0..GROUPS {
                let probe = _mm256_min_epi32(_mm256_add_epi32(at[g], offset), end[g]);
                let (entry, _) = data.gather(cpu, probe);
                let above = _mm256_cmpgt_epi32(entry, key[g]);
                at[g] = _mm256_add_epi32(at[g], _mm256_andnot_si256(above, s));
            }
            step /= 2;
        }
        let mut count = [_mm256_setzero_si256(); GROUPS];
        for g in 0..GROUPS {
            count[g] = _mm256_min_epi32(_mm256_sub_epi32(at[g], base[g]), last[g]);
        }
        count
    }
}

/// The first step of [`lift_at_or_below`] for lists of up to `longest`
/// entries (their `last + 1`): half of `longest` rounded up to a power of
/// two, 0 for lists of one entry.
#[inline(always)]
pub fn first_step(longest: usize) -> usize {
    longest.next_power_of_two() / 2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::search::lanes::{lanes_i32, load_i32, STAGE};
    use proptest::prelude::*;

    fn registers(cpu: Avx2, v: &[i32; STAGE]) -> [__m256i; GROUPS] {
        std::array::from_fn(|g| load_i32(cpu, &v[8 * g..]))
    }

    fn unpack(cpu: Avx2, r: &[__m256i; GROUPS]) -> Vec<i32> {
        r.iter().flat_map(|&v| lanes_i32(cpu, v)).collect()
    }

    /// Sorted lists one after another, each ending at the type's largest
    /// value; every lane searches one of them for a key below it, and the
    /// count is that of `partition_point` over the list's inner entries.
    fn check<T: Narrow + Into<i32>>(lists: &[Vec<T>], keys: &[i32], pad: usize, zero: T) {
        let Some(cpu) = crate::cpu::avx2() else {
            println!("skipped: this CPU has no AVX2 and FMA (or ACDF_CPU=portable)");
            return;
        };
        let mut data: Vec<T> = Vec::new();
        let mut starts = Vec::new();
        for l in lists {
            starts.push(data.len());
            data.extend(l);
        }
        data.extend(std::iter::repeat_n(zero, pad));
        let pairs = Pairs::new(&data).expect("at least four bytes");
        let (mut base, mut last, mut key) = ([0; STAGE], [0; STAGE], [0; STAGE]);
        let mut longest = 1;
        for lane in 0..STAGE {
            let which = lane % lists.len();
            base[lane] = starts[which] as i32 + 1;
            last[lane] = lists[which].len() as i32 - 2;
            key[lane] = keys[lane % keys.len()];
            longest = longest.max(lists[which].len() - 1);
        }
        // SAFETY: every list has at least two entries and the padding
        // keeps its last pair readable.
        let count = unsafe {
            lift_at_or_below(
                cpu,
                &pairs,
                &registers(cpu, &base),
                &registers(cpu, &last),
                &registers(cpu, &key),
                first_step(longest),
            )
        };
        let count = unpack(cpu, &count);
        for lane in 0..STAGE {
            let list = &lists[lane % lists.len()];
            let inner = &list[1..list.len() - 1];
            let want = inner.partition_point(|&e| e.into() <= key[lane]);
            assert_eq!(count[lane] as usize, want, "lane {lane}");
        }
        // The pairs read at every segment: its two ends.
        let index: [i32; STAGE] = std::array::from_fn(|l| (l % (data.len() - pad)) as i32);
        for g in 0..GROUPS {
            // SAFETY: every index is below the unpadded length.
            let (a, b) = unsafe { pairs.gather(cpu, load_i32(cpu, &index[8 * g..])) };
            for (l, (a, b)) in lanes_i32(cpu, a)
                .into_iter()
                .zip(lanes_i32(cpu, b))
                .enumerate()
            {
                let i = index[8 * g + l] as usize;
                assert_eq!((a, b), (data[i].into(), data[i + 1].into()));
            }
        }
    }

    /// A list like a quantised CDF: 0, then the running sums of `steps`
    /// held below `top`, then `top`.
    fn rising(steps: impl Iterator<Item = u32>, top: u32) -> impl Iterator<Item = u32> {
        let sums = steps.scan(0u32, move |acc, d| {
            *acc = (*acc + d).min(top - 1);
            Some(*acc)
        });
        std::iter::once(0).chain(sums).chain(std::iter::once(top))
    }

    proptest! {
        #[test]
        fn sixteen_bit_counts_are_those_of_a_plain_search(
            steps in prop::collection::vec(prop::collection::vec(0u16..3000, 0..70), 1..5),
            keys in prop::collection::vec(0i32..65535, 1..40),
        ) {
            let lists: Vec<Vec<u16>> = steps.iter().map(|s| {
                rising(s.iter().map(|&d| d as u32), 65535).map(|v| v as u16).collect()
            }).collect();
            check(&lists, &keys, 1, 0u16);
        }

        #[test]
        fn eight_bit_counts_are_those_of_a_plain_search(
            steps in prop::collection::vec(prop::collection::vec(0u8..20, 0..40), 1..5),
            keys in prop::collection::vec(0i32..255, 1..40),
        ) {
            let lists: Vec<Vec<u8>> = steps.iter().map(|s| {
                rising(s.iter().map(|&d| d as u32), 255).map(|v| v as u8).collect()
            }).collect();
            check(&lists, &keys, 3, 0u8);
        }
    }

    #[test]
    fn a_key_above_the_last_entry_stops_at_the_last_index() {
        let Some(cpu) = crate::cpu::avx2() else {
            println!("skipped: this CPU has no AVX2 and FMA (or ACDF_CPU=portable)");
            return;
        };
        let data: Vec<u16> = vec![0, 5, 9, 12, 0];
        let pairs = Pairs::new(&data).expect("ten bytes");
        assert_eq!(pairs.max_index(), 3);
        // SAFETY: the list is data[1..=2], so base + last = 2 is below
        // max_index = 3.
        let count = unsafe {
            lift_at_or_below(
                cpu,
                &pairs,
                &[_mm256_set1_epi32(1); GROUPS],
                &[_mm256_set1_epi32(1); GROUPS],
                &[_mm256_set1_epi32(1000); GROUPS],
                1,
            )
        };
        assert!(unpack(cpu, &count).iter().all(|&c| c == 1));
    }
}
