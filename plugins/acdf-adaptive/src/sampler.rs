//! The adaptive measured-BRDF sampler: `acdf-tabulated`'s generic
//! tabulated sampler, whose slices are [`AdaptiveCdf2D`](acdf_adaptive_cdf::AdaptiveCdf2D)s built from the
//! tabulated half-vector values.

use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_core::{Brdf, Result};
use acdf_tabulated::{Resolution, TabulatedBrdfSampler};
use std::sync::Arc;

/// The adaptive sampler: tabulation, cell lookup, cosine mixing and lazy
/// building are `acdf-tabulated`'s; only the slice distribution differs.
///
/// Defensive mixing matters more here than for the uniform sampler. A slice
/// is tabulated at the centre of its outgoing cell; for other `wo` in the
/// cell the BRDF's tails move, and a merged low-density segment can sit far
/// below them. A small cosine mix (`with_cosine_mix(0.05)`) bounds the
/// weight in those tails: it helps a material with a diffuse tail, such as
/// nickel, which the adaptive sampler otherwise under-samples, and costs a
/// lobe-only material, such as the near-mirror, the share of draws that go
/// where f is 0 (measured in `docs/results.md`).
pub type AdaptiveBrdfSampler = TabulatedBrdfSampler<AdaptiveBuilder>;

/// An adaptive sampler of `brdf` at `resolution` with the simplifier called
/// `simplifier` at `tolerance` (its default when `None`).
pub fn adaptive_sampler(
    brdf: Arc<dyn Brdf>,
    resolution: Resolution,
    simplifier: &str,
    tolerance: Option<f64>,
) -> Result<AdaptiveBrdfSampler> {
    TabulatedBrdfSampler::new(
        brdf,
        resolution,
        AdaptiveBuilder::by_name(simplifier, tolerance)?,
    )
}

/// The average kept resolution over the slices built so far, as in the
/// paper's table: (mean number of marginal vertices over θ_h, mean number of
/// vertices of the stored conditionals over φ_h). (0, 0) when nothing is
/// built.
pub fn average_resolution(sampler: &AdaptiveBrdfSampler) -> (f64, f64) {
    let (mut slices, mut marginal) = (0usize, 0usize);
    let (mut conditionals, mut conditional_vertices) = (0usize, 0usize);
    for d in sampler.built_slices() {
        slices += 1;
        marginal += d.marginal_vertex_count();
        for j in 0..d.conditional_count() {
            let c = d.conditional_vertex_count(j);
            if c > 0 {
                conditionals += 1;
                conditional_vertices += c;
            }
        }
    }
    let mean = |a: usize, b: usize| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    (
        mean(marginal, slices),
        mean(conditional_vertices, conditionals),
    )
}
