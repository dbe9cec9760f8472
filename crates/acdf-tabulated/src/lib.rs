//! `acdf-tabulated` is what every tabulated measured-BRDF sampler shares,
//! whatever distribution its slices become. For every cell of outgoing
//! directions (θ_o, φ_o) a BRDF is tabulated over the half vector (θ_h,
//! φ_h); a sampler family turns each such slice into a 2D distribution and
//! [`TabulatedBrdfSampler`] does the rest: it finds the slice of `wo`,
//! builds it on first use, maps a draw over the unit square to `wi` and back,
//! mixes in a cosine lobe on request, runs the batch paths, and saves and
//! loads built samplers in one file format.
//!
//! - [`Resolution`]: the four tabulation counts, `32x16x256x32` and so on.
//! - [`tabulate`]: the outgoing cells, the half-vector axes and the
//!   tabulation of a slice.
//! - [`SliceDistribution`] and [`SliceBuilder`]: what a sampler family
//!   implements (the uniform plug-in with piecewise-constant tables, the
//!   adaptive one with simplified CDFs).
//! - [`TabulatedBrdfSampler`]: the generic sampler.
//! - [`persist`]: the sampler file format.
//!
//! Plug-ins depend on this crate and on `acdf-core`, never on each other.

// `!(x > 0.0)` is how this crate says "not positive, or NaN": the negated
// comparison is the point, since NaN must take the rejecting branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![forbid(unsafe_code)]

pub mod persist;
pub mod resolution;
pub mod sampler;
pub mod slice;
pub mod tabulate;

pub use resolution::Resolution;
pub use sampler::{
    check_cosine_fraction, half_vector_cell, mix_with_cosine, outgoing_cell, TabulatedBrdfSampler,
};
pub use slice::{SliceBuilder, SliceDistribution};
pub use tabulate::{tabulate_for, tabulate_slice};
