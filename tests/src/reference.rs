//! Small reference distributions written for the battery: piecewise-constant
//! 1D/2D (a table value is the function's mean over its cell) and
//! piecewise-linear 1D / bilinear 2D (a table value is the function at a
//! vertex). They keep the contract of `acdf_core::distribution`, are the
//! healthy originals of the mutants, and show that the battery accepts a
//! correct implementation of either table semantics.

use acdf_core::{
    clamp_unit, validate_table, Distribution1D, Distribution2D, Error, Result, Sample1D, Sample2D,
    Vec2, ONE_MINUS_EPSILON,
};

/// The largest f32 below `x` (x > 0 finite), without `f32::next_down`
/// (newer than the workspace's minimum Rust version).
#[inline]
fn float_below(x: f32) -> f32 {
    if x > 0.0 {
        f32::from_bits(x.to_bits() - 1)
    } else {
        x
    }
}

/// The smallest f32 above `x` (x ≥ 0 finite).
#[inline]
fn float_above(x: f32) -> f32 {
    if x == 0.0 {
        f32::from_bits(1)
    } else {
        f32::from_bits(x.to_bits() + 1)
    }
}

/// Normalised densities below this are flushed to zero. Without it a table
/// spanning 1e-30 .. 1e30 has cells with positive mass whose density
/// underflows f32, and a sample drawn there would report pdf 0. The mass
/// lost is below n · 1e-30 of the total.
pub const FLUSH_DENSITY: f64 = 1e-30;

/// The table with every value whose density relative to the mean is below
/// [`FLUSH_DENSITY`] set to zero.
fn flush_tiny(values: &[f32]) -> Vec<f64> {
    let mean = piecewise_constant_integral_1d(values);
    values
        .iter()
        .map(|&v| {
            let v = v as f64;
            if mean > 0.0 && v / mean < FLUSH_DENSITY {
                0.0
            } else {
                v
            }
        })
        .collect()
}

/// ∫₀¹ of the piecewise-constant function with cell means `table`:
/// (1/n) Σ v_k, in f64.
pub fn piecewise_constant_integral_1d(table: &[f32]) -> f64 {
    table.iter().map(|&v| v as f64).sum::<f64>() / table.len().max(1) as f64
}

/// ∫∫ over the unit square of the piecewise-constant function with cell
/// means `table` (row-major, `nx` per row): (1/(nx ny)) Σ v.
pub fn piecewise_constant_integral_2d(table: &[f32], _nx: usize, _ny: usize) -> f64 {
    piecewise_constant_integral_1d(table)
}

/// ∫₀¹ of the piecewise-linear interpolant of the vertex values `table`
/// (vertex k at k/(n-1); one vertex means a constant): the trapezoid rule.
pub fn piecewise_linear_integral_1d(table: &[f32]) -> f64 {
    let n = table.len();
    if n < 2 {
        return table.first().map_or(0.0, |&v| v as f64);
    }
    let s: f64 = table
        .windows(2)
        .map(|w| 0.5 * (w[0] as f64 + w[1] as f64))
        .sum();
    s / (n - 1) as f64
}

/// ∫∫ of the bilinear interpolant of vertex values (row-major, `nx` per
/// row): the trapezoid rule over rows of trapezoid row integrals.
pub fn bilinear_integral_2d(table: &[f32], nx: usize, ny: usize) -> f64 {
    let rows: Vec<f64> = table
        .chunks(nx.max(1))
        .take(ny)
        .map(piecewise_linear_integral_1d)
        .collect();
    if rows.len() < 2 {
        return rows.first().copied().unwrap_or(0.0);
    }
    rows.windows(2).map(|w| 0.5 * (w[0] + w[1])).sum::<f64>() / (rows.len() - 1) as f64
}

/// Check the dimensions of a row-major `nx` × `ny` table and its values.
pub fn validate_table_2d(what: &'static str, table: &[f32], nx: usize, ny: usize) -> Result<()> {
    let Some(expected) = nx.checked_mul(ny) else {
        return Err(Error::InvalidParameter {
            name: "nx * ny",
            reason: format!("{nx} x {ny} overflows"),
        });
    };
    if expected == 0 {
        return Err(Error::EmptyTable { what });
    }
    if table.len() != expected {
        return Err(Error::SizeMismatch {
            what,
            expected,
            got: table.len(),
        });
    }
    validate_table(what, table)
}

