//! A slice of the outgoing sampler in its stored form: an
//! [`AdaptiveCdf2D`]'s kept vertices as grid indices (16 bits along θ_h, 8
//! along φ_h) and 16-bit CDF values, sampled and evaluated in that form.

use crate::curve::Curve;
use crate::packed_env::{column_sums, grid_positions, row_sums, segment_masses};
use crate::AdaptiveCdf2D;
use acdf_core::search::Key;
use acdf_core::{Error, Result};

/// The largest quantised CDF value: a CDF value c is stored as
/// round(c · 65535).
pub const Q: u16 = u16::MAX;
/// [`Q`] as a float, the scale of a u in [0, 1) on the stored values.
pub const QF: f32 = Q as f32;

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
///
/// The 16-bit arrays (marginal positions, marginal CDF values, conditional
/// offsets, conditional CDF values) are kept one after another in one
/// buffer, so that a search can compare a fixed window of 32 entries
/// around any of them at once, whatever follows the curve searched; the
/// conditional positions are a buffer of their own.
#[derive(Debug, Clone, PartialEq)]
pub struct PackedCdf2D {
    /// Marginal positions, marginal CDF values, offsets, conditional CDF
    /// values, at the starts below.
    values: Vec<u16>,
    /// Where the marginal CDF values, the offsets and the conditional CDF
    /// values start in `values` (the marginal positions start at 0).
    marginal_cdf_at: usize,
    offsets_at: usize,
    conditional_cdf_at: usize,
    /// Conditional positions in 8 bits (at most 255 columns).
    conditional_pos: Vec<u8>,
}

/// A stored vertex position or CDF value: an unsigned integer, searched
/// with the workspace's one search
/// ([`count_one`](acdf_core::search::count_one)).
pub trait Stored: Key {
    /// The value as a float.
    fn float(self) -> f32;
    /// The key of a point t >= 0 in the values' units: floor(t), clamped to
    /// the type's range. For an integer p, p <= t exactly when p <= key.
    fn key(t: f32) -> Self;
}

impl Stored for u16 {
    #[inline(always)]
    fn float(self) -> f32 {
        self as f32
    }
    #[inline(always)]
    fn key(t: f32) -> u16 {
        t.max(0.0).min(u16::MAX as f32) as u16
    }
}

impl Stored for u8 {
    #[inline(always)]
    fn float(self) -> f32 {
        self as f32
    }
    #[inline(always)]
    fn key(t: f32) -> u8 {
        t.max(0.0).min(u8::MAX as f32) as u8
    }
}

