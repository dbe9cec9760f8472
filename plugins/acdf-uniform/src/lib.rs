//! `acdf-uniform` is the baseline of acdf's results: importance sampling of
//! a measured BRDF from uniformly tabulated, piecewise-constant CDFs. For
//! every cell of outgoing directions (θ_o, φ_o) it tabulates the density of
//! incident directions over the half vector (θ_h, φ_h) and samples it by
//! inverting a marginal CDF over θ_h and a conditional CDF over φ_h. The
//! tabulation and the sampler are generic over what a slice becomes
//! ([`SliceBuilder`]), so the adaptive plug-in reuses them with its own
//! simplified CDFs; the cosine-lobe mixing that makes either sampler robust
//! lives here once.
//!
//! - [`PiecewiseConstant1D`], [`PiecewiseConstant2D`]: the distributions.
//! - [`Resolution`]: the four tabulation counts, `32x16x256x32` and so on.
//! - [`tabulate`]: the cell geometry and the half-vector tabulation.
//! - [`TabulatedBrdfSampler`], [`UniformBrdfSampler`]: the sampler.

// `!(x > 0.0)` is how this crate says "not positive, or NaN": the negated
// comparison is the point, since NaN must take the rejecting branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod distribution;
pub mod persist;
pub mod resolution;
pub mod sampler;
pub mod tabulate;

pub use distribution::{PiecewiseConstant1D, PiecewiseConstant2D};
pub use resolution::Resolution;
pub use sampler::{
    half_vector_cell, outgoing_cell, PiecewiseConstantBuilder, SliceBuilder, TabulatedBrdfSampler,
    UniformBrdfSampler,
};
pub use tabulate::{tabulate_for, tabulate_slice};
