//! Adaptive (curve-simplified) distributions over [0, 1) and [0, 1)^2.

use crate::curve::{cdf_points, f32_below, prefix_sums, push_vertices, Curve, Running};
use crate::simplify::{validate_tolerance, ErrorBound, Simplifier};
use acdf_core::{
    clamp_unit, validate_table, Distribution1D, Distribution2D, Error, Result, Sample1D, Sample2D,
    Vec2, ONE_MINUS_EPSILON,
};

/// Tables longer than this cannot give distinct f32 vertex positions k / n.
const MAX_TABLE_LEN: usize = 1 << 24;

fn check_len(what: &'static str, n: usize) -> Result<()> {
    if n > MAX_TABLE_LEN {
        return Err(Error::InvalidParameter {
            name: what,
            reason: format!("at most {MAX_TABLE_LEN} entries per dimension, got {n}"),
        });
    }
    Ok(())
}

/// Simplify the tabulated CDF of `values` (given by its running sums) and
/// append its kept vertices; an all-zero table gives the two vertices of the
/// uniform CDF.
fn simplify_into(
    prefix: &Running,
    simplifier: &dyn Simplifier,
    tolerance: f64,
    xs: &mut Vec<f32>,
    cdfs: &mut Vec<f32>,
) {
    match cdf_points(prefix) {
        Some((x, p)) => {
            let kept = simplifier.simplify(&x, &p, tolerance);
            push_vertices(prefix, &kept, xs, cdfs);
        }
        None => {
            xs.extend([0.0, 1.0]);
            cdfs.extend([0.0, 1.0]);
        }
    }
}

/// The (marginal, conditional) tolerances of [`AdaptiveCdf2D::from_values`].
fn split_tolerance(simplifier: &dyn Simplifier, tolerance: f64) -> (f64, f64) {
    match simplifier.bound() {
        ErrorBound::ChiSquare => (0.75 * tolerance, 0.25 * tolerance),
        _ => (tolerance, tolerance),
    }
}

/// A piecewise-linear CDF through a few kept vertices of a tabulated CDF: a
/// piecewise-constant density between the vertices.
///
/// Built from a table of n non-negative values on the cells [k/n, (k+1)/n):
/// the tabulated CDF has the points (k/n, P_k), P_k = (v_0 + ... + v_{k-1}) /
/// (v_0 + ... + v_{n-1}) (sums in f64), and a [`Simplifier`] picks which of
/// them to keep. Each segment between kept vertices carries exactly the mass
/// of the table cells it covers, so the density is positive wherever the
/// table is (up to the f32 resolution of the stored CDF values, about 6e-8).
///
/// An all-zero table gives the uniform density and `integral() == 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveCdf1D {
    x: Box<[f32]>,
    cdf: Box<[f32]>,
    integral: f64,
}

impl AdaptiveCdf1D {
    /// Build from a table of non-negative values (the function is v_k on
    /// [k/n, (k+1)/n)), simplified by `simplifier` at `tolerance`.
    pub fn from_values(
        values: &[f32],
        simplifier: &dyn Simplifier,
        tolerance: f64,
    ) -> Result<Self> {
        validate_table("AdaptiveCdf1D", values)?;
        check_len("AdaptiveCdf1D", values.len())?;
        validate_tolerance(tolerance)?;
        let prefix = prefix_sums(values.iter().map(|&v| v as f64));
        let n = values.len();
        let (mut x, mut cdf) = (Vec::new(), Vec::new());
        simplify_into(&prefix, simplifier, tolerance, &mut x, &mut cdf);
        Ok(Self {
            x: x.into_boxed_slice(),
            cdf: cdf.into_boxed_slice(),
            integral: prefix[n] / n as f64,
        })
    }

