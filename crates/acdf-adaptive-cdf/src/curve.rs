//! The piecewise-linear CDF through a few vertices, shared by the 1D
//! distribution and by every marginal and conditional of the 2D one.
//!
//! A curve of m vertices is stored as 2m `f32` values in a row: the vertex
//! positions 0 = x_0 < x_1 < ... < x_{m-1} = 1, then the CDF values
//! 0 = c_0 <= c_1 <= ... <= c_{m-1} = 1. Segment i carries mass
//! c_{i+1} - c_i spread evenly over [x_i, x_{i+1}), so the density there is
//! (c_{i+1} - c_i) / (x_{i+1} - x_i). An empty curve (no vertices) stands for
//! the uniform density; the 2D distribution uses it for conditionals that
//! can never be reached.
//!
//! Sampling, density and inversion all locate the segment with the searches
//! of [`crate::search`], which return exactly what a binary search would, and
//! every density is (c_{i+1} - c_i) / (x_{i+1} - x_i) in f32 by the one
//! function `density_of`, so the pdf returned with a sample is bit-for-bit
//! the pdf evaluated at that sample.

use acdf_core::search::{count_at_or_below, count_one, Guide};
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

/// A borrowed curve: `len` vertex positions from `data[start]` on, then
/// their `len` CDF values; see the module documentation.
///
/// The curve is addressed inside its whole buffer (not as two slices) so
/// that a short curve can be searched with a fixed-size window that also
/// covers entries of the buffer around it (which are not counted).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Curve<'a> {
    data: &'a [f32],
    start: usize,
    len: usize,
    guide: Option<&'a CurveGuide>,
}

/// The number of equal intervals of a [`CurveGuide`]: 32, so that its
/// counts take 66 bytes and no interval holds more than the 32 entries one
/// window compares (at most 18 CDF values on every slice of nickel,
/// gray-plastic and blue-metallic-paint with `dp` and `chi2` at the
/// isotropic resolution, counted when the guide was chosen).
pub(crate) const CURVE_GUIDE_CELLS: usize = 32;

/// A guide ([`Guide`]) of a curve's inner CDF values c_1..c_{m-2} with
/// [`CURVE_GUIDE_CELLS`] intervals, derived from the curve: the search for
/// the segment of u starts from u's interval, whose index u gives before
/// the curve is read, instead of cutting the whole list down by a four-way
/// step first.
///
/// Only u gets a guide. The segment of a position x (a density lookup) is
/// searched as before: x arrives late, at the end of a chain of
/// arctangents, and the four-way step's loads do not wait for it while a
/// guide's do, so a guide of the positions would add its read to the
/// chain of every `pdf` call instead of taking a step off it.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub(crate) struct CurveGuide {
    cdfs: Guide,
}

impl CurveGuide {
    /// The guide of the curve filling `data` (positions, then CDF values).
    pub fn new(data: &[f32]) -> Self {
        let m = data.len() / 2;
        if m < 3 {
            return CurveGuide::default();
        }
        CurveGuide {
            cdfs: Guide::new(&data[m + 1..2 * m - 1], CURVE_GUIDE_CELLS),
        }
    }

    /// Heap bytes of the index.
    pub fn bytes(&self) -> usize {
        self.cdfs.bytes()
    }

    /// The first segment that a draw with this u can land in (0 without
    /// a guide).
    #[inline(always)]
    pub fn first_segment(&self, u: f32) -> usize {
        self.cdfs.first(Guide::cell(u, CURVE_GUIDE_CELLS))
    }
}

impl<'a> Curve<'a> {
    /// The curve filling `data`: its first half positions, second half CDF
    /// values.
    #[inline(always)]
    pub fn whole(data: &'a [f32]) -> Self {
        Curve {
            data,
            start: 0,
            len: data.len() / 2,
            guide: None,
        }
    }

    /// [`whole`](Self::whole) with the curve's [`CurveGuide`].
    #[inline(always)]
    pub fn guided(data: &'a [f32], guide: &'a CurveGuide) -> Self {
        Curve {
            guide: Some(guide),
            ..Self::whole(data)
        }
    }