/// A piecewise-constant density over [0, 1) with `n` equal cells, built from
/// f64 cell values (so that 2D marginals keep their precision).
#[derive(Debug, Clone)]
pub struct PiecewiseConstant1D {
    values: Vec<f64>,
    /// cdf[k] = P(k / n), cdf[0] = 0, cdf[n] = 1.
    cdf: Vec<f64>,
    /// (1/n) Σ v, 0 when all values are zero.
    integral: f64,
}

impl PiecewiseConstant1D {
    /// Build from an f32 table of cell means.
    pub fn new(table: &[f32]) -> Result<Self> {
        validate_table("reference piecewise-constant 1D", table)?;
        let mut d = Self::from_f64(flush_tiny(table));
        d.integral = piecewise_constant_integral_1d(table);
        Ok(d)
    }

    /// Build from validated, non-negative finite f64 values.
    pub fn from_f64(values: Vec<f64>) -> Self {
        let n = values.len();
        let total: f64 = values.iter().sum();
        let zero = total == 0.0 || !total.is_finite();
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut acc = 0.0;
        for &v in &values {
            acc += if zero { 1.0 } else { v };
            cdf.push(acc);
        }
        for c in &mut cdf {
            *c /= acc;
        }
        cdf[n] = 1.0;
        Self {
            values,
            cdf,
            integral: if zero { 0.0 } else { total / n as f64 },
        }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Always false: construction rejects empty tables.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// The cell of x: ⌊x n⌋, for x in [0, 1).
    #[inline]
    pub fn cell(&self, x: f32) -> usize {
        ((x as f64 * self.len() as f64) as usize).min(self.len() - 1)
    }

    /// The probability mass of cell k: `cdf[k + 1] - cdf[k]`.
    #[inline]
    pub fn mass(&self, k: usize) -> f64 {
        self.cdf[k + 1] - self.cdf[k]
    }

    /// The cell sampled for u: the first k with cdf[k + 1] > u, which has
    /// positive mass.
    #[inline]
    pub fn find_cell(&self, u: f64) -> usize {
        (self.cdf.partition_point(|&c| c <= u).max(1) - 1).min(self.len() - 1)
    }

    /// `x = (k + t) / n` inside cell `k`, `t = (u - cdf[k]) / mass`, kept inside
    /// the cell after rounding to f32.
    #[inline]
    pub fn position_in_cell(&self, k: usize, u: f64) -> f32 {
        let n = self.len() as f64;
        let m = self.mass(k);
        let t = if m > 0.0 {
            ((u - self.cdf[k]) / m).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let mut x = ((k as f64 + t) / n) as f32;
        let lo = (k as f64 / n) as f32;
        while self.cell(x) > k && x > lo {
            x = float_below(x);
        }
        while self.cell(x) < k {
            x = float_above(x);
        }
        x.min(ONE_MINUS_EPSILON)
    }

    /// p(x) = n mass(⌊x n⌋) for x in [0, 1), else 0.
    #[inline]
    pub fn density(&self, x: f32) -> f32 {
        if !(0.0..1.0).contains(&x) {
            return 0.0;
        }
        let k = self.cell(x);
        (self.mass(k) * self.len() as f64) as f32
    }
}

impl Distribution1D for PiecewiseConstant1D {
    fn sample(&self, u: f32) -> Sample1D {
        let u = clamp_unit(u) as f64;
        let k = self.find_cell(u);
        let x = self.position_in_cell(k, u);
        Sample1D {
            x,
            pdf: self.density(x),
        }
    }

    fn pdf(&self, x: f32) -> f32 {
        self.density(x)
    }

    fn invert(&self, x: f32) -> f32 {
        let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) } as f64;
        let n = self.len() as f64;
        let k = ((x * n) as usize).min(self.len() - 1);
        let t = x * n - k as f64;
        (self.cdf[k] + t * self.mass(k)) as f32
    }

    fn integral(&self) -> f64 {
        self.integral
    }

    fn storage_bytes(&self) -> usize {
        (self.values.len() + self.cdf.len()) * std::mem::size_of::<f64>()
    }
}

/// A piecewise-constant density over [0, 1)^2: a marginal over rows (y) and
/// one conditional per row (x).
#[derive(Debug, Clone)]
pub struct PiecewiseConstant2D {
    pub marginal: PiecewiseConstant1D,
    pub conditionals: Vec<PiecewiseConstant1D>,
    integral: f64,
}

