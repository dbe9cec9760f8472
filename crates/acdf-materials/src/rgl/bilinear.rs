//! Bilinear densities over the unit square, sampled and inverted exactly, and
//! stacks of them blended linearly over parameters.
//!
//! A grid of nx × ny values `v[j][i]` sits at (x, y) = (i/(nx−1), j/(ny−1)) and
//! is interpolated bilinearly. Within a cell the density is linear in x for a
//! fixed y, and the marginal m(y) = ∫ f(x, y) dx is linear in y, so both
//! cumulative distributions are quadratics per cell: sampling solves one
//! quadratic for y (marginal) and one for x (conditional), and the inverse
//! map evaluates them. Because the cumulative sums are linear in the data, a
//! blend of normalised slices is sampled by blending their cumulative tables
//! on the fly, without building the blended table.

use acdf_core::{
    clamp_unit, validate_table, Distribution2D, Error, Result, Sample2D, Vec2, ONE_MINUS_EPSILON,
};
use glam::DVec2;

/// The cell of a grid with `n` points containing `x` ∈ [0, 1], and the
/// fraction of the way through it: index min(⌊x(n−1)⌋, n−2), fraction in
/// [0, 1]. NaN acts as 0.
#[inline]
pub(crate) fn grid_cell(x: f64, n: usize) -> (usize, f64) {
    let x = if x > 0.0 { x.min(1.0) } else { 0.0 };
    let s = x * (n - 1) as f64;
    let i = (s.floor() as usize).min(n - 2);
    (i, (s - i as f64).clamp(0.0, 1.0))
}

/// Weights of up to four slices of a table with parameter axes (φ_i, θ_i):
/// the bilinear blend of the two neighbouring values on each axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamBlend {
    // The first `len` entries are the terms with non-zero weight.
    slices: [usize; 4],
    weights: [f64; 4],
    len: usize,
}

impl ParamBlend {
    /// The blend that takes slice `index` alone.
    pub fn single(index: usize) -> ParamBlend {
        ParamBlend {
            slices: [index; 4],
            weights: [1.0, 0.0, 0.0, 0.0],
            len: 1,
        }
    }

    /// The blend at parameters (p0, p1) over axes `axis0` (slow) and `axis1`
    /// (fast); slice index = k0 · len(axis1) + k1. On each axis with n ≥ 2
    /// values, k = the largest index in [0, n−2] with axis_k ≤ p, and
    /// t = clamp((p − axis_k) / (axis_{k+1} − axis_k), 0, 1); an axis with one
    /// value contributes k = 0, t = 0. Axes must be strictly increasing.
    pub fn new(axis0: &[f32], axis1: &[f32], p0: f64, p1: f64) -> ParamBlend {
        let (k0, t0) = axis_blend(axis0, p0);
        let (k1, t1) = axis_blend(axis1, p1);
        let n1 = axis1.len().max(1);
        let mut blend = ParamBlend {
            slices: [0; 4],
            weights: [0.0; 4],
            len: 0,
        };
        for (d0, w0) in [(0, 1.0 - t0), (1, t0)] {
            for (d1, w1) in [(0, 1.0 - t1), (1, t1)] {
                let w = w0 * w1;
                if w != 0.0 {
                    blend.slices[blend.len] = (k0 + d0) * n1 + k1 + d1;
                    blend.weights[blend.len] = w;
                    blend.len += 1;
                }
            }
        }
        blend
    }

    /// The (slice, weight) pairs with a non-zero weight.
    #[inline]
    pub fn terms(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.slices[..self.len]
            .iter()
            .copied()
            .zip(self.weights[..self.len].iter().copied())
    }

    /// The same blend with every slice index limited to `count − 1`, so that
    /// indexing a table with `count` slices cannot go out of bounds.
    pub(crate) fn limited(mut self, count: usize) -> ParamBlend {
        for s in &mut self.slices {
            *s = (*s).min(count.saturating_sub(1));
        }
        self
    }
}

fn axis_blend(axis: &[f32], p: f64) -> (usize, f64) {
    if axis.len() < 2 {
        return (0, 0.0);
    }
    let n = axis.len();
    let k = axis[1..n - 1].partition_point(|&v| (v as f64) <= p);
    let (a, b) = (axis[k] as f64, axis[k + 1] as f64);
    let t = (p - a) / (b - a);
    (k, if t > 0.0 { t.min(1.0) } else { 0.0 })
}

