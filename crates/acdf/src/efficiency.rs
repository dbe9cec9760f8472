//! Estimator efficiency: how much a sampler's importance sampling is worth per
//! second of work.
//!
//! Fix an environment light L (in `acdf report` and `acdf sweep`, the
//! procedural sky without its sun, [`Sky::dome`](crate::env::Sky::dome)),
//! a surface whose normal points up (world `+y`) and a set of outgoing
//! directions ω_o,j. For each ω_o,j draw ω_i,k from the sampler and form the
//! one-sample estimator of the reflected luminance
//!
//! Y_k = Y( f_r(ω_o, ω_i,k) ⊙ L(ω_i,k) ) · cos θ_i,k / p(ω_i,k),
//!
//! where Y is the Rec. 709 luminance and ⊙ the product per channel; a draw
//! that fails (`None`) contributes Y_k = 0. With s²_j the unbiased sample
//! variance of the Y_k for ω_o,j, the **variance** is V = (1/J) Σ_j s²_j.
//!
//! The **time per sample** is t = t_sample + v·(t_eval + t_pdf), measured on
//! one thread after every table is built: t_sample is the mean time of one
//! `sample` call over 12 × `timing_samples_per_direction` draws, t_eval of one
//! BRDF evaluation and t_pdf of one `pdf` call at the directions those draws
//! returned, and v is the fraction of draws that succeed (a failed draw needs
//! neither). Each of the three is the fastest of
//! [`timing_passes`](EfficiencyConfig::timing_passes) timed passes, which
//! discounts interference from other processes. [`measure_efficiencies`]
//! (the results table) times several samplers in turns, one pass of each
//! per round, so that a change of the machine's speed during the run (its
//! clock, other tenants) reaches them all alike and the ratios of their
//! times hold. Timed one after another instead, a sampler timed while the
//! clock drops is charged for it.
//! The environment lookup is not included: it is the same for every
//! sampler.
//!
//! The **efficiency** is 1 / (V · t), in 1/s (for luminance in units of the
//! environment's radiance); reports also divide it by the efficiency of the
//! uniform tabulated sampler.

use std::hint::black_box;
use std::time::Instant;

use acdf_core::{luminance, Brdf, BxdfSampler, Frame, Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

use crate::env::Environment;

/// The outgoing directions of every efficiency measurement: θ_o ∈ {10°, 30°,
/// 50°, 70°} × φ_o ∈ {0°, 120°, 240°}, in the local shading frame.
pub fn standard_outgoing_directions() -> Vec<Vec3> {
    let mut out = Vec::with_capacity(12);
    for theta in [10.0f32, 30.0, 50.0, 70.0] {
        for phi in [0.0f32, 120.0, 240.0] {
            out.push(acdf_core::geometry::spherical_direction(
                theta.to_radians(),
                phi.to_radians(),
            ));
        }
    }
    out
}

/// The shading frame of the measured surface: its normal is world `+y`, so it
/// faces the sky.
pub fn standard_frame() -> Frame {
    Frame::from_z(Vec3::Y)
}

/// What to measure with.
#[derive(Debug, Clone)]
pub struct EfficiencyConfig {
    /// Outgoing directions ω_o,j in the local frame (each with ω_o.z > 0).
    pub outgoing: Vec<Vec3>,
    /// The local shading frame in world space.
    pub frame: Frame,
    /// Draws per outgoing direction for the variance.
    pub samples_per_direction: usize,
    /// Draws per outgoing direction for each timed pass.
    pub timing_samples_per_direction: usize,
    /// Timed passes per sampler, the fastest kept (at least 1).
    pub timing_passes: usize,
    /// Seed of the uniform numbers; the same for every sampler (common random
    /// numbers), so differences come from the samplers.
    pub seed: u64,
}

impl Default for EfficiencyConfig {
    /// 12 standard directions × 2^17 draws for the variance (1.6 M draws; the
    /// relative standard error of V is printed with it), 2^13 timed draws per
    /// direction, the fastest of three passes.
    fn default() -> Self {
        EfficiencyConfig {
            outgoing: standard_outgoing_directions(),
            frame: standard_frame(),
            samples_per_direction: 1 << 17,
            timing_samples_per_direction: 1 << 13,
            timing_passes: 3,
            seed: 2005,
        }
    }
}

impl EfficiencyConfig {
    /// Total draws behind the variance estimate.
    pub fn total_samples(&self) -> usize {
        self.outgoing.len() * self.samples_per_direction
    }
}

/// Per-call times, in seconds, of the three operations a sample costs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Timing {
    /// Mean time of one `sample` call.
    pub seconds_per_draw: f64,
    /// Mean time of one `pdf` call at a drawn direction.
    pub seconds_per_pdf: f64,
    /// Mean time of one BRDF evaluation at a drawn direction.
    pub seconds_per_eval: f64,
    /// Fraction of draws that returned a direction.
    pub valid_fraction: f64,
}

