//! `acdf` is the facade of the acdf workspace: it re-exports the core traits,
//! the materials and the sampler plug-ins, names samplers for the command
//! line, and holds the experiments (the results table, sweeps, benchmarks and
//! the renderer) that the `acdf` binary runs.

pub use acdf_core as core;
pub use acdf_cosine as cosine;

use acdf_core::{BxdfSampler, Vec2, Vec3};
use rand::{Rng, SeedableRng};

/// Monte Carlo estimate of the directional albedo ∫ f cos θ_i dω_i of a
/// Lambertian surface with reflectance `rho` (f = rho / π), drawing `n`
/// directions from `sampler` for outgoing direction `wo`. Returns the mean and
/// its standard error.
pub fn lambert_albedo_estimate(
    sampler: &dyn BxdfSampler,
    rho: f32,
    wo: Vec3,
    n: usize,
    seed: u64,
) -> (f64, f64) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for _ in 0..n {
        let u = Vec2::new(rng.random(), rng.random());
        let w = match sampler.sample(wo, u) {
            Some(s) => (rho / std::f32::consts::PI * s.wi.z / s.pdf) as f64,
            None => 0.0,
        };
        sum += w;
        sum2 += w * w;
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(0.0);
    (mean, (var / n as f64).sqrt())
}
