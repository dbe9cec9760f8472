//! The uniform family's environment samplers: the lat-long luminance table
//! (or its compensated form) as a [`PiecewiseConstant2D`], the classic
//! environment-map sampler.

use crate::{PiecewiseConstant2D, PiecewiseConstantBuilder};
use acdf_core::Result;
use acdf_lights::{EnvMap, LatLongSampler, TableKind};

/// Directions drawn from a piecewise-constant table over the texels of a
/// lat-long map: `uniform` (luminance × solid angle) and `uniform-comp`
/// (its compensated form, for multiple importance sampling).
pub type UniformEnvSampler = LatLongSampler<PiecewiseConstant2D>;

/// The uniform environment sampler of `map` for the table `kind`, named
/// `uniform` or `uniform-comp`. Storage: 4 bytes per texel (one
/// conditional CDF value each) plus the marginal over rows.
pub fn uniform_env_sampler(map: &EnvMap, kind: TableKind) -> Result<UniformEnvSampler> {
    let name = match kind {
        TableKind::Luminance => "uniform",
        TableKind::Compensated => "uniform-comp",
    };
    LatLongSampler::build(name, map, kind, &PiecewiseConstantBuilder)
}
