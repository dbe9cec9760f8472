//! Estimator efficiency: how much a sampler's importance sampling is worth per
//! second of its own work.
//!
//! Fix an environment light L (in `acdf report`, `acdf sweep` and
//! `acdf survey`, the procedural sky without its sun,
//! [`Sky::dome`](acdf::env::Sky::dome)), a surface whose normal points up
//! (world `+y`) and a set of outgoing directions ω_o,j (θ_o ∈ {10, 30, 50,
//! 70}° × φ_o ∈ {0, 120, 240}°). For each ω_o,j the one-sample estimator of
//! the reflected luminance draws ω_i from the sampler and returns
//!
//! Y = Y( f_r(ω_o, ω_i) ⊙ L(ω_i) ) · cos θ_i / p(ω_i),
//!
//! (Y the Rec. 709 luminance, ⊙ the product per channel; a failed draw
//! returns 0), whose mean is the reflected luminance F_j.
//!
//! **Relative variance, by quadrature** (noise-free, the primary measure):
//! r_j = Var(Y) / F_j², computed as ∫ g²/p dω − (∫_{p>0} g dω)² over F_j²
//! with g = Y(f ⊙ L) cos θ_i by the midpoint rule on a fixed grid of
//! incident directions ([`acdf_core::Integrand`], by default
//! [`VARIANCE_GRID`], 1024 × 128 cells over the half vector), and
//! r = (1/J) Σ_j r_j. It is deterministic: the same sampler gives the same r
//! on every run and machine. N samples give a relative standard error of
//! sqrt(r / N).
//!
//! **Firefly measure**: the largest weight Y(f) cos θ_i / p over the same
//! grid points (where p > 0), divided by the mean weight ∫_{p>0} Y(f) cos θ_i
//! dω, the largest over the ω_o,j. 1 for a density proportional to
//! f cos θ_i; a sampler whose density is small where f is not makes bright
//! isolated pixels of that many times the mean.
//!
//! **Relative variance, by Monte Carlo** (the cross-check): with s²_j the
//! unbiased sample variance of n draws of Y at ω_o,j, r̂ = (1/J) Σ_j s²_j /
//! F_j² (F_j from the quadrature), with its standard error from the fourth
//! moments of the draws. Where the weights are heavy-tailed the estimate
//! and its error are themselves unreliable, which is why the quadrature is
//! the primary measure.
//!
//! **Time of the sampler's own work**: t_s = t_sample + v · t_pdf per draw,
//! v the fraction of draws that succeed (a failed draw needs no density),
//! measured on one thread after every table is built, in CPU time of that
//! thread ([`thread_seconds`]: time spent waiting for a core on a shared
//! machine is not counted): a fixed batch of
//! [`timing_samples_per_direction`](EfficiencyConfig::timing_samples_per_direction)
//! draws per outgoing direction, then `pdf` at the directions drawn, timed
//! [`timing_repeats`](EfficiencyConfig::timing_repeats) times, the
//! fastest repeat kept. Other work on the machine only ever adds time to a
//! repeat (a preemption that evicts the tables from the caches, a sibling
//! thread sharing the core), so many short repeats and their minimum
//! measure the sampler's own cost more repeatably than a median of long
//! ones: among many short repeats some run undisturbed, while a long one
//! rarely does (the spread between runs of `acdf report` under both rules
//! is in `docs/performance.md`). Several samplers are timed in turns (one
//! repeat of each per round, [`time_samplers`]), so that each sees the
//! machine in the same states. The BRDF evaluation at the
//! drawn directions, the same work whichever sampler drew them, is timed in
//! the same rounds and reported beside it (t_eval), but is not part of t_s;
//! nor is the environment lookup.
//!
//! The **efficiency** is 1 / (r · t_s), in 1/s: how many samples' worth of
//! relative precision a second of sampling buys. Reports divide it by the
//! efficiency of a reference sampler (the uniform tabulated one by
//! default), which leaves the ratio of the variances times the ratio of the
//! times.