    /// The curve of `len` vertices whose positions start at `data[start]`
    /// (its CDF values at `data[start + len]`).
    #[inline(always)]
    pub fn within(data: &'a [f32], start: usize, len: usize) -> Self {
        debug_assert!(start + 2 * len <= data.len());
        Curve {
            data,
            start,
            len,
            guide: None,
        }
    }

    /// The vertex positions x_0, ..., x_{m-1}.
    pub fn xs(&self) -> &'a [f32] {
        &self.data[self.start..self.start + self.len]
    }

    /// The CDF values c_0, ..., c_{m-1}.
    pub fn cdfs(&self) -> &'a [f32] {
        &self.data[self.start + self.len..self.start + 2 * self.len]
    }

    #[inline(always)]
    pub fn is_uniform(&self) -> bool {
        self.len < 2
    }

    #[inline(always)]
    fn x(&self, i: usize) -> f32 {
        self.data[self.start + i]
    }

    #[inline(always)]
    fn c(&self, i: usize) -> f32 {
        self.data[self.start + self.len + i]
    }

    /// The density of segment i, [`segment_density`].
    #[inline(always)]
    pub fn density(&self, i: usize) -> f32 {
        segment_density(self.segment(i))
    }

    /// The ends of segment i.
    #[inline(always)]
    pub fn segment(&self, i: usize) -> Segment {
        Segment {
            x0: self.x(i),
            x1: self.x(i + 1),
            c0: self.c(i),
            c1: self.c(i + 1),
        }
    }

    /// The segment i with x_i <= x < x_{i+1} (the last segment for x >= 1,
    /// the first for x < 0 or NaN), for a curve of at least two vertices.
    ///
    /// It is the number of inner positions x_1, ..., x_{m-2} at or below x:
    /// x_0 = 0 and x_{m-1} = 1 need no comparison once the result is kept
    /// in [0, m - 2].
    #[inline(always)]
    pub fn segment_of(&self, x: f32) -> usize {
        count_one(self.data, self.start + 1, self.len - 2, x)
    }

    /// The segment i with c_i <= u < c_{i+1} for u in [0, 1) (a zero-mass
    /// segment, an empty interval, is never chosen), for a curve of at least
    /// two vertices: the number of inner CDF values c_1, ..., c_{m-2} at or
    /// below u, since c_0 = 0 <= u < 1 = c_{m-1}.
    #[inline(always)]
    pub fn segment_of_u(&self, u: f32) -> usize {
        let start = self.start + self.len + 1;
        match self.guide {
            Some(g) if !g.cdfs.is_empty() => {
                g.cdfs
                    .count(self.data, start, u, Guide::cell(u, CURVE_GUIDE_CELLS))
            }
            _ => count_one(self.data, start, self.len - 2, u),
        }
    }

    /// [`segment_of_u`](Self::segment_of_u) for L values of u at once, by the
    /// four-way search (the lanes' loads overlap).
    #[inline(always)]
    pub fn segments_of_u<const L: usize>(&self, u: [f32; L]) -> [usize; L] {
        count_at_or_below(self.data, self.start + self.len + 1, self.len - 2, u)
    }

    /// x = P^{-1}(u), the segment i it lies in and that segment's ends (u
    /// clamped into [0, 1)): i by [`segment_of_u`](Self::segment_of_u), x
    /// and its density by [`segment_samples`]. The uniform stand-in gives
    /// x = u, density 1 and the ends of [`Segment::UNIFORM`].
    #[inline(always)]
    pub fn sample(&self, u: f32) -> (Sample1D, usize, Segment) {
        let u = clamp_unit(u);
        if self.is_uniform() {
            return (Sample1D { x: u, pdf: 1.0 }, 0, Segment::UNIFORM);
        }
        let i = self.segment_of_u(u);
        let segment = self.segment(i);
        let ([x], [pdf]) = segment_samples(&[segment], &[u]);
        (Sample1D { x, pdf }, i, segment)
    }

    /// p(x): the density of the segment holding x, 0 outside [0, 1).
    #[inline(always)]
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
        let (c0, c1) = (self.c(i), self.c(i + 1));
        let (x0, x1) = (self.x(i), self.x(i + 1));
        let t = ((x - x0) / (x1 - x0)).clamp(0.0, 1.0);
        (c0 + t * (c1 - c0)).clamp(c0, c1)
    }
}

