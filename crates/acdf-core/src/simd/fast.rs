//! Arctangent and sine/cosine for the samplers' hot paths.
//!
//! A sampler maps a half vector to table coordinates (two arctangents) and
//! back (a sine and cosine per axis) on every draw and every density; the
//! libm functions cost more than the table search itself. These versions
//! are branch-free (a polynomial for the arctangent, a table of 64 angles
//! and short polynomials for the sine and cosine), accurate to a few 1e-7
//! rad, with no libm call, and they are the same in `sample` and `pdf`, so
//! the two stay consistent.

use std::f32::consts::{FRAC_PI_2, PI};

/// Coefficients c_k of atan(a) ≈ a Σ c_k a^{2k} on [0, 1]: the Chebyshev
/// interpolant of atan(√t)/√t in t = a² at degree 7, converted to powers of
/// t. Its error is below 6.4e-8 rad, under the 1.2e-7 rad of `f32` rounding
/// of a result near π, so the approximation adds nothing a caller can see
/// beyond an ulp or two (the tests check 4e-7 rad against `f64`).
const ATAN_COEFFICIENTS: [f32; 8] = [
    0.999_999_9,
    -0.333_318_13,
    0.199_669_62,
    -0.140_032_9,
    0.098_688_65,
    -0.058_829_75,
    0.023_780_52,
    -0.004_559_792,
];

/// atan(a) for a in [0, 1], by the polynomial of [`ATAN_COEFFICIENTS`].
#[inline(always)]
fn atan_unit(a: f32) -> f32 {
    // Estrin's form, as in `sin_cos_turns`: four pairs in t, combined with
    // t² and t⁴.
    let t = a * a;
    let t2 = t * t;
    let t4 = t2 * t2;
    let c = &ATAN_COEFFICIENTS;
    let p01 = c[0] + c[1] * t;
    let p23 = c[2] + c[3] * t;
    let p45 = c[4] + c[5] * t;
    let p67 = c[6] + c[7] * t;
    let p = (p01 + p23 * t2) + (p45 + p67 * t2) * t4;
    a * p
}

/// atan2(y, x) in [-π, π] without a libm call, to within 4e-7 rad; 0 for
/// (0, 0), and a finite angle for NaN input (0 when x is not negative). The
/// sampler's inverse map uses it in `sample` and `pdf` alike, so the two
/// stay consistent exactly; its error only moves cell boundaries by a
/// fraction of an ulp of the angle.
#[inline(always)]
pub fn fast_atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    // a = min / max in [0, 1]; NaN (from 0/0, an infinity or a NaN input)
    // fails the comparison and becomes 0.
    let a = ax.min(ay) / ax.max(ay);
    let a = if a >= 0.0 && !(x.is_nan() || y.is_nan()) {
        a.min(1.0)
    } else {
        0.0
    };
    let r = atan_unit(a);
    // The octant fix-ups r -> π/2 - r (|y| > |x|) and r -> π - r (x < 0)
    // as arithmetic on 0/1 factors rather than branches: the signs of a
    // sampler's half vectors are random, so branches would be mispredicted
    // half the time. Each step is exact or a single rounding, as the
    // subtraction it replaces.
    let steep = (ay > ax) as u32 as f32;
    let r = steep * FRAC_PI_2 + (1.0 - 2.0 * steep) * r;
    let left = (x < 0.0) as u32 as f32;
    let r = left * PI + (1.0 - 2.0 * left) * r;
    // r >= 0 here, so the sign of a negative y can be or-ed in.
    f32::from_bits(r.to_bits() | (((y < 0.0) as u32) << 31))
}

/// v truncated toward zero, as `v as i32` gives it for |v| < 2^30; beyond
/// that v is first clamped to ±2^30, and NaN gives -2^30.
///
/// `as i32` saturates and maps NaN to 0, which x86-64 does with a compare
/// and two conditional moves around the conversion, one lane at a time; a
/// clamp written as two selects (`maxps`/`minps`) and an unchecked
/// conversion keep a loop over many values in SIMD (one `cvttps2dq` for
/// eight lanes).
#[inline(always)]
pub fn truncate_i32(v: f32) -> i32 {
    const LIMIT: f32 = 1_073_741_824.0;
    // Selects in the operand order of maxps and minps: a NaN v loses.
    let v = if v > -LIMIT { v } else { -LIMIT };
    let v = if v < LIMIT { v } else { LIMIT };
    // SAFETY: v is finite and within ±2^30, inside i32's range.
    unsafe { v.to_int_unchecked::<i32>() }
}

