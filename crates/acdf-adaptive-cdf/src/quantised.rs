//! Adaptive CDFs in a quantised stored form, as the outgoing samplers keep
//! their slices: vertices as grid indices (16 bits along θ_h, 8 along φ_h)
//! and CDF values as 16-bit integers. [`PackedCdf2D`] is one slice with
//! vertices of its own; [`SharedSlices`] holds many slices on one shared
//! grid of vertices, each with its own CDF values there.

// `!(x > 0.0)` says "not positive, or NaN", as elsewhere in acdf.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod packed;
mod shared;

pub use packed::{
    check_curve, check_offsets, conditional_masses, grid_indices, quantise, PackedCdf2D,
    QuantisedSegment, Stored, Q, QF,
};
pub use shared::{
    CompactSlices, GridCell, GridDraw, SharedSlices, NO_CONDITIONAL, SHARED_MARGINAL_SHARE,
};