impl Timing {
    /// t = t_sample + v·(t_eval + t_pdf).
    pub fn seconds_per_sample(&self) -> f64 {
        self.seconds_per_draw + self.valid_fraction * (self.seconds_per_eval + self.seconds_per_pdf)
    }
}

/// The outcome of [`measure_efficiency`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Efficiency {
    /// The sampler's name.
    pub sampler: String,
    /// (1/J) Σ_j mean_k Y_k: the reflected luminance averaged over the
    /// outgoing directions (equal for all unbiased samplers up to noise).
    pub estimate: f64,
    /// Standard error of `estimate`.
    pub estimate_se: f64,
    /// V = (1/J) Σ_j s²_j.
    pub variance: f64,
    /// Relative standard error of V (from the fourth moments).
    pub variance_rel_se: f64,
    /// Draws behind V.
    pub samples: usize,
    /// The per-call times.
    pub timing: Timing,
    /// t = t_sample + v·(t_eval + t_pdf).
    pub seconds_per_sample: f64,
    /// 1 / (V·t).
    pub efficiency: f64,
}

/// Moments of the estimator for one outgoing direction.
struct DirectionMoments {
    mean: f64,
    variance: f64,
    /// Var(s²) ≈ (m4 − s⁴ (n−3)/(n−1)) / n.
    variance_of_variance: f64,
}

fn uniform_pairs(seed: u64, stream: usize, n: usize) -> Vec<Vec2> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(
        seed ^ (stream as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15),
    );
    (0..n)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect()
}

/// Y_k for one draw: Y(f ⊙ L) cos θ_i / p, or 0 for a failed draw.
#[inline]
fn luminance_estimate(
    brdf: &dyn Brdf,
    env: &dyn Environment,
    frame: &Frame,
    wo: Vec3,
    wi: Vec3,
    pdf: f32,
) -> f64 {
    if pdf <= 0.0 || !pdf.is_finite() {
        return 0.0;
    }
    let f = brdf.eval(wo, wi);
    let l = env.radiance(frame.to_world(wi));
    let y = luminance(f * l) as f64 * wi.z.max(0.0) as f64 / pdf as f64;
    if y.is_finite() {
        y
    } else {
        0.0
    }
}

fn direction_moments(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    env: &dyn Environment,
    frame: &Frame,
    wo: Vec3,
    u: &[Vec2],
) -> DirectionMoments {
    let n = u.len().max(1);
    let ys: Vec<f64> = u
        .iter()
        .map(|&u| match sampler.sample(wo, u) {
            Some(s) => luminance_estimate(brdf, env, frame, wo, s.wi, s.pdf),
            None => 0.0,
        })
        .collect();
    let mean = ys.iter().sum::<f64>() / n as f64;
    let (mut m2, mut m4) = (0.0f64, 0.0f64);
    for y in &ys {
        let d = y - mean;
        let d2 = d * d;
        m2 += d2;
        m4 += d2 * d2;
    }
    let nf = n as f64;
    let variance = if n > 1 { m2 / (nf - 1.0) } else { 0.0 };
    let m4 = m4 / nf;
    let variance_of_variance = if n > 3 {
        ((m4 - variance * variance * (nf - 3.0) / (nf - 1.0)) / nf).max(0.0)
    } else {
        0.0
    };
    DirectionMoments {
        mean,
        variance,
        variance_of_variance,
    }
}

/// Time the three operations of a sample on this thread, the fastest of
/// `passes` passes over every outgoing direction.
pub fn measure_timing(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    outgoing: &[Vec3],
    samples_per_direction: usize,
    passes: usize,
    seed: u64,
) -> Timing {
    let mut run = TimingRun::new(outgoing, samples_per_direction, seed);
    for _ in 0..passes.max(1) {
        run.pass(brdf, sampler);
    }
    run.timing()
}