/// floor(t) clamped to [0, top] for an integer-valued `top` in [0, 2^24]:
/// the cell of a scaled coordinate t = x n on a grid whose last cell is
/// `top` = n - 1. NaN and negative t give 0, t beyond `top` (+∞ included)
/// gives `top`, exactly as `(t as u32 as usize).min(top)` would. Any other
/// `top` (negative, larger, NaN) still gives a cell in [0, 2^24].
///
/// The saturating `as u32` costs a conversion, two compares and two
/// conditional moves, and the `min` two more instructions; clamping in
/// `f32` first (selects in the operand order of `maxss`/`minss`, so that
/// NaN loses) leaves one unchecked conversion. Since `top` is an integer,
/// flooring the clamped value equals clamping the floor.
#[inline(always)]
pub fn grid_cell(t: f32, top: f32) -> usize {
    const LARGEST: f32 = 16_777_216.0;
    // Kept in [0, 2^24] whatever it is (NaN included); off the chain from t.
    let top = if top < LARGEST { top } else { LARGEST };
    let top = if top > 0.0 { top } else { 0.0 };
    let t = if t > 0.0 { t } else { 0.0 };
    let t = if t < top { t } else { top };
    // SAFETY: whatever t and top were, t is now in [0, 2^24], inside u32's
    // range.
    unsafe { t.to_int_unchecked::<u32>() as usize }
}

/// 1.5 · 2^23: added to an `f32` of magnitude below 2^22 and taken away
/// again, it leaves the value rounded to the nearest integer (ties to even),
/// since the sum's unit in the last place is 1.
const ROUND_TO_INTEGER: f32 = 12_582_912.0;

/// Entries of [`TURN_TABLE`], one per 64th of a turn: a power of two, so
/// that the entry of an angle is the low bits of its rounded step count.
const TURN_STEPS: usize = 64;

/// One step of the table, 2π/64 radians, in `f64`.
const STEP: f64 = std::f64::consts::TAU / TURN_STEPS as f64;

/// (sin a, cos a) by their Taylor series in `f64`, for |a| <= π/2: 40 terms
/// leave only the rounding of the sum, about 1e-16, far below the `f32`
/// rounding of the table. Run by the compiler, to fill [`TURN_TABLE`].
const fn sin_cos_series(a: f64) -> (f64, f64) {
    let (mut sin, mut cos) = (0.0, 0.0);
    // term = a^n / n!; even n go to the cosine, odd n to the sine, with
    // the sign of (-1)^(n/2). 40 terms are many more than |a| <= π/2 needs.
    let mut term = 1.0;
    let mut n = 0;
    while n < 40 {
        let signed = if (n / 2) % 2 == 0 { term } else { -term };
        if n % 2 == 0 {
            cos += signed;
        } else {
            sin += signed;
        }
        n += 1;
        term *= a / n as f64;
    }
    (sin, cos)
}

/// (sin, cos)(2πk/64) for k = 0..64, each rounded once to `f32`.
static TURN_TABLE: [[f32; 2]; TURN_STEPS] = {
    let mut table = [[0.0f32; 2]; TURN_STEPS];
    let mut k = 0;
    while k < TURN_STEPS {
        // The series of the angle within its quarter turn (below π/2, where
        // its terms stay small), turned by whole quarters exactly.
        let quarter = TURN_STEPS / 4;
        let (s, c) = sin_cos_series(STEP * (k % quarter) as f64);
        let (sin, cos) = match k / quarter {
            0 => (s, c),
            1 => (c, -s),
            2 => (-s, -c),
            _ => (-c, s),
        };
        table[k] = [sin as f32, cos as f32];
        k += 1;
    }
    table
};

