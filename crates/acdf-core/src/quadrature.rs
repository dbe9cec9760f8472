//! Deterministic quadrature over the incident hemisphere: what a sampler
//! does with the light a BRDF reflects, computed without drawing a sample.
//!
//! For one outgoing direction wo, an [`Integrand`] holds the points of a
//! [`HemisphereGrid`] where the BRDF reflects anything, each with its solid
//! angle dω, g_Y = Y(f_r(wo, wi)) cos θ_i (Y the luminance) and, under an
//! optional light L(wi), g_L = Y(f_r ⊙ L) cos θ_i (⊙ per channel; g_L = g_Y
//! without a light). [`Integrand::moments`] sums, for a sampler of density
//! p, with the midpoint rule over the grid's cells:
//!
//! - the **missed share** ∫_{p=0} g_Y dω / ∫ g_Y dω: the light a sampler
//!   used alone can never draw ([`missed_share`]);
//! - the first two moments of the one-sample estimator Y = g_L(wi) / p(wi),
//!   wi drawn from the sampler (a draw that fails counts 0): its mean
//!   ∫_{p>0} g_L dω and its second moment ∫_{p>0} g_L² / p dω, hence its
//!   variance and its **relative variance** Var / (∫ g_L dω)²;
//! - the largest **weight** g_Y / p (= Y(f) cos θ_i / p) at a grid point
//!   where p > 0: the brightest single sample, a firefly.
//!
//! The integrand is built once per (BRDF, wo, light) and reused for every
//! sampler compared on it; only the sampler's density is evaluated per
//! sampler, in batches ([`BxdfSampler::pdf_batch`]). Sums run in `f64` in a
//! fixed order, so results do not change from run to run.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use crate::{luminance, Brdf, BxdfSampler, Rgb, Vec3};

/// The cells of a quadrature over the incident hemisphere, each evaluated
/// at its centre.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HemisphereGrid {
    /// `n_cos` × `n_phi` cells of equal solid angle over the incident
    /// hemisphere: equal steps in cos θ_i and φ_i. The midpoint rule is
    /// exact for anything linear in cos θ_i (a Lambertian f cos θ_i), and
    /// the cells reach the horizon evenly, where light a tabulation misses
    /// tends to lie.
    EqualArea { n_cos: usize, n_phi: usize },
    /// `n_v` × `n_x` cells over the half vector h of wi, in the coordinates
    /// of the tabulated samplers: rows v ∈ [0, 1) with θ_h = (π/2) v²,
    /// columns x ∈ [0, 1) with φ_h = φ_o + 2π x (measured from wo's
    /// azimuth). Each cell weighs dω_i = 4 (wo·h) J(v) Δx Δv with
    /// J = (π v)(2π) sin θ_h; half vectors that reflect wo to or below the
    /// horizon are left out. Rows crowd near θ_h = 0, where the specular
    /// peaks of measured materials are narrow; with counts that are
    /// multiples of a tabulation's (256 θ_h × 32 φ_h), the cells nest in
    /// its cells for a one-slice isotropic sampler.
    HalfVector { n_v: usize, n_x: usize },
}

impl HemisphereGrid {
    /// The number of cells.
    pub fn cells(&self) -> usize {
        match *self {
            HemisphereGrid::EqualArea { n_cos, n_phi } => n_cos.max(1) * n_phi.max(1),
            HemisphereGrid::HalfVector { n_v, n_x } => n_v.max(1) * n_x.max(1),
        }
    }