/// The timed passes of one sampler, taken one at a time so that the passes
/// of several samplers can alternate ([`measure_efficiencies`]).
struct TimingRun<'a> {
    outgoing: &'a [Vec3],
    /// The uniform pairs of each outgoing direction.
    us: Vec<Vec<Vec2>>,
    /// The directions drawn in the first pass: the pdf and eval passes use
    /// them, so they see the distribution of wi of real use.
    drawn: Vec<Vec<Vec3>>,
    draws: usize,
    valid: usize,
    passes: usize,
    best_draw: f64,
    best_pdf: f64,
    best_eval: f64,
}

impl<'a> TimingRun<'a> {
    fn new(outgoing: &'a [Vec3], samples_per_direction: usize, seed: u64) -> Self {
        let n = samples_per_direction.max(1);
        TimingRun {
            outgoing,
            us: (0..outgoing.len())
                .map(|j| uniform_pairs(seed ^ 0x7431, j, n))
                .collect(),
            drawn: vec![Vec::with_capacity(n); outgoing.len()],
            draws: 0,
            valid: 0,
            passes: 0,
            best_draw: f64::INFINITY,
            best_pdf: f64::INFINITY,
            best_eval: f64::INFINITY,
        }
    }

    /// One timed pass of draws, densities and evaluations.
    fn pass(&mut self, brdf: &dyn Brdf, sampler: &dyn BxdfSampler) {
        let first = self.passes == 0;
        let start = Instant::now();
        for (j, &wo) in self.outgoing.iter().enumerate() {
            for &u in &self.us[j] {
                let s = black_box(sampler.sample(black_box(wo), black_box(u)));
                if first {
                    self.draws += 1;
                    if let Some(s) = s {
                        self.valid += 1;
                        self.drawn[j].push(s.wi);
                    }
                }
            }
        }
        self.best_draw = self.best_draw.min(start.elapsed().as_secs_f64());

        let start = Instant::now();
        for (j, &wo) in self.outgoing.iter().enumerate() {
            for &wi in &self.drawn[j] {
                black_box(sampler.pdf(black_box(wo), black_box(wi)));
            }
        }
        self.best_pdf = self.best_pdf.min(start.elapsed().as_secs_f64());

        let start = Instant::now();
        for (j, &wo) in self.outgoing.iter().enumerate() {
            for &wi in &self.drawn[j] {
                black_box(brdf.eval(black_box(wo), black_box(wi)));
            }
        }
        self.best_eval = self.best_eval.min(start.elapsed().as_secs_f64());
        self.passes += 1;
    }

    /// The per-call times of the fastest passes (zeros before any pass).
    fn timing(&self) -> Timing {
        if self.passes == 0 {
            return Timing::default();
        }
        let draws = self.draws.max(1) as f64;
        let valid_calls = self.valid.max(1) as f64;
        Timing {
            seconds_per_draw: self.best_draw / draws,
            seconds_per_pdf: self.best_pdf / valid_calls,
            seconds_per_eval: self.best_eval / valid_calls,
            valid_fraction: self.valid as f64 / draws,
        }
    }
}

/// Measure variance, time per sample and efficiency of `sampler` for `brdf`
/// under `env`, as defined in the module documentation. The variance pass runs
/// in parallel over outgoing directions (and so also builds any lazily built
/// tables before the timing pass); the timing pass runs on this thread.
pub fn measure_efficiency(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    env: &dyn Environment,
    config: &EfficiencyConfig,
) -> Efficiency {
    let n = config.samples_per_direction.max(2);
    let moments = direction_moments_all(brdf, sampler, env, config, n);
    let timing = measure_timing(
        brdf,
        sampler,
        &config.outgoing,
        config.timing_samples_per_direction,
        config.timing_passes,
        config.seed,
    );
    summarise(sampler.name(), &moments, n, timing)
}