/// The Taylor coefficients, in powers of the remainder d in steps (|d| <=
/// 1/2, an angle a = d · 2π/64 of at most π/64), of sin a ≈ a - a³/6 and
/// cos a ≈ 1 - a²/2 + a⁴/24, the step's powers folded in. Their truncation
/// errors at |a| = π/64 are 2.4e-9 and 1.9e-11.
const SIN_1: f32 = STEP as f32;
const SIN_3: f32 = (-STEP * STEP * STEP / 6.0) as f32;
const COS_2: f32 = (-STEP * STEP / 2.0) as f32;
const COS_4: f32 = (STEP * STEP * STEP * STEP / 24.0) as f32;

/// (sin 2πt, cos 2πt) for an angle t in turns, without a libm call: the
/// table entry of the nearest 64th of a turn, turned by the rest through the
/// angle-sum formulas (`sin_cos_steps` of 64 t). Within 2e-7 of the exact
/// values for |t| < 2^16; NaN for a NaN or infinite t.
#[inline(always)]
pub fn sin_cos_turns(t: f32) -> (f32, f32) {
    sin_cos_steps(t * TURN_STEPS as f32)
}

/// (sin(πs/2), cos(πs/2)) for an angle s in quarter turns, as
/// [`sin_cos_turns`] computes it (`sin_cos_steps` of 16 s).
#[inline(always)]
pub fn sin_cos_quarter_turns(s: f32) -> (f32, f32) {
    sin_cos_steps(s * (TURN_STEPS / 4) as f32)
}

/// (sin, cos) of `steps` 64ths of a turn: the table entry of the nearest
/// whole step k, turned by the rest d = steps - k (|d| <= 1/2, at most
/// π/64 radians) through the angle-sum formulas, with the sine and cosine
/// of d from [`SIN_1`].. [`COS_4`]. k is split off exactly for |steps| <
/// 2^22 (angles below 2^16 turns), so the error is that of `f32` rounding:
/// within 2e-7 of the exact values (the tests measure it). NaN and
/// infinities give NaN.
///
/// Why a table of 64ths rather than a reduction to the nearest quarter turn
/// with polynomials of degree 9 and 8 in the rest: the table entry is read
/// while d is being formed, and the short polynomials and the turn make a
/// shorter chain, which every one-at-a-time `sample` waits for. The batch
/// forms, which must pick the entries in their lanes
/// ([`sin_cos_turns_each`]), lose a little against polynomials in SIMD,
/// which need no table; `sample` one call at a time is the path that
/// matters here.
#[inline(always)]
fn sin_cos_steps(steps: f32) -> (f32, f32) {
    let shifted = steps + ROUND_TO_INTEGER;
    let k = shifted - ROUND_TO_INTEGER;
    // Exact: |steps - k| <= 1/2 and both are multiples of steps' ulp.
    let d = steps - k;
    // The sum holds 2^22 + k in its mantissa, whose low six bits are k mod
    // 64 in two's complement: the entry of k, the table being periodic.
    let [sin_k, cos_k] = TURN_TABLE[shifted.to_bits() as usize & (TURN_STEPS - 1)];
    let d2 = d * d;
    let sin_d = d * (SIN_1 + d2 * SIN_3);
    let cos_d = 1.0 + d2 * (COS_2 + d2 * COS_4);
    (sin_k * cos_d + cos_k * sin_d, cos_k * cos_d - sin_k * sin_d)
}

/// [`sin_cos_turns`] of every `turns[i]` into `sin[i]`, `cos[i]` (over the
/// shortest of the three lengths), bit for bit: eight at a time in AVX2
/// lanes where the CPU has it, the table entries picked from registers (a
/// loop over the scalar form would read them one at a time).
pub fn sin_cos_turns_each(turns: &[f32], sin: &mut [f32], cos: &mut [f32]) {
    sin_cos_steps_each(TURN_STEPS as f32, turns, sin, cos);
}

/// [`sin_cos_quarter_turns`] of every `quarter_turns[i]`, as
/// [`sin_cos_turns_each`] does it.
pub fn sin_cos_quarter_turns_each(quarter_turns: &[f32], sin: &mut [f32], cos: &mut [f32]) {
    sin_cos_steps_each((TURN_STEPS / 4) as f32, quarter_turns, sin, cos);
}

