//! `acdf-adaptive-cdf` holds the machinery of the adaptive numerical CDF of
//! Lawrence, Rusinkiewicz and Ramamoorthi (2005), shared by the sampler
//! plug-ins that use it: every CDF curve of a table is replaced by a few of
//! its vertices, chosen by a curve simplifier, so that the tables shrink
//! while the sampler follows the table nearly as well.
//!
//! The pieces:
//! - [`simplify`]: the [`Simplifier`]s, each stating which error its
//!   tolerance bounds, and their table [`simplify::SIMPLIFIERS`] (command-line
//!   name, description, default tolerance), from which every list of names
//!   in acdf is derived;
//! - [`AdaptiveCdf1D`] and [`AdaptiveCdf2D`]: piecewise-linear CDFs through the
//!   kept vertices (piecewise-constant densities), implementing acdf-core's
//!   `Distribution1D` and `Distribution2D`;
//! - [`AdaptiveBuilder`]: a simplifier and its tolerance, which builds an
//!   [`AdaptiveCdf2D`] from a BRDF slice or an environment table;
//! - [`PackedEnvCdf2D`]: the vertices of an [`AdaptiveCdf2D`] over an
//!   environment table, kept in 16-bit form for the orientation-aware
//!   sampler;
//! - [`persist`]: the adaptive tables in the sampler file format.
//!
//! The sampler families built on these are plug-ins: `acdf-adaptive` (one
//! adaptive table per outgoing-direction cell), `acdf-outgoing` (tables
//! only at the outgoing angles a material needs) and `acdf-adaptive-env`
//! (environment maps).
//!
//! # Tolerances
//!
//! Vertical-error tolerances are in units of probability (1e-4: the
//! simplified CDF is within 0.01% of the slice's mass of the tabulated one at
//! every tabulated point). The `chi2` tolerance is a budget on the
//! chi-square divergence of the tabulated slice from the adaptive one, which
//! is the relative variance the sampler adds when the BRDF equals its table.
//! How each default was chosen, with the command that measures it, is in
//! `docs/results.md`.

#![forbid(unsafe_code)]

mod builder;
mod curve;
pub mod dist;
pub mod packed_env;
pub mod persist;
pub mod quantised;
pub mod simplify;

pub use builder::AdaptiveBuilder;
pub use dist::{AdaptiveCdf1D, AdaptiveCdf2D};
pub use packed_env::{PackedEnvBuilder, PackedEnvCdf2D};
pub use simplify::{
    chi_square_error, perpendicular_error, simplifier_by_name, vertical_error, ChiSquareOptimal,
    DouglasPeucker, ErrorBound, OptimalVertical, ReumannWitkam, Simplifier, VisvalingamWhyatt,
    SIMPLIFIER_NAMES,
};

#[cfg(test)]
mod tests;
