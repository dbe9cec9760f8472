//! `acdf-adaptive` is the adaptive measured-BRDF sampler of Lawrence,
//! Rusinkiewicz and Ramamoorthi (2005): `acdf-tabulated`'s tabulated sampler
//! with an [`AdaptiveCdf2D`](acdf_adaptive_cdf::AdaptiveCdf2D) per
//! outgoing-direction slice, every CDF curve simplified by a simplifier of
//! `acdf-adaptive-cdf`. Its command-line names are `adaptive:SIMPLIFIER`.
//!
//! [`AdaptiveBrdfSampler`] is the sampler, [`adaptive_sampler`] builds one
//! by simplifier name, and [`average_resolution`] reports the mean kept
//! vertices as in the paper.

#![forbid(unsafe_code)]

pub mod sampler;

pub use sampler::{adaptive_sampler, average_resolution, AdaptiveBrdfSampler};

#[cfg(test)]
mod tests;
