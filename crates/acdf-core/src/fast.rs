//! Polynomial arctangent and sine/cosine for the samplers' hot paths.
//!
//! A sampler maps a half vector to table coordinates (two arctangents) and
//! back (a sine and cosine per axis) on every draw and every density; the
//! libm functions cost more than the table search itself. These versions are
//! branch-free polynomials, accurate to a few 1e-7 rad, with no libm call,
//! and they are the same in `sample` and `pdf`, so the two stay consistent.

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

/// (sin 2πt, cos 2πt) for an angle t in turns: [`sin_cos_quarter_turns`]
/// of 4t (exact, a power-of-two scaling).
#[inline(always)]
pub fn sin_cos_turns(t: f32) -> (f32, f32) {
    sin_cos_quarter_turns(t * 4.0)
}

/// 1.5 · 2^23: added to an `f32` of magnitude below 2^22 and taken away
/// again, it leaves the value rounded to the nearest integer (ties to even),
/// since the sum's unit in the last place is 1.
const ROUND_TO_INTEGER: f32 = 12_582_912.0;

/// Taylor coefficients of sin(πr/2) / r in powers of r², to r⁸ (degree
/// 9): (-1)^k (π/2)^(2k+1) / (2k+1)!, so that the polynomial takes the
/// remainder r in quarter turns without first scaling it to radians.
const SIN_QUARTER_TAYLOR: [f32; 5] = [
    1.570_796_4,
    -0.645_964_1,
    0.079_692_624,
    -0.004_681_754,
    0.000_160_441_18,
];

/// Taylor coefficients of cos(πr/2) in powers of r², to r⁸: (-1)^k
/// (π/2)^(2k) / (2k)!.
const COS_QUARTER_TAYLOR: [f32; 5] = [
    1.0,
    -1.233_700_5,
    0.253_669_5,
    -0.020_863_48,
    0.000_919_260_26,
];

/// (sin(πs/2), cos(πs/2)) for an angle s in quarter turns, without a libm
/// call: the nearest quarter turn q is split off exactly and the rest r (at
/// most half a quarter turn, π/4, in magnitude) goes to Taylor polynomials
/// of degree 9 (sine) and 8 (cosine) in r, whose truncation errors at
/// r = 1/2 are 1.8e-9 and 2.5e-8. The reduction is exact for |s| < 8, so
/// the error is that of `f32` rounding, a few 1e-8 absolute.
///
/// q comes from adding and removing 1.5 · 2^23, and its low bits
/// from the bits of the sum, rather than from a conversion to an integer
/// and back: two additions instead of a clamp and two conversions on the
/// chain every draw's direction waits for, and no conversion at all in a
/// loop over many angles. One call at a time the tabulated samplers'
/// `sample` ran 2 to 6% faster (uniform 15.7-16.0 to 16.2-16.3 M/s,
/// `adaptive:dp` 14.6-15.0 to 15.0-15.8, built-in nickel, best of 10 runs
/// of 10^6 calls, three alternating runs on a Zen 5 machine).
///
/// The polynomials take r itself (their coefficients carry the powers of
/// π/2) and the quarter turns are applied by swapping sine and cosine and
/// flipping sign bits: one multiply fewer, and a select and an exclusive
/// or instead of a multiply and an add, on the same chain. With the paired
/// form in the samplers' `sample` that took the uniform sampler from 584
/// to 567 instructions per call (callgrind, 10^5 calls) and from 17.7-18.4
/// to 18.4-18.9 M/s, `adaptive:dp` from 14.7-15.4 to 15.2-15.9 (built-in
/// nickel, best of 10 runs of 10^6 calls, five alternating runs on a Zen 5
/// machine).
#[inline(always)]
pub fn sin_cos_quarter_turns(s: f32) -> (f32, f32) {
    let shifted = s + ROUND_TO_INTEGER;
    let q = shifted - ROUND_TO_INTEGER;
    // s - q is exact (|s - q| <= 1/2 and both are multiples of s's ulp).
    let r = s - q;
    // The polynomials in r² are evaluated in Estrin's form (pairs of terms
    // combined with r⁴) rather than Horner's: the same number of
    // operations but about half the chain of dependent ones, which is what
    // a single draw waits on.
    let r2 = r * r;
    let r4 = r2 * r2;
    let estrin = |c: &[f32; 5]| (c[0] + r2 * c[1]) + r4 * ((c[2] + r2 * c[3]) + r4 * c[4]);
    let sin_r = r * estrin(&SIN_QUARTER_TAYLOR);
    let cos_r = estrin(&COS_QUARTER_TAYLOR);
    // (sin, cos)(r + q π/2) is (sin r, cos r) for q = 0 mod 4, (cos r,
    // -sin r) for 1, (-sin r, -cos r) for 2 and (-cos r, sin r) for 3: an
    // odd q swaps the two, bit 1 of q negates the sine and bit 1 of q + 1
    // the cosine. The sum holds 2^22 + q in its mantissa, whose two low bits
    // are those of q in two's complement. Selects and bit operations rather
    // than a four-way branch, so that loops over many angles vectorise.
    let bits = shifted.to_bits();
    let (sin_u, cos_u) = if bits & 1 != 0 {
        (cos_r, sin_r)
    } else {
        (sin_r, cos_r)
    };
    let sin_sign = (bits & 2) << 30;
    let cos_sign = (bits.wrapping_add(1) & 2) << 30;
    (
        f32::from_bits(sin_u.to_bits() ^ sin_sign),
        f32::from_bits(cos_u.to_bits() ^ cos_sign),
    )
}