    /// Call `each(wi, dω)` for every cell centre whose incident direction is
    /// above the horizon, row by row.
    fn for_each_point(&self, wo: Vec3, mut each: impl FnMut(Vec3, f64)) {
        match *self {
            HemisphereGrid::EqualArea { n_cos, n_phi } => {
                let (n_cos, n_phi) = (n_cos.max(1), n_phi.max(1));
                let d_omega = TAU / (n_cos * n_phi) as f64;
                for k in 0..n_cos {
                    let cos_t = (k as f64 + 0.5) / n_cos as f64;
                    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                    for l in 0..n_phi {
                        let phi = TAU * (l as f64 + 0.5) / n_phi as f64;
                        let wi = Vec3::new(
                            (sin_t * phi.cos()) as f32,
                            (sin_t * phi.sin()) as f32,
                            cos_t as f32,
                        );
                        each(wi, d_omega);
                    }
                }
            }
            HemisphereGrid::HalfVector { n_v, n_x } => {
                let (n_v, n_x) = (n_v.max(1), n_x.max(1));
                let (ox, oy, oz) = (wo.x as f64, wo.y as f64, wo.z as f64);
                let len = (ox * ox + oy * oy + oz * oz).sqrt();
                if !(len > 0.0 && len.is_finite()) {
                    return;
                }
                let (ox, oy, oz) = (ox / len, oy / len, oz / len);
                let phi_o = if ox == 0.0 && oy == 0.0 {
                    0.0
                } else {
                    oy.atan2(ox)
                };
                let cell = 1.0 / (n_v * n_x) as f64;
                for iv in 0..n_v {
                    let v = (iv as f64 + 0.5) / n_v as f64;
                    let theta_h = FRAC_PI_2 * v * v;
                    let (sin_h, cos_h) = theta_h.sin_cos();
                    let jacobian = PI * v * TAU * sin_h;
                    for ix in 0..n_x {
                        let phi = phi_o + TAU * (ix as f64 + 0.5) / n_x as f64;
                        let (hx, hy, hz) = (sin_h * phi.cos(), sin_h * phi.sin(), cos_h);
                        let wo_h = ox * hx + oy * hy + oz * hz;
                        if wo_h.is_nan() || wo_h <= 0.0 {
                            continue;
                        }
                        let wi = (
                            2.0 * wo_h * hx - ox,
                            2.0 * wo_h * hy - oy,
                            2.0 * wo_h * hz - oz,
                        );
                        if wi.2.is_nan() || wi.2 <= 0.0 {
                            continue;
                        }
                        let wi = Vec3::new(wi.0 as f32, wi.1 as f32, wi.2 as f32);
                        each(wi, 4.0 * wo_h * jacobian * cell);
                    }
                }
            }
        }
    }
}

/// The points of a [`HemisphereGrid`] at which a BRDF reflects light
/// towards one outgoing direction (see the module documentation).
#[derive(Debug, Clone)]
pub struct Integrand {
    wo: Vec3,
    wi: Vec<Vec3>,
    /// dω of each point.
    solid_angle: Vec<f64>,
    /// g_Y = Y(f) cos θ_i at each point.
    reflected: Vec<f64>,
    /// g_L = Y(f ⊙ L) cos θ_i at each point (g_Y without a light).
    lit: Vec<f64>,
}

/// Points handed to [`BxdfSampler::pdf_batch`] at once.
const CHUNK: usize = 512;

impl Integrand {
    /// The integrand of `brdf` at `wo` on `grid`, under `light` (the
    /// radiance arriving from each incident direction of the local frame;
    /// `None` weighs every direction by 1 and needs only the BRDF's
    /// luminance). Points where g_Y is not positive and finite are left out.
    pub fn new(
        brdf: &dyn Brdf,
        wo: Vec3,
        grid: HemisphereGrid,
        light: Option<&dyn Fn(Vec3) -> Rgb>,
    ) -> Integrand {
        let mut out = Integrand {
            wo,
            wi: Vec::new(),
            solid_angle: Vec::new(),
            reflected: Vec::new(),
            lit: Vec::new(),
        };
        grid.for_each_point(wo, |wi, d_omega| {
            let cos = wi.z as f64;
            let (g, g_lit) = match light {
                None => {
                    let g = brdf.luminance(wo, wi) as f64 * cos;
                    (g, g)
                }
                Some(light) => {
                    let f = brdf.eval(wo, wi);
                    (
                        luminance(f) as f64 * cos,
                        luminance(f * light(wi)) as f64 * cos,
                    )
                }
            };
            if !(g.is_finite() && g > 0.0) {
                return;
            }
            out.wi.push(wi);
            out.solid_angle.push(d_omega);
            out.reflected.push(g);
            out.lit.push(if g_lit.is_finite() {
                g_lit.max(0.0)
            } else {
                0.0
            });
        });
        out
    }

    /// The outgoing direction.
    pub fn wo(&self) -> Vec3 {
        self.wo
    }

    /// The number of points kept (those where the BRDF reflects light).
    pub fn len(&self) -> usize {
        self.wi.len()
    }

    /// Whether the BRDF reflects nothing towards wo on the grid.
    pub fn is_empty(&self) -> bool {
        self.wi.is_empty()
    }

    /// ∫ g_L dω: the reflected luminance the estimator estimates.
    pub fn integral(&self) -> f64 {
        self.lit
            .iter()
            .zip(&self.solid_angle)
            .map(|(g, d)| g * d)
            .sum()
    }

