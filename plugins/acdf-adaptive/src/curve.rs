//! The piecewise-linear CDF through a few vertices, shared by the 1D
//! distribution and by every marginal and conditional of the 2D one.
//!
//! A curve is two equally long `f32` slices: vertex positions
//! 0 = x_0 < x_1 < ... < x_m = 1 and CDF values 0 = c_0 <= c_1 <= ... <= c_m = 1.
//! Segment i carries mass c_{i+1} - c_i spread evenly over [x_i, x_{i+1}), so
//! the density there is (c_{i+1} - c_i) / (x_{i+1} - x_i). An empty curve (no
//! vertices) stands for the uniform density; the 2D distribution uses it for
//! conditionals that can never be reached.
//!
//! Sampling, density and inversion all locate the segment the same way and
//! compute the density with the one function [`Curve::density`], so the pdf
//! returned with a sample is bit-for-bit the pdf evaluated at that sample.

use acdf_core::{clamp_unit, Sample1D, ONE_MINUS_EPSILON};

/// The largest f32 strictly below `v` (for v > 0 finite).
#[inline]
pub(crate) fn f32_below(v: f32) -> f32 {
    if v > 0.0 {
        f32::from_bits(v.to_bits() - 1)
    } else {
        v
    }
}

/// A borrowed vertex list; see the module documentation.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Curve<'a> {
    pub x: &'a [f32],
    pub cdf: &'a [f32],
}

impl Curve<'_> {
    #[inline]
    fn is_uniform(&self) -> bool {
        self.x.len() < 2
    }

    /// The density of segment i: (c_{i+1} - c_i) / (x_{i+1} - x_i), evaluated
    /// in f64 (differences of f32 values are exact there) and rounded once.
    #[inline]
    pub fn density(&self, i: usize) -> f32 {
        let mass = self.cdf[i + 1] as f64 - self.cdf[i] as f64;
        let width = self.x[i + 1] as f64 - self.x[i] as f64;
        (mass / width) as f32
    }

    /// The segment i with x_i <= x < x_{i+1} (the last segment for x >= 1).
    #[inline]
    pub fn segment_of(&self, x: f32) -> usize {
        let last = self.x.len() - 2;
        self.x
            .partition_point(|&v| v <= x)
            .saturating_sub(1)
            .min(last)
    }

    /// x = P^{-1}(u) and the segment it lies in. The segment is the one with
    /// c_i <= u < c_{i+1}: an empty interval for a zero-mass segment, so such
    /// a segment is never chosen. Inside it,
    /// x = x_i + (u - c_i) / (c_{i+1} - c_i) (x_{i+1} - x_i), with the two
    /// differences taken exactly in f64, so a nearly flat CDF segment (a steep
    /// inverse) loses no digits to cancellation; the result is clamped into
    /// [x_i, x_{i+1}) so that it stays in the segment after rounding to f32.
    #[inline]
    pub fn sample(&self, u: f32) -> (Sample1D, usize) {
        let u = clamp_unit(u);
        if self.is_uniform() {
            return (Sample1D { x: u, pdf: 1.0 }, 0);
        }
        let last = self.cdf.len() - 2;
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .saturating_sub(1)
            .min(last);
        let (c0, c1) = (self.cdf[i] as f64, self.cdf[i + 1] as f64);
        let (x0, x1) = (self.x[i], self.x[i + 1]);
        let t = ((u as f64 - c0) / (c1 - c0)).clamp(0.0, 1.0);
        let x = (x0 as f64 + t * (x1 as f64 - x0 as f64)) as f32;
        let x = x.clamp(x0, f32_below(x1)).min(ONE_MINUS_EPSILON);
        (
            Sample1D {
                x,
                pdf: self.density(i),
            },
            i,
        )
    }

    /// p(x): the density of the segment holding x, 0 outside [0, 1).
    #[inline]
    pub fn pdf(&self, x: f32) -> f32 {
        if !(0.0..1.0).contains(&x) {
            return 0.0;
        }
        if self.is_uniform() {
            return 1.0;
        }
        self.density(self.segment_of(x))
    }

    /// P(x) = c_i + (x - x_i) / (x_{i+1} - x_i) (c_{i+1} - c_i), x clamped to
    /// [0, 1] (NaN acts as 0).
    #[inline]
    pub fn invert(&self, x: f32) -> f32 {
        let x = if x > 0.0 { x.min(1.0) } else { 0.0 };
        if self.is_uniform() {
            return x;
        }
        if x >= 1.0 {
            return 1.0;
        }
        let i = self.segment_of(x);
        let (c0, c1) = (self.cdf[i], self.cdf[i + 1]);
        let (x0, x1) = (self.x[i] as f64, self.x[i + 1] as f64);
        let t = ((x as f64 - x0) / (x1 - x0)).clamp(0.0, 1.0);
        ((c0 as f64 + t * (c1 as f64 - c0 as f64)) as f32).clamp(c0, c1)
    }
}

