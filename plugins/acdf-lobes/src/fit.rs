//! The fit of a mixture to a material.
//!
//! For an outgoing direction wo, drawing wi from a density p and weighing
//! it by g(wi) / p(wi), g = Y(f_r(wo, wi)) cos θ_i (Y the luminance), has
//! relative variance ∫ g² / p dω / (∫ g dω)² − 1: the chi-square divergence
//! between g / ∫ g dω and p. The fit minimises its mean over a fixed set of
//! outgoing directions ([`FitOptions::theta_o_degrees`], at one azimuth for
//! an isotropic material and three for an anisotropic one), each integral
//! taken by the deterministic midpoint rule of
//! [`acdf_core::quadrature::Integrand`] on half-vector cells, which crowd
//! near the specular peak.
//!
//! The parameters searched are, for n GGX lobes, the n values ln α_k and n
//! logits s_k of a softmax whose cosine-lobe logit is 0: the weights are
//! w_d = m + (1 − m) q_0 and w_k = (1 − m) q_k, q the softmax and m
//! [`MIN_DIFFUSE`]. One lobe starts from the best of a
//! grid of α and weights, each further lobe from the best fit with one lobe
//! fewer and a new lobe sharper or broader than the others; each is
//! refined by Nelder–Mead for a fixed number of iterations. Every step is
//! deterministic (fixed starts, sums in a fixed order, ties broken by
//! position), so a material always gets the same bits.
//!
//! The lobe count, from none (cosine sampling alone) to [`MAX_LOBES`], is
//! the one of least objective times [`FitOptions::draw_cost`], the time a
//! draw takes with that many lobes: the product is the inverse of the
//! sampler's efficiency, as `acdf report` measures it. A further lobe is
//! also required to lower that product by [`FitOptions::min_gain`]. A
//! matte material keeps no lobe: there a GGX lobe lowers the variance by
//! a few percent and doubles the time of a draw.

use crate::{Lobes, Mixture, ALPHA_MAX, ALPHA_MIN, MAX_LOBES, MIN_DIFFUSE};
use acdf_core::geometry::spherical_direction;
use acdf_core::{Brdf, Error, HemisphereGrid, Integrand, Result};

/// What the fit looks at and how long it searches.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// θ_o of the outgoing directions whose mean relative variance is
    /// minimised, in degrees.
    pub theta_o_degrees: Vec<f32>,
    /// The quadrature cells per outgoing direction.
    pub grid: HemisphereGrid,
    /// Nelder–Mead iterations per searched parameter.
    pub iterations_per_parameter: usize,
    /// The relative decrease of objective × draw cost a further lobe must
    /// bring.
    pub min_gain: f64,
    /// The time of a draw (sample and density) with 0 to [`MAX_LOBES`] GGX
    /// lobes, relative to none.
    pub draw_cost: [f64; MAX_LOBES + 1],
}

impl Default for FitOptions {
    /// θ_o 10, 30, 50, 70 and 85°; 256 θ_h rows × 32 φ_h columns; 40
    /// iterations per parameter; a further lobe must gain 2%; a draw with
    /// GGX lobes takes twice the time of one without, whatever their
    /// number (the ns/sample of `acdf report --samples 0 --sampler lobes`
    /// over the 100 MERL materials: 16 to 18 with none, 27 to 59 with one
    /// to three; `docs/results.md`).
    fn default() -> Self {
        FitOptions {
            theta_o_degrees: vec![10.0, 30.0, 50.0, 70.0, 85.0],
            grid: HemisphereGrid::HalfVector { n_v: 256, n_x: 32 },
            iterations_per_parameter: 40,
            min_gain: 0.02,
            draw_cost: [1.0, 2.0, 2.0, 2.0],
        }
    }
}

/// The outcome of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// The mixture chosen.
    pub lobes: Lobes,
    /// Its mean relative variance over the fit's directions.
    pub objective: f64,
    /// The best objective found with 0 (cosine sampling), 1, 2 and 3 GGX
    /// lobes.
    pub by_count: [f64; MAX_LOBES + 1],
    /// How many mixtures the search evaluated.
    pub evaluations: usize,
}

/// Fit a mixture to `brdf` with the default options.
pub fn fit(brdf: &dyn Brdf) -> Result<Lobes> {
    fit_with(brdf, &FitOptions::default()).map(|f| f.lobes)
}

/// The fit's objective for given lobes: their mean relative variance over
/// the directions of `options` (module documentation).
pub fn objective(brdf: &dyn Brdf, lobes: &Lobes, options: &FitOptions) -> Result<f64> {
    Ok(Objective::new(brdf, options)?.value(lobes))
}