/// [`sin_cos_quarter_turns`] of two angles at once, bit for bit:
/// ((sin, cos)(π s0 / 2), (sin, cos)(π s1 / 2)).
///
/// A sampler's draw needs the sine and cosine of both half-vector angles.
/// Where the CPU has SSE2 (every x86-64) the four values are the four lanes
/// of one register, each lane running the scalar operations of its value
/// in the same order, so that one call costs about half the instructions
/// of two scalar calls while a loop over many draws can keep the scalar
/// form and still get the same bits. In the uniform sampler's `sample` it
/// took the function from 555 to 507 instructions per call (callgrind,
/// built-in nickel, wo changing every call, 10^5 calls).
#[inline(always)]
pub fn sin_cos_quarter_turns_pair(s0: f32, s1: f32) -> ((f32, f32), (f32, f32)) {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe { sin_cos_pair_sse2(s0, s1) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        (sin_cos_quarter_turns(s0), sin_cos_quarter_turns(s1))
    }
}

/// [`sin_cos_quarter_turns_pair`] in the lanes (sin s0, cos s0, sin s1,
/// cos s1).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn sin_cos_pair_sse2(s0: f32, s1: f32) -> ((f32, f32), (f32, f32)) {
    use std::arch::x86_64::*;
    // Lane k of the result holds the sine (even k) or cosine (odd k).
    let lanes = |sin: f32, cos: f32| _mm_setr_ps(sin, cos, sin, cos);
    let s = _mm_setr_ps(s0, s0, s1, s1);
    let round = _mm_set1_ps(ROUND_TO_INTEGER);
    let shifted = _mm_add_ps(s, round);
    let q = _mm_sub_ps(shifted, round);
    let r = _mm_sub_ps(s, q);
    let r2 = _mm_mul_ps(r, r);
    let r4 = _mm_mul_ps(r2, r2);
    let c = |k: usize| lanes(SIN_QUARTER_TAYLOR[k], COS_QUARTER_TAYLOR[k]);
    let estrin = _mm_add_ps(
        _mm_add_ps(c(0), _mm_mul_ps(r2, c(1))),
        _mm_mul_ps(
            r4,
            _mm_add_ps(_mm_add_ps(c(2), _mm_mul_ps(r2, c(3))), _mm_mul_ps(r4, c(4))),
        ),
    );
    // The sine lanes take the factor r, the cosine lanes 1 (exact).
    let one = _mm_set1_ps(1.0);
    let factor = _mm_unpacklo_ps(_mm_shuffle_ps::<0b10_00_10_00>(r, r), one);
    let unrotated = _mm_mul_ps(estrin, factor);
    // The quarter turns of the scalar form: where q is odd each lane takes
    // its partner's value (sine and cosine swapped), then the sign bit
    // flips with bit 1 of q in the sine lanes and of q + 1 in the cosine
    // lanes.
    let bits = _mm_castps_si128(shifted);
    let one_bit = _mm_set1_epi32(1);
    let odd = _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(bits, one_bit), one_bit));
    let swapped = _mm_shuffle_ps::<0b10_11_00_01>(unrotated, unrotated);
    let chosen = _mm_or_ps(_mm_and_ps(odd, swapped), _mm_andnot_ps(odd, unrotated));
    let plus_one_in_cosine_lanes = _mm_setr_epi32(0, 1, 0, 1);
    let sign = _mm_slli_epi32::<30>(_mm_and_si128(
        _mm_add_epi32(bits, plus_one_in_cosine_lanes),
        _mm_set1_epi32(2),
    ));
    let rotated = _mm_xor_ps(chosen, _mm_castsi128_ps(sign));
    let mut out = [0.0f32; 4];
    _mm_storeu_ps(out.as_mut_ptr(), rotated);
    ((out[0], out[1]), (out[2], out[3]))
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

    /// The paired sine/cosine is bit for bit two calls of the scalar one,
    /// over several turns, at the quarter-turn ties and for non-finite
    /// input.
    #[test]
    fn paired_sine_cosine_equals_two_calls() {
        let mut angles: Vec<f32> = (0..=20_000).map(|k| k as f32 / 1000.0 - 8.0).collect();
        angles.extend([0.5, -0.5, 1.5, 2.5, 3.5, 1e-30, -0.0, 7.999_999, 1e6]);
        angles.extend([f32::NAN, f32::INFINITY, f32::NEG_INFINITY]);
        let bits = |(s, c): (f32, f32)| (s.to_bits(), c.to_bits());
        for (i, &s0) in angles.iter().enumerate() {
            let s1 = angles[(i * 7919 + 13) % angles.len()];
            let (first, second) = sin_cos_quarter_turns_pair(s0, s1);
            assert_eq!(bits(first), bits(sin_cos_quarter_turns(s0)), "{s0}");
            assert_eq!(bits(second), bits(sin_cos_quarter_turns(s1)), "{s1}");
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
