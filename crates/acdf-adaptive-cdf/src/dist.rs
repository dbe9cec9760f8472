//! Adaptive (curve-simplified) distributions over [0, 1) and [0, 1)^2.

use crate::curve::{
    cdf_points, prefix_sums, push_vertices, segment_samples, Curve, CurveGuide, Running, Segment,
};
use crate::simplify::{validate_tolerance, ErrorBound, Simplifier};
use acdf_core::simd::adaptive_cdf::{self, AdaptiveCurve, AdaptiveTable, STAGE};
use acdf_core::simd::Avx2;
use acdf_core::{
    clamp_unit, validate_table, Distribution1D, Distribution2D, Error, Result, Sample1D, Sample2D,
    Vec2,
};
use acdf_tabulated::SliceDistribution;

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
    /// The m vertex positions, then the m CDF values.
    vertices: Box<[f32]>,
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
        Ok(Self::from_vertices(x, &cdf, prefix[n] / n as f64))
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
        Ok(Self::from_vertices(x, &cdf, prefix[n] / n as f64))
    }

    fn from_vertices(mut x: Vec<f32>, cdf: &[f32], integral: f64) -> Self {
        x.extend_from_slice(cdf);
        Self {
            vertices: x.into_boxed_slice(),
            integral,
        }
    }

    #[inline(always)]
    fn curve(&self) -> Curve<'_> {
        Curve::whole(&self.vertices)
    }

    /// The number of kept vertices (segments + 1).
    pub fn vertex_count(&self) -> usize {
        self.vertices.len() / 2
    }

    /// The kept vertex positions x_i (0 first, 1 last).
    pub fn vertex_positions(&self) -> &[f32] {
        self.curve().xs()
    }

    /// The CDF values c_i at the kept vertices (0 first, 1 last).
    pub fn vertex_cdf(&self) -> &[f32] {
        self.curve().cdfs()
    }

    /// The index i of the segment [x_i, x_{i+1}) holding `x` (x clamped to
    /// the last segment at and above 1, to the first below 0 and for NaN).
    pub fn segment_of(&self, x: f32) -> usize {
        self.curve().segment_of(x)
    }
}

impl Distribution1D for AdaptiveCdf1D {
    /// x = x_i + (u - c_i) / (c_{i+1} - c_i) (x_{i+1} - x_i) on the segment
    /// with c_i <= u < c_{i+1}; pdf = (c_{i+1} - c_i) / (x_{i+1} - x_i).
    #[inline]
    fn sample(&self, u: f32) -> Sample1D {
        self.curve().sample(u).0
    }

    /// (c_{i+1} - c_i) / (x_{i+1} - x_i) on the segment holding x.
    #[inline]
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

    /// 4 bytes per vertex position plus 4 per CDF value (the searches use
    /// no index beyond them).
    fn storage_bytes(&self) -> usize {
        std::mem::size_of_val(&*self.vertices)
    }

    /// The same samples as [`sample`](Distribution1D::sample): where the CPU
    /// has AVX2, whole stages of draws in SIMD lanes (the kernel of
    /// `acdf_core::simd::adaptive_cdf`), and the rest eight at a time in
    /// scalar stages.
    fn sample_batch(&self, u: &[f32], out: &mut [Sample1D]) {
        acdf_core::dispatch!(Self::sample_batch_one, self, u, out)
    }
}

