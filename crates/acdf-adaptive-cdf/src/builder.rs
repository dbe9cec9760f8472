//! [`AdaptiveBuilder`]: the simplifier and tolerance that turn a table of
//! values into an [`AdaptiveCdf2D`], for BRDF slices and environment tables
//! alike (one [`TableBuilder`]).

use crate::simplify::{simplifier_by_name, validate_tolerance, Simplifier};
use crate::AdaptiveCdf2D;
use acdf_core::{Result, TableBuilder};
use std::sync::Arc;

/// Builds an [`AdaptiveCdf2D`] per tabulated slice: the marginal over θ_h
/// (rows) and the conditionals over φ_h (columns) simplified by `simplifier`
/// at `tolerance`, with the first θ_h row pinned
/// ([`AdaptiveCdf2D::from_values_pinned`]).
#[derive(Debug, Clone)]
pub struct AdaptiveBuilder {
    pub simplifier: Arc<dyn Simplifier>,
    pub tolerance: f64,
}

impl AdaptiveBuilder {
    /// A builder with the given simplifier and tolerance (an error for a
    /// negative or NaN tolerance).
    pub fn new(simplifier: Arc<dyn Simplifier>, tolerance: f64) -> Result<Self> {
        validate_tolerance(tolerance)?;
        Ok(Self {
            simplifier,
            tolerance,
        })
    }

    /// The simplifier called `name` at `tolerance`, or at its default
    /// tolerance when `None`.
    pub fn by_name(name: &str, tolerance: Option<f64>) -> Result<Self> {
        let simplifier = simplifier_by_name(name)?;
        let tolerance = tolerance.unwrap_or_else(|| simplifier.default_tolerance());
        Self::new(simplifier, tolerance)
    }
}

/// The table simplified as a whole by the builder's simplifier and
/// tolerance ([`AdaptiveCdf2D::from_values`]); a BRDF slice keeps its first
/// θ_h row as a marginal segment of its own
/// ([`AdaptiveCdf2D::from_values_pinned`]), an environment table pins no
/// row: a lat-long table has no Jacobian that vanishes at an edge (each
/// texel is sampled uniformly in solid angle).
impl TableBuilder for AdaptiveBuilder {
    type Dist = AdaptiveCdf2D;

    /// `adaptive:<simplifier>`, e.g. `adaptive:optimal`.
    fn name(&self) -> String {
        format!("adaptive:{}", self.simplifier.name())
    }

    fn build(&self, values: &[f32], nx: usize, ny: usize) -> Result<AdaptiveCdf2D> {
        AdaptiveCdf2D::from_values(values, nx, ny, &*self.simplifier, self.tolerance)
    }

    fn build_slice(
        &self,
        values: &[f32],
        n_phi_h: usize,
        n_theta_h: usize,
    ) -> Result<AdaptiveCdf2D> {
        AdaptiveCdf2D::from_values_pinned(
            values,
            n_phi_h,
            n_theta_h,
            &*self.simplifier,
            self.tolerance,
            1,
        )
    }
}
