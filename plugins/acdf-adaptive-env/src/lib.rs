//! `acdf-adaptive-env` is the adaptive family of environment-map samplers: the lat-long tables of
//! `acdf-lights` as [`AdaptiveCdf2D`]s, every CDF curve simplified by a
//! [`Simplifier`](acdf_adaptive_cdf::Simplifier) of [`SIMPLIFIERS`](acdf_adaptive_cdf::simplify::SIMPLIFIERS).
//!
//! - [`AdaptiveEnvSampler`]: the luminance table (`adaptive:NAME`) or its
//!   compensated form (`adaptive-comp:NAME`);
//! - [`OrientedEnvSampler`]: one adaptive table per region of normals (a
//!   cell of a grid, or a polar cap), built on first use and kept packed
//!   ([`PackedEnvCdf2D`](acdf_adaptive_cdf::PackedEnvCdf2D)); a shading normal draws from its region's table
//!   (`oriented:NAME`).

#![forbid(unsafe_code)]

use std::sync::Arc;

use acdf_adaptive_cdf::packed_env::PackedEnvBuilder;
use acdf_adaptive_cdf::{AdaptiveBuilder, AdaptiveCdf2D};
use acdf_core::Result;
use acdf_lights::{EnvMap, LatLongSampler, NormalGrid, OrientedSampler, TableKind};

/// Directions from an adaptive table over the texels of a lat-long map.
pub type AdaptiveEnvSampler = LatLongSampler<AdaptiveCdf2D>;

/// The orientation-aware sampler with adaptive tables in packed form: a
/// scene reads one table per region of normals it reaches, so their size
/// decides how many of its reads hit the cache.
pub type OrientedEnvSampler = OrientedSampler<PackedEnvBuilder>;

/// The adaptive environment sampler of `map` for the table `kind`, named
/// `adaptive:NAME` or `adaptive-comp:NAME`.
pub fn adaptive_env_sampler(
    map: &EnvMap,
    kind: TableKind,
    builder: &AdaptiveBuilder,
) -> Result<AdaptiveEnvSampler> {
    let name = match kind {
        TableKind::Luminance => format!("adaptive:{}", builder.simplifier.name()),
        TableKind::Compensated => format!("adaptive-comp:{}", builder.simplifier.name()),
    };
    LatLongSampler::build(name, map, kind, builder)
}

/// The orientation-aware sampler of `map`, named `oriented:NAME`, with the
/// normal cells of `grid` and the defensive share `defensive` (see
/// [`OrientedSampler`]).
pub fn oriented_env_sampler(
    map: Arc<EnvMap>,
    builder: AdaptiveBuilder,
    grid: NormalGrid,
    defensive: f32,
) -> Result<OrientedEnvSampler> {
    let name = format!("oriented:{}", builder.simplifier.name());
    OrientedSampler::new(name, map, PackedEnvBuilder(builder), grid, defensive)
}

/// The mean kept vertices of an adaptive table: (marginal vertices, mean
/// vertices of the stored conditionals).
pub fn table_vertices(d: &AdaptiveCdf2D) -> (f64, f64) {
    (
        d.marginal_vertex_count() as f64,
        d.mean_conditional_vertices(),
    )
}