impl AdaptiveCdf1D {
    /// This curve as the SIMD kernels read it.
    #[inline(always)]
    fn lanes(&self) -> AdaptiveCurve<'_> {
        AdaptiveCurve {
            vertices: &self.vertices,
        }
    }

    /// [`Distribution1D::sample_batch`] itself, in the instance `cpu`
    /// names: the core kernel's whole stages, then the scalar stages.
    #[inline(always)]
    fn sample_batch_one(&self, u: &[f32], out: &mut [Sample1D], cpu: Option<Avx2>) {
        let done = match cpu {
            Some(cpu) => adaptive_cdf::sample_batch_1d(cpu, &self.lanes(), u, out),
            None => 0,
        };
        self.sample_batch_lanes(&u[done..], &mut out[done..]);
    }

    /// The same samples as [`sample`](Distribution1D::sample), [`LANES`] at
    /// a time: their segments by one search stepping all lanes together,
    /// then their positions and densities as SIMD arithmetic.
    #[inline(always)]
    fn sample_batch_lanes(&self, u: &[f32], out: &mut [Sample1D]) {
        let curve = self.curve();
        let len = u.len().min(out.len());
        let (u, out) = (&u[..len], &mut out[..len]);
        // A built or decoded 1D curve always has two vertices or more.
        let lanes = if curve.is_uniform() {
            0
        } else {
            len / LANES * LANES
        };
        let mut u_chunks = u[..lanes].chunks_exact(LANES);
        let mut out_chunks = out[..lanes].chunks_exact_mut(LANES);
        for (uc, oc) in (&mut u_chunks).zip(&mut out_chunks) {
            let ul: [f32; LANES] = std::array::from_fn(|l| clamp_unit(uc[l]));
            let i = curve.segments_of_u(ul);
            let seg = i.map(|i| curve.segment(i));
            let (x, pdf) = segment_samples(&seg, &ul);
            for (l, o) in oc.iter_mut().enumerate() {
                *o = Sample1D {
                    x: x[l],
                    pdf: pdf[l],
                };
            }
        }
        for (o, &u) in out[lanes..].iter_mut().zip(&u[lanes..]) {
            *o = self.sample(u);
        }
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
/// 0, so its conditional is stored empty. In memory the marginal also keeps
/// a guide of its CDF values, 33 counts of two bytes derived from it
/// (`curve::CurveGuide`; not written by `persist`), which
/// `storage_bytes` counts: 66 bytes, about 0.35% of an adaptive:dp slice
/// of the built-in nickel.
///
/// Sampling and density lookups search these lists without branches that
/// follow the random numbers (one at a time, a 32-entry window compared at
/// once, reached through the guide for the marginal's u and by a four-way
/// search for longer lists, see `acdf_core::search`; in batches on AVX2,
/// binary lifting in SIMD lanes, see `acdf_core::simd::adaptive_cdf`).
///
/// # Examples
///
/// ```
/// use acdf_adaptive_cdf::{AdaptiveCdf2D, DouglasPeucker};
/// use acdf_core::{Distribution2D, Sample2D, Vec2};
///
/// // 64 rows of 32 cells: a peak on row 10 and column 5 over a floor.
/// let (nx, ny) = (32, 64);
/// let table: Vec<f32> = (0..nx * ny)
///     .map(|k| if k / nx == 10 && k % nx == 5 { 100.0 } else { 1.0 })
///     .collect();
/// let simplifier = DouglasPeucker::vertical();
/// let d = AdaptiveCdf2D::from_values(&table, nx, ny, &simplifier, 1e-3)?;
/// // Far fewer vertices than the 64 rows: the floor is one straight CDF.
/// assert!(d.marginal_vertex_count() < 16);
/// let s = d.sample(Vec2::new(0.3, 0.6));
/// assert!(s.pdf > 0.0);
/// // The density a draw reports is the density `pdf` gives its point.
/// assert_eq!(d.pdf(s.p), s.pdf);
/// // The batch form gives the same samples, bit for bit.
/// let u = [Vec2::new(0.3, 0.6), Vec2::new(0.99, 0.01)];
/// let mut out = [Sample2D::default(); 2];
/// d.sample_batch(&u, &mut out);
/// assert_eq!(out[0], s);
/// # Ok::<(), acdf_core::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveCdf2D {
    /// The marginal's m vertex positions, then its m CDF values.
    pub(crate) marginal: Box<[f32]>,
    /// Conditional j occupies `conditionals[2 o_j .. 2 o_{j+1}]`: its vertex
    /// positions, then its CDF values (o = `offsets`).
    pub(crate) offsets: Box<[u32]>,
    pub(crate) conditionals: Box<[f32]>,
    pub(crate) integral: f64,
    /// The guide of the marginal's CDF values, derived from it.
    pub(crate) marginal_guide: CurveGuide,
    /// The most vertices of any conditional, derived from the offsets: the
    /// batch searches take their number of steps from it.
    pub(crate) longest_conditional: usize,
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
        let split = split_tolerance(simplifier, tolerance);
        Self::from_values_pinned_split(values, n_x, n_y, simplifier, split, pinned_rows)
    }

    /// [`from_values_pinned`](Self::from_values_pinned) with the marginal
    /// and the conditionals simplified at tolerances of their own, where
    /// the caller knows a better split than the simplifier's default (the
    /// outgoing sampler's shared grid,
    /// [`SHARED_MARGINAL_SHARE`](crate::quantised::SHARED_MARGINAL_SHARE)).
    pub fn from_values_pinned_split(
        values: &[f32],
        n_x: usize,
        n_y: usize,
        simplifier: &dyn Simplifier,
        (marginal, conditional): (f64, f64),
        pinned_rows: usize,
    ) -> Result<Self> {
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

    /// Build: the marginal's vertices ([`marginal_vertices`]), the column
    /// sums of each marginal segment's rows ([`segment_columns`]), then each
    /// segment's simplified conditional ([`conditional_vertices`]).
    fn build(
        values: &[f32],
        n_x: usize,
        n_y: usize,
        simplifier: &dyn Simplifier,
        marginal_tolerance: f64,
        conditional_tolerance: f64,
        pinned_rows: usize,
    ) -> Result<Self> {
        let cells = check_table(values, n_x, n_y)?;
        validate_tolerance(marginal_tolerance)?;
        validate_tolerance(conditional_tolerance)?;
        let row_prefix = prefix_sums(
            values
                .chunks_exact(n_x)
                .map(|r| r.iter().map(|&v| v as f64).sum::<f64>()),
        );
        let total = row_prefix[n_y];
        let marginal = marginal_vertices(
            values,
            n_x,
            &row_prefix,
            simplifier,
            marginal_tolerance,
            pinned_rows,
        );
        let columns = segment_columns(values, n_x, &marginal, total);
        let (offsets, conditionals) =
            conditional_vertices(&columns, n_x, total, simplifier, conditional_tolerance)?;
        // The marginal is stored as its positions, then its CDF values.
        let (mut mx, mc) = marginal;
        mx.extend_from_slice(&mc);
        Ok(Self::from_parts(
            mx,
            offsets,
            conditionals,
            total / cells as f64,
        ))
    }

    /// The distribution of stored arrays (checked by the caller), with the
    /// marginal's guide derived from them.
    pub(crate) fn from_parts(
        marginal: Vec<f32>,
        offsets: Vec<u32>,
        conditionals: Vec<f32>,
        integral: f64,
    ) -> Self {
        let longest_conditional = offsets
            .windows(2)
            .map(|o| o[1].saturating_sub(o[0]) as usize)
            .max()
            .unwrap_or(0);
        AdaptiveCdf2D {
            marginal_guide: CurveGuide::new(&marginal),
            longest_conditional,
            marginal: marginal.into_boxed_slice(),
            offsets: offsets.into_boxed_slice(),
            conditionals: conditionals.into_boxed_slice(),
            integral,
        }
    }

    #[inline(always)]
    fn marginal_curve(&self) -> Curve<'_> {
        Curve::guided(&self.marginal, &self.marginal_guide)
    }

    /// This table as the SIMD kernels read it.
    #[inline(always)]
    fn lanes(&self) -> AdaptiveTable<'_> {
        AdaptiveTable {
            marginal: &self.marginal,
            offsets: &self.offsets,
            conditionals: &self.conditionals,
            longest_conditional: self.longest_conditional,
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

    /// The marginal's kept vertex positions in [0, 1] (the row coordinate),
    /// ascending.
    pub fn marginal_positions(&self) -> &[f32] {
        &self.marginal[..self.marginal_vertex_count()]
    }

    /// Conditional j's kept vertex positions in [0, 1] (the column
    /// coordinate), ascending; empty for a zero-mass row.
    pub fn conditional_positions(&self, j: usize) -> &[f32] {
        let (a, b) = (self.offsets[j] as usize, self.offsets[j + 1] as usize);
        &self.conditionals[2 * a..2 * a + (b - a)]
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

    /// Conditional j, the curve of marginal segment j.
    #[inline(always)]
    fn conditional(&self, j: usize) -> Curve<'_> {
        let (a, b) = (self.offsets[j] as usize, self.offsets[j + 1] as usize);
        Curve::within(&self.conditionals, 2 * a, b - a)
    }

    /// Start loading the conditional that a draw with this u.y most likely
    /// takes: that of the first marginal segment of u.y's guide interval
    /// (`acdf_core::search::prefetch`), so that its read is in flight while
    /// the marginal is searched: where the guess is right, the
    /// conditional's first read no longer waits for memory after the
    /// marginal search.
    #[inline(always)]
    fn prefetch_likely_conditional(&self, uy: f32) {
        let last = self.offsets.len().saturating_sub(2);
        // Clamped as the draw clamps it, so the compiler shares the two.
        let j = self.marginal_guide.first_segment(clamp_unit(uy)).min(last);
        if let (Some(&a), Some(&b)) = (self.offsets.get(j), self.offsets.get(j + 1)) {
            let (a, b) = (a as usize, b as usize);
            acdf_core::search::prefetch(&self.conditionals, 2 * a, 2 * (b - a));
        }
    }

    /// y from the marginal with u.y, then x from the conditional of y's
    /// marginal segment with u.x; pdf = p_marginal(y) p_j(x).
    #[inline(always)]
    fn sample_inline(&self, u: Vec2) -> Sample2D {
        self.prefetch_likely_conditional(u.y);
        let (sy, j, _) = self.marginal_curve().sample(u.y);
        let (sx, _, _) = self.conditional(j).sample(u.x);
        Sample2D {
            p: Vec2::new(sx.x, sy.x),
            pdf: sy.pdf * sx.pdf,
        }
    }

    /// The same samples as [`sample`](Distribution2D::sample), [`LANES`]
    /// draws at a time in stages (marginal segments, marginal samples,
    /// conditional segments, conditional samples), so that the core sees
    /// that many independent chains of loads at each stage instead of one
    /// long chain per draw.
    ///
    /// With `SAME`, also the box test of every draw against `margin` into
    /// `same` (which must be as long as `out`), from the drawn segments.
    #[inline(always)]
    fn sample_batch_lanes<const SAME: bool>(
        &self,
        u: &[Vec2],
        out: &mut [Sample2D],
        margin: Vec2,
        same: &mut [bool],
    ) {
        let len = u.len().min(out.len());
        let (u, out) = (&u[..len], &mut out[..len]);
        let marginal = self.marginal_curve();
        let mut u_chunks = u.chunks_exact(LANES);
        let mut out_chunks = out.chunks_exact_mut(LANES);
        // Non-short-circuit `&`: the box test of `sample_and_same_cell`.
        let inside = |x: f32, m: f32, s: &Segment| {
            (x - m >= 0.0) & (x + m < 1.0) & (x - m >= s.x0) & (x + m < s.x1)
        };
        for (chunk, (uc, oc)) in (&mut u_chunks).zip(&mut out_chunks).enumerate() {
            let (mut ux, mut uy) = ([0.0f32; LANES], [0.0f32; LANES]);
            for ((x, y), u) in ux.iter_mut().zip(&mut uy).zip(uc) {
                *x = clamp_unit(u.x);
                *y = clamp_unit(u.y);
            }
            let j = marginal.segments_of_u(uy);
            let mut seg = [Segment::UNIFORM; LANES];
            for (s, &j) in seg.iter_mut().zip(&j) {
                *s = marginal.segment(j);
            }
            let sy = segment_samples(&seg, &uy);
            let marginal_seg = seg;
            for (s, (&j, &u)) in seg.iter_mut().zip(j.iter().zip(&ux)) {
                let c = self.conditional(j);
                *s = if c.is_uniform() {
                    Segment::UNIFORM
                } else {
                    c.segment(c.segment_of_u(u))
                };
            }
            let sx = segment_samples(&seg, &ux);
            for (l, o) in oc.iter_mut().enumerate() {
                *o = Sample2D {
                    p: Vec2::new(sx.0[l], sy.0[l]),
                    pdf: sy.1[l] * sx.1[l],
                };
            }
            if SAME {
                for l in 0..LANES {
                    let m = if marginal.is_uniform() {
                        Segment::UNIFORM
                    } else {
                        marginal_seg[l]
                    };
                    same[chunk * LANES + l] =
                        inside(sy.0[l], margin.y, &m) & inside(sx.0[l], margin.x, &seg[l]);
                }
            }
        }
        let tail = len / LANES * LANES;
        for (k, (o, &u)) in out_chunks
            .into_remainder()
            .iter_mut()
            .zip(u_chunks.remainder())
            .enumerate()
        {
            if SAME {
                let (sample, inside) = self.sample_and_same_cell(u, margin);
                *o = sample;
                same[tail + k] = inside;
            } else {
                *o = self.sample_inline(u);
            }
        }
    }
}

