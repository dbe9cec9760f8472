//! Geometry of the local shading frame.
//!
//! The frame has `z` along the surface normal; θ is measured from `z` and φ
//! counter-clockwise from `x`. All functions take and return unit vectors
//! unless stated otherwise.

use glam::Vec3;
use std::f32::consts::TAU;

/// cos θ = z.
#[inline(always)]
pub fn cos_theta(w: Vec3) -> f32 {
    w.z
}

/// sin θ = sqrt(x² + y²), exact near the pole, unlike sqrt(1 - z²).
#[inline(always)]
pub fn sin_theta(w: Vec3) -> f32 {
    (w.x * w.x + w.y * w.y).sqrt()
}

/// θ = atan2(sqrt(x² + y²), z) in [0, π].
///
/// atan2 keeps full relative precision near θ = 0, where acos(z) loses about
/// half the digits (its derivative is infinite at z = 1).
#[inline]
pub fn theta(w: Vec3) -> f32 {
    sin_theta(w).atan2(w.z)
}

/// φ = atan2(y, x) wrapped to [0, 2π); 0 on the pole.
#[inline]
pub fn phi(w: Vec3) -> f32 {
    wrap_angle(w.y.atan2(w.x))
}

/// Wrap any finite angle to [0, 2π).
#[inline]
pub fn wrap_angle(a: f32) -> f32 {
    let r = a.rem_euclid(TAU);
    // rem_euclid can round up to exactly 2π for tiny negative inputs.
    if r >= TAU {
        0.0
    } else {
        r
    }
}

/// The unit vector (sin θ cos φ, sin θ sin φ, cos θ).
#[inline]
pub fn spherical_direction(theta: f32, phi: f32) -> Vec3 {
    let (sin_t, cos_t) = theta.sin_cos();
    let (sin_p, cos_p) = phi.sin_cos();
    Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t)
}

/// Mirror `w` about the unit vector `h`: 2 (w·h) h - w. Applying it twice
/// gives `w` back.
#[inline(always)]
pub fn reflect(w: Vec3, h: Vec3) -> Vec3 {
    reflect_given_dot(w, h, w.dot(h))
}

/// [`reflect`] for a caller that already holds w·h (found another way,
/// e.g. in other axes): 2 (w·h) h - w.
#[inline(always)]
pub fn reflect_given_dot(w: Vec3, h: Vec3, w_dot_h: f32) -> Vec3 {
    2.0 * w_dot_h * h - w
}

/// The half vector h = (wi + wo) / |wi + wo|, or `None` when the two
/// directions are opposite (h undefined).
#[inline]
pub fn half_vector(wi: Vec3, wo: Vec3) -> Option<Vec3> {
    let s = wi + wo;
    let len2 = s.length_squared();
    if len2 > 1e-20 && len2.is_finite() {
        Some(s / len2.sqrt())
    } else {
        None
    }
}

/// The Jacobian of the half-vector map h(wi) for a fixed wo:
/// dω_h / dω_i = 1 / (4 |wi·h|).
///
/// A density over half vectors p_h becomes a density over incident directions
/// as p_i = p_h · dω_h/dω_i. Since wi is the mirror of wo about h,
/// |wi·h| = |wo·h|. It is infinite only when wi ⟂ h, i.e. wi = -wo.
#[inline(always)]
pub fn half_vector_jacobian(wi: Vec3, h: Vec3) -> f32 {
    1.0 / (4.0 * wi.dot(h).abs())
}

/// An orthonormal, right-handed frame (x, y, z): `to_local` expresses a world
/// vector in it, `to_world` undoes that.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub x: Vec3,
    pub y: Vec3,
    pub z: Vec3,
}

impl Frame {
    /// The frame with the identity axes.
    pub const IDENTITY: Frame = Frame {
        x: Vec3::X,
        y: Vec3::Y,
        z: Vec3::Z,
    };

    /// A frame whose `z` is the unit vector `n`; `x` and `y` are chosen
    /// continuously except across n.z = 0 (the branch-free construction of
    /// Duff et al. 2017, as glam provides it).
    pub fn from_z(n: Vec3) -> Frame {
        let (x, y) = n.any_orthonormal_pair();
        // Make the frame right-handed whatever glam's orientation is.
        if x.cross(y).dot(n) >= 0.0 {
            Frame { x, y, z: n }
        } else {
            Frame { x: y, y: x, z: n }
        }
    }

    /// Coordinates of the world vector `w` in this frame: (w·x, w·y, w·z).
    #[inline]
    pub fn to_local(&self, w: Vec3) -> Vec3 {
        Vec3::new(w.dot(self.x), w.dot(self.y), w.dot(self.z))
    }