    /// Build with at most `budget` vertices (at least 2), for simplifiers that
    /// have a budget form; `InvalidParameter` for the others.
    pub fn from_values_with_budget(
        values: &[f32],
        simplifier: &dyn Simplifier,
        budget: usize,
    ) -> Result<Self> {
        validate_table("AdaptiveCdf1D", values)?;
        check_len("AdaptiveCdf1D", values.len())?;
        let prefix = prefix_sums(values.iter().map(|&v| v as f64));
        let n = values.len();
        let (mut x, mut cdf) = (Vec::new(), Vec::new());
        match cdf_points(&prefix) {
            Some((px, pp)) => {
                let kept = simplifier
                    .simplify_to_budget(&px, &pp, budget)
                    .ok_or_else(|| Error::InvalidParameter {
                        name: "budget",
                        reason: format!("simplifier `{}` has no budget form", simplifier.name()),
                    })?;
                push_vertices(&prefix, &kept, &mut x, &mut cdf);
            }
            None => {
                x.extend([0.0, 1.0]);
                cdf.extend([0.0, 1.0]);
            }
        }
        Ok(Self {
            x: x.into_boxed_slice(),
            cdf: cdf.into_boxed_slice(),
            integral: prefix[n] / n as f64,
        })
    }

    fn curve(&self) -> Curve<'_> {
        Curve {
            x: &self.x,
            cdf: &self.cdf,
        }
    }

    /// The number of kept vertices (segments + 1).
    pub fn vertex_count(&self) -> usize {
        self.x.len()
    }

    /// The kept vertex positions x_i (0 first, 1 last).
    pub fn vertex_positions(&self) -> &[f32] {
        &self.x
    }

    /// The CDF values c_i at the kept vertices (0 first, 1 last).
    pub fn vertex_cdf(&self) -> &[f32] {
        &self.cdf
    }

    /// The index i of the segment [x_i, x_{i+1}) holding `x` (x clamped to
    /// the last segment at and above 1, to the first below 0 and for NaN).
    pub fn segment_of(&self, x: f32) -> usize {
        self.curve().segment_of(if x > 0.0 { x } else { 0.0 })
    }
}

impl Distribution1D for AdaptiveCdf1D {
    /// x = x_i + (u - c_i) / (c_{i+1} - c_i) (x_{i+1} - x_i) on the segment
    /// with c_i <= u < c_{i+1}; pdf = (c_{i+1} - c_i) / (x_{i+1} - x_i).
    fn sample(&self, u: f32) -> Sample1D {
        self.curve().sample(u).0
    }

    /// (c_{i+1} - c_i) / (x_{i+1} - x_i) on the segment holding x.
    fn pdf(&self, x: f32) -> f32 {
        self.curve().pdf(x)
    }

    /// The piecewise-linear CDF at x.
    fn invert(&self, x: f32) -> f32 {
        self.curve().invert(x)
    }

    /// (v_0 + ... + v_{n-1}) / n.
    fn integral(&self) -> f64 {
        self.integral
    }

    /// 4 bytes per vertex position plus 4 per CDF value.
    fn storage_bytes(&self) -> usize {
        std::mem::size_of_val(&*self.x) + std::mem::size_of_val(&*self.cdf)
    }
}

/// A density over [0, 1)^2 from a row-major table, with the marginal over
/// rows (y) and the conditionals over columns (x) both simplified.
///
/// The marginal CDF over the n_y rows is simplified first (or, for a
/// simplifier with a whole-table criterion, [`Simplifier::simplify_rows`]
/// picks the marginal vertices). Each kept marginal
/// segment, covering rows [a, b), gets one conditional: the average of the
/// conditionals of its rows weighted by their marginal mass, which is the
/// normalised column sum of rows a..b-1. That conditional is then simplified
/// too. The density is p(x, y) = p_marginal(y) p_j(x), j the marginal segment
/// holding y.
///
/// Storage: the marginal's vertices, one offset (u32) per marginal segment
/// plus one, and the conditionals' vertices, all f32 (position and CDF
/// value). A marginal segment of zero mass is never sampled and has density
/// 0, so its conditional is stored empty.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveCdf2D {
    /// The marginal's m vertex positions, then its m CDF values.
    pub(crate) marginal: Box<[f32]>,
    /// Conditional j occupies `conditionals[2 o_j .. 2 o_{j+1}]`: its vertex
    /// positions, then its CDF values (o = `offsets`).
    pub(crate) offsets: Box<[u32]>,
    pub(crate) conditionals: Box<[f32]>,
    pub(crate) integral: f64,
}