impl AdaptiveCdf2D {
    /// The stages of
    /// [`sample_each_and_same_cell`](Self::sample_each_and_same_cell),
    /// for slices of equal length.
    #[inline(always)]
    fn sample_each_lanes(
        dists: &[&AdaptiveCdf2D],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        let mut d_chunks = dists.chunks_exact(LANES);
        let mut u_chunks = u.chunks_exact(LANES);
        let mut out_chunks = out.chunks_exact_mut(LANES);
        let mut same_chunks = same.chunks_exact_mut(LANES);
        // The segment u falls in, with its index (the uniform stand-in's one
        // segment for a curve of fewer than two vertices).
        #[inline(always)]
        fn drawn_segment(curve: Curve<'_>, u: f32) -> (usize, Segment) {
            if curve.is_uniform() {
                (0, Segment::UNIFORM)
            } else {
                let i = curve.segment_of_u(u);
                (i, curve.segment(i))
            }
        }
        let inside = |x: f32, m: f32, s: &Segment| {
            (x - m >= 0.0) & (x + m < 1.0) & (x - m >= s.x0) & (x + m < s.x1)
        };
        for (((dc, uc), oc), sc) in (&mut d_chunks)
            .zip(&mut u_chunks)
            .zip(&mut out_chunks)
            .zip(&mut same_chunks)
        {
            let (mut ux, mut uy) = ([0.0f32; LANES], [0.0f32; LANES]);
            for ((x, y), u) in ux.iter_mut().zip(&mut uy).zip(uc) {
                *x = clamp_unit(u.x);
                *y = clamp_unit(u.y);
            }
            let mut rows = [Segment::UNIFORM; LANES];
            let mut j = [0usize; LANES];
            for l in 0..LANES {
                (j[l], rows[l]) = drawn_segment(dc[l].marginal_curve(), uy[l]);
            }
            let mut columns = [Segment::UNIFORM; LANES];
            for l in 0..LANES {
                columns[l] = drawn_segment(dc[l].conditional(j[l]), ux[l]).1;
            }
            let sy = segment_samples(&rows, &uy);
            let sx = segment_samples(&columns, &ux);
            for l in 0..LANES {
                oc[l] = Sample2D {
                    p: Vec2::new(sx.0[l], sy.0[l]),
                    pdf: sy.1[l] * sx.1[l],
                };
                sc[l] =
                    inside(sy.0[l], margin.y, &rows[l]) & inside(sx.0[l], margin.x, &columns[l]);
            }
        }
        for (((d, &u), o), s) in d_chunks
            .remainder()
            .iter()
            .zip(u_chunks.remainder())
            .zip(out_chunks.into_remainder())
            .zip(same_chunks.into_remainder())
        {
            (*o, *s) = d.sample_and_same_cell(u, margin);
        }
    }
}

