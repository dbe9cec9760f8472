//! Compression and sampling efficiency of the adaptive sampler against the
//! uniform one.
//!
//! ```sh
//! cargo run -p acdf --release --example compression
//! cargo run -p acdf --release --example compression -- \
//!     --resolution 32x1x256x32 --materials nickel --simplifiers optimal,dp \
//!     --tolerances 0.002,0.005,0.01,0.02 --cosine-mix 0.05
//! ```
//!
//! For every material, the uniform sampler and one adaptive sampler per
//! (simplifier, tolerance) are fully built; the table reports the storage
//! ratio (uniform bytes / adaptive bytes, both `BxdfSampler::storage_bytes`),
//! the average kept resolution (marginal vertices over θ_h x conditional
//! vertices over φ_h), and the efficiency: the relative variance
//! Var / mean^2 of the estimator Y(f) cos θ_i / pdf, averaged over a fixed set
//! of outgoing directions, of the uniform sampler divided by that of the
//! adaptive one (> 1: the adaptive sampler is better). The variances are
//! computed by quadrature over a fine half-vector grid, not by sampling, so
//! they carry no Monte Carlo noise (the quadrature of `acdf report`,
//! [`acdf_core::Integrand`], without the environment); "missed" is the
//! largest fraction of the integrand where a sampler's pdf is 0 (bias; it
//! should be 0).

use acdf_adaptive::{average_resolution, AdaptiveBrdfSampler};
use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_core::geometry::spherical_direction;
use acdf_core::{Brdf, BxdfSampler, Distribution2D, HemisphereGrid, Integrand, Vec2, Vec3};
use acdf_tabulated::tabulate::tabulate_slice;
use acdf_tabulated::{Resolution, TabulatedBrdfSampler};
use acdf_uniform::PiecewiseConstantBuilder;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::sync::Arc;
use std::time::Instant;

struct Options {
    resolution: Resolution,
    materials: Vec<String>,
    simplifiers: Vec<String>,
    tolerances: Option<Vec<f64>>,
    cosine_mix: f32,
    directions: usize,
    quad_x: usize,
    quad_v: usize,
}

