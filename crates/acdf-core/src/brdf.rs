//! The interface of BRDF sources: measured tables, networks, analytic models.

use glam::Vec3;

/// Linear RGB in the Rec. 709 primaries.
pub type Rgb = Vec3;

/// Rec. 709 luminance weights: Y = 0.2126 R + 0.7152 G + 0.0722 B.
pub const LUMINANCE_WEIGHTS: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

/// The luminance Y of a linear Rec. 709 colour.
#[inline(always)]
pub fn luminance(c: Rgb) -> f32 {
    c.dot(LUMINANCE_WEIGHTS)
}

/// A bidirectional reflectance distribution function.
///
/// The contract every source keeps:
/// - `eval(wo, wi)` is f_r in 1/sr, *not* multiplied by cos θ_i;
/// - it is zero when either direction is at or below the horizon;
/// - every channel is finite and non-negative for every input, including
///   non-unit, degenerate or NaN directions (which give zero).
pub trait Brdf: Send + Sync {
    /// A short name for tables and file headers (`nickel`, `lambert`, ...).
    fn name(&self) -> &str;

    /// f_r(wo, wi) per RGB channel, in 1/sr.
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb;

    /// Whether f_r depends on the two azimuths only through their difference,
    /// so a sampler may tabulate one azimuth slice of wo.
    fn is_isotropic(&self) -> bool;

    /// The luminance of f_r(wo, wi); what samplers importance-sample.
    #[inline]
    fn luminance(&self, wo: Vec3, wi: Vec3) -> f32 {
        luminance(self.eval(wo, wi))
    }

    /// The luminance over a ring of half vectors at one θ_h: for each column
    /// c with `columns[c]` = (cos φ_c, sin φ_c),
    /// out\[c\] = Y(f_r(wo, wi_c)) with h_c = (sin θ_h cos φ_c, sin θ_h sin φ_c,
    /// cos θ_h) and wi_c = 2 (wo·h_c) h_c − wo, the mirror of wo about h_c.
    ///
    /// Tabulating over the half vector evaluates whole rings, and a source
    /// can hoist the work that depends only on θ_h and wo out of the loop
    /// (a measured table's θ_h index, say). `wo`, (sin θ_h, cos θ_h) and the
    /// columns are meant to be unit; an override must give what the default
    /// gives, [`luminance`](Brdf::luminance) at each (wo, wi_c), up to float
    /// rounding and the error of its trigonometry. Only
    /// min(columns.len(), out.len()) values are written.
    fn luminance_half_ring(
        &self,
        wo: Vec3,
        (sin_theta_h, cos_theta_h): (f32, f32),
        columns: &[(f32, f32)],
        out: &mut [f32],
    ) {
        for (&(cos_phi, sin_phi), y) in columns.iter().zip(out.iter_mut()) {
            let h = Vec3::new(sin_theta_h * cos_phi, sin_theta_h * sin_phi, cos_theta_h);
            *y = self.luminance(wo, crate::geometry::reflect(wo, h));
        }
    }
}

impl<T: Brdf + ?Sized> Brdf for Box<T> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        (**self).eval(wo, wi)
    }
    fn is_isotropic(&self) -> bool {
        (**self).is_isotropic()
    }
    fn luminance(&self, wo: Vec3, wi: Vec3) -> f32 {
        (**self).luminance(wo, wi)
    }
    fn luminance_half_ring(
        &self,
        wo: Vec3,
        half: (f32, f32),
        columns: &[(f32, f32)],
        out: &mut [f32],
    ) {
        (**self).luminance_half_ring(wo, half, columns, out)
    }
}

impl<T: Brdf + ?Sized> Brdf for std::sync::Arc<T> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        (**self).eval(wo, wi)
    }
    fn is_isotropic(&self) -> bool {
        (**self).is_isotropic()
    }
    fn luminance(&self, wo: Vec3, wi: Vec3) -> f32 {
        (**self).luminance(wo, wi)
    }
    fn luminance_half_ring(
        &self,
        wo: Vec3,
        half: (f32, f32),
        columns: &[(f32, f32)],
        out: &mut [f32],
    ) {
        (**self).luminance_half_ring(wo, half, columns, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn luminance_of_white_is_one() {
        approx::assert_relative_eq!(luminance(Vec3::ONE), 1.0, max_relative = 1e-6);
    }
}