impl AdaptiveCdf2D {
    /// The scalar stages of [`pdf_each`](Self::pdf_each), for slices of
    /// equal length.
    fn pdf_each_lanes(dists: &[&AdaptiveCdf2D], p: &[Vec2], out: &mut [f32]) {
        let mut d_chunks = dists.chunks_exact(LANES);
        let mut p_chunks = p.chunks_exact(LANES);
        let mut out_chunks = out.chunks_exact_mut(LANES);
        for ((dc, pc), oc) in (&mut d_chunks).zip(&mut p_chunks).zip(&mut out_chunks) {
            // Points outside the square look up (0, 0) and get 0 below.
            let mut inside = [false; LANES];
            let (mut x, mut y) = ([0.0f32; LANES], [0.0f32; LANES]);
            for l in 0..LANES {
                inside[l] = (0.0..1.0).contains(&pc[l].x) && (0.0..1.0).contains(&pc[l].y);
                (x[l], y[l]) = if inside[l] {
                    (pc[l].x, pc[l].y)
                } else {
                    (0.0, 0.0)
                };
            }
            let mut j = [0usize; LANES];
            let mut py = [0.0f32; LANES];
            for l in 0..LANES {
                let m = dc[l].marginal_curve();
                if m.is_uniform() {
                    py[l] = 1.0;
                } else {
                    j[l] = m.segment_of(y[l]);
                    py[l] = m.density(j[l]);
                }
            }
            for l in 0..LANES {
                let c = dc[l].conditional(j[l]);
                let px = if c.is_uniform() {
                    1.0
                } else {
                    c.density(c.segment_of(x[l]))
                };
                oc[l] = if inside[l] && py[l] != 0.0 {
                    py[l] * px
                } else {
                    0.0
                };
            }
        }
        for ((o, d), &p) in out_chunks
            .into_remainder()
            .iter_mut()
            .zip(d_chunks.remainder())
            .zip(p_chunks.remainder())
        {
            *o = d.pdf(p);
        }
    }
}

