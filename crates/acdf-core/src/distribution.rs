//! Sampling distributions over the unit interval and the unit square.
//!
//! A distribution is built from a non-negative function (usually a table) and
//! maps a uniform number `u` to a sample `x` with density `pdf(x)`, so that
//! `pdf = f / integral(f)`. Every implementation shares these rules, stated
//! once here:
//!
//! - **Uniform numbers.** `u` is expected in [0, 1). Anything else is mapped by
//!   [`clamp_unit`]: NaN and negative values act as 0, values at or above 1 act
//!   as [`ONE_MINUS_EPSILON`]. Sampling therefore never fails and never returns
//!   NaN.
//! - **Samples** lie in [0, 1) (or [0, 1)^2) and have a finite, strictly
//!   positive density: a sample is never drawn where the density is zero.
//! - **`pdf(x)`** is zero outside [0, 1) (and for NaN), finite everywhere.
//! - **All-zero functions.** A function that integrates to zero has no shape to
//!   follow; distributions then fall back to the uniform density, and
//!   `integral()` reports 0 so a caller can tell.
//! - **Bad tables** (NaN, infinity, negative values, empty or mis-sized) are
//!   rejected at construction with an [`Error`], checked by [`validate_table`].

use crate::error::{Error, Result};
use glam::Vec2;

/// The largest `f32` strictly below one: 1 - 2^-24.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Map any `f32` to a usable uniform number in [0, 1).
///
/// NaN and values below 0 give 0; values at or above 1 give
/// [`ONE_MINUS_EPSILON`]. This is the single place where acdf decides what a
/// `u` outside [0, 1) means.
#[inline(always)]
pub fn clamp_unit(u: f32) -> f32 {
    // Written so that NaN fails the comparison and lands on 0.
    if u > 0.0 {
        u.min(ONE_MINUS_EPSILON)
    } else {
        0.0
    }
}

/// Check that `values` can be a (non-normalised) density table: non-empty,
/// every entry finite and non-negative.
pub fn validate_table(what: &'static str, values: &[f32]) -> Result<()> {
    if values.is_empty() {
        return Err(Error::EmptyTable { what });
    }
    for (index, &v) in values.iter().enumerate() {
        if !v.is_finite() {
            return Err(Error::NonFinite {
                what,
                index,
                value: v as f64,
            });
        }
        if v < 0.0 {
            return Err(Error::Negative {
                what,
                index,
                value: v as f64,
            });
        }
    }
    Ok(())
}

/// A sample from a [`Distribution1D`]: the value and its density there.
///
/// `repr(C)`: two consecutive `f32` (x, pdf), so that batch paths can write
/// samples with vector stores.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct Sample1D {
    pub x: f32,
    pub pdf: f32,
}

/// A sample from a [`Distribution2D`]: the point and its density there.
///
/// `repr(C)`: three consecutive `f32` (x, y, pdf), so that batch paths can
/// write samples with vector stores.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct Sample2D {
    pub p: Vec2,
    pub pdf: f32,
}

/// A density over [0, 1) that can be sampled by inversion.
pub trait Distribution1D: Send + Sync {
    /// Draw x = P^{-1}(u), where P is the cumulative distribution; returns x
    /// and p(x).
    fn sample(&self, u: f32) -> Sample1D;

    /// The density p(x) = f(x) / ∫f; zero outside [0, 1).
    fn pdf(&self, x: f32) -> f32;

    /// The cumulative distribution P(x): the `u` that [`sample`](Self::sample)
    /// maps to `x`. Used by tests and for stratification. `x` is clamped to
    /// [0, 1].
    fn invert(&self, x: f32) -> f32;

    /// ∫₀¹ f(x) dx of the unnormalised function the distribution was built
    /// from (0 for an all-zero function, see the module documentation).
    fn integral(&self) -> f64;

    /// Heap bytes held by the distribution's tables.
    fn storage_bytes(&self) -> usize;

    /// Sample many `u` at once: `out[k] = sample(u[k])` for every `k` below
    /// the shorter of the two lengths. Fast implementations override this.
    fn sample_batch(&self, u: &[f32], out: &mut [Sample1D]) {
        for (o, &u) in out.iter_mut().zip(u) {
            *o = self.sample(u);
        }
    }
}