use std::hint::black_box;

use acdf_core::{luminance, Brdf, BxdfSampler, Frame, HemisphereGrid, Integrand, Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

use acdf::env::Environment;

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

/// The quadrature grid of the relative variance and the firefly measure:
/// 1024 θ_h rows × 512 φ_h columns over the half vector (multiples of the
/// default tabulation's 256 × 32, so that its cells nest in the table's),
/// 524,288 cells per outgoing direction. On the three measured materials
/// of `acdf report`, the relative variances of `uniform` and
/// `adaptive:chi2` are within 0.25% of those on 2048 × 1024 cells (within
/// 1.2% on 512 × 256, 4% on 1024 × 128: the φ_h columns matter most);
/// `cargo run --release -p acdf-experiments --example quadrature` prints the
/// comparison. The firefly measure, a maximum over the grid's points,
/// grows slowly with the grid (by about 10% per doubling of both counts).
pub const VARIANCE_GRID: HemisphereGrid = HemisphereGrid::HalfVector {
    n_v: 1024,
    n_x: 512,
};

/// What to measure with.
#[derive(Debug, Clone)]
pub struct EfficiencyConfig {
    /// Outgoing directions ω_o,j in the local frame (each with ω_o.z > 0).
    pub outgoing: Vec<Vec3>,
    /// The local shading frame in world space.
    pub frame: Frame,
    /// The quadrature grid of the noise-free measures.
    pub grid: HemisphereGrid,
    /// Draws per outgoing direction for the Monte Carlo cross-check; 0
    /// skips it.
    pub samples_per_direction: usize,
    /// Draws per outgoing direction in each timed repeat.
    pub timing_samples_per_direction: usize,
    /// Timed repeats per sampler, the fastest kept (at least 1).
    pub timing_repeats: usize,
    /// Whether to time the BRDF evaluation too (reported beside the
    /// sampler's time, never part of it).
    pub time_eval: bool,
    /// Seed of the uniform numbers; the same for every sampler (common random
    /// numbers), so differences come from the samplers.
    pub seed: u64,
}

impl Default for EfficiencyConfig {
    /// 12 standard directions, the [`VARIANCE_GRID`] quadrature, 2^17 Monte
    /// Carlo draws per direction, and the fastest of 45 timed repeats of
    /// 2^9 draws per direction.
    fn default() -> Self {
        EfficiencyConfig {
            outgoing: standard_outgoing_directions(),
            frame: standard_frame(),
            grid: VARIANCE_GRID,
            samples_per_direction: 1 << 17,
            timing_samples_per_direction: 1 << 9,
            timing_repeats: 45,
            time_eval: true,
            seed: 2005,
        }
    }
}

impl EfficiencyConfig {
    /// Total draws behind the Monte Carlo estimate.
    pub fn total_samples(&self) -> usize {
        self.outgoing.len() * self.samples_per_direction
    }

    /// Check the memory the draw counts ask for against the memory limit
    /// ([`acdf_io::limits`]) before any of it is allocated: the uniform
    /// pairs of the Monte Carlo estimate (8 bytes a draw, every outgoing
    /// direction at once) and of a timed repeat (8 bytes, and the draws it
    /// keeps, 24 bytes, a draw).
    pub fn check_memory(&self) -> acdf_core::Result<()> {
        use acdf_io::limits::{bytes_of, check_memory};
        let directions = self.outgoing.len() as u64;
        check_memory(
            "the Monte Carlo draws (--samples per direction)",
            bytes_of(bytes_of(directions, self.samples_per_direction as u64), 8),
        )?;
        check_memory(
            "the timed draws (--timing-samples per direction)",
            bytes_of(
                bytes_of(directions, self.timing_samples_per_direction as u64),
                8 + 24,
            ),
        )
    }
}

/// Per-call times, in seconds, of what a sample costs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Timing {
    /// Median time of one `sample` call.
    pub seconds_per_draw: f64,
    /// Median time of one `pdf` call at a drawn direction.
    pub seconds_per_pdf: f64,
    /// Median time of one BRDF evaluation at a drawn direction.
    pub seconds_per_eval: f64,
    /// Fraction of draws that returned a direction.
    pub valid_fraction: f64,
}

