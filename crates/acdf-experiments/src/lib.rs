//! `acdf-experiments` measures what a sampler is worth, so that the `acdf`
//! command, the tests and the Python package all report the same figures:
//! the estimator efficiency of a sampler under an environment light
//! ([`efficiency`]), the per-material results table ([`report`]), the
//! tolerance sweep of the adaptive simplifiers ([`sweep`]), the search of a
//! tolerance for a target efficiency ([`target`]), the survey of all 100
//! MERL materials ([`survey`]) and its storage frontier ([`frontier`]), the storage and irradiance-variance report
//! of the environment samplers ([`env_report`]) and the figures ([`plot`]).
//!
//! Estimator efficiency is 1 / (r · t_s): r the relative variance of the
//! one-sample estimator of reflected luminance under the procedural sky,
//! computed by quadrature (no sampling noise) and averaged over twelve fixed
//! outgoing directions, and t_s the time of the sampler's own work, one
//! `sample` plus, for a successful draw, one `pdf` call. The exact
//! definition is in [`efficiency`].

#![deny(unsafe_code)]
// `!(x > 0.0)` is how this crate says "not positive, or NaN": the negated
// comparison is the point, since NaN must take the rejecting branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod efficiency;
pub mod env_report;
pub mod frontier;
pub mod plot;
pub mod report;
pub mod survey;
pub mod sweep;
pub mod target;

pub use efficiency::{measure_efficiencies, measure_efficiency, Efficiency, EfficiencyConfig};