/// [`measure_efficiency`] of several samplers of one `brdf`, their timed
/// passes taken in turns: each round times one pass of every sampler, and
/// each keeps its fastest of [`timing_passes`](EfficiencyConfig::timing_passes)
/// rounds. The variances are those `measure_efficiency` finds.
pub fn measure_efficiencies(
    brdf: &dyn Brdf,
    samplers: &[&dyn BxdfSampler],
    env: &dyn Environment,
    config: &EfficiencyConfig,
) -> Vec<Efficiency> {
    let n = config.samples_per_direction.max(2);
    let moments: Vec<Vec<DirectionMoments>> = samplers
        .iter()
        .map(|&sampler| direction_moments_all(brdf, sampler, env, config, n))
        .collect();
    let mut runs: Vec<TimingRun> = samplers
        .iter()
        .map(|_| {
            TimingRun::new(
                &config.outgoing,
                config.timing_samples_per_direction,
                config.seed,
            )
        })
        .collect();
    for _ in 0..config.timing_passes.max(1) {
        for (run, &sampler) in runs.iter_mut().zip(samplers) {
            run.pass(brdf, sampler);
        }
    }
    samplers
        .iter()
        .zip(&moments)
        .zip(&runs)
        .map(|((sampler, moments), run)| summarise(sampler.name(), moments, n, run.timing()))
        .collect()
}

/// The moments of every outgoing direction of `config`, n draws each, in
/// parallel over the directions (which also builds any lazily built
/// tables before a timed pass).
fn direction_moments_all(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    env: &dyn Environment,
    config: &EfficiencyConfig,
    n: usize,
) -> Vec<DirectionMoments> {
    config
        .outgoing
        .par_iter()
        .enumerate()
        .map(|(j, &wo)| {
            let u = uniform_pairs(config.seed, j, n);
            direction_moments(brdf, sampler, env, &config.frame, wo, &u)
        })
        .collect()
}

fn summarise(name: &str, moments: &[DirectionMoments], n: usize, timing: Timing) -> Efficiency {
    let j = moments.len().max(1) as f64;
    let estimate = moments.iter().map(|m| m.mean).sum::<f64>() / j;
    let variance = moments.iter().map(|m| m.variance).sum::<f64>() / j;
    let estimate_se = (moments.iter().map(|m| m.variance / n as f64).sum::<f64>()).sqrt() / j;
    let variance_se = moments
        .iter()
        .map(|m| m.variance_of_variance)
        .sum::<f64>()
        .sqrt()
        / j;
    let variance_rel_se = if variance > 0.0 {
        variance_se / variance
    } else {
        0.0
    };
    let seconds_per_sample = timing.seconds_per_sample();
    let efficiency = if variance > 0.0 && seconds_per_sample > 0.0 {
        1.0 / (variance * seconds_per_sample)
    } else {
        f64::INFINITY
    };
    Efficiency {
        sampler: name.to_string(),
        estimate,
        estimate_se,
        variance,
        variance_rel_se,
        samples: moments.len() * n,
        timing,
        seconds_per_sample,
        efficiency,
    }
}

/// The quadrature of [`missed_share`]: `n_cos` × `n_phi` cells of equal
/// solid angle over the upper hemisphere, equal steps in cos θ_i and φ_i,
/// each evaluated at its centre.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct HemisphereGrid {
    pub n_cos: usize,
    pub n_phi: usize,
}

impl HemisphereGrid {
    /// 256 × 512 cells (of 2.4e-5 sr each) in cos θ_i × φ_i: the grid of
    /// `acdf report`'s missed-share column.
    pub const REPORT: HemisphereGrid = HemisphereGrid {
        n_cos: 256,
        n_phi: 512,
    };
}

/// The outgoing polar angles, in degrees, of `acdf report`'s missed share
/// (at φ_o = [`MISSED_SHARE_PHI_O`]): from the normal to 89.5°, denser at
/// grazing angles, where a tabulated slice's horizon moves most across its
/// outgoing cell.
pub const MISSED_SHARE_THETA_O: [f32; 8] = [0.0, 30.0, 60.0, 70.0, 80.0, 85.0, 89.0, 89.5];

/// The outgoing azimuth, in radians, of [`MISSED_SHARE_THETA_O`]: 1 rad,
/// off the centre of every φ_o cell of the tabulated resolutions.
pub const MISSED_SHARE_PHI_O: f32 = 1.0;

/// The share of the reflected luminance that `sampler` can never draw at
/// `wo`, on `grid`: [`acdf_core::missed_share`].
pub fn missed_share(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    wo: Vec3,
    grid: HemisphereGrid,
) -> f64 {
    acdf_core::missed_share(brdf, sampler, wo, grid.n_cos, grid.n_phi).share
}

