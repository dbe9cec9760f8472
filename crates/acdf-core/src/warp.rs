//! Analytic warps from the unit square to the disk and hemisphere, shared by
//! the cosine sampler and by samplers that mix in a cosine lobe.

use crate::distribution::clamp_unit;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_4};

/// Shirley and Chiu's concentric map from [0,1)^2 to the unit disk: squares
/// around the centre go to circles, so strata keep their shape and area.
#[inline]
pub fn square_to_concentric_disk(u: Vec2) -> Vec2 {
    let a = 2.0 * clamp_unit(u.x) - 1.0;
    let b = 2.0 * clamp_unit(u.y) - 1.0;
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    let (r, angle) = if a.abs() > b.abs() {
        (a, FRAC_PI_4 * (b / a))
    } else {
        (b, 2.0 * FRAC_PI_4 - FRAC_PI_4 * (a / b))
    };
    let (s, c) = angle.sin_cos();
    Vec2::new(r * c, r * s)
}

/// Malley's method: lift a uniform point of the unit disk to the hemisphere,
/// z = sqrt(1 - x² - y²), which gives density cos θ / π per solid angle.
#[inline]
pub fn square_to_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = square_to_concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// The density of [`square_to_cosine_hemisphere`]: max(cos θ, 0) / π.
#[inline]
pub fn cosine_hemisphere_pdf(w: Vec3) -> f32 {
    w.z.max(0.0) * FRAC_1_PI
}

/// Uniform directions on the upper hemisphere: z = u.x, φ = 2π u.y.
#[inline]
pub fn square_to_uniform_hemisphere(u: Vec2) -> Vec3 {
    let z = clamp_unit(u.x);
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * clamp_unit(u.y);
    let (s, c) = phi.sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// The density of [`square_to_uniform_hemisphere`]: 1 / (2π) above the
/// horizon, 0 below.
#[inline]
pub fn uniform_hemisphere_pdf(w: Vec3) -> f32 {
    if w.z > 0.0 {
        0.5 * FRAC_1_PI
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn concentric_disk_stays_in_the_disk_at_the_corners() {
        for u in [
            Vec2::ZERO,
            Vec2::new(0.5, 0.5),
            Vec2::splat(crate::ONE_MINUS_EPSILON),
            Vec2::new(0.0, crate::ONE_MINUS_EPSILON),
            Vec2::new(f32::NAN, 2.0),
        ] {
            let d = square_to_concentric_disk(u);
            assert!(d.is_finite());
            assert!(d.length() <= 1.0 + 1e-6);
            let w = square_to_cosine_hemisphere(u);
            assert!(w.is_finite() && w.z >= 0.0);
        }
    }
}