/// The smallest f32 strictly above `v` (for 0 <= v finite).
#[inline]
fn f32_above(v: f32) -> f32 {
    if v >= 0.0 {
        f32::from_bits((v + 0.0).to_bits() + 1)
    } else {
        v
    }
}

/// The kept vertices of a tabulated CDF, rounded to f32, appended to `xs` and
/// `cdfs`.
///
/// `prefix[k]` is the exact running sum of the first k table entries (f64),
/// `kept` the indices chosen by a simplifier (0 and n included). The two ends
/// are set to exactly 0 and 1. A segment whose mass is positive but below the
/// f32 spacing of its CDF values (about 6e-8 near 1) would round to zero mass
/// and density 0 where the table is positive, which would bias a sampler; its
/// end is moved up by one f32 step instead (and, near 1, the ends below are
/// moved down), so every segment keeps a positive mass exactly when its table
/// cells do.
pub(crate) fn push_vertices(
    prefix: &Running,
    kept: &[usize],
    xs: &mut Vec<f32>,
    cdfs: &mut Vec<f32>,
) {
    let n = prefix.sum.len() - 1;
    let total = prefix[n];
    let last = kept.len() - 1;
    let start = cdfs.len();
    for (pos, &k) in kept.iter().enumerate() {
        let (x, c) = if pos == 0 {
            (0.0, 0.0)
        } else if pos == last {
            (1.0, 1.0)
        } else {
            ((k as f64 / n as f64) as f32, (prefix[k] / total) as f32)
        };
        xs.push(x);
        cdfs.push(c);
    }
    let c = &mut cdfs[start..];
    let positive = |i: usize| prefix.positive[kept[i + 1]] > prefix.positive[kept[i]];
    for i in 1..last {
        c[i] = if positive(i - 1) {
            c[i].max(f32_above(c[i - 1]))
        } else {
            c[i].max(c[i - 1])
        };
    }
    for i in (1..last).rev() {
        c[i] = if positive(i) {
            c[i].min(f32_below(c[i + 1]))
        } else {
            c[i].min(c[i + 1])
        };
    }
}

/// Running sums of a table: `sum[k]` = v_0 + ... + v_{k-1} in f64, and
/// `positive[k]` the number of v_l > 0 among them. The count tells whether a
/// span of cells carries mass even when its cells are so much smaller than
/// the running sum (below 1e-16 relative) that the f64 sum does not move.
#[derive(Debug, Clone)]
pub(crate) struct Running {
    pub sum: Vec<f64>,
    pub positive: Vec<usize>,
}

impl std::ops::Index<usize> for Running {
    type Output = f64;
    fn index(&self, k: usize) -> &f64 {
        &self.sum[k]
    }
}

/// The [`Running`] sums of `values` (all non-negative).
pub(crate) fn prefix_sums(values: impl Iterator<Item = f64>) -> Running {
    let mut sum = vec![0.0];
    let mut positive = vec![0usize];
    let (mut acc, mut count) = (0.0f64, 0usize);
    for v in values {
        acc += v;
        count += usize::from(v > 0.0);
        sum.push(acc);
        positive.push(count);
    }
    Running { sum, positive }
}

/// The points (k / n, prefix[k] / total) of the normalised tabulated CDF, or
/// `None` when the total is zero.
pub(crate) fn cdf_points(prefix: &Running) -> Option<(Vec<f64>, Vec<f64>)> {
    let prefix = &prefix.sum;
    let n = prefix.len() - 1;
    let total = prefix[n];
    if total <= 0.0 {
        return None;
    }
    let x = (0..=n).map(|k| k as f64 / n as f64).collect();
    let p = prefix.iter().map(|&s| s / total).collect();
    Some((x, p))
}