impl PiecewiseConstant2D {
    /// Build from a row-major table of cell means, `nx` per row, `ny` rows.
    pub fn new(table: &[f32], nx: usize, ny: usize) -> Result<Self> {
        validate_table_2d("reference piecewise-constant 2D", table, nx, ny)?;
        let flushed = flush_tiny(table);
        let conditionals: Vec<PiecewiseConstant1D> = flushed
            .chunks(nx)
            .map(|row| PiecewiseConstant1D::from_f64(row.to_vec()))
            .collect();
        let marginal = PiecewiseConstant1D::from_f64(
            flushed
                .chunks(nx)
                .map(|row| row.iter().sum::<f64>())
                .collect(),
        );
        Ok(Self {
            integral: piecewise_constant_integral_2d(table, nx, ny),
            marginal,
            conditionals,
        })
    }
}

impl Distribution2D for PiecewiseConstant2D {
    fn sample(&self, u: Vec2) -> Sample2D {
        let y = self.marginal.sample(u.y);
        let row = self.marginal.cell(y.x);
        let x = self.conditionals[row].sample(u.x);
        Sample2D {
            p: Vec2::new(x.x, y.x),
            pdf: x.pdf * y.pdf,
        }
    }

    fn pdf(&self, p: Vec2) -> f32 {
        if !(0.0..1.0).contains(&p.x) || !(0.0..1.0).contains(&p.y) {
            return 0.0;
        }
        let row = self.marginal.cell(p.y);
        self.marginal.density(p.y) * self.conditionals[row].density(p.x)
    }

    fn invert(&self, p: Vec2) -> Vec2 {
        let y = if p.y.is_nan() {
            0.0
        } else {
            p.y.clamp(0.0, 1.0)
        };
        let row = self.marginal.cell(y.min(ONE_MINUS_EPSILON));
        Vec2::new(
            self.conditionals[row].invert(p.x),
            self.marginal.invert(p.y),
        )
    }

    fn integral(&self) -> f64 {
        self.integral
    }

    fn storage_bytes(&self) -> usize {
        self.marginal.storage_bytes()
            + self
                .conditionals
                .iter()
                .map(|c| c.storage_bytes())
                .sum::<usize>()
    }
}

/// The linear interpolant of vertex values over [0, 1): vertex k at
/// k/(n-1); sampling inverts the quadratic CDF of each segment.
#[derive(Debug, Clone)]
pub struct PiecewiseLinear1D {
    /// Vertex values, normalised so the interpolant integrates to 1 (all
    /// ones for the all-zero fallback); at least two.
    density: Vec<f64>,
    /// cdf[k] = P(k / (n - 1)).
    cdf: Vec<f64>,
    integral: f64,
}

impl PiecewiseLinear1D {
    /// Build from vertex values; one value means a constant.
    pub fn new(table: &[f32]) -> Result<Self> {
        validate_table("reference piecewise-linear 1D", table)?;
        let mut d = Self::from_f64(flush_tiny(table));
        d.integral = piecewise_linear_integral_1d(table);
        Ok(d)
    }

    /// Build from validated f64 vertex values.
    pub fn from_f64(mut values: Vec<f64>) -> Self {
        if values.len() == 1 {
            values.push(values[0]);
        }
        let segments = (values.len() - 1) as f64;
        let integral: f64 = values.windows(2).map(|w| 0.5 * (w[0] + w[1])).sum::<f64>() / segments;
        let zero = integral == 0.0 || !integral.is_finite();
        let density: Vec<f64> = if zero {
            vec![1.0; values.len()]
        } else {
            values.iter().map(|v| v / integral).collect()
        };
        let mut cdf = vec![0.0];
        for w in density.windows(2) {
            let last = *cdf.last().unwrap_or(&0.0);
            cdf.push(last + 0.5 * (w[0] + w[1]) / segments);
        }
        let total = *cdf.last().unwrap_or(&1.0);
        for c in &mut cdf {
            *c /= total;
        }
        Self {
            density,
            cdf,
            integral: if zero { 0.0 } else { integral },
        }
    }

    fn segments(&self) -> usize {
        self.density.len() - 1
    }

    /// p(x) by linear interpolation, in f64; 0 outside [0, 1).
    pub fn density_f64(&self, x: f64) -> f64 {
        if !(0.0..1.0).contains(&x) {
            return 0.0;
        }
        let s = x * self.segments() as f64;
        let k = (s as usize).min(self.segments() - 1);
        let t = s - k as f64;
        (1.0 - t) * self.density[k] + t * self.density[k + 1]
    }