impl AdaptiveCdf2D {
    /// Build from `values` (row-major, `n_y` rows of `n_x`) with one
    /// simplifier and tolerance.
    ///
    /// For the vertical-error (and the other curve) simplifiers the marginal
    /// and every conditional get the tolerance. For a chi-square simplifier
    /// ([`ErrorBound::ChiSquare`]) the tolerance is the budget of the whole
    /// table: the rows get 3/4 of it and the conditionals, together, 1/4, so
    /// the divergence of the table from the distribution is at most
    /// (1 + 3t/4)(1 + t/4) - 1 (this split gave the most compression at equal
    /// efficiency on the built-in nickel, against 1/2 : 1/2 and 1/4 : 3/4).
    pub fn from_values(
        values: &[f32],
        n_x: usize,
        n_y: usize,
        simplifier: &dyn Simplifier,
        tolerance: f64,
    ) -> Result<Self> {
        let (marginal, conditional) = split_tolerance(simplifier, tolerance);
        Self::from_values_with(values, n_x, n_y, simplifier, marginal, conditional)
    }

    /// Build with separate tolerances for the marginal and the conditionals.
    pub fn from_values_with(
        values: &[f32],
        n_x: usize,
        n_y: usize,
        simplifier: &dyn Simplifier,
        marginal_tolerance: f64,
        conditional_tolerance: f64,
    ) -> Result<Self> {
        Self::build(
            values,
            n_x,
            n_y,
            simplifier,
            marginal_tolerance,
            conditional_tolerance,
            0,
        )
    }

    /// [`from_values`](Self::from_values), with the first `pinned_rows` rows
    /// kept as marginal segments of their own (the rest is simplified as a
    /// table of its own, so the error bounds still hold).
    ///
    /// The BRDF sampler pins the first θ_h row: there the half-vector
    /// Jacobian vanishes like v^3, so a density constant over (x, v) becomes
    /// a solid-angle density growing like 1/v^3 towards θ_h = 0. Kept on its
    /// own, that row confines the growth to the same tiny cap as the uniform
    /// table instead of spreading it over a merged segment.
    pub fn from_values_pinned(
        values: &[f32],
        n_x: usize,
        n_y: usize,
        simplifier: &dyn Simplifier,
        tolerance: f64,
        pinned_rows: usize,
    ) -> Result<Self> {
        let (marginal, conditional) = split_tolerance(simplifier, tolerance);
        Self::build(
            values,
            n_x,
            n_y,
            simplifier,
            marginal,
            conditional,
            pinned_rows,
        )
    }