/// A bilinear density on [0, 1]² from an nx × ny grid (row-major, x fast),
/// normalised to integrate to 1, with its cumulative tables.
///
/// `conditional_cdf[j][i]` = ∫₀^{x_i} f(x, y_j) dx and `marginal_cdf[j]` =
/// ∫₀^{y_j} ∫₀¹ f dx dy, both of the normalised density.
#[derive(Debug, Clone, PartialEq)]
pub struct Bilinear2D {
    nx: usize,
    ny: usize,
    density: Vec<f32>,
    conditional_cdf: Vec<f32>,
    marginal_cdf: Vec<f32>,
    integral: f64,
}

/// Trapezoid sums of a bilinear grid: (conditional cumulative per row,
/// marginal cumulative), unnormalised, in f64.
fn cumulate(nx: usize, ny: usize, v: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (dx, dy) = (1.0 / (nx - 1) as f64, 1.0 / (ny - 1) as f64);
    let mut conditional = vec![0.0; nx * ny];
    for j in 0..ny {
        let row = &v[j * nx..(j + 1) * nx];
        let mut acc = 0.0;
        for i in 1..nx {
            acc += 0.5 * (row[i - 1] + row[i]) * dx;
            conditional[j * nx + i] = acc;
        }
    }
    let mut marginal = vec![0.0; ny];
    for j in 1..ny {
        let r0 = conditional[(j - 1) * nx + nx - 1];
        let r1 = conditional[j * nx + nx - 1];
        marginal[j] = marginal[j - 1] + 0.5 * (r0 + r1) * dy;
    }
    (conditional, marginal)
}

impl Bilinear2D {
    /// Build from `values` (nx · ny entries, finite, non-negative). The
    /// integral Σ_cells mean(corners) / ((nx−1)(ny−1)) is divided out; an
    /// all-zero grid becomes the uniform density and reports integral 0. An
    /// axis with a single vertex means a function constant along it (the
    /// vertex is repeated at both ends).
    pub fn new(nx: usize, ny: usize, values: &[f32]) -> Result<Bilinear2D> {
        let expected = nx.checked_mul(ny).ok_or_else(|| Error::InvalidParameter {
            name: "bilinear grid size",
            reason: format!("{nx} × {ny} overflows"),
        })?;
        if expected == 0 {
            return Err(Error::EmptyTable {
                what: "bilinear density",
            });
        }
        if values.len() != expected {
            return Err(Error::SizeMismatch {
                what: "bilinear density",
                expected,
                got: values.len(),
            });
        }
        validate_table("bilinear density", values)?;
        let (gx, gy) = (nx.max(2), ny.max(2));
        let mut v = Vec::with_capacity(gx * gy);
        for j in 0..gy {
            let row = &values[j.min(ny - 1) * nx..][..nx];
            v.extend((0..gx).map(|i| row[i.min(nx - 1)] as f64));
        }
        let (nx, ny) = (gx, gy);
        let (mut conditional, mut marginal) = cumulate(nx, ny, &v);
        let mut integral = marginal[ny - 1];
        if !(integral > 0.0 && integral.is_finite()) {
            v.iter_mut().for_each(|x| *x = 1.0);
            (conditional, marginal) = cumulate(nx, ny, &v);
            integral = 0.0;
        }
        let norm = 1.0 / marginal[ny - 1];
        let scaled = |t: &[f64]| t.iter().map(|&x| (x * norm) as f32).collect();
        Ok(Bilinear2D {
            nx,
            ny,
            density: scaled(&v),
            conditional_cdf: scaled(&conditional),
            marginal_cdf: scaled(&marginal),
            integral,
        })
    }

    /// Grid points along x (columns; at least 2).
    pub fn nx(&self) -> usize {
        self.nx
    }

    /// Grid points along y (rows; at least 2).
    pub fn ny(&self) -> usize {
        self.ny
    }

    /// The normalised grid values, row-major.
    pub fn density_table(&self) -> &[f32] {
        &self.density
    }

    /// This density as a one-slice blended view, through which all the
    /// sampling arithmetic goes.
    pub fn view(&self) -> BlendedBilinear<'_> {
        BlendedBilinear {
            slices: std::slice::from_ref(self),
            blend: ParamBlend::single(0),
            nx: self.nx,
            ny: self.ny,
        }
    }

    fn bytes(&self) -> usize {
        4 * (self.density.len() + self.conditional_cdf.len() + self.marginal_cdf.len())
    }
}

#[derive(Clone, Copy)]
enum Table {
    Density,
    Conditional,
    Marginal,
}

/// The density f = Σ_k w_k f_k of a blend of normalised slices of equal grid
/// size; it integrates to 1 when the weights sum to 1.
#[derive(Debug, Clone, Copy)]
pub struct BlendedBilinear<'a> {
    slices: &'a [Bilinear2D],
    blend: ParamBlend,
    nx: usize,
    ny: usize,
}

