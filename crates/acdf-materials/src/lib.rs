//! placeholder: owned by the materials work (issue 4); `rgl` by issue 9.
pub mod rgl;
