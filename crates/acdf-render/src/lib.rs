//! `acdf-render` is the renderer of `acdf render`: a sphere of a measured
//! material under an environment map, shaded by direct lighting with BRDF
//! sampling, light sampling and their multiple importance sampling
//! combinations, compared with a reference at equal samples, equal time and
//! equal CPU time ([`render`]), and the same scene written for Mitsuba 3
//! ([`mitsuba`]).

#![forbid(unsafe_code)]
// `!(x > 0.0)` is how this crate says "not positive, or NaN": the negated
// comparison is the point, since NaN must take the rejecting branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod mitsuba;
pub mod render;
