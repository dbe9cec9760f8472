//! `acdf-uniform` is the baseline of acdf's results: importance sampling of
//! a measured BRDF from uniformly tabulated, piecewise-constant CDFs. Every
//! half-vector slice that `acdf-tabulated` tabulates becomes a
//! [`PiecewiseConstant2D`], sampled by inverting a marginal CDF over θ_h and
//! a conditional CDF over φ_h; the generic
//! [`TabulatedBrdfSampler`](acdf_tabulated::TabulatedBrdfSampler) does the
//! rest.
//!
//! - [`PiecewiseConstant1D`], [`PiecewiseConstant2D`]: the distributions.
//! - [`PiecewiseConstantBuilder`], [`UniformBrdfSampler`]: the sampler
//!   family, named `uniform`.
//! - [`UniformEnvSampler`]: the same tables over the texels of an
//!   environment map, the classic environment sampler (`env` module).

// `!(x > 0.0)` is how this crate says "not positive, or NaN": the negated
// comparison is the point, since NaN must take the rejecting branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![forbid(unsafe_code)]

pub mod builder;
pub mod distribution;
pub mod env;

pub use builder::{PiecewiseConstantBuilder, UniformBrdfSampler};
pub use distribution::{PiecewiseConstant1D, PiecewiseConstant2D};
pub use env::{uniform_env_sampler, UniformEnvSampler};