/// The integrands of the fit's directions and the count of evaluations.
struct Objective {
    integrands: Vec<Integrand>,
    evaluations: usize,
}

impl Objective {
    fn new(brdf: &dyn Brdf, options: &FitOptions) -> Result<Objective> {
        let phis: &[f32] = if brdf.is_isotropic() {
            &[0.0]
        } else {
            &[
                0.0,
                std::f32::consts::TAU / 3.0,
                2.0 * std::f32::consts::TAU / 3.0,
            ]
        };
        let mut integrands = Vec::new();
        for &theta in &options.theta_o_degrees {
            if !(theta.is_finite() && (0.0..90.0).contains(&theta)) {
                return Err(Error::InvalidParameter {
                    name: "theta_o_degrees",
                    reason: format!("{theta}° is not in [0, 90)"),
                });
            }
            for &phi in phis {
                let wo = spherical_direction(theta.to_radians(), phi);
                let integrand = Integrand::new(brdf, wo, options.grid, None);
                if integrand.integral() > 0.0 && integrand.integral().is_finite() {
                    integrands.push(integrand);
                }
            }
        }
        if integrands.is_empty() {
            return Err(Error::ZeroMaterial {
                material: brdf.name().to_string(),
            });
        }
        Ok(Objective {
            integrands,
            evaluations: 0,
        })
    }

    /// The mean relative variance of `lobes`; +∞ for anything not finite.
    fn value(&mut self, lobes: &Lobes) -> f64 {
        self.evaluations += 1;
        let mixture = Mixture::new(*lobes);
        let sum: f64 = self
            .integrands
            .iter()
            .map(|i| i.moments(&mixture).relative_variance())
            .sum();
        let mean = sum / self.integrands.len() as f64;
        if mean.is_finite() {
            mean
        } else {
            f64::INFINITY
        }
    }

    /// [`value`](Self::value) of the mixture the search point `x` stands for.
    fn at(&mut self, x: &[f64]) -> f64 {
        match decode(x) {
            Ok(lobes) => self.value(&lobes),
            Err(_) => f64::INFINITY,
        }
    }
}

/// The mixture of a search point: n values ln α, then n logits.
fn decode(x: &[f64]) -> Result<Lobes> {
    let n = x.len() / 2;
    let (ln_alpha, logits) = x.split_at(n);
    let clamp_logit = |s: f64| {
        if s.is_nan() {
            0.0
        } else {
            s.clamp(-40.0, 40.0)
        }
    };
    let exps: Vec<f64> = logits.iter().map(|&s| clamp_logit(s).exp()).collect();
    let total = 1.0 + exps.iter().sum::<f64>();
    let m = MIN_DIFFUSE as f64;
    let diffuse = (m + (1.0 - m) / total) as f32;
    let lobes: Vec<(f32, f32)> = ln_alpha
        .iter()
        .zip(&exps)
        .map(|(&a, &e)| {
            let alpha = if a.is_nan() { 0.0 } else { a.exp() as f32 };
            (
                ((1.0 - m) * e / total) as f32,
                alpha.clamp(ALPHA_MIN, ALPHA_MAX),
            )
        })
        .collect();
    Lobes::new(diffuse.max(MIN_DIFFUSE), &lobes)
}

/// Fit a mixture to `brdf` (module documentation).
pub fn fit_with(brdf: &dyn Brdf, options: &FitOptions) -> Result<Fit> {
    if !options.draw_cost.iter().all(|&c| c > 0.0 && c.is_finite()) {
        return Err(Error::InvalidParameter {
            name: "draw_cost",
            reason: format!("{:?} are not all positive and finite", options.draw_cost),
        });
    }
    let mut objective = Objective::new(brdf, options)?;
    let mut by_count = [f64::INFINITY; MAX_LOBES + 1];
    // No GGX lobe: the search point with no parameters.
    let mut best: Vec<(Vec<f64>, f64)> = vec![(Vec::new(), objective.at(&[]))];
    by_count[0] = best[0].1;

    // One lobe: the best of a grid of α and shares, refined.
    let mut start = (Vec::new(), f64::INFINITY);
    for i in 0..12 {
        let alpha = 0.002f64 * (500.0f64).powf(i as f64 / 11.0);
        for share in [0.3f64, 0.7, 0.95] {
            let x = vec![alpha.ln(), (share / (1.0 - share)).ln()];
            let value = objective.at(&x);
            if value < start.1 {
                start = (x, value);
            }
        }
    }
    for n in 1..=MAX_LOBES {
        if n > 1 {
            start = extend(&mut objective, &best[n - 1].0);
        }
        let iterations = options.iterations_per_parameter * 2 * n;
        let refined = nelder_mead(|x| objective.at(x), &start.0, iterations);
        let refined = if refined.1 <= start.1 {
            refined
        } else {
            start.clone()
        };
        by_count[n] = refined.1;
        best.push(refined);
    }
    let cost = |n: usize| best[n].1 * options.draw_cost[n];
    let mut chosen = 0;
    for n in 1..=MAX_LOBES {
        if cost(n) < cost(chosen) * (1.0 - options.min_gain) {
            chosen = n;
        }
    }
    let (x, value) = &best[chosen];
    Ok(Fit {
        lobes: decode(x)?,
        objective: *value,
        by_count,
        evaluations: objective.evaluations,
    })
}