    /// The world vector with local coordinates `l`: l.x x + l.y y + l.z z.
    #[inline]
    pub fn to_world(&self, l: Vec3) -> Vec3 {
        l.x * self.x + l.y * self.y + l.z * self.z
    }
}

/// Rusinkiewicz's half/difference coordinates of a pair (wi, wo).
///
/// h = normalize(wi + wo) has spherical angles (θ_h, φ_h). The difference
/// vector d is wi expressed in the frame that carries h to the pole:
/// d = R_y(-θ_h) R_z(-φ_h) wi, with spherical angles (θ_d, φ_d). Then wi·h =
/// cos θ_d, and wo is the mirror image of wi about h. For isotropic BRDFs φ_h
/// drops out; for reciprocal ones (wi, wo) and (wo, wi) differ only by
/// φ_d → φ_d + π.
///
/// Angles: θ_h, θ_d ∈ [0, π]; φ_h, φ_d ∈ [0, 2π).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfDiff {
    pub theta_h: f32,
    pub phi_h: f32,
    pub theta_d: f32,
    pub phi_d: f32,
}

/// The two axes (R_z(φ_h) R_y(θ_h)) e_x and (R_z(φ_h) R_y(θ_h)) e_y of the
/// frame whose pole is `h`, computed from h's components without trigonometry.
#[inline]
fn half_frame_axes(h: Vec3) -> (Vec3, Vec3) {
    let sin_th = sin_theta(h);
    let (cos_ph, sin_ph) = if sin_th > 0.0 {
        (h.x / sin_th, h.y / sin_th)
    } else {
        (1.0, 0.0)
    };
    let t1 = Vec3::new(h.z * cos_ph, h.z * sin_ph, -sin_th);
    let t2 = Vec3::new(-sin_ph, cos_ph, 0.0);
    (t1, t2)
}

impl HalfDiff {
    /// Half/difference coordinates of (wi, wo); `None` when wi = -wo.
    pub fn from_directions(wi: Vec3, wo: Vec3) -> Option<HalfDiff> {
        let h = half_vector(wi, wo)?;
        let (t1, t2) = half_frame_axes(h);
        let d = Vec3::new(wi.dot(t1), wi.dot(t2), wi.dot(h));
        Some(HalfDiff {
            theta_h: theta(h),
            phi_h: phi(h),
            theta_d: theta(d),
            phi_d: phi(d),
        })
    }

    /// The half vector (θ_h, φ_h).
    pub fn half(&self) -> Vec3 {
        spherical_direction(self.theta_h, self.phi_h)
    }

    /// The difference vector (θ_d, φ_d).
    pub fn difference(&self) -> Vec3 {
        spherical_direction(self.theta_d, self.phi_d)
    }