/// [`missed_share`] at each of [`MISSED_SHARE_THETA_O`] (φ_o =
/// [`MISSED_SHARE_PHI_O`]) on `grid`, in that order.
pub fn missed_shares(brdf: &dyn Brdf, sampler: &dyn BxdfSampler, grid: HemisphereGrid) -> Vec<f64> {
    MISSED_SHARE_THETA_O
        .par_iter()
        .map(|&t| {
            let wo = acdf_core::geometry::spherical_direction(t.to_radians(), MISSED_SHARE_PHI_O);
            missed_share(brdf, sampler, wo, grid)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::Sky;
    use acdf_core::Rgb;
    use acdf_materials::analytic::Lambert;

    /// The Lambertian material of albedo `rho` in every channel.
    fn lambert(rho: f32) -> Lambert {
        Lambert::new("lambert", Rgb::splat(rho)).unwrap()
    }

    /// A constant environment makes Y_k constant for cosine sampling of a
    /// Lambertian surface: the variance must vanish and the estimate equal ρ.
    struct White;
    impl Environment for White {
        fn radiance(&self, _dir: Vec3) -> Rgb {
            Vec3::ONE
        }
    }

    fn small() -> EfficiencyConfig {
        EfficiencyConfig {
            samples_per_direction: 4096,
            timing_samples_per_direction: 256,
            ..EfficiencyConfig::default()
        }
    }

    #[test]
    fn cosine_sampling_of_lambert_under_white_light_has_zero_variance() {
        let e = measure_efficiency(&lambert(0.5), &acdf_cosine::CosineSampler, &White, &small());
        assert!((e.estimate - 0.5).abs() < 1e-5, "{}", e.estimate);
        assert!(e.variance < 1e-10, "{}", e.variance);
        assert_eq!(e.samples, 12 * 4096);
        assert!(e.seconds_per_sample > 0.0);
    }

    /// Under the sky the estimate is the irradiance-weighted albedo; the
    /// variance is positive and its relative error small at 2^12 × 12 draws.
    #[test]
    fn sky_estimate_is_positive_and_variance_is_finite() {
        let e = measure_efficiency(
            &lambert(0.5),
            &acdf_cosine::CosineSampler,
            &Sky::default(),
            &small(),
        );
        assert!(e.estimate > 0.1 && e.estimate.is_finite());
        assert!(e.variance > 0.0 && e.variance.is_finite());
        assert!(e.variance_rel_se < 0.5, "{}", e.variance_rel_se);
        assert!(e.efficiency.is_finite() && e.efficiency > 0.0);
        assert!(e.timing.valid_fraction > 0.99);
    }

    /// Timed in turns, each sampler keeps the variance and estimate it has
    /// alone (the same draws), its own timing, and its order.
    #[test]
    fn samplers_timed_in_turns_keep_their_own_measures() {
        let brdf = lambert(0.5);
        let sky = Sky::default();
        let config = EfficiencyConfig {
            timing_passes: 2,
            ..small()
        };
        let cosine = acdf_cosine::CosineSampler;
        let uniform = uniform_tabulation(&brdf);
        let both: [&dyn BxdfSampler; 2] = [&uniform, &cosine];
        let together = measure_efficiencies(&brdf, &both, &sky, &config);
        assert_eq!(together.len(), 2);
        for (e, sampler) in together.iter().zip(both) {
            let alone = measure_efficiency(&brdf, sampler, &sky, &config);
            assert_eq!(e.sampler, alone.sampler);
            assert_eq!(e.variance, alone.variance);
            assert_eq!(e.estimate, alone.estimate);
            assert_eq!(e.timing.valid_fraction, alone.timing.valid_fraction);
            assert!(e.seconds_per_sample > 0.0 && e.seconds_per_sample.is_finite());
        }
        assert!(together[0].variance != together[1].variance);
    }

    /// The uniform tabulated sampler of `brdf` at a small resolution.
    fn uniform_tabulation(brdf: &Lambert) -> acdf_uniform::UniformBrdfSampler {
        let brdf: std::sync::Arc<dyn Brdf> = std::sync::Arc::new(brdf.clone());
        acdf_uniform::UniformBrdfSampler::new(
            brdf,
            "8x1x16x8".parse().unwrap(),
            acdf_uniform::PiecewiseConstantBuilder,
        )
        .unwrap()
    }

    #[test]
    fn standard_directions_are_above_the_horizon() {
        let dirs = standard_outgoing_directions();
        assert_eq!(dirs.len(), 12);
        assert!(dirs
            .iter()
            .all(|w| w.z > 0.0 && (w.length() - 1.0).abs() < 1e-5));
    }
}