    /// Draw x for u in [0, 1) (f64), then step off a zero of the density so
    /// that no sample has pdf 0.
    pub fn sample_f64(&self, u: f64) -> f32 {
        let k = (self.cdf.partition_point(|&c| c <= u).max(1) - 1).min(self.segments() - 1);
        let n = self.segments() as f64;
        let (a, b) = (self.density[k], self.density[k + 1]);
        // Mass left to cover inside the segment, in units of the segment
        // width: solve a t + (b - a) t² / 2 = m; the form
        // t = 2m / (a + sqrt(a² + 2 (b - a) m)) has no cancellation.
        let m = ((u - self.cdf[k]) * n).max(0.0);
        let disc = (a * a + 2.0 * (b - a) * m).max(0.0);
        let denom = a + disc.sqrt();
        let t = if denom > 0.0 {
            (2.0 * m / denom).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let mut x = (((k as f64) + t) / n).min(ONE_MINUS_EPSILON as f64) as f32;
        let mut steps = 0;
        while self.density_f64(x as f64) <= 0.0 && x < ONE_MINUS_EPSILON && steps < 64 {
            x = float_above(x);
            steps += 1;
        }
        x
    }
}

impl Distribution1D for PiecewiseLinear1D {
    fn sample(&self, u: f32) -> Sample1D {
        let x = self.sample_f64(clamp_unit(u) as f64);
        Sample1D {
            x,
            pdf: self.pdf(x),
        }
    }

    fn pdf(&self, x: f32) -> f32 {
        self.density_f64(x as f64) as f32
    }

    fn invert(&self, x: f32) -> f32 {
        let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) } as f64;
        let n = self.segments() as f64;
        let k = ((x * n) as usize).min(self.segments() - 1);
        let t = x * n - k as f64;
        let (a, b) = (self.density[k], self.density[k + 1]);
        (self.cdf[k] + (a * t + 0.5 * (b - a) * t * t) / n) as f32
    }

    fn integral(&self) -> f64 {
        self.integral
    }

    fn storage_bytes(&self) -> usize {
        (self.density.len() + self.cdf.len()) * std::mem::size_of::<f64>()
    }
}

/// The bilinear interpolant of a row-major grid of vertex values over
/// [0, 1)^2. The marginal over y is the linear interpolant of the row
/// integrals; given y, the conditional over x is the linear interpolant of
/// the two neighbouring rows blended, built per sample (fine for the small
/// tables of the battery).
#[derive(Debug, Clone)]
pub struct Bilinear2D {
    rows: Vec<Vec<f64>>,
    marginal: PiecewiseLinear1D,
    integral: f64,
}

impl Bilinear2D {
    /// Build from vertex values, `nx` per row, `ny` rows.
    pub fn new(table: &[f32], nx: usize, ny: usize) -> Result<Self> {
        validate_table_2d("reference bilinear 2D", table, nx, ny)?;
        let integral = bilinear_integral_2d(table, nx, ny);
        let flushed = flush_tiny(table);
        let mut rows: Vec<Vec<f64>> = flushed
            .chunks(nx)
            .map(|r| {
                let mut r: Vec<f64> = r.to_vec();
                if r.len() == 1 {
                    r.push(r[0]);
                }
                r
            })
            .collect();
        if integral == 0.0 {
            for r in &mut rows {
                r.iter_mut().for_each(|v| *v = 1.0);
            }
        }
        if rows.len() == 1 {
            rows.push(rows[0].clone());
        }
        let row_integrals: Vec<f64> = rows
            .iter()
            .map(|r| r.windows(2).map(|w| 0.5 * (w[0] + w[1])).sum::<f64>())
            .collect();
        Ok(Self {
            marginal: PiecewiseLinear1D::from_f64(row_integrals),
            rows,
            integral,
        })
    }

    /// The row segment j containing y and the blend weight t within it.
    fn row_of(&self, y: f64) -> (usize, f64) {
        let segs = self.rows.len() - 1;
        let s = y * segs as f64;
        let j = (s as usize).min(segs - 1);
        (j, s - j as f64)
    }
}

/// Vertex k of the row blended between rows a and b: (1 - t) a_k + t b_k.
#[inline]
fn blend(a: &[f64], b: &[f64], t: f64, k: usize) -> f64 {
    (1.0 - t) * a[k] + t * b[k]
}