    fn build(
        values: &[f32],
        n_x: usize,
        n_y: usize,
        simplifier: &dyn Simplifier,
        marginal_tolerance: f64,
        conditional_tolerance: f64,
        pinned_rows: usize,
    ) -> Result<Self> {
        const WHAT: &str = "AdaptiveCdf2D";
        if n_x == 0 || n_y == 0 {
            return Err(Error::EmptyTable { what: WHAT });
        }
        let expected = n_x.checked_mul(n_y).ok_or(Error::InvalidParameter {
            name: "n_x * n_y",
            reason: "overflows usize".into(),
        })?;
        if values.len() != expected {
            return Err(Error::SizeMismatch {
                what: WHAT,
                expected,
                got: values.len(),
            });
        }
        validate_table(WHAT, values)?;
        check_len(WHAT, n_x)?;
        check_len(WHAT, n_y)?;
        validate_tolerance(marginal_tolerance)?;
        validate_tolerance(conditional_tolerance)?;

        let rows = || values.chunks_exact(n_x);
        let row_prefix = prefix_sums(rows().map(|r| r.iter().map(|&v| v as f64).sum::<f64>()));
        let total = row_prefix[n_y];
        let (mut mx, mut mc) = (Vec::new(), Vec::new());
        if total > 0.0 {
            // Pinned rows are segments of their own; the rest is simplified
            // as a table of its own. Its errors, relative to its own mass,
            // are at most the tolerance, so relative to the whole they are
            // too.
            let pinned = pinned_rows.min(n_y);
            let rest = n_y - pinned;
            let mut kept: Vec<usize> = (0..pinned).collect();
            if rest > 0 {
                let tail = &values[pinned * n_x..];
                let tail_kept = match simplifier.simplify_rows(tail, n_x, rest, marginal_tolerance)
                {
                    Some(k) => k,
                    None => {
                        let sub = prefix_sums(
                            tail.chunks_exact(n_x)
                                .map(|r| r.iter().map(|&v| v as f64).sum::<f64>()),
                        );
                        match cdf_points(&sub) {
                            Some((x, p)) => simplifier.simplify(&x, &p, marginal_tolerance),
                            None => vec![0, rest],
                        }
                    }
                };
                kept.extend(tail_kept.into_iter().map(|k| k + pinned));
            } else {
                kept.push(n_y);
            }
            push_vertices(&row_prefix, &kept, &mut mx, &mut mc);
        } else {
            simplify_into(
                &row_prefix,
                simplifier,
                marginal_tolerance,
                &mut mx,
                &mut mc,
            );
        }
        let marginal_curve = Curve { x: &mx, cdf: &mc };

        // Row boundaries of the marginal segments: vertex x = k / n_y.
        let bounds: Vec<usize> = if total > 0.0 {
            mx.iter()
                .map(|&x| (x as f64 * n_y as f64).round() as usize)
                .collect()
        } else {
            vec![0, n_y]
        };
        let segments = mx.len() - 1;
        let mut offsets = Vec::with_capacity(segments + 1);
        let (mut cx, mut cc) = (Vec::new(), Vec::new());
        let mut conditionals = Vec::new();
        offsets.push(0u32);
        // The conditional of each marginal segment: the column sums of its
        // rows (None for a zero-mass segment, which is never drawn).
        let columns: Vec<Option<Running>> = (0..segments)
            .map(|j| {
                let zero_mass = marginal_curve.density(j) == 0.0;
                (!(zero_mass && total > 0.0)).then(|| {
                    let mut column = vec![0.0f64; n_x];
                    for row in rows().take(bounds[j + 1]).skip(bounds[j]) {
                        for (c, &v) in column.iter_mut().zip(row) {
                            *c += v as f64;
                        }
                    }
                    prefix_sums(column.into_iter())
                })
            })
            .collect();
        let shared = if total > 0.0 {
            let mut curves = Vec::new();
            let mut weights = Vec::new();
            for prefix in columns.iter().flatten() {
                if let Some(points) = cdf_points(prefix) {
                    weights.push(prefix[n_x] / total);
                    curves.push(points);
                }
            }
            simplifier.simplify_many(&curves, &weights, conditional_tolerance)
        } else {
            None
        };
        let mut shared = shared.map(Vec::into_iter);
        for prefix in &columns {
            if let Some(prefix) = prefix {
                cx.clear();
                cc.clear();
                let kept = match (&mut shared, prefix[n_x] > 0.0) {
                    (Some(it), true) => it.next(),
                    _ => None,
                };
                match kept {
                    Some(kept) => push_vertices(prefix, &kept, &mut cx, &mut cc),
                    None => {
                        simplify_into(prefix, simplifier, conditional_tolerance, &mut cx, &mut cc)
                    }
                }
                conditionals.extend_from_slice(&cx);
                conditionals.extend_from_slice(&cc);
            }
            let end =
                u32::try_from(conditionals.len() / 2).map_err(|_| Error::InvalidParameter {
                    name: "table",
                    reason: "more than 2^32 conditional vertices".into(),
                })?;
            offsets.push(end);
        }
        mx.extend_from_slice(&mc);
        Ok(Self {
            marginal: mx.into_boxed_slice(),
            offsets: offsets.into_boxed_slice(),
            conditionals: conditionals.into_boxed_slice(),
            integral: total / expected as f64,
        })
    }