/// The ends (x_i, c_i) and (x_{i+1}, c_{i+1}) of one curve segment, with
/// x_i < x_{i+1} and c_i <= c_{i+1}.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Segment {
    pub x0: f32,
    pub x1: f32,
    pub c0: f32,
    pub c1: f32,
}

impl Segment {
    /// The one segment of the uniform density, (0, 0) to (1, 1): it samples
    /// x = u with density 1, as the uniform stand-in curve does.
    pub const UNIFORM: Segment = Segment {
        x0: 0.0,
        x1: 1.0,
        c0: 0.0,
        c1: 1.0,
    };
}

/// The density of a segment: (c_{i+1} - c_i) / (x_{i+1} - x_i), in f32.
///
/// Neither difference cancels badly: two f32 within a factor of two of each
/// other subtract exactly (Sterbenz), and further apart the difference is
/// rounded once like any other operation, so the density is within three
/// roundings of the exact slope of the stored vertices. `sample` and `pdf`
/// both take it from here, so they agree bit for bit.
#[inline(always)]
pub(crate) fn segment_density(s: Segment) -> f32 {
    density_of(s.c1 - s.c0, s.x1 - s.x0)
}

/// mass / width: the one formula of every density.
#[inline(always)]
fn density_of(mass: f32, width: f32) -> f32 {
    mass / width
}

/// The samples of N segments for their u, c_i <= u < c_{i+1}: the
/// positions x = x_i + (u - c_i) / (c_{i+1} - c_i) (x_{i+1} - x_i) in f32
/// (the differences lose no digits, see [`segment_density`]), clamped into
/// [x_i, x_{i+1}) so that rounding cannot carry them out of their segment,
/// and below 1; and the densities, as [`segment_density`] computes them.
///
/// One code for a single draw (N = 1) and for a batch's lanes: each step is
/// one operation over all N values, on one array per segment end, with
/// selects for the clamps and the largest f32 below x_{i+1} > 0 taken as its
/// bit pattern minus one, so that the compiler turns a batch's steps into
/// SIMD arithmetic; every lane goes through the same IEEE operations, so
/// the results do not depend on N.
#[inline(always)]
pub(crate) fn segment_samples<const N: usize>(
    seg: &[Segment; N],
    u: &[f32; N],
) -> ([f32; N], [f32; N]) {
    let ends = |end: fn(&Segment) -> f32| -> [f32; N] { std::array::from_fn(|l| end(&seg[l])) };
    let (x0, x1) = (ends(|s| s.x0), ends(|s| s.x1));
    let (c0, c1) = (ends(|s| s.c0), ends(|s| s.c1));
    let mut t = [0.0f32; N];
    let mut pdf = [0.0f32; N];
    for l in 0..N {
        t[l] = (u[l] - c0[l]) / (c1[l] - c0[l]);
        pdf[l] = density_of(c1[l] - c0[l], x1[l] - x0[l]);
    }
    for t in &mut t {
        *t = if *t < 0.0 { 0.0 } else { *t };
        *t = if *t > 1.0 { 1.0 } else { *t };
    }
    let mut x = [0.0f32; N];
    for l in 0..N {
        x[l] = x0[l] + t[l] * (x1[l] - x0[l]);
    }
    // x >= x_i already (t >= 0 and x_{i+1} >= x_i), so only the top needs
    // a clamp, and its two bounds are combined before x is known: one select
    // on the chain a single draw waits for instead of three.
    for (x, s) in x.iter_mut().zip(seg) {
        let below_x1 = f32::from_bits(s.x1.to_bits().wrapping_sub(1));
        let top = if below_x1 > ONE_MINUS_EPSILON {
            ONE_MINUS_EPSILON
        } else {
            below_x1
        };
        *x = if *x > top { top } else { *x };
    }
    (x, pdf)
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

/// The points `(k / n, prefix[k] / total)` of the normalised tabulated CDF, or
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
