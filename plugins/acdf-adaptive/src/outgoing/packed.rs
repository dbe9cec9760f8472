//! A slice of the outgoing sampler in its stored form: an
//! [`AdaptiveCdf2D`]'s kept vertices as grid indices (16 bits along θ_h, 8
//! along φ_h) and 16-bit CDF values, sampled and evaluated in that form.

use crate::AdaptiveCdf2D;
use acdf_core::{Error, Result};

/// The largest quantised CDF value: a CDF value c is stored as
/// round(c · 65535).
pub(crate) const Q: u16 = u16::MAX;
const QF: f32 = Q as f32;

/// A point of a [`PackedCdf2D`], its density, and whether the density is
/// the same over a box around it.
#[derive(Debug, Clone, Copy)]
pub struct Located {
    pub p: (f32, f32),
    pub pdf: f32,
    pub same_around: bool,
}

/// A piecewise-linear 2D CDF over the unit square (x → φ_h across
/// `n_x` columns, y → θ_h across `n_y` rows) with its vertices on the
/// tabulation grid: a marginal over y and, per marginal segment, a
/// conditional over x. Positions are grid indices (vertex k at
/// `pos[k] / n`), CDF values are multiples of 1/65535.
///
/// Every segment whose table cells hold mass keeps at least 1/65535 of it
/// (see `from_adaptive`), so the density is positive wherever the tabulated table
/// is. A marginal segment without mass has no conditional (empty).
#[derive(Debug, Clone, PartialEq)]
pub struct PackedCdf2D {
    pub(crate) marginal_pos: Vec<u16>,
    pub(crate) marginal_cdf: Vec<u16>,
    /// Conditional j holds vertices `offsets[j] .. offsets[j + 1]`; one
    /// entry per marginal vertex.
    pub(crate) offsets: Vec<u16>,
    /// Conditional positions in 8 bits (at most 255 columns).
    pub(crate) conditional_pos: Vec<u8>,
    pub(crate) conditional_cdf: Vec<u16>,
}

/// A stored vertex position or CDF value: an unsigned integer that
/// counts the stored values at or below a point in 16-bit or 8-bit
/// lanes.
pub(crate) trait Stored: Copy {
    /// The value as a float.
    fn float(self) -> f32;
    /// The number of `values` at or below `t` (t >= 0 in the values'
    /// units): integer compares, which the compiler runs in SIMD lanes.
    fn count_at_or_below(values: &[Self], t: f32) -> usize;
}

impl Stored for u16 {
    #[inline(always)]
    fn float(self) -> f32 {
        self as f32
    }
    #[inline(always)]
    fn count_at_or_below(values: &[u16], t: f32) -> usize {
        // For an integer p, p <= t exactly when p <= floor(t); a curve
        // has fewer than 65536 vertices.
        let k = t.max(0.0).min(u16::MAX as f32) as u16;
        values
            .iter()
            .fold(0u16, |n, &p| n.wrapping_add((p <= k) as u16)) as usize
    }
}

impl Stored for u8 {
    #[inline(always)]
    fn float(self) -> f32 {
        self as f32
    }
    #[inline(always)]
    fn count_at_or_below(values: &[u8], t: f32) -> usize {
        // At most 254 inner vertices over 255 columns.
        let k = t.max(0.0).min(u8::MAX as f32) as u8;
        values
            .iter()
            .fold(0u8, |n, &p| n.wrapping_add((p <= k) as u8)) as usize
    }
}

/// The segment of a curve holding `t` (in grid units): the number of inner
/// vertices at or below it.
#[inline(always)]
fn segment_of<P: Stored>(pos: &[P], t: f32) -> usize {
    P::count_at_or_below(&pos[1..pos.len() - 1], t)
}