impl Timing {
    /// t_s = t_sample + v·t_pdf: the sampler's own work per draw.
    pub fn sampler_seconds(&self) -> f64 {
        self.seconds_per_draw + self.valid_fraction * self.seconds_per_pdf
    }

    /// t_s + v·t_eval: a draw with its BRDF evaluation.
    pub fn seconds_per_sample(&self) -> f64 {
        self.sampler_seconds() + self.valid_fraction * self.seconds_per_eval
    }
}

/// The deterministic measures of one sampler (module documentation).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseFree {
    /// r = (1/J) Σ_j Var_j / F_j².
    pub relative_variance: f64,
    /// r_j of each outgoing direction, in the order of the configuration.
    pub relative_variance_by_direction: Vec<f64>,
    /// max_j (max weight / mean weight).
    pub firefly: f64,
    /// The largest share of Y(f) cos θ_i the sampler cannot draw, over the
    /// outgoing directions, on the same grid.
    pub missed_share: f64,
    /// Per outgoing direction, Var_j / F_j² and the variance of a sample
    /// variance of n draws, (μ₄ − Var²)/n without the 1/n, over F_j⁴:
    /// what [`NoiseFree::monte_carlo_rel_se`] combines.
    #[serde(skip)]
    spread: Vec<(f64, f64)>,
}

impl NoiseFree {
    /// The relative standard error that a Monte Carlo estimate of r with
    /// `n` draws per outgoing direction has, from the estimator's fourth
    /// moment by the same quadrature ([`acdf_core::Moments::variance_rel_se`]):
    /// the honest error bar of the Monte Carlo column, which counts the
    /// draws too rare to appear among n.
    pub fn monte_carlo_rel_se(&self, n: usize) -> f64 {
        let j = self.spread.len().max(1) as f64;
        let var: f64 = self
            .spread
            .iter()
            .map(|&(r, s)| {
                let nf = n.max(4) as f64;
                ((s - r * r * (nf - 3.0) / (nf - 1.0)) / nf).max(0.0)
            })
            .sum();
        if self.relative_variance > 0.0 {
            var.sqrt() / j / self.relative_variance
        } else {
            0.0
        }
    }
}

/// The Monte Carlo cross-check of one sampler.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MonteCarlo {
    /// r̂ = (1/J) Σ_j s²_j / F_j².
    pub relative_variance: f64,
    /// The standard error of r̂ at this number of draws, relative to r,
    /// from the estimator's fourth moment by quadrature
    /// ([`NoiseFree::monte_carlo_rel_se`]): the error r̂ really has.
    pub relative_variance_rel_se: f64,
    /// The same error as the draws themselves estimate it (from their
    /// fourth moments), relative to r̂. Where much of the variance comes
    /// from draws rarer than one in n, the draws cannot see it and this
    /// understates the error.
    pub sample_rel_se: f64,
    /// (1/J) Σ_j mean_k Y_k: the reflected luminance averaged over the
    /// outgoing directions.
    pub estimate: f64,
    /// Standard error of `estimate`.
    pub estimate_se: f64,
    /// Draws behind the estimates.
    pub samples: usize,
}

/// The outcome of [`measure_efficiency`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Efficiency {
    /// The sampler's name.
    pub sampler: String,
    /// Relative variance, firefly measure and missed share by quadrature.
    pub noise_free: NoiseFree,
    /// The Monte Carlo estimate, when draws were asked for.
    pub monte_carlo: Option<MonteCarlo>,
    /// The per-call times of the fastest repeats.
    pub timing: Timing,
    /// 1 / (r · t_s); infinite when r is 0.
    pub efficiency: f64,
}