    /// The moments of `sampler` on this integrand (module documentation).
    pub fn moments(&self, sampler: &dyn BxdfSampler) -> Moments {
        let mut m = Moments::default();
        let mut worst: Option<(f64, Vec3)> = None;
        let mut pdf = vec![0.0f32; CHUNK];
        for (start, wi) in (0..self.wi.len()).step_by(CHUNK).zip(self.wi.chunks(CHUNK)) {
            let pdf = &mut pdf[..wi.len()];
            sampler.pdf_batch(self.wo, wi, pdf);
            for (k, &p) in pdf.iter().enumerate() {
                let i = start + k;
                let (g, g_lit, d_omega) = (self.reflected[i], self.lit[i], self.solid_angle[i]);
                m.reflected += g * d_omega;
                m.integral += g_lit * d_omega;
                // A NaN density draws nothing either.
                if !(p > 0.0 && p.is_finite()) {
                    m.missed += g * d_omega;
                    if worst.is_none_or(|(largest, _)| g > largest) {
                        worst = Some((g, wi[k]));
                    }
                    continue;
                }
                let p = p as f64;
                let y = g_lit / p;
                m.mean += g_lit * d_omega;
                m.second_moment += g_lit * y * d_omega;
                m.third_moment += g_lit * y * y * d_omega;
                m.fourth_moment += g_lit * y * y * y * d_omega;
                m.max_weight = m.max_weight.max(g / p);
            }
        }
        m.worst_missed = worst.map(|(_, wi)| wi);
        m
    }
}

/// What [`Integrand::moments`] finds for one sampler: integrals over the
/// grid (module documentation), all finite and non-negative.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Moments {
    /// ∫ g_Y dω = ∫ Y(f) cos θ_i dω: the luminance albedo.
    pub reflected: f64,
    /// ∫_{p=0} g_Y dω: the part of it the sampler never draws.
    pub missed: f64,
    /// The incident direction of the largest missed g_Y, if any.
    pub worst_missed: Option<Vec3>,
    /// ∫ g_L dω: what the estimator estimates.
    pub integral: f64,
    /// ∫_{p>0} g_L dω: the estimator's mean.
    pub mean: f64,
    /// ∫_{p>0} g_L² / p dω: the estimator's second moment.
    pub second_moment: f64,
    /// ∫_{p>0} g_L³ / p² dω and ∫_{p>0} g_L⁴ / p³ dω: its third and fourth
    /// moments, which set how precisely n draws estimate its variance.
    pub third_moment: f64,
    pub fourth_moment: f64,
    /// The largest g_Y / p over the grid's points with p > 0.
    pub max_weight: f64,
}

impl Moments {
    /// missed / reflected; 0 when the BRDF reflects nothing.
    pub fn missed_share(&self) -> f64 {
        if self.reflected > 0.0 {
            self.missed / self.reflected
        } else {
            0.0
        }
    }

    /// The variance of the one-sample estimator, second moment − mean²
    /// (clamped at 0 against rounding).
    pub fn variance(&self) -> f64 {
        (self.second_moment - self.mean * self.mean).max(0.0)
    }

    /// variance / integral²: the variance of the estimator relative to the
    /// square of what it estimates, which N samples divide by N. 0 when
    /// nothing is reflected.
    pub fn relative_variance(&self) -> f64 {
        if self.integral > 0.0 {
            self.variance() / (self.integral * self.integral)
        } else {
            0.0
        }
    }

    /// The standard error of the sample variance of `n` draws of the
    /// estimator, relative to the variance: sqrt(Var(s²)) / Var with
    /// Var(s²) = (μ₄ − σ⁴ (n − 3)/(n − 1)) / n, the central fourth moment
    /// μ₄ taken from the raw moments (a failed draw counts 0). This is the
    /// error
    /// a Monte Carlo estimate of the variance really has, including the
    /// part of it that comes from draws too rare to appear among n; an
    /// estimate of μ₄ from the draws themselves cannot see those. 0 when
    /// the variance is 0.
    pub fn variance_rel_se(&self, n: usize) -> f64 {
        let var = self.variance();
        if var.is_nan() || var <= 0.0 || n < 4 {
            return 0.0;
        }
        let mu = self.mean;
        // The raw moments already count a failed draw as 0.
        let mu4 = self.fourth_moment - 4.0 * mu * self.third_moment
            + 6.0 * mu * mu * self.second_moment
            - 3.0 * mu.powi(4);
        let nf = n as f64;
        let var_s2 = ((mu4 - var * var * (nf - 3.0) / (nf - 1.0)) / nf).max(0.0);
        var_s2.sqrt() / var
    }