/// The number of cells of a table of `n_y` rows of `n_x`, after checking
/// the table: non-empty dimensions, `n_x · n_y` values, each finite and
/// non-negative, at most [`MAX_TABLE_LEN`] along each axis.
fn check_table(values: &[f32], n_x: usize, n_y: usize) -> Result<usize> {
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
    Ok(expected)
}

/// The marginal's kept vertices (positions, CDF values) over the rows of
/// `values`, whose running row sums are `row_prefix`.
///
/// The first `pinned_rows` rows are segments of their own; the rest is
/// simplified as a table of its own (by the simplifier's whole-table
/// criterion, [`Simplifier::simplify_rows`], where it has one). Its errors,
/// relative to its own mass, are at most the tolerance, so relative to the
/// whole they are too. An all-zero table gives the uniform marginal.
fn marginal_vertices(
    values: &[f32],
    n_x: usize,
    row_prefix: &Running,
    simplifier: &dyn Simplifier,
    tolerance: f64,
    pinned_rows: usize,
) -> (Vec<f32>, Vec<f32>) {
    let n_y = values.len() / n_x;
    let (mut mx, mut mc) = (Vec::new(), Vec::new());
    if row_prefix[n_y] <= 0.0 {
        // All zero (the sums of a checked table are finite and not negative).
        simplify_into(row_prefix, simplifier, tolerance, &mut mx, &mut mc);
        return (mx, mc);
    }
    let pinned = pinned_rows.min(n_y);
    let rest = n_y - pinned;
    let mut kept: Vec<usize> = (0..pinned).collect();
    if rest > 0 {
        let tail = &values[pinned * n_x..];
        let tail_kept = match simplifier.simplify_rows(tail, n_x, rest, tolerance) {
            Some(k) => k,
            None => {
                let sub = prefix_sums(
                    tail.chunks_exact(n_x)
                        .map(|r| r.iter().map(|&v| v as f64).sum::<f64>()),
                );
                match cdf_points(&sub) {
                    Some((x, p)) => simplifier.simplify(&x, &p, tolerance),
                    None => vec![0, rest],
                }
            }
        };
        kept.extend(tail_kept.into_iter().map(|k| k + pinned));
    } else {
        kept.push(n_y);
    }
    push_vertices(row_prefix, &kept, &mut mx, &mut mc);
    (mx, mc)
}

