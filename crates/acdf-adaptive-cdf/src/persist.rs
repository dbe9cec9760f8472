//! Adaptive samplers in the sampler file format of
//! [`acdf_tabulated::persist`], where the layout is documented. This module
//! adds what is specific to them: the builder's parameters and the layout of
//! an [`AdaptiveCdf2D`].

use crate::simplify::{simplifier_by_name, validate_tolerance};
use crate::{AdaptiveBuilder, AdaptiveCdf2D};
use acdf_tabulated::persist::{ByteReader, ByteWriter, Persist, PersistBuilder, PersistError};

/// Stored as the simplifier name (`string`) and the tolerance (f64).
impl Persist for AdaptiveBuilder {
    fn encode(&self, w: &mut ByteWriter) {
        w.string(self.simplifier.name());
        w.f64(self.tolerance);
    }

    fn decode(r: &mut ByteReader<'_>) -> Result<Self, PersistError> {
        let name = r.string("simplifier")?;
        let simplifier = simplifier_by_name(&name)?;
        let tolerance = r.f64("tolerance")?;
        validate_tolerance(tolerance)?;
        Ok(AdaptiveBuilder {
            simplifier,
            tolerance,
        })
    }
}

impl PersistBuilder for AdaptiveBuilder {
    const KIND: &'static str = "adaptive";
}

/// Check that `x` and `cdf` form a curve that sampling can walk: either
/// fewer than two vertices (a uniform stand-in, as stored for zero-mass
/// segments), or positions strictly increasing from 0 to 1 and CDF values
/// non-decreasing from 0 to 1, so every segment has a positive width and
/// every u in [0, 1) finds one.
fn check_curve(field: &'static str, x: &[f32], cdf: &[f32]) -> Result<(), PersistError> {
    let invalid = |reason: String| PersistError::Invalid { field, reason };
    if x.len() < 2 {
        return Ok(());
    }
    if x.iter().chain(cdf).any(|v| !v.is_finite()) {
        return Err(invalid("holds a NaN or an infinity".into()));
    }
    let ends = |v: &[f32]| v[0] == 0.0 && v[v.len() - 1] == 1.0;
    if !ends(x) || !ends(cdf) {
        return Err(invalid("does not run from (0, 0) to (1, 1)".into()));
    }
    if let Some(k) = (1..x.len()).find(|&k| x[k] <= x[k - 1]) {
        return Err(invalid(format!("vertex positions not increasing at {k}")));
    }
    if let Some(k) = (1..cdf.len()).find(|&k| cdf[k] < cdf[k - 1]) {
        return Err(invalid(format!("CDF decreasing at {k}")));
    }
    Ok(())
}

/// Stored as three arrays, the marginal (m positions then m CDF values,
/// `f32 array`), the conditional offsets (m u32, as an `f32 array` of their
/// bit patterns) and the conditionals (`f32 array`), then the integral (f64).
impl Persist for AdaptiveCdf2D {
    fn encode(&self, w: &mut ByteWriter) {
        w.f32_array(&self.marginal);
        let offsets: Vec<f32> = self.offsets.iter().map(|&o| f32::from_bits(o)).collect();
        w.f32_array(&offsets);
        w.f32_array(&self.conditionals);
        w.f64(self.integral);
    }

    fn decode(r: &mut ByteReader<'_>) -> Result<Self, PersistError> {
        let marginal = r.f32_array("AdaptiveCdf2D marginal")?;
        let m = marginal.len() / 2;
        if marginal.len() % 2 != 0 || m < 2 {
            return Err(PersistError::Invalid {
                field: "AdaptiveCdf2D marginal",
                reason: format!(
                    "{} values do not form at least two vertices",
                    marginal.len()
                ),
            });
        }
        check_curve("AdaptiveCdf2D marginal", &marginal[..m], &marginal[m..])?;
        let offsets: Vec<u32> = r
            .f32_array("AdaptiveCdf2D offsets")?
            .into_iter()
            .map(f32::to_bits)
            .collect();
        let conditionals = r.f32_array("AdaptiveCdf2D conditionals")?;
        let bad_offsets = |reason: String| PersistError::Invalid {
            field: "AdaptiveCdf2D offsets",
            reason,
        };
        if offsets.len() != m || offsets[0] != 0 {
            return Err(bad_offsets(format!(
                "{} offsets for {m} vertices",
                offsets.len()
            )));
        }
        if offsets.windows(2).any(|w| w[1] < w[0]) {
            return Err(bad_offsets("not non-decreasing".into()));
        }
        if offsets[m - 1] as usize * 2 != conditionals.len() {
            return Err(bad_offsets(format!(
                "end at {} vertices, the conditionals hold {} values",
                offsets[m - 1],
                conditionals.len()
            )));
        }
        for j in 0..m - 1 {
            let (a, b) = (offsets[j] as usize, offsets[j + 1] as usize);
            let (x, cdf) = conditionals[2 * a..2 * b].split_at(b - a);
            check_curve("AdaptiveCdf2D conditional", x, cdf)?;
        }
        let integral = r.f64("integral")?;
        if !integral.is_finite() || integral < 0.0 {
            return Err(PersistError::Invalid {
                field: "integral",
                reason: format!("{integral} is not a finite non-negative number"),
            });
        }
        Ok(AdaptiveCdf2D::from_parts(
            marginal,
            offsets,
            conditionals,
            integral,
        ))
    }
}