    /// The largest weight relative to the mean weight:
    /// max g_Y / p ÷ ∫_{p>0} g_Y dω (the mean of g_Y / p over the
    /// sampler's draws). 1 for a sampler whose density is proportional to
    /// f cos θ_i; 0 when the sampler draws nothing the BRDF reflects.
    pub fn firefly(&self) -> f64 {
        let drawn = self.reflected - self.missed;
        if drawn > 0.0 {
            self.max_weight / drawn
        } else {
            0.0
        }
    }
}

/// The share of the reflected luminance that `sampler` can never draw: the
/// result of [`missed_share`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissedShare {
    /// ∫_{p = 0} Y(f) cos θ_i dω / ∫ Y(f) cos θ_i dω; 0 when the BRDF
    /// reflects nothing at wo.
    pub share: f64,
    /// The incident direction of the largest missed term, if any.
    pub worst: Option<Vec3>,
}

/// The share of the reflected luminance that `sampler` can never draw at
/// `wo`, ∫_{p = 0} Y(f) cos θ_i dω / ∫ Y(f) cos θ_i dω over the upper
/// hemisphere (f = `brdf.eval`, p = `sampler.pdf`, Y the luminance), by the
/// midpoint rule on `n_cos` × `n_phi` cells of equal solid angle
/// ([`HemisphereGrid::EqualArea`]).
///
/// An unbiased estimator of the light reflected towards wo needs p > 0
/// wherever f cos θ_i > 0: the share is the fraction by which a sampler
/// used alone is biased dark, whatever the sample count, and neither a
/// chi-square test nor the integral of the pdf sees it (sample and pdf
/// still agree). Deterministic: the cells are summed in a fixed order.
pub fn missed_share(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    wo: Vec3,
    n_cos: usize,
    n_phi: usize,
) -> MissedShare {
    let m =
        Integrand::new(brdf, wo, HemisphereGrid::EqualArea { n_cos, n_phi }, None).moments(sampler);
    MissedShare {
        share: m.missed_share(),
        worst: m.worst_missed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::spherical_direction;
    use crate::BxdfSample;
    use glam::Vec2;

    /// f_r = c cos^(k-1) θ_i: f cos θ_i ∝ cos^k θ_i.
    struct PowerCosine {
        k: i32,
        c: f32,
    }
    impl Brdf for PowerCosine {
        fn name(&self) -> &str {
            "power-cosine"
        }
        fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
            if wo.z > 0.0 && wi.z > 0.0 {
                Rgb::splat(self.c * wi.z.powi(self.k - 1))
            } else {
                Rgb::ZERO
            }
        }
        fn is_isotropic(&self) -> bool {
            true
        }
    }

    /// p = (k + 1) / (2π) cos^k θ_i, drawn by cos θ = u^(1/(k+1)).
    struct PowerCosineSampler {
        k: i32,
    }
    impl BxdfSampler for PowerCosineSampler {
        fn name(&self) -> &str {
            "power-cosine"
        }
        fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
            let cos = u.x.powf(1.0 / (self.k + 1) as f32);
            let wi = spherical_direction(cos.acos(), TAU as f32 * u.y);
            Some(BxdfSample {
                wi,
                pdf: self.pdf(wo, wi),
            })
        }
        fn pdf(&self, _wo: Vec3, wi: Vec3) -> f32 {
            if wi.z > 0.0 {
                (self.k + 1) as f32 / TAU as f32 * wi.z.powi(self.k)
            } else {
                0.0
            }
        }
        fn storage_bytes(&self) -> usize {
            0
        }
    }

    /// p = 1 / (2π) on the upper hemisphere.
    struct UniformHemisphere;
    impl BxdfSampler for UniformHemisphere {
        fn name(&self) -> &str {
            "uniform-hemisphere"
        }
        fn sample(&self, _wo: Vec3, _u: Vec2) -> Option<BxdfSample> {
            None
        }
        fn pdf(&self, _wo: Vec3, wi: Vec3) -> f32 {
            if wi.z > 0.0 {
                1.0 / TAU as f32
            } else {
                0.0
            }
        }
        fn storage_bytes(&self) -> usize {
            0
        }
    }

    const GRIDS: [HemisphereGrid; 2] = [
        HemisphereGrid::EqualArea {
            n_cos: 256,
            n_phi: 512,
        },
        HemisphereGrid::HalfVector { n_v: 512, n_x: 128 },
    ];

    /// Both grids cover the hemisphere: the solid angles add up to 2π (to
    /// 1e-3: the horizon cuts half-vector cells) and ∫ cos θ_i dω to π.
    #[test]
    fn grids_cover_the_hemisphere() {
        let one = PowerCosine { k: 1, c: 1.0 };
        for grid in GRIDS {
            for theta in [0.0f32, 0.5, 1.2, 1.5] {
                let wo = spherical_direction(theta, 0.7);
                let q = Integrand::new(&one, wo, grid, None);
                let area: f64 = q.solid_angle.iter().sum();
                assert!((area - TAU).abs() < 1e-3 * TAU, "{grid:?} {theta}: {area}");
                assert!(
                    (q.integral() - PI).abs() < 1e-4,
                    "{grid:?}: {}",
                    q.integral()
                );
            }
        }
    }

    /// A density proportional to f cos θ_i gives the weight the same value
    /// everywhere: relative variance 0 up to the quadrature's relative
    /// error in ∫ f cos θ_i (the variance is c ∫g − (∫g)² with c the exact
    /// integral), at most 1.3e-5 here; for Lambert on the equal-area grid,
    /// where the midpoint rule is exact, 0 to the f32 rounding of f and p.
    /// The firefly measure is 1.
    #[test]
    fn a_density_proportional_to_the_integrand_has_no_variance() {
        for k in [1, 4] {
            let brdf = PowerCosine { k, c: 0.3 };
            let sampler = PowerCosineSampler { k };
            for grid in GRIDS {
                let wo = spherical_direction(0.6, 2.0);
                let m = Integrand::new(&brdf, wo, grid, None).moments(&sampler);
                assert!(m.relative_variance() < 2e-5, "{k} {grid:?}: {m:?}");
                if k == 1 && matches!(grid, HemisphereGrid::EqualArea { .. }) {
                    assert!(m.relative_variance() < 1e-6, "{m:?}");
                }
                assert!((m.firefly() - 1.0).abs() < 1e-3, "{k} {grid:?}: {m:?}");
                assert_eq!(m.missed, 0.0);
            }
        }
    }

    /// A constant density 1/(2π) for a Lambertian f cos θ_i = ρ cos θ_i / π:
    /// E[Y²] = ∫ (ρ cos/π)² 2π dω = 4ρ²/3, so Var/ρ² = 1/3; the largest
    /// weight is 2ρ cos θ_i → 2ρ against the mean ρ.
    #[test]
    fn a_constant_density_for_lambert_has_relative_variance_one_third() {
        let lambert = PowerCosine {
            k: 1,
            c: 0.8 / PI as f32,
        };
        for grid in GRIDS {
            let m = Integrand::new(&lambert, spherical_direction(0.3, 0.0), grid, None)
                .moments(&UniformHemisphere);
            assert!(
                (m.relative_variance() - 1.0 / 3.0).abs() < 1e-4,
                "{grid:?}: {}",
                m.relative_variance()
            );
            assert!(
                (m.firefly() - 2.0).abs() < 1e-2,
                "{grid:?}: {}",
                m.firefly()
            );
        }
    }

    /// A light multiplies the integrand channel by channel: under white
    /// light of radiance 2 the integral doubles and the relative variance
    /// stays.
    #[test]
    fn a_light_scales_the_integral() {
        let brdf = PowerCosine { k: 3, c: 0.2 };
        let wo = spherical_direction(0.4, 1.0);
        let grid = GRIDS[1];
        let dark = Integrand::new(&brdf, wo, grid, None).moments(&UniformHemisphere);
        let two = |_: Vec3| Rgb::splat(2.0);
        let lit = Integrand::new(&brdf, wo, grid, Some(&two)).moments(&UniformHemisphere);
        assert!((lit.integral - 2.0 * dark.integral).abs() < 1e-9 * lit.integral);
        assert!((lit.relative_variance() - dark.relative_variance()).abs() < 1e-9);
        assert_eq!(lit.reflected, dark.reflected);
    }

    /// A density that is 0 on half the hemisphere (φ_i in [0, π)) misses
    /// half of an isotropic integrand.
    #[test]
    fn a_density_with_a_hole_misses_its_share() {
        struct Half;
        impl BxdfSampler for Half {
            fn name(&self) -> &str {
                "half"
            }
            fn sample(&self, _wo: Vec3, _u: Vec2) -> Option<BxdfSample> {
                None
            }
            fn pdf(&self, _wo: Vec3, wi: Vec3) -> f32 {
                if wi.z > 0.0 && wi.y < 0.0 {
                    1.0 / PI as f32
                } else {
                    0.0
                }
            }
            fn storage_bytes(&self) -> usize {
                0
            }
        }
        let lambert = PowerCosine { k: 1, c: 0.5 };
        let share = missed_share(&lambert, &Half, Vec3::Z, 64, 128);
        assert!((share.share - 0.5).abs() < 1e-9, "{share:?}");
        assert!(share.worst.is_some_and(|w| w.y >= 0.0));
    }
}
