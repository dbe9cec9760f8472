//! The file layout of the piecewise-constant distributions (see
//! [`acdf_tabulated::persist`] for the envelope), and the checks a stored
//! table passes before it is used.

use super::{
    marginal_guide, CdfGuide, GridScale, PiecewiseConstant1D, PiecewiseConstant2D, MAX_CELLS,
};
use acdf_tabulated::persist::{ByteReader, ByteWriter, Persist, PersistError};

/// Check that a stored CDF is one [`fill_cdf`] could have produced: finite,
/// within [0, 1], non-decreasing and ending at exactly 1. Sampling relies on
/// each of these (a search that always finds a cell, a positive cell mass).
fn check_stored_cdf(field: &'static str, cdf: &[f32]) -> std::result::Result<(), PersistError> {
    let invalid = |reason: String| PersistError::Invalid { field, reason };
    if cdf.is_empty() || cdf.len() > MAX_CELLS {
        return Err(invalid(format!("{} cells", cdf.len())));
    }
    let mut previous = 0.0f32;
    for (k, &c) in cdf.iter().enumerate() {
        if !(c >= previous && c <= 1.0) {
            return Err(invalid(format!(
                "entry {k} ({c}) breaks monotonicity in [0, 1]"
            )));
        }
        previous = c;
    }
    if previous != 1.0 {
        return Err(invalid(format!("ends at {previous}, not 1")));
    }
    Ok(())
}

fn check_stored_integral(integral: f64) -> std::result::Result<f64, PersistError> {
    if integral.is_finite() && integral >= 0.0 {
        Ok(integral)
    } else {
        Err(PersistError::Invalid {
            field: "integral",
            reason: format!("{integral} is not a finite non-negative number"),
        })
    }
}

/// Stored as the CDF (`f32 array`) and the integral (f64).
impl Persist for PiecewiseConstant1D {
    fn encode(&self, w: &mut ByteWriter) {
        w.f32_array(&self.cdf);
        w.f64(self.integral);
    }

    fn decode(r: &mut ByteReader<'_>) -> std::result::Result<Self, PersistError> {
        let cdf = r.f32_array("PiecewiseConstant1D cdf")?;
        check_stored_cdf("PiecewiseConstant1D cdf", &cdf)?;
        let integral = check_stored_integral(r.f64("integral")?)?;
        Ok(PiecewiseConstant1D {
            guide: CdfGuide::new(&cdf),
            cdf,
            integral,
        })
    }
}

/// Stored as nx, ny (u32), the conditional CDFs (`f32 array`, ny rows of nx),
/// the marginal CDF (`f32 array` of ny) and the integral (f64).
impl Persist for PiecewiseConstant2D {
    fn encode(&self, w: &mut ByteWriter) {
        w.length(self.nx);
        w.length(self.ny);
        w.f32_array(&self.conditional);
        w.f32_array(&self.marginal);
        w.f64(self.integral);
    }

    fn decode(r: &mut ByteReader<'_>) -> std::result::Result<Self, PersistError> {
        let nx = r.u32("nx")? as usize;
        let ny = r.u32("ny")? as usize;
        let conditional = r.f32_array("PiecewiseConstant2D conditional")?;
        if nx == 0 || ny == 0 || nx.checked_mul(ny) != Some(conditional.len()) {
            return Err(PersistError::Invalid {
                field: "PiecewiseConstant2D conditional",
                reason: format!("{} entries for {nx} x {ny}", conditional.len()),
            });
        }
        for row in conditional.chunks_exact(nx) {
            check_stored_cdf("PiecewiseConstant2D conditional", row)?;
        }
        let marginal = r.f32_array("PiecewiseConstant2D marginal")?;
        if marginal.len() != ny {
            return Err(PersistError::Invalid {
                field: "PiecewiseConstant2D marginal",
                reason: format!("{} entries for {ny} rows", marginal.len()),
            });
        }
        check_stored_cdf("PiecewiseConstant2D marginal", &marginal)?;
        let integral = check_stored_integral(r.f64("integral")?)?;
        Ok(PiecewiseConstant2D {
            nx,
            ny,
            conditional,
            marginal_guide: marginal_guide(&marginal),
            marginal,
            integral,
            scale: GridScale::new(nx, ny),
        })
    }
}
