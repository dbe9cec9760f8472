//! Analytic BRDFs for the battery: an ordinary pair (Lambertian, anisotropic
//! GGX) for the weight check, and three extreme ones that a tabulating
//! sampler must survive (zero everywhere, one narrow spike, a range of sixty
//! orders of magnitude).

use crate::samplers::{ggx_d, tilted_axis};
use acdf_core::geometry::{half_vector, reflect};
use acdf_core::{Brdf, Rgb, Vec3};
use std::f32::consts::FRAC_1_PI;
use std::sync::Arc;

/// Both directions strictly above the horizon and finite.
#[inline]
fn above(wo: Vec3, wi: Vec3) -> bool {
    wo.z > 0.0 && wi.z > 0.0 && wo.is_finite() && wi.is_finite()
}

/// f = albedo / π.
#[derive(Debug, Clone, Copy)]
pub struct Lambertian {
    pub albedo: Rgb,
}

impl Brdf for Lambertian {
    fn name(&self) -> &str {
        "lambertian"
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if above(wo, wi) {
            self.albedo * FRAC_1_PI
        } else {
            Rgb::ZERO
        }
    }
    fn is_isotropic(&self) -> bool {
        true
    }
}

/// An anisotropic microfacet BRDF without shadowing or Fresnel:
/// f = D(h) / (4 cos θ_i cos θ_o), cos products clamped below at 1e-3 so that
/// it stays finite at grazing angles.
#[derive(Debug, Clone, Copy)]
pub struct GgxBrdf {
    pub alpha_x: f32,
    pub alpha_y: f32,
    pub color: Rgb,
}

impl Brdf for GgxBrdf {
    fn name(&self) -> &str {
        "ggx"
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if !above(wo, wi) {
            return Rgb::ZERO;
        }
        let Some(h) = half_vector(wi, wo) else {
            return Rgb::ZERO;
        };
        let d = ggx_d(h, self.alpha_x, self.alpha_y);
        self.color * (d / (4.0 * (wi.z * wo.z).max(1e-3)))
    }
    fn is_isotropic(&self) -> bool {
        self.alpha_x == self.alpha_y
    }
}

/// Zero for every pair of directions.
#[derive(Debug, Clone, Copy)]
pub struct ZeroBrdf;

impl Brdf for ZeroBrdf {
    fn name(&self) -> &str {
        "zero"
    }
    fn eval(&self, _: Vec3, _: Vec3) -> Rgb {
        Rgb::ZERO
    }
    fn is_isotropic(&self) -> bool {
        true
    }
}

/// One narrow spike: 1e6 / sr within `width` radians of the mirror direction
/// of wo, zero elsewhere. A box, so a tabulation at any resolution misses
/// most of it or smears it.
#[derive(Debug, Clone, Copy)]
pub struct SpikeBrdf {
    pub width: f32,
}

impl Brdf for SpikeBrdf {
    fn name(&self) -> &str {
        "spike"
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if above(wo, wi) && wi.dot(reflect(wo, Vec3::Z)) >= self.width.cos() {
            Rgb::splat(1e6)
        } else {
            Rgb::ZERO
        }
    }
    fn is_isotropic(&self) -> bool {
        true
    }
}

/// A smooth BRDF spanning 1e-30 .. 1e30: f = 10^(30 c) with c the cosine
/// between wi and an axis tilted from the mirror direction toward the
/// normal (so it is not reciprocal either).
#[derive(Debug, Clone, Copy)]
pub struct HugeRangeBrdf;

impl Brdf for HugeRangeBrdf {
    fn name(&self) -> &str {
        "huge-range"
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if !above(wo, wi) {
            return Rgb::ZERO;
        }
        let c = wi.dot(tilted_axis(wo)).clamp(-1.0, 1.0);
        Rgb::splat(10f32.powf(30.0 * c))
    }
    fn is_isotropic(&self) -> bool {
        false
    }
}

/// The ordinary analytic BRDFs: a grey Lambertian and an anisotropic GGX.
pub fn ordinary_brdfs() -> Vec<Arc<dyn Brdf>> {
    vec![
        Arc::new(Lambertian {
            albedo: Rgb::new(0.8, 0.5, 0.2),
        }),
        Arc::new(GgxBrdf {
            alpha_x: 0.15,
            alpha_y: 0.4,
            color: Rgb::new(0.9, 0.8, 0.7),
        }),
    ]
}

/// The extreme BRDFs every sampler constructor is fed: zero, a 0.5° spike,
/// and a 1e-30 .. 1e30 range. A constructor may reject them with an error;
/// if it accepts them, the sampler must draw without NaN.
pub fn extreme_brdfs() -> Vec<Arc<dyn Brdf>> {
    vec![
        Arc::new(ZeroBrdf),
        Arc::new(SpikeBrdf {
            width: 0.5f32.to_radians(),
        }),
        Arc::new(HugeRangeBrdf),
    ]
}