impl BlendedBilinear<'_> {
    #[inline]
    fn mix(&self, table: Table, index: usize) -> f64 {
        let load = |k: usize| {
            let slice = &self.slices[self.blend.slices[k]];
            let t = match table {
                Table::Density => &slice.density,
                Table::Conditional => &slice.conditional_cdf,
                Table::Marginal => &slice.marginal_cdf,
            };
            self.blend.weights[k] * t[index] as f64
        };
        // One or two slices are the common cases (one θ_i axis); the loop
        // covers blends over both parameter axes.
        match self.blend.len {
            1 => load(0),
            2 => load(0) + load(1),
            n => (0..n).map(load).sum(),
        }
    }

    #[inline]
    fn value(&self, index: usize) -> f64 {
        self.mix(Table::Density, index)
    }

    /// ∫₀^{x_i} f(x, y) dx for y a fraction `fy` through row cell `j`.
    #[inline]
    fn conditional_at(&self, j: usize, fy: f64, i: usize) -> f64 {
        let c0 = self.mix(Table::Conditional, j * self.nx + i);
        let c1 = self.mix(Table::Conditional, (j + 1) * self.nx + i);
        (1.0 - fy) * c0 + fy * c1
    }

    /// The row integral r_j = ∫₀¹ f(x, y_j) dx.
    #[inline]
    fn row_integral(&self, j: usize) -> f64 {
        self.mix(Table::Conditional, j * self.nx + self.nx - 1)
    }

    /// The two grid values at the ends of column cell i, on row cell j at
    /// fraction fy.
    #[inline]
    fn row_values(&self, j: usize, fy: f64, i: usize) -> (f64, f64) {
        let at = |i: usize| {
            (1.0 - fy) * self.value(j * self.nx + i) + fy * self.value((j + 1) * self.nx + i)
        };
        (at(i), at(i + 1))
    }

    /// f(p): the bilinear interpolant of the blended, normalised grid at p
    /// (clamped to [0, 1]²).
    pub fn density(&self, p: DVec2) -> f64 {
        let (i, fx) = grid_cell(p.x, self.nx);
        let (j, fy) = grid_cell(p.y, self.ny);
        let (v0, v1) = self.row_values(j, fy, i);
        ((1.0 - fx) * v0 + fx * v1).max(0.0)
    }

    /// ∫∫ f over the square (1 up to rounding for weights that sum to 1).
    pub fn total(&self) -> f64 {
        self.mix(Table::Marginal, self.ny - 1)
    }

    /// The inverse of [`sample`](Self::sample): u.y = M(p.y) / M(1) with
    /// M(y) = ∫₀^y ∫₀¹ f, and u.x = C(p.x | p.y) / C(1 | p.y) with
    /// C(x | y) = ∫₀^x f(x', y) dx'. Returns u and f(p).
    pub fn invert(&self, p: DVec2) -> (DVec2, f64) {
        let (i, fx) = grid_cell(p.x, self.nx);
        let (j, fy) = grid_cell(p.y, self.ny);
        let (r0, r1) = (self.row_integral(j), self.row_integral(j + 1));
        let dy = 1.0 / (self.ny - 1) as f64;
        let m0 = self.mix(Table::Marginal, j);
        let marginal = m0 + dy * fy * (r0 + 0.5 * (r1 - r0) * fy);
        let total = self.total();
        let uy = if total > 0.0 { marginal / total } else { p.y };

        let (v0, v1) = self.row_values(j, fy, i);
        let dx = 1.0 / (self.nx - 1) as f64;
        let c = self.conditional_at(j, fy, i) + dx * fx * (v0 + 0.5 * (v1 - v0) * fx);
        let row_total = self.conditional_at(j, fy, self.nx - 1);
        let ux = if row_total > 0.0 { c / row_total } else { p.x };
        let u = DVec2::new(ux.clamp(0.0, 1.0), uy.clamp(0.0, 1.0));
        (u, ((1.0 - fx) * v0 + fx * v1).max(0.0))
    }

    /// Draw p = (C⁻¹(u.x | y), M⁻¹(u.y)): find the row cell by binary search
    /// on M, solve its quadratic for y, then the same for x on the
    /// conditional at that y. Returns p and f(p). `u` is clamped to [0, 1]
    /// (NaN acts as 0).
    pub fn sample(&self, u: DVec2) -> (DVec2, f64) {
        // The f64 analogue of `clamp_unit`: NaN and negatives act as 0.
        let unit = |u: f64| if u > 0.0 { u.min(1.0) } else { 0.0 };
        let (ux, uy) = (unit(u.x), unit(u.y));

        let target = uy * self.total();
        let j = search(self.ny, |j| self.mix(Table::Marginal, j) <= target);
        let (r0, r1) = (self.row_integral(j), self.row_integral(j + 1));
        let tau = (target - self.mix(Table::Marginal, j)) * (self.ny - 1) as f64;
        let fy = solve_cell(r0, r1, tau);
        let y = (j as f64 + fy) / (self.ny - 1) as f64;

        // When y lands exactly on a row without mass (u.y on a breakpoint of
        // M), x is drawn from the limit of the conditional as y moves into
        // the cell: the row at the cell's other edge.
        let mut fy_x = fy;
        let mut row_total = self.conditional_at(j, fy, self.nx - 1);
        if row_total <= 0.0 {
            fy_x = if r1 > 0.0 { 1.0 } else { 0.0 };
            row_total = self.conditional_at(j, fy_x, self.nx - 1);
        }
        let x = if row_total > 0.0 {
            let target = ux * row_total;
            let i = search(self.nx, |i| self.conditional_at(j, fy_x, i) <= target);
            let (v0, v1) = self.row_values(j, fy_x, i);
            let tau = (target - self.conditional_at(j, fy_x, i)) * (self.nx - 1) as f64;
            (i as f64 + solve_cell(v0, v1, tau)) / (self.nx - 1) as f64
        } else {
            // A cell without any mass is drawn only through rounding.
            ux
        };
        let p = DVec2::new(x.clamp(0.0, 1.0), y.clamp(0.0, 1.0));
        (p, self.density(p))
    }
}