fn parse() -> Result<Options, String> {
    let mut o = Options {
        resolution: Resolution::PAPER,
        materials: ["nickel", "blue-metallic-paint", "gray-plastic"]
            .map(String::from)
            .to_vec(),
        simplifiers: ["dp", "vw", "rw", "optimal"].map(String::from).to_vec(),
        tolerances: None,
        cosine_mix: 0.0,
        directions: 48,
        quad_x: 128,
        quad_v: 1024,
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let list = |s: &str| s.split(',').map(String::from).collect::<Vec<_>>();
    for pair in args.chunks(2) {
        let [key, value] = pair else {
            return Err(format!("missing value after {}", pair[0]));
        };
        match key.as_str() {
            "--resolution" => o.resolution = value.parse().map_err(|e| format!("{e}"))?,
            "--materials" => o.materials = list(value),
            "--simplifiers" => o.simplifiers = list(value),
            "--tolerances" => {
                o.tolerances = Some(
                    list(value)
                        .iter()
                        .map(|t| t.parse().map_err(|e| format!("{t}: {e}")))
                        .collect::<Result<_, _>>()?,
                )
            }
            "--cosine-mix" => o.cosine_mix = value.parse().map_err(|e| format!("{e}"))?,
            "--directions" => o.directions = value.parse().map_err(|e| format!("{e}"))?,
            "--quadrature" => {
                let (a, b) = value.split_once('x').ok_or("--quadrature wants NXxNV")?;
                o.quad_x = a.parse().map_err(|e| format!("{e}"))?;
                o.quad_v = b.parse().map_err(|e| format!("{e}"))?;
            }
            _ => return Err(format!("unknown option {key}")),
        }
    }
    Ok(o)
}

/// Outgoing directions spread over the hemisphere up to θ_o = 80°, fixed.
fn directions(count: usize) -> Vec<Vec3> {
    let mut rng = Pcg64::seed_from_u64(1);
    (0..count)
        .map(|_| {
            let theta = rng.random_range(0.0..80f32.to_radians());
            let phi = rng.random_range(0.0..std::f32::consts::TAU);
            spherical_direction(theta, phi)
        })
        .collect()
}

/// Per direction: the relative variance Var / F^2 of the estimator
/// Y(f) cos θ_i / pdf by quadrature ([`acdf_core::Integrand`] on the
/// half-vector grid, no light), and the largest share of Y(f) cos θ_i
/// where the pdf is 0 (bias; it should be 0).
fn relative_variances(sampler: &dyn BxdfSampler, qs: &[Integrand]) -> (Vec<f64>, f64) {
    let mut missed = 0.0f64;
    let rel = qs
        .iter()
        .map(|q| {
            let m = q.moments(sampler);
            missed = missed.max(m.missed_share());
            m.relative_variance()
        })
        .collect();
    (rel, missed)
}

/// The mean over slices of the chi-square divergence of each tabulated slice
/// (at its centre wo) from the adaptive slice distribution:
/// (1/N) sum_c t_c^2 / q_c - 1 with t the normalised table and q the adaptive
/// density at the cell centre.
fn table_chi_square(sampler: &AdaptiveBrdfSampler) -> f64 {
    let res = sampler.resolution();
    let (nx, ny) = (res.phi_h, res.theta_h);
    let mut sum = 0.0;
    let mut count = 0usize;
    for i in 0..res.theta_o {
        for j in 0..res.phi_o {
            let Some(Ok(dist)) = sampler.slice(i, j) else {
                continue;
            };
            let values = tabulate_slice(&**sampler.brdf(), &res, i, j);
            let n = values.len() as f64;
            let mean = values.iter().map(|&v| v as f64).sum::<f64>() / n;
            if mean <= 0.0 {
                continue;
            }
            let mut m2 = 0.0;
            for (k, &v) in values.iter().enumerate() {
                if v <= 0.0 {
                    continue;
                }
                let p = Vec2::new(
                    ((k % nx) as f32 + 0.5) / nx as f32,
                    ((k / nx) as f32 + 0.5) / ny as f32,
                );
                let q = dist.pdf(p) as f64;
                let t = v as f64 / mean;
                m2 += if q > 0.0 { t * t / q } else { f64::INFINITY };
            }
            sum += m2 / n - 1.0;
            count += 1;
        }
    }
    sum / count.max(1) as f64
}

fn main() {
    let o = match parse() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("compression: {e}");
            std::process::exit(2);
        }
    };
    let wos = directions(o.directions);
    println!(
        "resolution {}, {} directions, quadrature {}x{} (phi_h x theta_h), cosine mix {}",
        o.resolution, o.directions, o.quad_x, o.quad_v, o.cosine_mix
    );
    println!(
        "| material | sampler | tolerance | bytes | ratio | avg res (theta_h x phi_h) | efficiency | build s |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for material in &o.materials {
        let brdf: Arc<dyn Brdf> = match acdf_materials::builtin(material) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("compression: {e}");
                std::process::exit(2);
            }
        };
        let t = Instant::now();
        let uniform =
            TabulatedBrdfSampler::new(brdf.clone(), o.resolution, PiecewiseConstantBuilder)
                .and_then(|s| s.with_cosine_mix(o.cosine_mix))
                .expect("uniform sampler");
        uniform.build_all().expect("uniform build");
        let build_u = t.elapsed().as_secs_f64();
        let uniform_bytes = uniform.storage_bytes();
        let grid = HemisphereGrid::HalfVector {
            n_v: o.quad_v,
            n_x: o.quad_x,
        };
        let qs: Vec<Integrand> = wos
            .iter()
            .map(|&wo| Integrand::new(&*brdf, wo, grid, None))
            .collect();
        let (var_u, missed_u) = relative_variances(&uniform, &qs);
        let mean_u = var_u.iter().sum::<f64>() / var_u.len() as f64;
        println!(
            "| {material} | uniform | - | {uniform_bytes} | 1 | {} x {} | 1 (relvar {mean_u:.3e}, missed {missed_u:.1e}) | {build_u:.1} |",
            o.resolution.theta_h, o.resolution.phi_h
        );
        for name in &o.simplifiers {
            let tolerances = match &o.tolerances {
                Some(t) => t.clone(),
                None => vec![acdf_adaptive_cdf::simplifier_by_name(name)
                    .expect("simplifier")
                    .default_tolerance()],
            };
            for tol in tolerances {
                let t = Instant::now();
                let sampler: AdaptiveBrdfSampler = TabulatedBrdfSampler::new(
                    brdf.clone(),
                    o.resolution,
                    AdaptiveBuilder::by_name(name, Some(tol)).expect("builder"),
                )
                .and_then(|s| s.with_cosine_mix(o.cosine_mix))
                .expect("adaptive sampler");
                sampler.build_all().expect("adaptive build");
                let build = t.elapsed().as_secs_f64();
                let bytes = sampler.storage_bytes();
                let (rt, rp) = average_resolution(&sampler);
                let (var_a, missed) = relative_variances(&sampler, &qs);
                let mean_a = var_a.iter().sum::<f64>() / var_a.len() as f64;
                println!(
                    "| {material} | {name} | {tol} | {bytes} | {:.1} | {rt:.1} x {rp:.1} | {:.3} (relvar {mean_a:.3e}, missed {missed:.1e}, table chi2 {:.2e}) | {build:.1} |",
                    uniform_bytes as f64 / bytes as f64,
                    mean_u / mean_a,
                    table_chi_square(&sampler),
                );
            }
        }
    }
}
