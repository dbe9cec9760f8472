//! The uniform family's slice builder: a tabulated slice becomes a
//! [`PiecewiseConstant2D`] as it is, and the sampler built with it is
//! [`UniformBrdfSampler`].

use crate::PiecewiseConstant2D;
use acdf_core::Result;
use acdf_core::TableBuilder;
use acdf_tabulated::persist::{ByteReader, ByteWriter, Persist, PersistBuilder, PersistError};
use acdf_tabulated::TabulatedBrdfSampler;

/// Builds [`PiecewiseConstant2D`] slices: the uniform tabulation itself.
#[derive(Debug, Clone, Copy, Default)]
pub struct PiecewiseConstantBuilder;

/// The table as it is, one cell per table entry, for slices and
/// environment tables alike.
impl TableBuilder for PiecewiseConstantBuilder {
    type Dist = PiecewiseConstant2D;

    fn name(&self) -> String {
        "uniform".to_string()
    }

    fn build(&self, values: &[f32], nx: usize, ny: usize) -> Result<PiecewiseConstant2D> {
        PiecewiseConstant2D::new(values, nx, ny)
    }
}

/// The builder has no parameters: nothing is written for it.
impl Persist for PiecewiseConstantBuilder {
    fn encode(&self, _: &mut ByteWriter) {}
    fn decode(_: &mut ByteReader<'_>) -> std::result::Result<Self, PersistError> {
        Ok(PiecewiseConstantBuilder)
    }
}

impl PersistBuilder for PiecewiseConstantBuilder {
    const KIND: &'static str = "uniform";
}

/// The uniformly tabulated sampler, named `uniform`.
pub type UniformBrdfSampler = TabulatedBrdfSampler<PiecewiseConstantBuilder>;