/// The integrand of one material under one environment at every outgoing
/// direction of a configuration: built once, then shared by every sampler
/// measured on it.
#[derive(Debug, Clone)]
pub struct Integrands {
    per_direction: Vec<Integrand>,
}

impl Integrands {
    /// Evaluate `brdf` and `env` at the grid points of every outgoing
    /// direction (in parallel over the directions).
    pub fn new(brdf: &dyn Brdf, env: &dyn Environment, config: &EfficiencyConfig) -> Integrands {
        let frame = config.frame;
        let light = move |wi: Vec3| env.radiance(frame.to_world(wi));
        let per_direction = config
            .outgoing
            .par_iter()
            .map(|&wo| Integrand::new(brdf, wo, config.grid, Some(&light)))
            .collect();
        Integrands { per_direction }
    }

    /// F_j, the reflected luminance at each outgoing direction.
    pub fn integrals(&self) -> Vec<f64> {
        self.per_direction.iter().map(Integrand::integral).collect()
    }

    /// The noise-free measures of `sampler` (in parallel over the
    /// directions).
    pub fn noise_free(&self, sampler: &dyn BxdfSampler) -> NoiseFree {
        let moments: Vec<_> = self
            .per_direction
            .par_iter()
            .map(|q| q.moments(sampler))
            .collect();
        let by_direction: Vec<f64> = moments.iter().map(|m| m.relative_variance()).collect();
        let j = by_direction.len().max(1) as f64;
        let spread = moments
            .iter()
            .map(|m| {
                let f2 = m.integral * m.integral;
                if f2.is_nan() || f2 <= 0.0 {
                    return (0.0, 0.0);
                }
                let mu = m.mean;
                let mu4 = m.fourth_moment - 4.0 * mu * m.third_moment
                    + 6.0 * mu * mu * m.second_moment
                    - 3.0 * mu.powi(4);
                (m.variance() / f2, mu4.max(0.0) / (f2 * f2))
            })
            .collect();
        NoiseFree {
            spread,
            relative_variance: by_direction.iter().sum::<f64>() / j,
            relative_variance_by_direction: by_direction,
            firefly: moments.iter().map(|m| m.firefly()).fold(0.0, f64::max),
            missed_share: moments.iter().map(|m| m.missed_share()).fold(0.0, f64::max),
        }
    }
}

/// Moments of the Monte Carlo estimator for one outgoing direction.
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

/// The Monte Carlo cross-check of `sampler`, `n` draws per direction (in
/// parallel over the directions), relative to the integrals `f` of the
/// quadrature.
fn monte_carlo(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    env: &dyn Environment,
    config: &EfficiencyConfig,
    f: &[f64],
) -> MonteCarlo {
    let n = config.samples_per_direction.max(2);
    let moments: Vec<DirectionMoments> = config
        .outgoing
        .par_iter()
        .enumerate()
        .map(|(j, &wo)| {
            let u = uniform_pairs(config.seed, j, n);
            direction_moments(brdf, sampler, env, &config.frame, wo, &u)
        })
        .collect();
    let j = moments.len().max(1) as f64;
    let square = |k: usize| f.get(k).map_or(0.0, |f| f * f);
    let (mut rel, mut rel_var) = (0.0, 0.0);
    for (k, m) in moments.iter().enumerate() {
        let f2 = square(k);
        if f2 > 0.0 {
            rel += m.variance / f2;
            rel_var += m.variance_of_variance / (f2 * f2);
        }
    }
    let relative_variance = rel / j;
    let rel_se = rel_var.sqrt() / j;
    MonteCarlo {
        relative_variance,
        relative_variance_rel_se: 0.0,
        sample_rel_se: if relative_variance > 0.0 {
            rel_se / relative_variance
        } else {
            0.0
        },
        estimate: moments.iter().map(|m| m.mean).sum::<f64>() / j,
        estimate_se: moments
            .iter()
            .map(|m| m.variance / n as f64)
            .sum::<f64>()
            .sqrt()
            / j,
        samples: moments.len() * n,
    }
}