    fn marginal_curve(&self) -> Curve<'_> {
        let m = self.marginal.len() / 2;
        Curve {
            x: &self.marginal[..m],
            cdf: &self.marginal[m..],
        }
    }

    /// The number of vertices kept by the marginal over y.
    pub fn marginal_vertex_count(&self) -> usize {
        self.marginal.len() / 2
    }

    /// The marginal density p(y) = (c_{j+1} - c_j) / (y_{j+1} - y_j) on the
    /// marginal segment j holding y; 0 outside [0, 1).
    pub fn marginal_pdf(&self, y: f32) -> f32 {
        self.marginal_curve().pdf(y)
    }

    /// The number of marginal segments, which is the number of conditionals.
    pub fn conditional_count(&self) -> usize {
        self.offsets.len() - 1
    }

    /// The number of vertices kept by conditional j (0 for a conditional of a
    /// zero-mass segment, which is never used).
    pub fn conditional_vertex_count(&self, j: usize) -> usize {
        (self.offsets[j + 1] - self.offsets[j]) as usize
    }

    /// The mean number of vertices of the stored (non-empty) conditionals.
    pub fn mean_conditional_vertices(&self) -> f64 {
        let counts: Vec<usize> = (0..self.conditional_count())
            .map(|j| self.conditional_vertex_count(j))
            .filter(|&c| c > 0)
            .collect();
        if counts.is_empty() {
            0.0
        } else {
            counts.iter().sum::<usize>() as f64 / counts.len() as f64
        }
    }

    fn conditional(&self, j: usize) -> Curve<'_> {
        let (a, b) = (self.offsets[j] as usize, self.offsets[j + 1] as usize);
        let (x, cdf) = self.conditionals[2 * a..2 * b].split_at(b - a);
        Curve { x, cdf }
    }

    /// y from the marginal with u.y, then x from the conditional of y's
    /// marginal segment with u.x, both by [`sample_curve`].
    #[inline(always)]
    fn sample_inline(&self, u: Vec2) -> Sample2D {
        let (sy, j) = sample_curve(self.marginal_curve(), u.y);
        let (sx, _) = sample_curve(self.conditional(j), u.x);
        Sample2D {
            p: Vec2::new(sx.x, sy.x),
            pdf: sy.pdf * sx.pdf,
        }
    }

    /// Whether the box [p.x ± margin.x] × [p.y ± margin.y] lies inside one
    /// marginal segment and, within it, one conditional segment, so that
    /// the density is the same all over it (false for a box reaching outside
    /// [0, 1)^2). Cheaper than a density lookup at its four corners: a
    /// tabulated BRDF sampler can take a draw's density from the drawn cell
    /// when this holds (`acdf_uniform::SliceBuilder::same_cell_around`).
    pub fn same_segment_around(&self, p: Vec2, margin: Vec2) -> bool {
        let inside = |curve: Curve<'_>, x: f32, m: f32| -> Option<usize> {
            if !(x - m >= 0.0 && x + m < 1.0) {
                return None;
            }
            if curve.x.len() < 2 {
                return Some(0);
            }
            let i = curve.segment_of(x);
            (x - m >= curve.x[i] && x + m < curve.x[i + 1]).then_some(i)
        };
        match inside(self.marginal_curve(), p.y, margin.y) {
            Some(j) => inside(self.conditional(j), p.x, margin.x).is_some(),
            None => false,
        }
    }

    /// [`sample_batch`](Distribution2D::sample_batch) compiled for AVX2 (the
    /// segment counts become 8-wide compares); the same IEEE operations in
    /// the same order, so the same samples.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn sample_batch_avx2(&self, u: &[Vec2], out: &mut [Sample2D]) {
        for (o, &u) in out.iter_mut().zip(u) {
            *o = self.sample_inline(u);
        }
    }
}