/// [`sin_cos_steps`] of `scale · angles[i]` for every i.
fn sin_cos_steps_each(scale: f32, angles: &[f32], sin: &mut [f32], cos: &mut [f32]) {
    let n = angles.len().min(sin.len()).min(cos.len());
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    if let Some(cpu) = crate::cpu::avx2() {
        // SAFETY: the token proves the CPU has AVX2, the one requirement of
        // the function's target features.
        done = unsafe { sin_cos_steps_avx2(cpu, scale, &angles[..n], sin, cos) };
    }
    for i in done..n {
        (sin[i], cos[i]) = sin_cos_steps(angles[i] * scale);
    }
}

/// [`sin_cos_steps`] of `scale · angles[i]` in eight lanes at a time, the
/// same IEEE operations in the same order; returns how many it did (a
/// multiple of eight), leaving the rest to the caller. Panics if `sin` or
/// `cos` is shorter than that.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn sin_cos_steps_avx2(
    cpu: crate::cpu::Avx2,
    scale: f32,
    angles: &[f32],
    sin: &mut [f32],
    cos: &mut [f32],
) -> usize {
    use std::arch::x86_64::*;
    let n = angles.len() / 8 * 8;
    assert!(sin.len() >= n && cos.len() >= n);
    let set = _mm256_set1_ps;
    let quarter = QuarterLanes::load(cpu);
    for i in (0..n).step_by(8) {
        // SAFETY: i + 8 <= n <= angles.len().
        let angles = unsafe { _mm256_loadu_ps(angles.as_ptr().add(i)) };
        let steps = _mm256_mul_ps(angles, set(scale));
        let shifted = _mm256_add_ps(steps, set(ROUND_TO_INTEGER));
        let k = _mm256_sub_ps(shifted, set(ROUND_TO_INTEGER));
        let d = _mm256_sub_ps(steps, k);
        let (sin_k, cos_k) = turn_entries_lanes(cpu, _mm256_castps_si256(shifted), &quarter);
        let d2 = _mm256_mul_ps(d, d);
        let sin_d = _mm256_mul_ps(d, _mm256_add_ps(set(SIN_1), _mm256_mul_ps(d2, set(SIN_3))));
        let cos_d = _mm256_add_ps(
            set(1.0),
            _mm256_mul_ps(d2, _mm256_add_ps(set(COS_2), _mm256_mul_ps(d2, set(COS_4)))),
        );
        let s = _mm256_add_ps(_mm256_mul_ps(sin_k, cos_d), _mm256_mul_ps(cos_k, sin_d));
        let c = _mm256_sub_ps(_mm256_mul_ps(cos_k, cos_d), _mm256_mul_ps(sin_k, sin_d));
        // SAFETY: i + 8 <= n, and both outputs hold n floats (checked
        // above).
        unsafe {
            _mm256_storeu_ps(sin.as_mut_ptr().add(i), s);
            _mm256_storeu_ps(cos.as_mut_ptr().add(i), c);
        }
    }
    n
}

/// The first quarter turn of [`TURN_TABLE`] (entries 0..16) in four
/// registers: sines of entries 0..8 and 8..16, cosines likewise.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct QuarterLanes {
    sin: [std::arch::x86_64::__m256; 2],
    cos: [std::arch::x86_64::__m256; 2],
}

#[cfg(target_arch = "x86_64")]
impl QuarterLanes {
    #[inline(always)]
    fn load(_: crate::cpu::Avx2) -> Self {
        use std::arch::x86_64::*;
        let column = |c: usize, from: usize| {
            let v: [f32; 8] = std::array::from_fn(|l| TURN_TABLE[from + l][c]);
            // SAFETY: the token proves the CPU has AVX2; the load reads the
            // eight floats of `v`.
            unsafe { _mm256_loadu_ps(v.as_ptr()) }
        };
        QuarterLanes {
            sin: [column(0, 0), column(0, 8)],
            cos: [column(1, 0), column(1, 8)],
        }
    }
}