/// The quantised curves' arithmetic: positions in grid units (`P`), CDF
/// values in units of 1/65535.
impl<P: Stored> Curve<'_, P, u16> {
    /// The positions and CDF values of vertices j and j + 1 (one bounds
    /// check each).
    #[inline(always)]
    fn segment(&self, j: usize) -> ((f32, f32), (u16, u16)) {
        let p = &self.xs[self.x_at + j..self.x_at + j + 2];
        let c = &self.cdfs[self.c_at + j..self.c_at + j + 2];
        ((p[0].float(), p[1].float()), (c[0], c[1]))
    }

    /// The segment holding `t` (in grid units): the number of inner
    /// vertices at or below it.
    #[inline(always)]
    fn segment_of(&self, t: f32) -> usize {
        self.positions_at_or_below(P::key(t))
    }

    /// Invert the curve at u in [0, 1): (position in [0, 1), segment, its
    /// density). The segment is the last vertex whose CDF is at or below u
    /// (zero-mass segments are never chosen).
    #[inline(always)]
    pub fn sample(&self, n: f32, u: f32) -> (f32, usize, QuantisedSegment) {
        let us = u * QF;
        let j = self.cdfs_at_or_below(u16::key(us));
        let s = QuantisedSegment::new(self.segment(j));
        let (c0, c1) = (s.c.0 as f32, s.c.1 as f32);
        let frac = if c1 > c0 {
            ((us - c0) / (c1 - c0)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let x = (s.p.0 + frac * (s.p.1 - s.p.0)) / n;
        (x.min(acdf_core::ONE_MINUS_EPSILON), j, s)
    }
}

/// One segment of a curve: its end positions (grid units) and CDF values.
#[derive(Clone, Copy)]
pub struct QuantisedSegment {
    pub p: (f32, f32),
    pub c: (u16, u16),
}

impl QuantisedSegment {
    #[inline(always)]
    fn new((p, c): ((f32, f32), (u16, u16))) -> Self {
        QuantisedSegment { p, c }
    }

    /// The density over [0, 1) of a curve over `n` cells.
    #[inline(always)]
    pub fn density(&self, n: f32) -> f32 {
        let mass = (self.c.1 - self.c.0) as f32;
        let width = self.p.1 - self.p.0;
        (mass * n) / (width * QF)
    }

    /// Whether [t - margin, t + margin] lies inside the segment (all in
    /// grid units).
    #[inline(always)]
    pub fn inside(&self, t: f32, margin: f32) -> bool {
        (self.p.0 <= t - margin) & (t + margin < self.p.1)
    }
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
        let rows = row_sums(values, n_x);
        let total: f64 = rows.iter().sum();
        let marginal_pos = grid_indices(d.marginal_positions(), n_y)?;
        if !(total > 0.0) {
            // No mass at all: the uniform density.
            return Ok(PackedCdf2D::from_arrays(
                &[0, n_y as u16],
                &[0, Q],
                &[0, 2],
                vec![0, n_x as u8],
                &[0, Q],
            ));
        }
        let marginal_cdf = quantise(&segment_masses(&rows, &marginal_pos));
        let mut offsets = vec![0u16];
        let (mut conditional_pos, mut conditional_cdf) = (Vec::new(), Vec::new());
        for (j, w) in marginal_pos.windows(2).enumerate() {
            if marginal_cdf[j + 1] > marginal_cdf[j] {
                let xs = d.conditional_positions(j);
                let pos = if xs.len() >= 2 {
                    grid_indices(xs, n_x)?
                } else {
                    vec![0, n_x as u16]
                };
                let masses = conditional_masses(values, n_x, (w[0], w[1]), &pos);
                conditional_cdf.extend(quantise(&masses));
                conditional_pos.extend(pos.iter().map(|&p| p as u8));
            }
            let end = conditional_pos.len();
            offsets.push(u16::try_from(end).map_err(|_| too_many("the conditional vertices"))?);
        }
        Ok(PackedCdf2D::from_arrays(
            &marginal_pos,
            &marginal_cdf,
            &offsets,
            conditional_pos,
            &conditional_cdf,
        ))
    }

    /// A slice of its five arrays, as a decoder reads them (check it with
    /// [`validate`](Self::validate) before use).
    pub fn from_arrays(
        marginal_pos: &[u16],
        marginal_cdf: &[u16],
        offsets: &[u16],
        conditional_pos: Vec<u8>,
        conditional_cdf: &[u16],
    ) -> Self {
        let marginal_cdf_at = marginal_pos.len();
        let offsets_at = marginal_cdf_at + marginal_cdf.len();
        let conditional_cdf_at = offsets_at + offsets.len();
        let values = [marginal_pos, marginal_cdf, offsets, conditional_cdf].concat();
        PackedCdf2D {
            values,
            marginal_cdf_at,
            offsets_at,
            conditional_cdf_at,
            conditional_pos,
        }
    }

    /// The marginal's vertex positions (θ_h grid indices).
    pub fn marginal_pos(&self) -> &[u16] {
        &self.values[..self.marginal_cdf_at]
    }

    /// The marginal's CDF values (multiples of 1/65535).
    pub fn marginal_cdf(&self) -> &[u16] {
        &self.values[self.marginal_cdf_at..self.offsets_at]
    }

    /// Per marginal vertex, where its segment's conditional starts in the
    /// conditional arrays (and the last, where they end).
    pub fn offsets(&self) -> &[u16] {
        &self.values[self.offsets_at..self.conditional_cdf_at]
    }

    /// The conditionals' vertex positions (φ_h grid indices), one after
    /// another.
    pub fn conditional_pos(&self) -> &[u8] {
        &self.conditional_pos
    }

    /// The conditionals' CDF values, one after another.
    pub fn conditional_cdf(&self) -> &[u16] {
        &self.values[self.conditional_cdf_at..]
    }

    /// The marginal curve (of a validated slice).
    #[inline(always)]
    fn marginal(&self) -> Curve<'_, u16, u16> {
        let len = self.marginal_cdf_at;
        Curve::new(&self.values, 0, &self.values, self.marginal_cdf_at, len)
    }

    /// Conditional j (of a validated slice, j a segment with mass).
    #[inline(always)]
    fn conditional(&self, j: usize) -> Curve<'_, u8, u16> {
        let at = &self.values[self.offsets_at + j..self.offsets_at + j + 2];
        let (a, b) = (at[0] as usize, at[1] as usize);
        let c_at = self.conditional_cdf_at + a;
        Curve::new(&self.conditional_pos, a, &self.values, c_at, b - a)
    }

    /// Draw (x, y) from u in [0, 1)^2: y from the marginal with u.y, x from
    /// the conditional of y's segment with u.x; with the density there and
    /// whether it is the same over the box (x, y) ± `margin` (in unit
    /// coordinates).
    #[inline(always)]
    pub fn sample(&self, u_x: f32, u_y: f32, n: (f32, f32), margin: (f32, f32)) -> Located {
        let (n_x, n_y) = n;
        let (y, j, sy) = self.marginal().sample(n_y, u_y);
        let (x, _, sx) = self.conditional(j).sample(n_x, u_x);
        Located {
            p: (x, y),
            pdf: sy.density(n_y) * sx.density(n_x),
            same_around: sy.inside(y * n_y, margin.1 * n_y) & sx.inside(x * n_x, margin.0 * n_x),
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
        let marginal = self.marginal();
        let ty = y * n_y;
        let j = marginal.segment_of(ty);
        let sy = QuantisedSegment::new(marginal.segment(j));
        let same_y = sy.inside(ty, margin.1 * n_y);
        if sy.c.1 == sy.c.0 {
            return Located {
                p: (x, y),
                pdf: 0.0,
                same_around: same_y,
            };
        }
        let conditional = self.conditional(j);
        let tx = x * n_x;
        let sx = QuantisedSegment::new(conditional.segment(conditional.segment_of(tx)));
        Located {
            p: (x, y),
            pdf: sy.density(n_y) * sx.density(n_x),
            same_around: same_y & sx.inside(tx, margin.0 * n_x),
        }
    }

    /// Bytes kept: two per stored value, one per conditional position.
    pub fn storage_bytes(&self) -> usize {
        2 * self.values.len() + self.conditional_pos.len()
    }

    /// The number of marginal vertices.
    pub fn marginal_vertex_count(&self) -> usize {
        self.marginal_cdf_at
    }

    /// The number of conditional vertices, and of non-empty conditionals.
    pub fn conditional_vertices(&self) -> (usize, usize) {
        let stored = self.offsets().windows(2).filter(|w| w[1] > w[0]).count();
        (self.conditional_pos.len(), stored)
    }

    /// Check what a decoder read: every curve runs over the grid from 0 to
    /// n with increasing positions and from 0 to 65535 with non-decreasing
    /// CDF values; each positive-mass marginal segment has a conditional.
    pub fn validate(&self, n_x: usize, n_y: usize) -> std::result::Result<(), String> {
        let (marginal_pos, marginal_cdf) = (self.marginal_pos(), self.marginal_cdf());
        check_curve("marginal", marginal_pos, marginal_cdf, n_y)?;
        let m = marginal_pos.len();
        let offsets = self.offsets();
        check_offsets(offsets, m, self.conditional_pos.len())?;
        let conditional_cdf = self.conditional_cdf();
        if conditional_cdf.len() != self.conditional_pos.len() {
            return Err(format!(
                "offsets end at {}, the conditionals hold {}",
                self.conditional_pos.len(),
                conditional_cdf.len()
            ));
        }
        for j in 0..m - 1 {
            let (a, b) = (offsets[j] as usize, offsets[j + 1] as usize);
            let (pos, cdf) = (&self.conditional_pos[a..b], &conditional_cdf[a..b]);
            let positive = marginal_cdf[j + 1] > marginal_cdf[j];
            match (positive, pos.len()) {
                (false, 0) => {}
                (false, _) => return Err(format!("conditional {j} of an empty segment")),
                (true, _) => check_curve("conditional", pos, cdf, n_x)?,
            }
        }
        Ok(())
    }
}