/// The longest curve whose segment is found by comparing every vertex.
const LINEAR_CURVE: usize = 32;

/// `Curve::segment_of` (the segment i with x_i <= x < x_{i+1}, the last for
/// x >= 1) for a curve of at least two vertices, with the vertices at or
/// below x counted without branches when the curve is short (see
/// [`sample_curve`]); the same segment.
#[inline(always)]
fn segment_of(curve: Curve<'_>, x: f32) -> usize {
    let last = curve.x.len() - 2;
    let at_or_below = if curve.x.len() <= LINEAR_CURVE {
        curve.x.iter().map(|&v| (v <= x) as usize).sum()
    } else {
        curve.x.partition_point(|&v| v <= x)
    };
    at_or_below.saturating_sub(1).min(last)
}

/// The curve's sample for `u`: the segment i with c_i <= u < c_{i+1}, then
/// x = x_i + (u - c_i) / (c_{i+1} - c_i) (x_{i+1} - x_i) in `f64`, clamped
/// into [x_i, x_{i+1}), and the segment's density. The arithmetic is
/// `Curve::sample`'s, so the result is the same bit for bit; only the
/// segment is found by counting the vertices at or below u (c_0 = 0 always
/// is) when the curve is short, which a compiler turns into SIMD compares
/// with no branch to mispredict, where a binary search's branches follow
/// the random u.
#[inline(always)]
fn sample_curve(curve: Curve<'_>, u: f32) -> (Sample1D, usize) {
    let u = clamp_unit(u);
    if curve.x.len() < 2 {
        return (Sample1D { x: u, pdf: 1.0 }, 0);
    }
    let last = curve.cdf.len() - 2;
    let at_or_below = if curve.cdf.len() <= LINEAR_CURVE {
        curve.cdf.iter().map(|&c| (c <= u) as usize).sum()
    } else {
        curve.cdf.partition_point(|&c| c <= u)
    };
    let i = at_or_below.saturating_sub(1).min(last);
    let (c0, c1) = (curve.cdf[i] as f64, curve.cdf[i + 1] as f64);
    let (x0, x1) = (curve.x[i], curve.x[i + 1]);
    let t = ((u as f64 - c0) / (c1 - c0)).clamp(0.0, 1.0);
    let x = (x0 as f64 + t * (x1 as f64 - x0 as f64)) as f32;
    let x = x.clamp(x0, f32_below(x1)).min(ONE_MINUS_EPSILON);
    (
        Sample1D {
            x,
            pdf: curve.density(i),
        },
        i,
    )
}

impl Distribution2D for AdaptiveCdf2D {
    /// y from the marginal with u.y, then x from the conditional of y's
    /// marginal segment with u.x; pdf = p_marginal(y) p_j(x).
    fn sample(&self, u: Vec2) -> Sample2D {
        self.sample_inline(u)
    }

    /// The same samples as [`sample`](Distribution2D::sample), in one loop
    /// (compiled for AVX2 where the CPU has it).
    fn sample_batch(&self, u: &[Vec2], out: &mut [Sample2D]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has just been found to support AVX2.
            unsafe { self.sample_batch_avx2(u, out) };
            return;
        }
        for (o, &u) in out.iter_mut().zip(u) {
            *o = self.sample_inline(u);
        }
    }

    /// p_marginal(y) p_j(x), 0 outside [0, 1)^2.
    fn pdf(&self, p: Vec2) -> f32 {
        if !((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y)) {
            return 0.0;
        }
        let m = self.marginal_curve();
        let j = segment_of(m, p.y);
        let py = m.density(j);
        if py == 0.0 {
            return 0.0;
        }
        let c = self.conditional(j);
        let px = if c.x.len() < 2 {
            1.0
        } else {
            c.density(segment_of(c, p.x))
        };
        py * px
    }

    /// (P_j(x), P_marginal(y)).
    fn invert(&self, p: Vec2) -> Vec2 {
        let y = if p.y > 0.0 { p.y.min(1.0) } else { 0.0 };
        let j = self.marginal_curve().segment_of(y);
        Vec2::new(
            self.conditional(j).invert(p.x),
            self.marginal_curve().invert(y),
        )
    }

    /// The sum of the table divided by n_x n_y.
    fn integral(&self) -> f64 {
        self.integral
    }

    /// Marginal vertices + offsets + conditional vertices, in bytes.
    fn storage_bytes(&self) -> usize {
        std::mem::size_of_val(&*self.marginal)
            + std::mem::size_of_val(&*self.offsets)
            + std::mem::size_of_val(&*self.conditionals)
    }
}