/// Invert one curve at u in [0, 1): (position in [0, 1), segment). The
/// segment is the last vertex whose CDF is at or below u (zero-mass
/// segments are never chosen).
#[inline(always)]
fn sample_curve<P: Stored>(pos: &[P], cdf: &[u16], n: f32, u: f32) -> (f32, usize) {
    let us = u * QF;
    let j = u16::count_at_or_below(&cdf[1..cdf.len() - 1], us);
    let (c0, c1) = (cdf[j] as f32, cdf[j + 1] as f32);
    let (p0, p1) = (pos[j].float(), pos[j + 1].float());
    let frac = if c1 > c0 {
        ((us - c0) / (c1 - c0)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let x = (p0 + frac * (p1 - p0)) / n;
    (x.min(acdf_core::ONE_MINUS_EPSILON), j)
}

/// The density of segment j of a curve over [0, 1).
#[inline(always)]
fn density<P: Stored>(pos: &[P], cdf: &[u16], n: f32, j: usize) -> f32 {
    let mass = (cdf[j + 1] - cdf[j]) as f32;
    let width = pos[j + 1].float() - pos[j].float();
    (mass * n) / (width * QF)
}

/// Whether [t - margin, t + margin] lies inside segment j (all in grid
/// units).
#[inline(always)]
fn inside<P: Stored>(pos: &[P], j: usize, t: f32, margin: f32) -> bool {
    (pos[j].float() <= t - margin) & (t + margin < pos[j + 1].float())
}

impl PackedCdf2D {
    /// The stored form of `d`, built from `values` (row-major, `n_y` rows of
    /// `n_x`): the vertices `d` kept, with CDF values recomputed from the
    /// table in f64 and quantised. Errors when `d`'s vertices are off the
    /// grid, too many for 16-bit offsets, or more than 255 φ_h or 65535
    /// θ_h cells.
    pub fn from_adaptive(
        d: &AdaptiveCdf2D,
        values: &[f32],
        n_x: usize,
        n_y: usize,
    ) -> Result<Self> {
        let too_many = |what: &str| Error::InvalidParameter {
            name: "outgoing slice",
            reason: format!("{what} do not fit the stored indices"),
        };
        if n_x > u8::MAX as usize || n_y > Q as usize {
            return Err(Error::InvalidParameter {
                name: "resolution",
                reason: format!(
                    "{n_y} theta_h x {n_x} phi_h cells: the outgoing sampler stores at most 65535 theta_h and 255 phi_h cells"
                ),
            });
        }
        let rows: Vec<f64> = values
            .chunks_exact(n_x)
            .map(|r| r.iter().map(|&v| v as f64).sum())
            .collect();
        let total: f64 = rows.iter().sum();
        let m = d.marginal_vertex_count();
        let marginal_pos = grid_indices(&d.marginal[..m], n_y)?;
        if !(total > 0.0) {
            // No mass at all: the uniform density.
            return Ok(PackedCdf2D {
                marginal_pos: vec![0, n_y as u16],
                marginal_cdf: vec![0, Q],
                offsets: vec![0, 2],
                conditional_pos: vec![0, n_x as u8],
                conditional_cdf: vec![0, Q],
            });
        }
        let segment_mass: Vec<f64> = marginal_pos
            .windows(2)
            .map(|w| rows[w[0] as usize..w[1] as usize].iter().sum())
            .collect();
        let marginal_cdf = quantise(&segment_mass);
        let mut offsets = vec![0u16];
        let (mut conditional_pos, mut conditional_cdf) = (Vec::new(), Vec::new());
        for (j, w) in marginal_pos.windows(2).enumerate() {
            if marginal_cdf[j + 1] > marginal_cdf[j] {
                let (a, b) = (d.offsets[j] as usize, d.offsets[j + 1] as usize);
                let xs = &d.conditionals[2 * a..2 * a + (b - a)];
                let pos = if xs.len() >= 2 {
                    grid_indices(xs, n_x)?
                } else {
                    vec![0, n_x as u16]
                };
                let mut columns = vec![0.0f64; n_x];
                for row in values[w[0] as usize * n_x..w[1] as usize * n_x].chunks_exact(n_x) {
                    for (c, &v) in columns.iter_mut().zip(row) {
                        *c += v as f64;
                    }
                }
                let masses: Vec<f64> = pos
                    .windows(2)
                    .map(|p| columns[p[0] as usize..p[1] as usize].iter().sum())
                    .collect();
                conditional_cdf.extend(quantise(&masses));
                conditional_pos.extend(pos.iter().map(|&p| p as u8));
            }
            let end = conditional_pos.len();
            offsets.push(u16::try_from(end).map_err(|_| too_many("the conditional vertices"))?);
        }
        Ok(PackedCdf2D {
            marginal_pos,
            marginal_cdf,
            offsets,
            conditional_pos,
            conditional_cdf,
        })
    }

    /// Conditional j's positions and CDF values.
    #[inline(always)]
    fn conditional(&self, j: usize) -> (&[u8], &[u16]) {
        let (a, b) = (self.offsets[j] as usize, self.offsets[j + 1] as usize);
        (&self.conditional_pos[a..b], &self.conditional_cdf[a..b])
    }

    /// Draw (x, y) from u in [0, 1)^2: y from the marginal with u.y, x from
    /// the conditional of y's segment with u.x; with the density there and
    /// whether it is the same over the box (x, y) ± `margin` (in unit
    /// coordinates).
    #[inline(always)]
    pub fn sample(&self, u_x: f32, u_y: f32, n: (f32, f32), margin: (f32, f32)) -> Located {
        let (n_x, n_y) = n;
        let (y, j) = sample_curve(&self.marginal_pos, &self.marginal_cdf, n_y, u_y);
        let (pos, cdf) = self.conditional(j);
        let (x, k) = sample_curve(pos, cdf, n_x, u_x);
        Located {
            p: (x, y),
            pdf: density(&self.marginal_pos, &self.marginal_cdf, n_y, j)
                * density(pos, cdf, n_x, k),
            same_around: inside(&self.marginal_pos, j, y * n_y, margin.1 * n_y)
                & inside(pos, k, x * n_x, margin.0 * n_x),
        }
    }

    /// The density at (x, y) in [0, 1)^2.
    #[inline]
    pub fn pdf(&self, x: f32, y: f32, n_x: f32, n_y: f32) -> f32 {
        self.locate(x, y, (n_x, n_y), (0.0, 0.0)).pdf
    }

    /// The density at (x, y) in [0, 1)^2 and whether it is the same over
    /// the box (x, y) ± `margin`.
    #[inline(always)]
    pub fn locate(&self, x: f32, y: f32, n: (f32, f32), margin: (f32, f32)) -> Located {
        let (n_x, n_y) = n;
        let ty = y * n_y;
        let j = segment_of(&self.marginal_pos, ty);
        let (c0, c1) = (self.marginal_cdf[j], self.marginal_cdf[j + 1]);
        let same_y = inside(&self.marginal_pos, j, ty, margin.1 * n_y);
        if c1 == c0 {
            return Located {
                p: (x, y),
                pdf: 0.0,
                same_around: same_y,
            };
        }
        let py = density(&self.marginal_pos, &self.marginal_cdf, n_y, j);
        let (pos, cdf) = self.conditional(j);
        let tx = x * n_x;
        let k = segment_of(pos, tx);
        Located {
            p: (x, y),
            pdf: py * density(pos, cdf, n_x, k),
            same_around: same_y & inside(pos, k, tx, margin.0 * n_x),
        }
    }

    /// Bytes kept: two per stored value, one per conditional position.
    pub fn storage_bytes(&self) -> usize {
        2 * (self.marginal_pos.len()
            + self.marginal_cdf.len()
            + self.offsets.len()
            + self.conditional_cdf.len())
            + self.conditional_pos.len()
    }

    /// The number of marginal vertices.
    pub fn marginal_vertex_count(&self) -> usize {
        self.marginal_pos.len()
    }

    /// The number of conditional vertices, and of non-empty conditionals.
    pub fn conditional_vertices(&self) -> (usize, usize) {
        let stored = self.offsets.windows(2).filter(|w| w[1] > w[0]).count();
        (self.conditional_pos.len(), stored)
    }

    /// Check what a decoder read: every curve runs over the grid from 0 to
    /// n with increasing positions and from 0 to 65535 with non-decreasing
    /// CDF values; each positive-mass marginal segment has a conditional.
    pub fn validate(&self, n_x: usize, n_y: usize) -> std::result::Result<(), String> {
        check_curve("marginal", &self.marginal_pos, &self.marginal_cdf, n_y)?;
        let m = self.marginal_pos.len();
        if self.offsets.len() != m || self.offsets[0] != 0 {
            return Err(format!(
                "{} offsets for {m} marginal vertices",
                self.offsets.len()
            ));
        }
        if self.offsets.windows(2).any(|w| w[1] < w[0]) {
            return Err("offsets decrease".into());
        }
        let end = self.offsets[m - 1] as usize;
        if end != self.conditional_pos.len() || end != self.conditional_cdf.len() {
            return Err(format!(
                "offsets end at {end}, the conditionals hold {}",
                self.conditional_pos.len()
            ));
        }
        for j in 0..m - 1 {
            let (pos, cdf) = self.conditional(j);
            let positive = self.marginal_cdf[j + 1] > self.marginal_cdf[j];
            match (positive, pos.len()) {
                (false, 0) => {}
                (false, _) => return Err(format!("conditional {j} of an empty segment")),
                (true, _) => check_curve("conditional", pos, cdf, n_x)?,
            }
        }
        Ok(())
    }
}

fn check_curve<P: Stored + PartialOrd>(
    what: &str,
    pos: &[P],
    cdf: &[u16],
    n: usize,
) -> std::result::Result<(), String> {
    let m = pos.len();
    if m < 2 || cdf.len() != m {
        return Err(format!(
            "{what}: {m} positions and {} CDF values",
            cdf.len()
        ));
    }
    if pos[0].float() != 0.0 || pos[m - 1].float() != n as f32 || cdf[0] != 0 || cdf[m - 1] != Q {
        return Err(format!("{what}: does not run from (0, 0) to ({n}, {Q})"));
    }
    if pos.windows(2).any(|w| w[1] <= w[0]) {
        return Err(format!("{what}: positions not increasing"));
    }
    if cdf.windows(2).any(|w| w[1] < w[0]) {
        return Err(format!("{what}: CDF decreasing"));
    }
    Ok(())
}

/// Grid indices of positions k / n (exact for the vertices a simplifier
/// keeps of a tabulated CDF).
fn grid_indices(xs: &[f32], n: usize) -> Result<Vec<u16>> {
    xs.iter()
        .map(|&x| {
            let t = x as f64 * n as f64;
            let k = t.round();
            if (t - k).abs() > 1e-3 || k < 0.0 || k > n as f64 {
                Err(Error::InvalidParameter {
                    name: "outgoing slice",
                    reason: format!("vertex at {x} is not on the grid of {n} cells"),
                })
            } else {
                Ok(k as u16)
            }
        })
        .collect()
}

/// Quantised CDF values (0 to 65535) of segments with these masses (not all
/// zero): round(c · 65535) of the exact CDF c, except that a segment with
/// mass keeps at least one unit and a segment without keeps none.
pub(crate) fn quantise(masses: &[f64]) -> Vec<u16> {
    let total: f64 = masses.iter().sum();
    let mut positive_after = vec![0u32; masses.len() + 1];
    for i in (0..masses.len()).rev() {
        positive_after[i] = positive_after[i + 1] + (masses[i] > 0.0) as u32;
    }
    let mut out = Vec::with_capacity(masses.len() + 1);
    out.push(0u16);
    let mut running = 0.0f64;
    for (i, &mass) in masses.iter().enumerate() {
        running += mass;
        let previous = *out.last().expect("one value") as u32;
        let q = if mass > 0.0 {
            let target = (running / total * Q as f64).round() as u32;
            target
                .max(previous + 1)
                .min(Q as u32 - positive_after[i + 1])
        } else {
            previous
        };
        out.push(q as u16);
    }
    // The last value is Q whenever a positive segment is last; after a
    // trailing run of empty segments it is carried to Q by the last
    // positive one (its bound is Q), so it always ends at Q.
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_agree_with_a_linear_count() {
        let values: Vec<u16> = vec![0, 0, 3, 5, 5, 9, 12, 40, 40, 41];
        for n in 0..=values.len() {
            let v = &values[..n];
            for t in 0..45 {
                let t = t as f32 + 0.25;
                let expected = v.iter().filter(|&&p| p as f32 <= t).count();
                assert_eq!(u16::count_at_or_below(v, t), expected, "{n} {t}");
            }
        }
    }

    #[test]
    fn quantised_cdfs_keep_every_positive_segment() {
        let masses = [1.0, 1e-12, 0.0, 3.0, 1e-9, 0.0];
        let q = quantise(&masses);
        assert_eq!(q[0], 0);
        assert_eq!(*q.last().unwrap(), Q);
        for (i, &m) in masses.iter().enumerate() {
            assert_eq!(q[i + 1] > q[i], m > 0.0, "segment {i}: {q:?}");
        }
        // Close to the exact CDF where the masses are large.
        assert!((q[1] as f64 / Q as f64 - 0.25).abs() < 2e-5);
    }
}
