//! The interface of BRDF sources: measured tables, networks, analytic models.

use std::hash::Hasher;

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

    /// A fingerprint of what the material evaluates to: equal for two
    /// materials with the same content, different (but for a 2^-64 chance)
    /// otherwise, whatever their names. A saved sampler records it, so that
    /// it is used only with the material it was built from.
    ///
    /// The default hashes `eval` on a fixed grid of direction pairs
    /// ([`fingerprint_by_eval`]); a source built from data should hash that
    /// data instead, which is exact and does not depend on the evaluation
    /// code.
    fn fingerprint(&self) -> u64 {
        fingerprint_by_eval(self)
    }

    /// Whether f_r is zero for every pair of directions, as far as the
    /// source can tell cheaply (a table of zeros, a network whose output is
    /// bounded by zero). Samplers that follow f_r refuse such a material:
    /// there is nothing to draw in proportion to. The default, `false`,
    /// claims nothing.
    fn is_zero_everywhere(&self) -> bool {
        false
    }
}

/// FNV-1a (64 bits) over explicit little-endian bytes: the same value on
/// every platform and in every version, for [`Brdf::fingerprint`].
#[derive(Default)]
pub struct Fingerprinter(fnv::FnvHasher);

impl Fingerprinter {
    /// An empty fingerprint.
    pub fn new() -> Self {
        Self::default()
    }
    /// Hash raw bytes.
    pub fn bytes(&mut self, bytes: &[u8]) {
        self.0.write(bytes);
    }
    /// Hash a u64 (little-endian).
    pub fn u64(&mut self, v: u64) {
        self.0.write(&v.to_le_bytes());
    }
    /// Hash the bits of `f32` values (little-endian).
    pub fn f32s(&mut self, values: &[f32]) {
        for v in values {
            self.0.write(&v.to_le_bytes());
        }
    }
    /// Hash the bits of `f64` values (little-endian).
    pub fn f64s(&mut self, values: &[f64]) {
        for v in values {
            self.0.write(&v.to_le_bytes());
        }
    }
    /// The fingerprint of everything hashed so far.
    pub fn finish(&self) -> u64 {
        self.0.finish()
    }
}

/// The default [`Brdf::fingerprint`]: the bits of f_r at 32 outgoing
/// directions (θ_o in 8 steps below 90°, φ_o in 4) times 64 incident ones
/// (8 × 8), and the isotropy flag.
pub fn fingerprint_by_eval<B: Brdf + ?Sized>(brdf: &B) -> u64 {
    let mut h = Fingerprinter::new();
    h.bytes(&[brdf.is_isotropic() as u8]);
    let direction = |i: usize, n: usize, j: usize, m: usize| {
        let theta = (i as f32 + 0.5) / n as f32 * std::f32::consts::FRAC_PI_2;
        let phi = (j as f32 + 0.25) / m as f32 * std::f32::consts::TAU;
        crate::geometry::spherical_direction(theta, phi)
    };
    for i in 0..8 {
        for j in 0..4 {
            let wo = direction(i, 8, j, 4);
            for k in 0..8 {
                for l in 0..8 {
                    h.f32s(&brdf.eval(wo, direction(k, 8, l, 8)).to_array());
                }
            }
        }
    }
    h.finish()
}

impl<T: Brdf + ?Sized> Brdf for Box<T> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn fingerprint(&self) -> u64 {
        (**self).fingerprint()
    }
    fn is_zero_everywhere(&self) -> bool {
        (**self).is_zero_everywhere()
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
    fn fingerprint(&self) -> u64 {
        (**self).fingerprint()
    }
    fn is_zero_everywhere(&self) -> bool {
        (**self).is_zero_everywhere()
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

    struct Constant(f32);
    impl Brdf for Constant {
        fn name(&self) -> &str {
            "constant"
        }
        fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
            Rgb::splat(if wo.z > 0.0 && wi.z > 0.0 {
                self.0
            } else {
                0.0
            })
        }
        fn is_isotropic(&self) -> bool {
            true
        }
    }

    /// The default fingerprint follows the values, not the name, and is
    /// the same through `Box` and `Arc`.
    #[test]
    fn fingerprints_follow_the_content() {
        let a = Constant(0.3).fingerprint();
        assert_eq!(a, Constant(0.3).fingerprint());
        assert_ne!(a, Constant(0.30001).fingerprint());
        assert_eq!(a, std::sync::Arc::new(Constant(0.3)).fingerprint());
        let boxed: Box<dyn Brdf> = Box::new(Constant(0.3));
        assert_eq!(a, boxed.fingerprint());
        assert!(!boxed.is_zero_everywhere());
    }

    #[test]
    fn luminance_of_white_is_one() {
        approx::assert_relative_eq!(luminance(Vec3::ONE), 1.0, max_relative = 1e-6);
    }
}