/// Seconds of CPU time this thread has used, where the platform has a
/// per-thread CPU clock (`CLOCK_THREAD_CPUTIME_ID`); wall-clock seconds
/// since the first call elsewhere. A thread that waits for a core (other
/// processes on a shared machine) does not advance its CPU clock, so a
/// timing read from it does not depend on how busy the machine is.
// The crate's one `unsafe`: the C library's clock of this thread.
#[allow(unsafe_code)]
pub fn thread_seconds() -> f64 {
    #[cfg(unix)]
    {
        let mut t = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `t` is a valid, writable timespec for the duration of the
        // call, and CLOCK_THREAD_CPUTIME_ID is a clock id every supported
        // unix defines; clock_gettime writes only to `t`.
        let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) } == 0;
        if ok {
            return t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9;
        }
    }
    static START: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
    START
        .get_or_init(std::time::Instant::now)
        .elapsed()
        .as_secs_f64()
}

/// The timed repeats of one sampler, taken one at a time so that the
/// repeats of several samplers can alternate ([`time_samplers`]).
struct TimingRun<'a> {
    outgoing: &'a [Vec3],
    /// The uniform pairs of each outgoing direction.
    us: Vec<Vec<Vec2>>,
    /// The directions drawn in the first repeat: the pdf and eval timings
    /// use them, so they see the distribution of wi of real use.
    drawn: Vec<Vec<Vec3>>,
    draws: usize,
    valid: usize,
    draw_seconds: Vec<f64>,
    pdf_seconds: Vec<f64>,
    eval_seconds: Vec<f64>,
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
            draw_seconds: Vec::new(),
            pdf_seconds: Vec::new(),
            eval_seconds: Vec::new(),
        }
    }

    /// One timed repeat of the draws, the densities and the evaluations.
    fn repeat(&mut self, brdf: Option<&dyn Brdf>, sampler: &dyn BxdfSampler) {
        let first = self.draw_seconds.is_empty();
        let start = thread_seconds();
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
        self.draw_seconds.push(thread_seconds() - start);

        let start = thread_seconds();
        for (j, &wo) in self.outgoing.iter().enumerate() {
            for &wi in &self.drawn[j] {
                black_box(sampler.pdf(black_box(wo), black_box(wi)));
            }
        }
        self.pdf_seconds.push(thread_seconds() - start);

        let Some(brdf) = brdf else { return };
        let start = thread_seconds();
        for (j, &wo) in self.outgoing.iter().enumerate() {
            for &wi in &self.drawn[j] {
                black_box(brdf.eval(black_box(wo), black_box(wi)));
            }
        }
        self.eval_seconds.push(thread_seconds() - start);
    }

    /// The per-call times of the fastest repeats (zeros before any): draw,
    /// pdf and evaluation each at its own fastest.
    fn timing(&self) -> Timing {
        if self.draw_seconds.is_empty() {
            return Timing::default();
        }
        let draws = self.draws.max(1) as f64;
        let valid_calls = self.valid.max(1) as f64;
        Timing {
            seconds_per_draw: fastest(&self.draw_seconds) / draws,
            seconds_per_pdf: fastest(&self.pdf_seconds) / valid_calls,
            seconds_per_eval: fastest(&self.eval_seconds) / valid_calls,
            valid_fraction: self.valid as f64 / draws,
        }
    }
}

/// The smallest of `xs`, NaN left out; 0 for none.
pub fn fastest(xs: &[f64]) -> f64 {
    let low = xs
        .iter()
        .copied()
        .filter(|x| !x.is_nan())
        .fold(f64::INFINITY, f64::min);
    if low.is_finite() {
        low
    } else {
        0.0
    }
}