/// The masses of the table `values` (rows of `n_x`) in rows `rows.0` to
/// `rows.1` (a marginal segment) between consecutive conditional
/// positions `pos` (grid indices along x), summed in f64.
pub fn conditional_masses(values: &[f32], n_x: usize, rows: (u16, u16), pos: &[u16]) -> Vec<f64> {
    let columns = column_sums(values, n_x, rows.0 as usize..rows.1 as usize);
    segment_masses(&columns, pos)
}

/// Check the offsets of `m` marginal vertices into `conditionals`
/// conditional vertices: one per vertex, from 0, never decreasing, and
/// ending where the conditionals end.
pub fn check_offsets(
    offsets: &[u16],
    m: usize,
    conditionals: usize,
) -> std::result::Result<(), String> {
    if m < 2 || offsets.len() != m || offsets[0] != 0 {
        return Err(format!(
            "{} offsets for {m} marginal vertices",
            offsets.len()
        ));
    }
    if offsets.windows(2).any(|w| w[1] < w[0]) {
        return Err("offsets decrease".into());
    }
    let end = offsets[m - 1] as usize;
    if end != conditionals {
        return Err(format!(
            "offsets end at {end}, the conditionals hold {conditionals}"
        ));
    }
    Ok(())
}

pub fn check_curve<P: Stored + PartialOrd>(
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
/// keeps of a tabulated CDF), in 16 bits (the caller has checked that n
/// fits).
pub fn grid_indices(xs: &[f32], n: usize) -> Result<Vec<u16>> {
    match grid_positions(xs, n) {
        Ok(k) => Ok(k.into_iter().map(|k| k as u16).collect()),
        Err(x) => Err(Error::InvalidParameter {
            name: "outgoing slice",
            reason: format!("vertex at {x} is not on the grid of {n} cells"),
        }),
    }
}

/// Quantised CDF values (0 to 65535) of segments with these masses (not all
/// zero): [`crate::packed_env::quantise`] at q = 65535.
pub fn quantise(masses: &[f64]) -> Vec<u16> {
    crate::packed_env::quantise(masses, Q as u32)
        .into_iter()
        .map(|v| v as u16)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sorted list of `n` values below `limit`, from a fixed-seed
    /// generator, with repeats.
    fn sorted_values(n: usize, limit: u32, seed: u64) -> Vec<u32> {
        let mut state = seed;
        let mut v: Vec<u32> = (0..n)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 33) % limit as u64) as u32
            })
            .collect();
        v.sort_unstable();
        v
    }

    /// The window counts equal a count one entry at a time for lists at
    /// every place of their data (at its start, in the middle, at its
    /// end, longer than one or two windows, empty), with unrelated values around
    /// them, and for data shorter than a window.
    fn counts_agree<P: Stored + TryFrom<u32> + std::fmt::Debug>(limit: u32)
    where
        <P as TryFrom<u32>>::Error: std::fmt::Debug,
    {
        for (len, total, seed) in [
            (0, 40, 1),
            (5, 40, 2),
            (31, 70, 3),
            (32, 32, 4),
            (33, 90, 5),
            (70, 100, 6),
            (10, 12, 7),
            (3, 3, 8),
            // Two windows at once.
            (33, 64, 9),
            (47, 200, 10),
            (64, 64, 11),
            (64, 70, 12),
            (50, 90, 13),
        ] {
            let noise = sorted_values(total, limit, seed + 100);
            let mut noise: Vec<P> = noise
                .iter()
                .rev()
                .map(|&x| P::try_from(x).unwrap())
                .collect();
            let list = sorted_values(len, limit, seed);
            for start in [0, (total - len) / 2, total - len] {
                for (i, &x) in list.iter().enumerate() {
                    noise[start + i] = P::try_from(x).unwrap();
                }
                for key in [0, 1, limit / 3, limit / 2, limit - 2, limit - 1] {
                    let key = P::try_from(key).unwrap();
                    let expected = noise[start..start + len]
                        .iter()
                        .filter(|&&p| p <= key)
                        .count();
                    assert_eq!(
                        acdf_core::search::count_one(&noise, start, len, key),
                        expected,
                        "{len} of {total} from {start}, key {key:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn window_counts_agree_with_a_linear_count() {
        counts_agree::<u16>(65536);
        counts_agree::<u16>(300);
        counts_agree::<u8>(256);
        counts_agree::<u8>(33);
    }

    /// Quantising keeps every segment with mass at one unit or more, even
    /// one 1e-12 of the total, and gives none to a segment without.
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
