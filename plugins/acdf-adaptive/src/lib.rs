//! `acdf-adaptive` implements the adaptive numerical CDF of Lawrence,
//! Rusinkiewicz and Ramamoorthi (2005): every CDF curve of a tabulated
//! measured-BRDF slice is replaced by a few of its vertices, chosen
//! by a curve simplifier, so that the tables shrink while the sampler follows
//! the BRDF nearly as well.
//!
//! The pieces:
//! - [`simplify`]: the [`Simplifier`] plug-ins, each stating which error its
//!   tolerance bounds, and their table [`simplify::SIMPLIFIERS`] (command-line
//!   name, description, default tolerance), from which every list of names
//!   in acdf is derived;
//! - [`AdaptiveCdf1D`] and [`AdaptiveCdf2D`]: piecewise-linear CDFs through the
//!   kept vertices (piecewise-constant densities), implementing acdf-core's
//!   `Distribution1D` and `Distribution2D`;
//! - [`AdaptiveBrdfSampler`]: the measured-BRDF sampler, which is
//!   `acdf-tabulated`'s generic `TabulatedBrdfSampler` with an
//!   [`AdaptiveCdf2D`] per outgoing-direction slice, built by
//!   [`AdaptiveBuilder`];
//!   [`average_resolution`] reports the mean kept vertices as in the paper;
//! - [`env`](mod@env): the same distributions over the texels of an environment map
//!   ([`AdaptiveEnvSampler`]) and per cell of shading normals
//!   ([`OrientedEnvSampler`], whose tables [`packed_env`] keeps in 16-bit
//!   form);
//! - [`outgoing`]: [`OutgoingSampler`], slices kept only at the θ_o
//!   breakpoints a material needs, blended linearly between them, stored
//!   in 16 bits; for anisotropic materials [`AnisotropicOutgoingSampler`],
//!   the same at θ_o breakpoints, each with φ_o breakpoints of its own.
//!
//! # Tolerances and how the defaults were chosen
//!
//! Vertical-error tolerances are in units of probability (1e-4: the
//! simplified CDF is within 0.01% of the slice's mass of the tabulated one at
//! every tabulated point). The `chi2` tolerance is a budget on the
//! chi-square divergence of the tabulated slice from the adaptive one, which
//! is the relative variance the sampler adds when the BRDF equals its table.
//!
//! Efficiency was measured without sampling noise by the `compression`
//! example: the relative variance of Y(f) cos θ_i / pdf for 48 fixed outgoing
//! directions, integrated by quadrature on a 128 x 1024 half-vector grid,
//! uniform sampler divided by adaptive sampler (both with a 5% cosine mix).
//! Each default is the largest tolerance tried whose efficiency stayed at or
//! above about 0.9 on the built-in nickel, gray-plastic and
//! blue-metallic-paint at the isotropic resolution 32x1x256x32
//! (`cargo run -p acdf --release --example compression --
//! --resolution 32x1x256x32 --cosine-mix 0.05 --simplifiers NAME
//! --tolerances LIST`):
//!
//! | simplifier | default | efficiency nickel / gray-plastic / blue-metallic-paint | storage ratio |
//! |---|---|---|---|
//! | `dp`       | 1e-4   | 0.96 / 0.91 / 1.02 | 1.7 - 1.9 |
//! | `vw`       | 1e-4   | 0.96 / 0.94 / 0.95 | 1.7 - 1.9 |
//! | `rw`       | 5e-4   | 0.96 / 0.92 / 0.96 | 2.0 - 2.2 |
//! | `optimal`  | 1e-4   | 0.94 / 0.90 / 1.01 | 2.0 - 2.1 |
//! | `chi2`     | 1.5e-3 | 0.95 / 0.92 / 0.95 | 4.6 - 6.1 |
//! | `dp-perp`  | 1e-4   | 0.93 / 0.89 / 1.01 | 2.1 - 2.7 |
//! | `vw-area`  | 5e-7   | 0.98 / 0.97 / -    | 1.4 - 1.5 |
//!
//! The vertical-error simplifiers at the seed's compression (about 20:1)
//! lose half or more of the efficiency under this noise-free measure: a
//! bounded CDF error is not a bounded density ratio in the low-density tails.
//! `chi2` bounds the variance directly and gives 2 to 3 times the
//! compression of `optimal` at equal efficiency.

#![deny(unsafe_op_in_unsafe_fn)]

mod curve;
pub mod dist;
pub mod env;
pub mod outgoing;
pub mod packed_env;
pub mod persist;
pub mod sampler;
pub mod simplify;

pub use dist::{AdaptiveCdf1D, AdaptiveCdf2D};
pub use env::{adaptive_env_sampler, oriented_env_sampler, AdaptiveEnvSampler, OrientedEnvSampler};
pub use outgoing::{AnisotropicOutgoingSampler, OutgoingBuilder, OutgoingSampler};
pub use packed_env::{PackedEnvBuilder, PackedEnvCdf2D};
pub use sampler::{adaptive_sampler, average_resolution, AdaptiveBrdfSampler, AdaptiveBuilder};
pub use simplify::{
    chi_square_error, perpendicular_error, simplifier_by_name, vertical_error, ChiSquareOptimal,
    DouglasPeucker, ErrorBound, OptimalVertical, ReumannWitkam, Simplifier, VisvalingamWhyatt,
    SIMPLIFIER_NAMES,
};

#[cfg(test)]
mod tests;