#[cfg(test)]
mod fast_sampling_tests {
    use super::*;
    use crate::simplify::DouglasPeucker;

    /// The counting search of `sample_curve` gives `Curve::sample`'s result
    /// bit for bit, and `sample_batch` gives `sample`'s, on tables with zero
    /// rows, peaks and flat runs, at tolerances that keep few and many
    /// vertices (curves shorter and longer than `LINEAR_CURVE`).
    #[test]
    fn fast_sampling_matches_the_curve_search() {
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let (nx, ny) = (16, 96);
        let values: Vec<f32> = (0..nx * ny)
            .map(|k| {
                let (x, y) = (k % nx, k / nx);
                if y % 7 == 3 {
                    0.0
                } else {
                    let peak = (-((y as f32 - 20.0) / 4.0).powi(2)).exp() * 50.0;
                    peak + 0.1 + (x as f32 * 0.7).sin().abs()
                }
            })
            .collect();
        let simplifier = DouglasPeucker::vertical();
        for tolerance in [0.0, 1e-4, 1e-2] {
            let d = AdaptiveCdf2D::from_values(&values, nx, ny, &simplifier, tolerance).unwrap();
            let mut u: Vec<Vec2> = (0..2000).map(|_| Vec2::new(next(), next())).collect();
            u.extend([
                Vec2::ZERO,
                Vec2::splat(ONE_MINUS_EPSILON),
                Vec2::splat(f32::NAN),
            ]);
            for &u in &u {
                let (sy, j) = d.marginal_curve().sample(u.y);
                let (sx, _) = d.conditional(j).sample(u.x);
                let expected = Sample2D {
                    p: Vec2::new(sx.x, sy.x),
                    pdf: sy.pdf * sx.pdf,
                };
                assert_eq!(d.sample(u), expected, "tolerance {tolerance} u {u}");
            }
            let mut out = vec![Sample2D::default(); u.len()];
            d.sample_batch(&u, &mut out);
            for (o, &u) in out.iter().zip(&u) {
                assert_eq!(*o, d.sample(u));
            }
            // The counting segment search gives the curves' density.
            for &u in &u[..500] {
                let m = d.marginal_curve();
                let j = m.segment_of(u.y);
                let py = m.density(j);
                let expected = if py == 0.0 || u.is_nan() {
                    0.0
                } else {
                    py * d.conditional(j).pdf(u.x)
                };
                assert_eq!(d.pdf(u), expected, "{u}");
            }
            // Where the box is said to lie in one segment, the density at its
            // corners is the density at its centre; most boxes qualify.
            let mut inside = 0;
            for s in &out[..2000] {
                for m in [1e-5f32, 1e-3, 0.05] {
                    let margin = Vec2::splat(m);
                    if d.same_segment_around(s.p, margin) {
                        inside += 1;
                        for c in [
                            Vec2::new(-1.0, -1.0),
                            Vec2::new(-1.0, 1.0),
                            Vec2::ONE,
                            Vec2::new(1.0, -1.0),
                        ] {
                            assert_eq!(d.pdf(s.p + c * margin), s.pdf, "{s:?} {m}");
                        }
                    }
                }
            }
            assert!(inside > 2000, "{inside}");
        }
    }
}