/// The start of a search with one lobe more than the point `x`: the best
/// of `x` with a lobe 6 or 2.5 times sharper than its sharpest or broader
/// than its broadest, of a quarter of its heaviest lobe's weight.
fn extend(objective: &mut Objective, x: &[f64]) -> (Vec<f64>, f64) {
    let n = x.len() / 2;
    let (ln_alpha, logits) = x.split_at(n);
    let sharpest = ln_alpha.iter().copied().fold(f64::INFINITY, f64::min);
    let broadest = ln_alpha.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let heaviest = logits.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (lo, hi) = ((ALPHA_MIN as f64).ln(), (ALPHA_MAX as f64).ln());
    let mut out = (Vec::new(), f64::INFINITY);
    for new_ln_alpha in [
        sharpest - 6f64.ln(),
        sharpest - 2.5f64.ln(),
        broadest + 2.5f64.ln(),
        broadest + 6f64.ln(),
    ] {
        let mut y: Vec<f64> = ln_alpha.to_vec();
        y.push(new_ln_alpha.clamp(lo, hi));
        y.extend_from_slice(logits);
        y.push(heaviest + 0.25f64.ln());
        let value = objective.at(&y);
        if value < out.1 {
            out = (y, value);
        }
    }
    out
}

/// Minimise `f` from `x0` by Nelder–Mead (reflection 1, expansion 2,
/// contraction and shrink ½) for `iterations` iterations, from a simplex of
/// steps of 0.5 along each axis; returns the best vertex and its value.
fn nelder_mead(mut f: impl FnMut(&[f64]) -> f64, x0: &[f64], iterations: usize) -> (Vec<f64>, f64) {
    let d = x0.len();
    let mut simplex: Vec<(Vec<f64>, f64)> = Vec::with_capacity(d + 1);
    simplex.push((x0.to_vec(), f(x0)));
    for i in 0..d {
        let mut x = x0.to_vec();
        x[i] += 0.5;
        let value = f(&x);
        simplex.push((x, value));
    }
    let along = |c: &[f64], towards: &[f64], t: f64| -> Vec<f64> {
        c.iter()
            .zip(towards)
            .map(|(a, b)| a + t * (b - a))
            .collect()
    };
    for _ in 0..iterations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let mut centroid = vec![0.0; d];
        for (x, _) in &simplex[..d] {
            for (c, v) in centroid.iter_mut().zip(x) {
                *c += v / d as f64;
            }
        }
        let (worst, f_worst) = simplex[d].clone();
        let (f_best, f_second) = (simplex[0].1, simplex[d - 1].1);
        let reflected = along(&centroid, &worst, -1.0);
        let f_reflected = f(&reflected);
        if f_reflected < f_best {
            let expanded = along(&centroid, &worst, -2.0);
            let f_expanded = f(&expanded);
            simplex[d] = if f_expanded < f_reflected {
                (expanded, f_expanded)
            } else {
                (reflected, f_reflected)
            };
        } else if f_reflected < f_second {
            simplex[d] = (reflected, f_reflected);
        } else {
            let (contracted, bound) = if f_reflected < f_worst {
                (along(&centroid, &reflected, 0.5), f_reflected)
            } else {
                (along(&centroid, &worst, 0.5), f_worst)
            };
            let f_contracted = f(&contracted);
            if f_contracted < bound {
                simplex[d] = (contracted, f_contracted);
            } else {
                let best = simplex[0].0.clone();
                for vertex in simplex.iter_mut().skip(1) {
                    let x = along(&best, &vertex.0, 0.5);
                    let value = f(&x);
                    *vertex = (x, value);
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex.swap_remove(0)
}