/// The running column sums of the rows of each marginal segment of
/// `marginal` (positions, CDF values): the unnormalised conditional of the
/// segment. `None` for a zero-mass segment of a table with mass, which is
/// never drawn and keeps no conditional.
fn segment_columns(
    values: &[f32],
    n_x: usize,
    marginal: &(Vec<f32>, Vec<f32>),
    total: f64,
) -> Vec<Option<Running>> {
    let n_y = values.len() / n_x;
    let (mx, mc) = marginal;
    let mut vertices = mx.clone();
    vertices.extend_from_slice(mc);
    let marginal_curve = Curve::whole(&vertices);
    let segments = mx.len() - 1;
    // Row boundaries of the marginal segments: vertex x = k / n_y.
    let bounds: Vec<usize> = if total > 0.0 {
        mx.iter()
            .map(|&x| (x as f64 * n_y as f64).round() as usize)
            .collect()
    } else {
        vec![0, n_y]
    };
    (0..segments)
        .map(|j| {
            let zero_mass = marginal_curve.density(j) == 0.0;
            (!(zero_mass && total > 0.0)).then(|| {
                let mut column = vec![0.0f64; n_x];
                for row in values.chunks_exact(n_x).take(bounds[j + 1]).skip(bounds[j]) {
                    for (c, &v) in column.iter_mut().zip(row) {
                        *c += v as f64;
                    }
                }
                prefix_sums(column.into_iter())
            })
        })
        .collect()
}

/// The offsets and vertices of the conditionals of the marginal segments
/// whose column sums are `columns` (`None`: stored empty).
///
/// A simplifier that simplifies several curves together
/// ([`Simplifier::simplify_many`], weighted by each segment's share of the
/// table) picks the vertices of every conditional with mass at once; the
/// others, and a simplifier without that form, simplify each conditional
/// on its own.
fn conditional_vertices(
    columns: &[Option<Running>],
    n_x: usize,
    total: f64,
    simplifier: &dyn Simplifier,
    tolerance: f64,
) -> Result<(Vec<u32>, Vec<f32>)> {
    let shared = if total > 0.0 {
        let mut curves = Vec::new();
        let mut weights = Vec::new();
        for prefix in columns.iter().flatten() {
            if let Some(points) = cdf_points(prefix) {
                weights.push(prefix[n_x] / total);
                curves.push(points);
            }
        }
        simplifier.simplify_many(&curves, &weights, tolerance)
    } else {
        None
    };
    let mut shared = shared.map(Vec::into_iter);
    let mut offsets = Vec::with_capacity(columns.len() + 1);
    let (mut cx, mut cc) = (Vec::new(), Vec::new());
    let mut conditionals = Vec::new();
    offsets.push(0u32);
    for prefix in columns {
        if let Some(prefix) = prefix {
            cx.clear();
            cc.clear();
            let kept = match (&mut shared, prefix[n_x] > 0.0) {
                (Some(it), true) => it.next(),
                _ => None,
            };
            match kept {
                Some(kept) => push_vertices(prefix, &kept, &mut cx, &mut cc),
                None => simplify_into(prefix, simplifier, tolerance, &mut cx, &mut cc),
            }
            conditionals.extend_from_slice(&cx);
            conditionals.extend_from_slice(&cc);
        }
        let end = u32::try_from(conditionals.len() / 2).map_err(|_| Error::InvalidParameter {
            name: "table",
            reason: "more than 2^32 conditional vertices".into(),
        })?;
        offsets.push(end);
    }
    Ok((offsets, conditionals))
}

/// The number of draws the batch samplers advance together.
const LANES: usize = 8;

impl Distribution2D for AdaptiveCdf2D {
    /// y from the marginal with u.y, then x from the conditional of y's
    /// marginal segment with u.x; pdf = p_marginal(y) p_j(x).
    #[inline(always)]
    fn sample(&self, u: Vec2) -> Sample2D {
        self.sample_inline(u)
    }

    /// The same samples as [`sample`](Distribution2D::sample): where the CPU
    /// has AVX2, whole stages of draws in SIMD lanes (the kernel of
    /// `acdf_core::simd::adaptive_cdf`), and the rest eight at a time in
    /// scalar stages (`sample_batch_lanes`).
    fn sample_batch(&self, u: &[Vec2], out: &mut [Sample2D]) {
        acdf_core::dispatch!(Self::sample_batch_one, self, u, out)
    }

    /// The same densities as [`pdf`](Distribution2D::pdf), bit for bit:
    /// where the CPU has AVX2, whole stages of points in SIMD lanes (the
    /// kernel of `acdf_core::simd::adaptive_cdf`), and the rest one at a
    /// time.
    fn pdf_batch(&self, p: &[Vec2], out: &mut [f32]) {
        acdf_core::dispatch!(Self::pdf_batch_one, self, p, out)
    }