    /// The pair (wi, wo): wi = R_z(φ_h) R_y(θ_h) d and wo = reflect(wi, h).
    pub fn to_directions(&self) -> (Vec3, Vec3) {
        let h = self.half();
        let d = self.difference();
        let (t1, t2) = half_frame_axes(h);
        let wi = d.x * t1 + d.y * t2 + d.z * h;
        (wi, reflect(wi, h))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f32::consts::{FRAC_PI_2, PI};

    fn unit_vector() -> impl Strategy<Value = Vec3> {
        (-1.0f32..1.0, 0.0f32..TAU).prop_map(|(z, phi)| {
            let r = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
    }

    /// θ values that stress the poles and the horizon as well as the middle.
    fn theta_upper() -> impl Strategy<Value = f32> {
        prop_oneof![
            0.0f32..FRAC_PI_2,
            0.0f32..1e-4,
            (FRAC_PI_2 - 1e-4)..FRAC_PI_2,
            Just(0.0f32),
        ]
    }

    /// φ values including both sides of the 0 / 2π seam.
    fn phi_any() -> impl Strategy<Value = f32> {
        prop_oneof![0.0f32..TAU, 0.0f32..1e-5, (TAU - 1e-5)..TAU, -1e-5f32..0.0,]
    }

    fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).abs().max_element() <= tol
    }

    proptest! {
        #[test]
        fn directions_half_diff_directions_round_trip(
            ti in theta_upper(), pi in phi_any(), to in theta_upper(), po in phi_any()
        ) {
            let wi = spherical_direction(ti, pi);
            let wo = spherical_direction(to, po);
            prop_assume!((wi + wo).length() > 1e-3);
            let hd = HalfDiff::from_directions(wi, wo).unwrap();
            prop_assert!(hd.theta_h >= 0.0 && hd.theta_h <= FRAC_PI_2 + 1e-6);
            prop_assert!((0.0..TAU).contains(&hd.phi_h) && (0.0..TAU).contains(&hd.phi_d));
            let (wi2, wo2) = hd.to_directions();
            prop_assert!(close(wi, wi2, 1e-5), "wi {wi} -> {wi2}");
            prop_assert!(close(wo, wo2, 1e-5), "wo {wo} -> {wo2}");
        }

        /// θ_d stops 0.01 short of π/2: there wi and wo are nearly opposite,
        /// |wi + wo| = 2 cos θ_d, and f32 directions fix h only to about
        /// 6e-8 / cos θ_d. The direction round trip above covers the horizon.
        #[test]
        fn half_diff_directions_half_diff_round_trip(
            th in theta_upper(), ph in phi_any(),
            td in prop_oneof![0.0f32..(FRAC_PI_2 - 0.01), 0.0f32..1e-4, Just(0.0f32)],
            pd in phi_any()
        ) {
            let hd = HalfDiff { theta_h: th, phi_h: wrap_angle(ph), theta_d: td, phi_d: wrap_angle(pd) };
            let (wi, wo) = hd.to_directions();
            let back = HalfDiff::from_directions(wi, wo).unwrap();
            // Compare as directions, because φ is undefined on the pole.
            prop_assert!(close(back.half(), hd.half(), 1e-5));
            prop_assert!((back.theta_h - th).abs() < 1e-5);
            prop_assert!((back.theta_d - td).abs() < 1e-5);
            // Near θ_h = 0 only φ_h + φ_d is determined (φ_h of an f32 h is
            // known to about 6e-8 / sin θ_h); there the pair of directions is
            // the invariant, and it must come back.
            if th > 0.01 {
                prop_assert!(close(back.difference(), hd.difference(), 1e-5));
            }
            let (wi2, wo2) = back.to_directions();
            prop_assert!(close(wi, wi2, 1e-5) && close(wo, wo2, 1e-5));
        }

        #[test]
        fn frames_are_orthonormal_and_right_handed(n in unit_vector()) {
            let f = Frame::from_z(n);
            for (a, b) in [(f.x, f.y), (f.y, f.z), (f.z, f.x)] {
                prop_assert!(a.dot(b).abs() < 1e-5);
            }
            for a in [f.x, f.y, f.z] {
                prop_assert!((a.length() - 1.0).abs() < 1e-5);
            }
            prop_assert!(close(f.x.cross(f.y), f.z, 1e-5));
        }

        #[test]
        fn frame_local_world_round_trip(n in unit_vector(), w in unit_vector()) {
            let f = Frame::from_z(n);
            prop_assert!(close(f.to_world(f.to_local(w)), w, 1e-5));
            prop_assert!((f.to_local(n).z - 1.0).abs() < 1e-5);
        }

        #[test]
        fn reflection_is_an_involution(w in unit_vector(), h in unit_vector()) {
            prop_assert!(close(reflect(reflect(w, h), h), w, 1e-5));
            // It preserves the angle to h and the length.
            prop_assert!((reflect(w, h).dot(h) - w.dot(h)).abs() < 1e-5);
            prop_assert!((reflect(w, h).length() - 1.0).abs() < 1e-5);
        }

        #[test]
        fn spherical_angles_round_trip(t in 0.0f32..PI, p in phi_any()) {
            let w = spherical_direction(t, p);
            prop_assert!((theta(w) - t).abs() < 1e-5);
            if t > 1e-3 && t < PI - 1e-3 {
                let dp = (phi(w) - wrap_angle(p)).abs();
                prop_assert!(dp.min(TAU - dp) < 1e-4);
            }
        }
    }

    #[test]
    fn half_diff_of_mirror_pair_is_at_the_pole() {
        let wo = spherical_direction(0.7, 1.0);
        let wi = reflect(wo, Vec3::Z);
        let hd = HalfDiff::from_directions(wi, wo).unwrap();
        assert!(hd.theta_h < 1e-6);
        assert!((hd.theta_d - 0.7).abs() < 1e-5);
    }

    #[test]
    fn opposite_directions_have_no_half_vector() {
        let w = Vec3::new(1.0, 0.0, 0.0);
        assert!(HalfDiff::from_directions(w, -w).is_none());
        assert!(half_vector(w, -w).is_none());
    }

    #[test]
    fn jacobian_matches_its_formula() {
        let wo = spherical_direction(0.5, 0.3);
        let h = spherical_direction(0.2, 2.0);
        let wi = reflect(wo, h);
        approx::assert_relative_eq!(
            half_vector_jacobian(wi, h),
            1.0 / (4.0 * wo.dot(h)),
            max_relative = 1e-5
        );
    }

    #[test]
    fn wrap_angle_stays_below_two_pi() {
        assert_eq!(wrap_angle(-1e-9), 0.0);
        assert!(wrap_angle(-1e-3) < TAU);
        assert_eq!(wrap_angle(TAU), 0.0);
    }
}