/// The table entries (sin, cos) of the step counts k mod 64 held in the low
/// bits of `shifted`, from registers: entry 16q + r is entry r turned by q
/// quarter turns, which swaps sine and cosine for odd q and flips their
/// signs as the table was filled (`TURN_TABLE`), so the values are the
/// table's bit for bit.
///
/// Why registers rather than memory: reading the entries from the table as
/// eight 8-byte loads per eight angles puts a round trip of the indices
/// through memory (stored from the vector, reloaded as addresses) and
/// eight loads on the chain of every eight angles of the batch forms
/// (`sample_each`, `sample_batch` of the tabulated samplers), where
/// permutes and blends pick every entry from the first quarter turn's,
/// held in four registers (`QuarterLanes`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn turn_entries_lanes(
    _: crate::cpu::Avx2,
    shifted: std::arch::x86_64::__m256i,
    quarter: &QuarterLanes,
) -> (std::arch::x86_64::__m256, std::arch::x86_64::__m256) {
    use std::arch::x86_64::*;
    // SAFETY: the token proves the CPU has AVX2; register arithmetic only.
    unsafe {
        let r = _mm256_and_si256(shifted, _mm256_set1_epi32(15));
        let q = _mm256_srli_epi32::<4>(shifted);
        // Entries 8..16 where bit 3 of r is set.
        let high = _mm256_castsi256_ps(_mm256_slli_epi32::<28>(r));
        let pick = |v: &[__m256; 2]| {
            _mm256_blendv_ps(
                _mm256_permutevar8x32_ps(v[0], r),
                _mm256_permutevar8x32_ps(v[1], r),
                high,
            )
        };
        let (s, c) = (pick(&quarter.sin), pick(&quarter.cos));
        let odd = _mm256_castsi256_ps(_mm256_slli_epi32::<31>(q));
        let (sin, cos) = (_mm256_blendv_ps(s, c, odd), _mm256_blendv_ps(c, s, odd));
        // The sine is negated for q = 2, 3 (bit 1 of q), the cosine for q = 1,
        // 2 (bit 1 of q + 1).
        let two = _mm256_set1_epi32(2);
        let sin_sign = _mm256_slli_epi32::<30>(_mm256_and_si256(q, two));
        let cos_sign = _mm256_slli_epi32::<30>(_mm256_and_si256(
            _mm256_add_epi32(q, _mm256_set1_epi32(1)),
            two,
        ));
        (
            _mm256_xor_ps(sin, _mm256_castsi256_ps(sin_sign)),
            _mm256_xor_ps(cos, _mm256_castsi256_ps(cos_sign)),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The truncation agrees with `as i32` inside ±2^30 and clamps
    /// outside; a wrong clamp or rounding mode fails here.
    #[test]
    fn truncation_matches_the_cast_inside_its_range() {
        let mut values = vec![
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            0.999_999_9,
            1.0,
            -1.0,
            8.5,
            16.499_998,
        ];
        values.extend((0..2000).map(|k| (k as f32 - 1000.0) * 0.37));
        values.extend([1.0e9, -1.0e9, 1_073_741_760.0, -1_073_741_760.0]);
        for v in values {
            assert_eq!(truncate_i32(v), v as i32, "{v}");
        }
        assert_eq!(truncate_i32(3.0e9), 1 << 30);
        assert_eq!(truncate_i32(f32::INFINITY), 1 << 30);
        assert_eq!(truncate_i32(f32::NEG_INFINITY), -(1 << 30));
        assert_eq!(truncate_i32(f32::NAN), -(1 << 30));
    }

    /// The many-angle forms give the scalar forms' bits in every lane and
    /// in the tail, over several turns either way, at the half-step ties
    /// and for non-finite input; a lane form that rounded differently (a
    /// fused multiply-add, another order) fails here.
    #[test]
    fn sine_cosine_of_many_equals_one_at_a_time() {
        let mut angles: Vec<f32> = (0..=20_001).map(|k| k as f32 / 1000.0 - 8.0).collect();
        angles.extend((0..200).map(|k| (k as f32 + 0.5) / 64.0));
        angles.extend([
            1e-30,
            -0.0,
            7.999_999,
            1e6,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ]);
        let bits = |(s, c): (f32, f32)| (s.to_bits(), c.to_bits());
        for len in [angles.len(), 7, 8, 9] {
            let angles = &angles[angles.len() - len..];
            let (mut sin, mut cos) = (vec![0.0; len], vec![0.0; len]);
            sin_cos_turns_each(angles, &mut sin, &mut cos);
            for (i, &t) in angles.iter().enumerate() {
                assert_eq!(bits((sin[i], cos[i])), bits(sin_cos_turns(t)), "turns {t}");
            }
            sin_cos_quarter_turns_each(angles, &mut sin, &mut cos);
            for (i, &s) in angles.iter().enumerate() {
                assert_eq!(
                    bits((sin[i], cos[i])),
                    bits(sin_cos_quarter_turns(s)),
                    "quarter turns {s}"
                );
            }
        }
    }

    /// The table holds the f32 rounding of each 64th of a turn (the series
    /// run at compile time is right), its entries are periodic in the low
    /// bits of negative step counts too, and non-finite angles give NaN.
    #[test]
    fn turn_table_and_reduction() {
        // Half an f32 ulp of the value, and 1e-15 for the zeros, which the
        // f64 angle only approximates.
        let rounded =
            |v: f32, exact: f64| (v as f64 - exact).abs() <= exact.abs() * 2f64.powi(-24) + 1e-15;
        for (k, &[s, c]) in TURN_TABLE.iter().enumerate() {
            let a = STEP * k as f64;
            assert!(
                rounded(s, a.sin()) && rounded(c, a.cos()),
                "entry {k}: {s} {c}"
            );
        }
        for k in -130..130 {
            let (s, c) = sin_cos_turns(k as f32 / 64.0);
            let a = std::f64::consts::TAU * k as f64 / 64.0;
            assert!(
                (s as f64 - a.sin()).abs() < 1e-7 && (c as f64 - a.cos()).abs() < 1e-7,
                "{k}"
            );
        }
        for t in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let (s, c) = sin_cos_turns(t);
            assert!(s.is_nan() && c.is_nan(), "{t}");
        }
    }

    /// The clamped floor agrees with the saturating cast and `min` it
    /// replaces, at the edges, beyond them and for NaN.
    #[test]
    fn grid_cell_matches_the_saturating_cast() {
        let mut values = vec![
            0.0f32,
            -0.0,
            -1e-30,
            -7.5,
            0.999_999_9,
            1.0,
            30.999_998,
            31.0,
            31.5,
            32.0,
            1e9,
            5e9,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        values.extend((0..4000).map(|k| (k as f32 - 500.0) * 0.013));
        for top in [0usize, 1, 31, 255, 1 << 24] {
            for &t in &values {
                let expected = (t as u32 as usize).min(top);
                assert_eq!(grid_cell(t, top as f32), expected, "t {t}, top {top}");
            }
        }
        // A top outside its range is not undefined behaviour.
        for top in [-1.0, 1e12, f32::INFINITY, f32::NAN] {
            for &t in &values {
                assert!(grid_cell(t, top) <= 1 << 24, "t {t}, top {top}");
            }
        }
    }

    /// The polynomial arctangent and sine/cosine are within their stated
    /// bounds of the `f64` functions over a dense grid of every quadrant.
    #[test]
    fn fast_trigonometry_is_accurate() {
        let mut worst_atan = 0.0f64;
        for k in 0..20_000 {
            let a = k as f64 / 20_000.0 * std::f64::consts::TAU;
            for r in [1e-6, 0.3, 1.0, 7.0] {
                let (y, x) = ((r * a.sin()) as f32, (r * a.cos()) as f32);
                let exact = (y as f64).atan2(x as f64);
                worst_atan = worst_atan.max((fast_atan2(y, x) as f64 - exact).abs());
            }
        }
        assert!(worst_atan < 4e-7, "atan2 error {worst_atan}");
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
        assert_eq!(fast_atan2(f32::NAN, 1.0), 0.0);
        let mut worst_sin_cos = 0.0f64;
        for k in 0..=40_000 {
            let t = k as f32 / 40_000.0 * 1.5 - 0.25;
            let (s, c) = sin_cos_turns(t);
            let a = t as f64 * std::f64::consts::TAU;
            worst_sin_cos = worst_sin_cos
                .max((s as f64 - a.sin()).abs())
                .max((c as f64 - a.cos()).abs());
        }
        assert!(worst_sin_cos < 2e-7, "sin/cos error {worst_sin_cos}");
    }
}