    /// p_marginal(y) p_j(x), 0 outside [0, 1)^2.
    #[inline]
    fn pdf(&self, p: Vec2) -> f32 {
        if !((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y)) {
            return 0.0;
        }
        let m = self.marginal_curve();
        let j = m.segment_of(p.y);
        let py = m.density(j);
        if py == 0.0 {
            return 0.0;
        }
        let c = self.conditional(j);
        let px = if c.is_uniform() {
            1.0
        } else {
            c.density(c.segment_of(p.x))
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

    /// Marginal vertices + offsets + conditional vertices + the marginal's
    /// guide, in bytes.
    fn storage_bytes(&self) -> usize {
        std::mem::size_of_val(&*self.marginal)
            + std::mem::size_of_val(&*self.offsets)
            + std::mem::size_of_val(&*self.conditionals)
            + self.marginal_guide.bytes()
    }
}

/// The tabulated sampler's questions answered from the segments: a box
/// lies in one density cell when it lies inside one marginal segment and,
/// within it, one conditional segment.
impl SliceDistribution for AdaptiveCdf2D {
    /// The kept vertices are grid lines of the table: every marginal
    /// position is a multiple of 1 / `n_y` and every conditional position a
    /// multiple of 1 / `n_x` (to well within one cell), and there are at
    /// most `n_y` + 1 marginal vertices.
    fn fits_grid(&self, n_x: usize, n_y: usize) -> bool {
        let on_grid = |positions: &[f32], n: usize| {
            positions.iter().all(|&x| {
                let k = x as f64 * n as f64;
                (k - k.round()).abs() <= 1e-3
            })
        };
        self.marginal_vertex_count() <= n_y + 1
            && on_grid(self.marginal_positions(), n_y)
            && (0..self.conditional_count()).all(|j| on_grid(self.conditional_positions(j), n_x))
    }

    /// Whether the box [p.x ± margin.x] × [p.y ± margin.y] lies inside one
    /// marginal segment and, within it, one conditional segment, so that
    /// the density is the same all over it (false for a box reaching outside
    /// [0, 1)^2). Cheaper than a density lookup at its four corners: the
    /// tabulated BRDF sampler takes a draw's density from the drawn cell
    /// when this holds.
    #[inline(always)]
    fn same_cell_around(&self, p: Vec2, margin: Vec2) -> bool {
        #[inline(always)]
        fn inside(curve: Curve<'_>, x: f32, m: f32) -> Option<usize> {
            if !(x - m >= 0.0 && x + m < 1.0) {
                return None;
            }
            if curve.is_uniform() {
                return Some(0);
            }
            let i = curve.segment_of(x);
            let xs = curve.xs();
            (x - m >= xs[i] && x + m < xs[i + 1]).then_some(i)
        }
        match inside(self.marginal_curve(), p.y, margin.y) {
            Some(j) => inside(self.conditional(j), p.x, margin.x).is_some(),
            None => false,
        }
    }

    /// [`sample`](Distribution2D::sample) and
    /// [`same_cell_around`](Self::same_cell_around)`(sample.p, margin)`
    /// at once. A draw lies in the marginal and conditional segments it was
    /// drawn from, so the box test reads their ends instead of searching for
    /// them again; the sample and the answer are those of the two calls.
    #[inline(always)]
    fn sample_and_same_cell(&self, u: Vec2, margin: Vec2) -> (Sample2D, bool) {
        self.prefetch_likely_conditional(u.y);
        let (sy, j, ys) = self.marginal_curve().sample(u.y);
        let (sx, _, xs) = self.conditional(j).sample(u.x);
        // Non-short-circuit `&`: four compares, no branches.
        let inside = |x: f32, m: f32, s: Segment| {
            (x - m >= 0.0) & (x + m < 1.0) & (x - m >= s.x0) & (x + m < s.x1)
        };
        let same = inside(sy.x, margin.y, ys) & inside(sx.x, margin.x, xs);
        let sample = Sample2D {
            p: Vec2::new(sx.x, sy.x),
            pdf: sy.pdf * sx.pdf,
        };
        (sample, same)
    }

    /// `sample_batch`, and for every draw
    /// [`same_cell_around`](Self::same_cell_around)`(sample.p, margin)`
    /// into `same`, from the segments each draw came from (as
    /// [`sample_and_same_cell`](Self::sample_and_same_cell) does for
    /// one draw). Entries beyond the shortest of the three lengths are left
    /// alone.
    fn sample_batch_and_same_cell(
        &self,
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        let len = u.len().min(out.len()).min(same.len());
        let (u, out, same) = (&u[..len], &mut out[..len], &mut same[..len]);
        acdf_core::dispatch!(
            Self::sample_batch_and_same_cell_one,
            self,
            u,
            margin,
            out,
            same
        )
    }

    /// Draw `u[k]` from `dists[k]` for every k (the slices of a batch of
    /// shading points) and answer, into `same`, the box test
    /// [`same_cell_around`](Self::same_cell_around)`(sample.p, margin)`
    /// of each draw in its own distribution: exactly
    /// `dists[k].sample_and_same_cell(u[k], margin)`. Where the CPU has
    /// AVX2, a stage of [`STAGE`] draws whose distributions all fit goes in
    /// SIMD lanes, each lane reading its own distribution (the kernel of
    /// `acdf_core::simd::adaptive_cdf`); the other draws go eight (`LANES`)
    /// at a time in scalar stages (marginal segments, conditional segments,
    /// then positions), so that the searches of different slices overlap.
    /// Entries beyond the shortest of the four lengths are left alone.
    fn sample_each_and_same_cell(
        dists: &[&Self],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        let len = dists.len().min(u.len()).min(out.len()).min(same.len());
        let (dists, u, out, same) = (&dists[..len], &u[..len], &mut out[..len], &mut same[..len]);
        acdf_core::dispatch!(
            Self::sample_each_and_same_cell_one,
            dists,
            u,
            margin,
            out,
            same
        )
    }

    /// `dists[k].pdf(p[k])` for every k (the slices of a batch of shading
    /// points), bit for bit, eight (`LANES`) at a time in stages (marginal
    /// segments, conditional segments, densities) so that the searches of
    /// different slices overlap; where the CPU has AVX2, a stage of
    /// [`STAGE`] points whose distributions all fit goes in SIMD lanes,
    /// each lane reading its own distribution (the kernel of
    /// `acdf_core::simd::adaptive_cdf`). Entries beyond the shortest of the
    /// three lengths are left alone.
    fn pdf_each(dists: &[&Self], p: &[Vec2], out: &mut [f32]) {
        let len = dists.len().min(p.len()).min(out.len());
        let (dists, p, out) = (&dists[..len], &p[..len], &mut out[..len]);
        acdf_core::dispatch!(Self::pdf_each_one, dists, p, out)
    }
}

/// The batch entry points themselves, in the instance of
/// [`acdf_core::dispatch!`] that `cpu` names: the core kernels where they
/// apply (`cpu` is the token and the tables fit their lanes), the scalar
/// code for the rest.
impl AdaptiveCdf2D {
    /// [`Distribution2D::sample_batch`].
    #[inline(always)]
    fn sample_batch_one(&self, u: &[Vec2], out: &mut [Sample2D], cpu: Option<Avx2>) {
        let done = match cpu {
            Some(cpu) => adaptive_cdf::sample_batch(cpu, &self.lanes(), u, out),
            None => 0,
        };
        self.sample_batch_lanes::<false>(&u[done..], &mut out[done..], Vec2::ZERO, &mut []);
    }

    /// [`Distribution2D::pdf_batch`].
    #[inline(always)]
    fn pdf_batch_one(&self, p: &[Vec2], out: &mut [f32], cpu: Option<Avx2>) {
        let done = match cpu {
            Some(cpu) => adaptive_cdf::pdf_batch(cpu, &self.lanes(), p, out),
            None => 0,
        };
        for (o, &p) in out[done..].iter_mut().zip(&p[done..]) {
            *o = self.pdf(p);
        }
    }

    /// [`SliceDistribution::sample_batch_and_same_cell`], for slices of
    /// equal length.
    #[inline(always)]
    fn sample_batch_and_same_cell_one(
        &self,
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
        cpu: Option<Avx2>,
    ) {
        let done = match cpu {
            Some(cpu) => {
                adaptive_cdf::sample_batch_and_same_cell(cpu, &self.lanes(), u, margin, out, same)
            }
            None => 0,
        };
        let (u, out, same) = (&u[done..], &mut out[done..], &mut same[done..]);
        self.sample_batch_lanes::<true>(u, out, margin, same);
    }

    /// [`SliceDistribution::sample_each_and_same_cell`], for slices of
    /// equal length, a stage of [`STAGE`] slices at a time.
    #[inline(always)]
    fn sample_each_and_same_cell_one(
        dists: &[&Self],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
        cpu: Option<Avx2>,
    ) {
        for (k, stage) in dists.chunks(STAGE).enumerate() {
            let at = k * STAGE..k * STAGE + stage.len();
            let (u, out, same) = (&u[at.clone()], &mut out[at.clone()], &mut same[at]);
            let done = match (cpu, <&[&Self; STAGE]>::try_from(stage)) {
                (Some(cpu), Ok(stage)) => {
                    let table = |l: usize| stage[l].lanes();
                    adaptive_cdf::sample_each_and_same_cell(cpu, table, u, margin, out, same)
                }
                _ => 0,
            };
            let (u, out, same) = (&u[done..], &mut out[done..], &mut same[done..]);
            Self::sample_each_lanes(&stage[done..], u, margin, out, same);
        }
    }

    /// [`SliceDistribution::pdf_each`], for slices of equal length, a
    /// stage of [`STAGE`] slices at a time.
    #[inline(always)]
    fn pdf_each_one(dists: &[&Self], p: &[Vec2], out: &mut [f32], cpu: Option<Avx2>) {
        for (k, stage) in dists.chunks(STAGE).enumerate() {
            let at = k * STAGE..k * STAGE + stage.len();
            let (p, out) = (&p[at.clone()], &mut out[at]);
            let done = match (cpu, <&[&Self; STAGE]>::try_from(stage)) {
                (Some(cpu), Ok(stage)) => adaptive_cdf::pdf_each(cpu, |l| stage[l].lanes(), p, out),
                _ => 0,
            };
            if done < stage.len() {
                Self::pdf_each_lanes(&stage[done..], &p[done..], &mut out[done..]);
            }
        }
    }
}

#[cfg(test)]
mod fast_sampling_tests;
