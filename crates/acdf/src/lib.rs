//! `acdf` is the facade of the acdf workspace and the home of its
//! experiments. It names materials and samplers the way the `acdf` command
//! does ([`spec`], [`material`], [`registry`]), and holds everything the
//! command measures, so that tests and other tools call the same code:
//! the estimator efficiency of a sampler under an environment light
//! ([`efficiency`]), the per-material results table ([`report`]), the
//! tolerance sweep of the adaptive simplifiers ([`sweep`]), the sphere
//! renderer ([`render`]) and the figures ([`plot`]).
//!
//! Estimator efficiency is 1 / (V · t): V the variance of the one-sample
//! estimator of reflected luminance under the procedural sky, averaged over
//! twelve fixed outgoing directions, and t the time of one `sample` plus, for
//! a successful draw, one BRDF evaluation and one `pdf` call. The exact
//! definition is in [`efficiency`].

pub use acdf_core as core;
pub use acdf_cosine as cosine;
pub use acdf_materials as materials;
pub use acdf_uniform as uniform;

pub mod efficiency;
pub mod env;
pub mod error;
pub mod material;
pub mod plot;
pub mod registry;
pub mod render;
pub mod report;
pub mod spec;
pub mod sweep;

pub use efficiency::{measure_efficiencies, measure_efficiency, Efficiency, EfficiencyConfig};
pub use env::{EnvMap, Environment, Sky};
pub use error::{Error, Result};
pub use material::{load_material, Material};
pub use registry::{make_sampler, AnySampler, SamplerOps, SamplerOptions, SAMPLERS};
pub use spec::{MaterialSpec, SamplerSpec, SimplifierName};