/// Builds a [`Distribution2D`] from a table of non-negative values: what a
/// sampler family supplies, for the slices of a tabulated BRDF and for the
/// tables of an environment map alike.
///
/// The distribution keeps its density constant over every table cell
/// (cells may be merged, never split): the samplers look a cell's density
/// up at its centre.
pub trait TableBuilder: Send + Sync {
    /// The distribution built.
    type Dist: Distribution2D;

    /// The family's name, e.g. `uniform` or `adaptive:chi2`.
    fn name(&self) -> String;

    /// Build from `values`: row-major, `ny` rows (y) of `nx` columns (x),
    /// every value finite and non-negative.
    fn build(&self, values: &[f32], nx: usize, ny: usize) -> Result<Self::Dist>;

    /// Build the table of one BRDF slice: `n_theta_h` rows (θ_h) of
    /// `n_phi_h` columns (φ_h), spaced as `acdf_tabulated::tabulate`
    /// documents. [`build`](Self::build), unless the family treats a
    /// slice's first θ_h row, where the half-vector map's Jacobian
    /// vanishes, apart (the adaptive family does).
    fn build_slice(&self, values: &[f32], n_phi_h: usize, n_theta_h: usize) -> Result<Self::Dist> {
        self.build(values, n_phi_h, n_theta_h)
    }
}

/// A density over the unit square [0, 1)^2 that can be sampled by inversion.
///
/// Implementations that factor the density into a marginal and conditionals
/// put the marginal on `y` (rows of a row-major table) and the conditional on
/// `x`; `u.y` drives the marginal, `u.x` the conditional.
pub trait Distribution2D: Send + Sync {
    /// Map `u` to a point p with density p(p).
    fn sample(&self, u: Vec2) -> Sample2D;

    /// The density at `p`; zero outside [0, 1)^2.
    fn pdf(&self, p: Vec2) -> f32;

    /// The `u` that [`sample`](Self::sample) maps to `p` (coordinates clamped
    /// to [0, 1]).
    fn invert(&self, p: Vec2) -> Vec2;

    /// ∫∫ f over the unit square, of the unnormalised function.
    fn integral(&self) -> f64;

    /// Heap bytes held by the distribution's tables.
    fn storage_bytes(&self) -> usize;

    /// Sample many `u` at once: `out[k] = sample(u[k])` for every `k` below
    /// the shorter of the two lengths.
    fn sample_batch(&self, u: &[Vec2], out: &mut [Sample2D]) {
        for (o, &u) in out.iter_mut().zip(u) {
            *o = self.sample(u);
        }
    }

    /// The density at many points at once: `out[k] = pdf(p[k])` for every
    /// `k` below the shorter of the two lengths, bit for bit. Fast
    /// implementations override this.
    fn pdf_batch(&self, p: &[Vec2], out: &mut [f32]) {
        for (o, &p) in out.iter_mut().zip(p) {
            *o = self.pdf(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clamp_unit_maps_everything_into_the_half_open_interval() {
        assert_eq!(clamp_unit(f32::NAN), 0.0);
        assert_eq!(clamp_unit(-3.0), 0.0);
        assert_eq!(clamp_unit(f32::NEG_INFINITY), 0.0);
        assert_eq!(clamp_unit(1.0), ONE_MINUS_EPSILON);
        assert_eq!(clamp_unit(f32::INFINITY), ONE_MINUS_EPSILON);
        assert_eq!(clamp_unit(0.25), 0.25);
        assert_eq!(ONE_MINUS_EPSILON.next_up(), 1.0);
    }

    #[test]
    fn validate_table_names_the_first_bad_entry() {
        assert_eq!(
            validate_table("t", &[]),
            Err(Error::EmptyTable { what: "t" })
        );
        assert!(matches!(
            validate_table("t", &[1.0, f32::NAN]),
            Err(Error::NonFinite { index: 1, .. })
        ));
        assert!(matches!(
            validate_table("t", &[1.0, 2.0, f32::INFINITY]),
            Err(Error::NonFinite { index: 2, .. })
        ));
        assert!(matches!(
            validate_table("t", &[-1e-30]),
            Err(Error::Negative { index: 0, .. })
        ));
        assert_eq!(validate_table("t", &[0.0, 1e30, 1e-30]), Ok(()));
    }
}