/// Invert the CDF of the linear interpolant of the blended row at u; the
/// uniform x when the row has no mass.
fn sample_blended(a: &[f64], b: &[f64], t: f64, u: f64) -> f32 {
    let segs = a.len() - 1;
    let mass = |k: usize| 0.5 * (blend(a, b, t, k) + blend(a, b, t, k + 1));
    let total: f64 = (0..segs).map(mass).sum();
    if total <= 0.0 || !total.is_finite() {
        return (u as f32).min(ONE_MINUS_EPSILON);
    }
    let target = u * total;
    let mut acc = 0.0;
    let mut k = 0;
    while k + 1 < segs && acc + mass(k) <= target {
        acc += mass(k);
        k += 1;
    }
    let (v0, v1) = (blend(a, b, t, k), blend(a, b, t, k + 1));
    // Solve v0 s + (v1 - v0) s² / 2 = m for s in [0, 1], without
    // cancellation.
    let m = (target - acc).max(0.0);
    let denom = v0 + (v0 * v0 + 2.0 * (v1 - v0) * m).max(0.0).sqrt();
    let s = if denom > 0.0 {
        (2.0 * m / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (((k as f64 + s) / segs as f64) as f32).min(ONE_MINUS_EPSILON)
}

/// The CDF at x of the linear interpolant of the blended row.
fn invert_blended(a: &[f64], b: &[f64], t: f64, x: f64) -> f64 {
    let segs = a.len() - 1;
    let mass = |k: usize| 0.5 * (blend(a, b, t, k) + blend(a, b, t, k + 1));
    let total: f64 = (0..segs).map(mass).sum();
    if total <= 0.0 || !total.is_finite() {
        return x;
    }
    let s = x * segs as f64;
    let k = (s as usize).min(segs - 1);
    let r = s - k as f64;
    let (v0, v1) = (blend(a, b, t, k), blend(a, b, t, k + 1));
    let before: f64 = (0..k).map(mass).sum();
    (before + v0 * r + 0.5 * (v1 - v0) * r * r) / total
}

impl Bilinear2D {
    fn density_f64(&self, x: f64, y: f64) -> f64 {
        if !(0.0..1.0).contains(&x) || !(0.0..1.0).contains(&y) {
            return 0.0;
        }
        let (sx, sy) = (self.rows[0].len() - 1, self.rows.len() - 1);
        let (fx, fy) = (x * sx as f64, y * sy as f64);
        let (i, j) = ((fx as usize).min(sx - 1), (fy as usize).min(sy - 1));
        let (tx, ty) = (fx - i as f64, fy - j as f64);
        let lerp = |r: &[f64]| (1.0 - tx) * r[i] + tx * r[i + 1];
        let f = (1.0 - ty) * lerp(&self.rows[j]) + ty * lerp(&self.rows[j + 1]);
        let norm = if self.integral > 0.0 {
            self.integral
        } else {
            1.0
        };
        f / norm
    }
}

impl Distribution2D for Bilinear2D {
    fn sample(&self, u: Vec2) -> Sample2D {
        let y = self.marginal.sample_f64(clamp_unit(u.y) as f64);
        let (j, ty) = self.row_of(y as f64);
        let mut x = sample_blended(&self.rows[j], &self.rows[j + 1], ty, clamp_unit(u.x) as f64);
        // Step off a zero of the density left by f32 rounding.
        let mut steps = 0;
        while self.density_f64(x as f64, y as f64) <= 0.0 && x < ONE_MINUS_EPSILON && steps < 64 {
            x = float_above(x);
            steps += 1;
        }
        let p = Vec2::new(x, y);
        Sample2D {
            p,
            pdf: self.pdf(p),
        }
    }

    fn pdf(&self, p: Vec2) -> f32 {
        self.density_f64(p.x as f64, p.y as f64) as f32
    }

    fn invert(&self, p: Vec2) -> Vec2 {
        let y = if p.y.is_nan() {
            0.0
        } else {
            p.y.clamp(0.0, 1.0)
        };
        let x = if p.x.is_nan() {
            0.0
        } else {
            p.x.clamp(0.0, 1.0)
        };
        let (j, ty) = self.row_of(y.min(ONE_MINUS_EPSILON) as f64);
        Vec2::new(
            invert_blended(&self.rows[j], &self.rows[j + 1], ty, x as f64) as f32,
            self.marginal.invert(y),
        )
    }

    fn integral(&self) -> f64 {
        self.integral
    }

    fn storage_bytes(&self) -> usize {
        self.rows.iter().map(|r| r.len() * 8).sum::<usize>() + self.marginal.storage_bytes()
    }
}