/// The largest k in [0, n−2] with `le(k)` true, for `le` monotone (true, then
/// false); 0 if it is false everywhere.
#[inline]
fn search(n: usize, le: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0usize, n - 1);
    // Invariant: the answer is in [lo, hi).
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if le(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The t ∈ [0, 1] with v0 t + (v1 − v0) t²/2 = τ, the cumulative of the linear
/// density v0 (1 − t) + v1 t. Written as 2τ / (v0 + sqrt(v0² + 2(v1 − v0)τ)),
/// which does not cancel for v0 ≥ 0.
#[inline]
fn solve_cell(v0: f64, v1: f64, tau: f64) -> f64 {
    let tau = tau.max(0.0);
    let disc = (v0 * v0 + 2.0 * (v1 - v0) * tau).max(0.0);
    let den = v0 + disc.sqrt();
    let t = if den > 0.0 { 2.0 * tau / den } else { 0.0 };
    if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

impl Distribution2D for Bilinear2D {
    /// p = the exact inverse of the bilinear CDFs at u (see
    /// [`BlendedBilinear::sample`]); the density f(p).
    fn sample(&self, u: Vec2) -> Sample2D {
        let u = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
        let (p, _) = self.view().sample(u.as_dvec2());
        let p = Vec2::new(
            (p.x as f32).min(ONE_MINUS_EPSILON),
            (p.y as f32).min(ONE_MINUS_EPSILON),
        );
        // The density is taken at the f32 point handed out, so that it equals
        // `pdf(p)`. A `u` on a CDF breakpoint (or rounding) can put p exactly
        // on a zero-valued vertex or edge of a cell that has mass; a point a
        // few ulps into that cell has a positive density, so look there.
        let pdf = self.pdf(p);
        if pdf > 0.0 {
            return Sample2D { p, pdf };
        }
        let step = |x: f32, k: f32| (x + k * f32::EPSILON).clamp(0.0, ONE_MINUS_EPSILON);
        for k in [1.0, 64.0, 4096.0] {
            for (dx, dy) in [
                (1.0, 0.0),
                (0.0, 1.0),
                (1.0, 1.0),
                (-1.0, 0.0),
                (0.0, -1.0),
                (-1.0, -1.0),
                (1.0, -1.0),
                (-1.0, 1.0),
            ] {
                let q = Vec2::new(step(p.x, k * dx), step(p.y, k * dy));
                let d = self.pdf(q);
                if d > 0.0 {
                    return Sample2D { p: q, pdf: d };
                }
            }
        }
        Sample2D { p, pdf }
    }

    /// The normalised bilinear interpolant; 0 outside [0, 1)².
    fn pdf(&self, p: Vec2) -> f32 {
        if !(p.x >= 0.0 && p.x < 1.0 && p.y >= 0.0 && p.y < 1.0) {
            return 0.0;
        }
        self.view().density(p.as_dvec2()) as f32
    }

    /// (C(p.x | p.y), M(p.y)), coordinates clamped to [0, 1].
    fn invert(&self, p: Vec2) -> Vec2 {
        self.view().invert(p.as_dvec2()).0.as_vec2()
    }

    fn integral(&self) -> f64 {
        self.integral
    }

    fn storage_bytes(&self) -> usize {
        self.bytes()
    }
}

/// A stack of normalised [`Bilinear2D`] slices of one grid size, indexed by
/// the flat parameter index of a [`ParamBlend`].
#[derive(Debug, Clone, PartialEq)]
pub struct BilinearStack {
    nx: usize,
    ny: usize,
    slices: Vec<Bilinear2D>,
}

impl BilinearStack {
    /// Split `values` (count · ny · nx entries) into `count` slices and
    /// normalise each.
    pub fn new(count: usize, nx: usize, ny: usize, values: &[f32]) -> Result<BilinearStack> {
        let per = nx.saturating_mul(ny);
        if count == 0 || per == 0 || per.checked_mul(count) != Some(values.len()) {
            return Err(Error::SizeMismatch {
                what: "bilinear stack",
                expected: per.saturating_mul(count),
                got: values.len(),
            });
        }
        let slices = values
            .chunks_exact(per)
            .map(|c| Bilinear2D::new(nx, ny, c))
            .collect::<Result<Vec<_>>>()?;
        Ok(BilinearStack { nx, ny, slices })
    }

    /// The slices, in parameter order.
    pub fn slices(&self) -> &[Bilinear2D] {
        &self.slices
    }

    /// The blended density Σ_k w_k f_k for the weights of `blend`.
    pub fn at(&self, blend: ParamBlend) -> BlendedBilinear<'_> {
        BlendedBilinear {
            slices: &self.slices,
            blend: blend.limited(self.slices.len()),
            nx: self.nx,
            ny: self.ny,
        }
    }

    /// Grid points along x.
    pub fn nx(&self) -> usize {
        self.nx
    }

    /// Grid points along y.
    pub fn ny(&self) -> usize {
        self.ny
    }

    /// Heap bytes of all slices' tables.
    pub fn storage_bytes(&self) -> usize {
        self.slices.iter().map(Bilinear2D::bytes).sum()
    }
}

/// A stack of raw (unnormalised) bilinear grids: `count` slices of ny × nx
/// values, interpolated without any normalisation (`rgb`, `ndf`, `sigma`).
#[derive(Debug, Clone, PartialEq)]
pub struct BilinearGrid {
    nx: usize,
    ny: usize,
    count: usize,
    values: Vec<f32>,
}

impl BilinearGrid {
    /// `values` holds `count` slices of ny × nx finite values, nx, ny ≥ 2.
    pub fn new(count: usize, nx: usize, ny: usize, values: Vec<f32>) -> Result<BilinearGrid> {
        if nx < 2 || ny < 2 || count == 0 {
            return Err(Error::InvalidParameter {
                name: "bilinear grid size",
                reason: format!("need at least one 2 × 2 grid, got {count} × {ny} × {nx}"),
            });
        }
        let expected = count
            .checked_mul(nx)
            .and_then(|c| c.checked_mul(ny))
            .unwrap_or(usize::MAX);
        if values.len() != expected {
            return Err(Error::SizeMismatch {
                what: "bilinear grid",
                expected,
                got: values.len(),
            });
        }
        Ok(BilinearGrid {
            nx,
            ny,
            count,
            values,
        })
    }

    /// The bilinear interpolant of slice `slice` at p (clamped to [0, 1]²); 0
    /// for a slice index out of range.
    pub fn eval(&self, slice: usize, p: DVec2) -> f64 {
        if slice >= self.count {
            return 0.0;
        }
        let base = slice * self.nx * self.ny;
        let (i, fx) = grid_cell(p.x, self.nx);
        let (j, fy) = grid_cell(p.y, self.ny);
        let at = |j: usize, i: usize| self.values[base + j * self.nx + i] as f64;
        let row0 = (1.0 - fx) * at(j, i) + fx * at(j, i + 1);
        let row1 = (1.0 - fx) * at(j + 1, i) + fx * at(j + 1, i + 1);
        (1.0 - fy) * row0 + fy * row1
    }

    /// Grid points along x.
    pub fn nx(&self) -> usize {
        self.nx
    }

    /// Grid points along y.
    pub fn ny(&self) -> usize {
        self.ny
    }

    /// The number of slices.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Heap bytes of the values.
    pub fn storage_bytes(&self) -> usize {
        4 * self.values.len()
    }
}
