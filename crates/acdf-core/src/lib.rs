//! `acdf-core` is the vocabulary every other acdf crate speaks: the traits for
//! sampling distributions over the unit interval and square (`Distribution1D`,
//! `Distribution2D`), for BRDF samplers (`BxdfSampler`) and BRDF sources
//! (`Brdf`), for lights at infinity and the samplers of directions over the
//! whole sphere that serve them (`Light`, `SphereSampler`); the geometry
//! of the local shading frame, spherical and Rusinkiewicz half/difference
//! coordinates; the warps shared by several samplers; the deterministic
//! quadrature over the incident hemisphere that measures a sampler
//! without drawing from it (`quadrature`: the light it misses, the
//! relative variance of its estimator, its largest weight); the hot-path
//! helpers every sampler uses (polynomial
//! trigonometry in `fast`, branch-free sorted-list searches in `search`, and
//! their SIMD-lane form for batches in `search::lanes`), with the one place
//! that detects the CPU features they choose their code by (`cpu`); and the
//! one error type. It holds no sampler, no data format and no file I/O
//! (that is `acdf-io`), so that
//! plug-ins and material readers depend on this small crate (the tabulated
//! plug-ins also on `acdf-tabulated`, the environment samplers on
//! `acdf-lights`) and never on each other.
//!
//! Conventions used throughout acdf:
//! - directions live in the local shading frame, `z` along the normal, and both
//!   `wo` (the given, outgoing direction) and `wi` (the sampled, incident one)
//!   point away from the surface;
//! - pdfs of directions are per unit solid angle;
//! - stored tables are `f32`, sums that accumulate are done in `f64`;
//! - uniform random numbers are sanitised in exactly one place,
//!   [`distribution::clamp_unit`].

// `!(x > 0.0)` is how this crate says "not positive, or NaN": the negated
// comparison is the point, since NaN must take the rejecting branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![deny(unsafe_op_in_unsafe_fn)]

pub mod brdf;
pub mod distribution;
pub mod error;
pub mod geometry;
pub mod light;
pub mod quadrature;
pub mod sampler;
pub mod simd;
pub mod warp;

pub use simd::{cpu, fast, search};

pub use brdf::{fingerprint_by_eval, luminance, Brdf, Fingerprinter, Rgb, LUMINANCE_WEIGHTS};
pub use distribution::{
    clamp_unit, validate_table, Distribution1D, Distribution2D, Sample1D, Sample2D, TableBuilder,
    ONE_MINUS_EPSILON,
};
pub use error::{Error, Result};
pub use geometry::{Frame, HalfDiff};
pub use light::{usable_normal, Light, LightSample, SphereSample, SphereSampler};
pub use quadrature::{missed_share, HemisphereGrid, Integrand, MissedShare, Moments};
pub use sampler::{is_valid_outgoing, BxdfSample, BxdfSampler};

/// Re-exported so that downstream crates name the same vector types.
pub use glam::{Vec2, Vec3};