/// The 32x16x256x32 table of Lawrence et al. for `material`, every slice
/// built: the reference of the efficiency experiments' examples.
pub fn paper_table(material: &acdf::material::Material) -> acdf::error::Result<acdf::AnySampler> {
    use acdf::SamplerOps as _;
    let options = acdf::SamplerOptions {
        resolution: acdf::tabulated::Resolution::PAPER,
        ..acdf::SamplerOptions::default()
    };
    let table = acdf::make_sampler("uniform", material, &options)?;
    table.build_all()?;
    Ok(table)
}

/// The median of `xs` (the mean of the middle two for an even count); 0
/// for none.
pub fn median(xs: &[f64]) -> f64 {
    let mut v: Vec<f64> = xs.iter().copied().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// Time several samplers of `brdf` on this thread, in turns: each round
/// times one repeat of every sampler, over
/// [`timing_repeats`](EfficiencyConfig::timing_repeats) rounds after an
/// untimed one (which also builds any table a sampler builds on first
/// use); each sampler keeps its fastest repeat (see the module
/// documentation).
pub fn time_samplers(
    brdf: &dyn Brdf,
    samplers: &[&dyn BxdfSampler],
    config: &EfficiencyConfig,
) -> Vec<Timing> {
    let brdf = config.time_eval.then_some(brdf);
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
    // A warm-up repeat of each (tables built, caches and branch
    // predictors primed), then the timed ones.
    for (run, &sampler) in runs.iter_mut().zip(samplers) {
        run.repeat(brdf, sampler);
        run.draw_seconds.clear();
        run.pdf_seconds.clear();
        run.eval_seconds.clear();
    }
    for _ in 0..config.timing_repeats.max(1) {
        for (run, &sampler) in runs.iter_mut().zip(samplers) {
            run.repeat(brdf, sampler);
        }
    }
    runs.iter().map(TimingRun::timing).collect()
}

/// 1 / (r · t_s), infinite when either is 0.
pub fn efficiency_of(relative_variance: f64, sampler_seconds: f64) -> f64 {
    if relative_variance > 0.0 && sampler_seconds > 0.0 {
        1.0 / (relative_variance * sampler_seconds)
    } else {
        f64::INFINITY
    }
}

/// Measure the relative variance and firefly measure by quadrature, the
/// Monte Carlo cross-check (unless `samples_per_direction` is 0) and the
/// times of several samplers of one `brdf` under `env`; the samplers are
/// timed in turns ([`time_samplers`]). The integrand is evaluated once for
/// all of them.
pub fn measure_efficiencies(
    brdf: &dyn Brdf,
    samplers: &[&dyn BxdfSampler],
    env: &dyn Environment,
    config: &EfficiencyConfig,
) -> Vec<Efficiency> {
    let integrands = Integrands::new(brdf, env, config);
    measure_with(&integrands, brdf, samplers, env, config)
}

/// [`measure_efficiencies`] on integrands already evaluated.
pub fn measure_with(
    integrands: &Integrands,
    brdf: &dyn Brdf,
    samplers: &[&dyn BxdfSampler],
    env: &dyn Environment,
    config: &EfficiencyConfig,
) -> Vec<Efficiency> {
    let f = integrands.integrals();
    let measured: Vec<(NoiseFree, Option<MonteCarlo>)> = samplers
        .iter()
        .map(|&sampler| {
            let noise_free = integrands.noise_free(sampler);
            let mc = (config.samples_per_direction > 0).then(|| MonteCarlo {
                relative_variance_rel_se: noise_free
                    .monte_carlo_rel_se(config.samples_per_direction.max(2)),
                ..monte_carlo(brdf, sampler, env, config, &f)
            });
            (noise_free, mc)
        })
        .collect();
    let timings = time_samplers(brdf, samplers, config);
    samplers
        .iter()
        .zip(measured)
        .zip(timings)
        .map(
            |((sampler, (noise_free, monte_carlo)), timing)| Efficiency {
                sampler: sampler.name().to_string(),
                efficiency: efficiency_of(noise_free.relative_variance, timing.sampler_seconds()),
                noise_free,
                monte_carlo,
                timing,
            },
        )
        .collect()
}

/// [`measure_efficiencies`] of one sampler.
pub fn measure_efficiency(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    env: &dyn Environment,
    config: &EfficiencyConfig,
) -> Efficiency {
    measure_efficiencies(brdf, &[sampler], env, config)
        .pop()
        .expect("one sampler gives one result")
}

/// The grid of `acdf report`'s missed-share column: 256 × 512 cells of
/// equal solid angle (2.4e-5 sr each) in cos θ_i × φ_i.
pub const MISSED_SHARE_GRID: HemisphereGrid = HemisphereGrid::EqualArea {
    n_cos: 256,
    n_phi: 512,
};

/// The outgoing polar angles, in degrees, of `acdf report`'s missed share
/// (at φ_o = [`MISSED_SHARE_PHI_O`]): from the normal to 89.5°, denser at
/// grazing angles, where a tabulated slice's horizon moves most across its
/// outgoing cell.
pub const MISSED_SHARE_THETA_O: [f32; 8] = [0.0, 30.0, 60.0, 70.0, 80.0, 85.0, 89.0, 89.5];

/// The outgoing azimuth, in radians, of [`MISSED_SHARE_THETA_O`]: 1 rad,
/// off the centre of every φ_o cell of the tabulated resolutions.
pub const MISSED_SHARE_PHI_O: f32 = 1.0;

/// The share of the reflected luminance that `sampler` can never draw at
/// `wo`, on `grid` ([`acdf_core::Moments::missed_share`]).
pub fn missed_share(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    wo: Vec3,
    grid: HemisphereGrid,
) -> f64 {
    Integrand::new(brdf, wo, grid, None)
        .moments(sampler)
        .missed_share()
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
    use acdf::env::Sky;
    use acdf_core::Rgb;
    use acdf_materials::analytic::Lambert;

    /// The Lambertian material of albedo `rho` in every channel.
    fn lambert(rho: f32) -> Lambert {
        Lambert::new("lambert", Rgb::splat(rho)).unwrap()
    }

    /// A constant environment.
    struct White;
    impl Environment for White {
        fn radiance(&self, _dir: Vec3) -> Rgb {
            Vec3::ONE
        }
    }

    fn small() -> EfficiencyConfig {
        EfficiencyConfig {
            grid: HemisphereGrid::HalfVector { n_v: 256, n_x: 64 },
            samples_per_direction: 4096,
            timing_samples_per_direction: 256,
            timing_repeats: 3,
            ..EfficiencyConfig::default()
        }
    }

    /// Under a constant environment cosine sampling of a Lambertian surface
    /// makes every Y_k equal to the albedo: both variances vanish, the
    /// estimate is ρ and the firefly measure 1.
    #[test]
    fn cosine_sampling_of_lambert_under_white_light_has_zero_variance() {
        let e = measure_efficiency(&lambert(0.5), &acdf_cosine::CosineSampler, &White, &small());
        assert!(e.noise_free.relative_variance < 1e-5, "{e:?}");
        assert!((e.noise_free.firefly - 1.0).abs() < 1e-3, "{e:?}");
        let mc = e.monte_carlo.as_ref().unwrap();
        assert!((mc.estimate - 0.5).abs() < 1e-5, "{}", mc.estimate);
        assert!(mc.relative_variance < 1e-10, "{}", mc.relative_variance);
        assert_eq!(mc.samples, 12 * 4096);
        assert!(e.timing.sampler_seconds() > 0.0);
        assert!(e.efficiency > 1e10 || e.efficiency.is_infinite());
    }

    /// A sampler of p = 1/(2π) on the upper hemisphere: the mismatched case
    /// of the module documentation, relative variance 1/3 for a Lambertian
    /// surface under a constant environment.
    struct UniformHemisphere;
    impl BxdfSampler for UniformHemisphere {
        fn name(&self) -> &str {
            "uniform-hemisphere"
        }
        fn sample(&self, wo: Vec3, u: Vec2) -> Option<acdf_core::BxdfSample> {
            let z = 1.0 - u.x;
            let wi = acdf_core::geometry::spherical_direction(
                z.clamp(0.0, 1.0).acos(),
                std::f32::consts::TAU * u.y,
            );
            (wi.z > 0.0).then(|| acdf_core::BxdfSample {
                wi,
                pdf: self.pdf(wo, wi),
            })
        }
        fn pdf(&self, _wo: Vec3, wi: Vec3) -> f32 {
            if wi.z > 0.0 {
                1.0 / std::f32::consts::TAU
            } else {
                0.0
            }
        }
        fn storage_bytes(&self) -> usize {
            0
        }
    }

    /// The quadrature finds the analytic 1/3, and the Monte Carlo estimate
    /// agrees within four of its standard errors.
    #[test]
    fn uniform_sampling_of_lambert_has_the_known_relative_variance() {
        let e = measure_efficiency(&lambert(0.7), &UniformHemisphere, &White, &small());
        let r = e.noise_free.relative_variance;
        assert!((r - 1.0 / 3.0).abs() < 1e-3, "{r}");
        assert!((e.noise_free.firefly - 2.0).abs() < 2e-2, "{e:?}");
        let mc = e.monte_carlo.unwrap();
        let se = mc.relative_variance_rel_se * mc.relative_variance;
        assert!(
            (mc.relative_variance - r).abs() < 4.0 * se,
            "{mc:?} against {r}"
        );
        assert!(e.efficiency.is_finite() && e.efficiency > 0.0);
    }

    /// Under the sky the estimate is the irradiance-weighted albedo; both
    /// relative variances are positive, finite and agree.
    #[test]
    fn sky_relative_variances_agree() {
        let e = measure_efficiency(
            &lambert(0.5),
            &acdf_cosine::CosineSampler,
            &Sky::default(),
            &small(),
        );
        let mc = e.monte_carlo.as_ref().unwrap();
        assert!(mc.estimate > 0.1 && mc.estimate.is_finite());
        let r = e.noise_free.relative_variance;
        assert!(r > 0.0 && r.is_finite());
        assert!(mc.relative_variance_rel_se < 0.5, "{mc:?}");
        assert!(e.efficiency.is_finite() && e.efficiency > 0.0);
        assert!(e.timing.valid_fraction > 0.99);
    }

    /// Timed in turns, each sampler keeps the measures it has alone (the
    /// same grid and draws) and its order.
    #[test]
    fn samplers_timed_in_turns_keep_their_own_measures() {
        let brdf = lambert(0.5);
        let sky = Sky::default();
        let config = small();
        let cosine = acdf_cosine::CosineSampler;
        let uniform = uniform_tabulation(&brdf);
        let both: [&dyn BxdfSampler; 2] = [&uniform, &cosine];
        let together = measure_efficiencies(&brdf, &both, &sky, &config);
        assert_eq!(together.len(), 2);
        for (e, sampler) in together.iter().zip(both) {
            let alone = measure_efficiency(&brdf, sampler, &sky, &config);
            assert_eq!(e.sampler, alone.sampler);
            assert_eq!(e.noise_free, alone.noise_free);
            assert_eq!(e.monte_carlo, alone.monte_carlo);
            assert_eq!(e.timing.valid_fraction, alone.timing.valid_fraction);
            assert!(e.timing.sampler_seconds() > 0.0);
            assert!(e.timing.seconds_per_eval > 0.0);
        }
        assert!(together[0].noise_free != together[1].noise_free);
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
    fn medians() {
        assert_eq!(fastest(&[]), 0.0);
        assert_eq!(fastest(&[3.0, f64::NAN, 1.0, 2.0]), 1.0);
        assert_eq!(median(&[]), 0.0);
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
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
