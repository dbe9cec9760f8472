//! Sampling throughput, as `acdf bench` measures it: how many samples per
//! second the distributions and the BRDF samplers deliver, and how long the
//! full 4D tables take to build.
//!
//! Every rate is samples (or densities) per second of wall-clock time, the
//! best of `repeats` runs over the same pre-drawn uniform numbers (a shared
//! machine only ever makes a run slower). The uniform numbers come from a
//! fixed-seed PCG so runs are comparable. What is timed:
//!
//! The material is any `--material` the other commands accept (built-in
//! nickel by default; `nbrdf:NAME` is evaluated from its baked MERL table,
//! an RGL `.bsdf` file by its own interpolation).
//!
//! - **2D distributions**: the slice of the material for the middle
//!   outgoing cell (θ_o cell 16 of 32 at the isotropic resolution,
//!   256 θ_h × 32 φ_h), as a [`PiecewiseConstant2D`] and as an
//!   [`AdaptiveCdf2D`] (Douglas-Peucker at its default tolerance, the
//!   default `adaptive` sampler); `sample_batch` over all the numbers on one
//!   thread, and split into chunks over every rayon thread.
//! - **BRDF samplers** (`uniform`, `adaptive`) on the material at
//!   the isotropic resolution, then the 32x16x256x32 table of Lawrence et
//!   al. (`uniform` at that resolution, 17 MB on nickel) and the recommended one
//!   (`adaptive:chi2` at the isotropic resolution, a few hundred KB), and
//!   for an isotropic material the adaptive-outgoing `outgoing:chi2` (at
//!   most 17.6 KB), all slices built beforehand, on one thread:
//!   `sample` called once per draw with the outgoing direction changing
//!   every draw (a path tracer's case, cycling through 64 directions);
//!   `sample_each` over the same (wo, u) pairs (a wavefront renderer's
//!   batch); `sample_batch` for one outgoing direction; and the densities
//!   of the drawn pairs by `pdf` once per pair, by `pdf_each`, and by
//!   `pdf_batch` for the one direction.
//! - **Clock**: the core clock read just before and just after the BRDF
//!   samplers (a chain of dependent additions), by which the text output
//!   turns their per-call rates into cycles per call.
//! - **Builds**: the material as a MERL-layout table (a MERL file or a
//!   baked `nbrdf:` material as it is, any other tabulated with
//!   [`MerlTable::tabulate`], not timed), then every slice of the uniform
//!   and the adaptive sampler built from that table with `build_all` (all
//!   threads) at the build resolution (the paper's 32x16x256x32 by default).

use std::sync::Arc;
use std::time::Instant;

use acdf_adaptive_cdf::{AdaptiveBuilder, AdaptiveCdf2D};
use acdf_core::geometry::spherical_direction;
use acdf_core::simd::clock::clock_ghz;
use acdf_core::{Brdf, BxdfSampler, Distribution2D, Sample2D, TableBuilder, Vec2, Vec3};
use acdf_materials::merl::MerlTable;
use acdf_tabulated::{tabulate_slice, Resolution, SliceBuilder, TabulatedBrdfSampler};
use acdf_uniform::{PiecewiseConstant2D, PiecewiseConstantBuilder, UniformBrdfSampler};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

use acdf::error::{Error, Result};
use acdf::material::load_material;
use acdf::registry::{effective_resolution, make_sampler, SamplerOps, SamplerOptions};
use acdf::spec::MaterialSpec;

use crate::common::load_average;

/// What `acdf bench` runs.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchConfig {
    /// The material, as `--material` names it (a bare built-in name such
    /// as `nickel` stands for `builtin:nickel`).
    pub material: String,
    /// Where `nbrdf:` weights are read from (`None`: the default place).
    pub nbrdf_weights: Option<std::path::PathBuf>,
    /// Uniform pairs drawn per timed run.
    pub samples: usize,
    /// Runs per figure; the best is reported.
    pub repeats: usize,
    /// Resolution of the timed 4D builds.
    pub build_resolution: Resolution,
    /// Seed of the uniform numbers.
    pub seed: u64,
}

impl Default for BenchConfig {
    /// Built-in nickel, 10^6 samples, best of 3, builds at the paper's
    /// resolution.
    fn default() -> Self {
        BenchConfig {
            material: "nickel".to_string(),
            nbrdf_weights: None,
            samples: 1_000_000,
            repeats: 3,
            build_resolution: Resolution::PAPER,
            seed: 1,
        }
    }
}

/// The results of `acdf bench`, as written to its JSON file. Field names are
/// stable; rates are per second of wall-clock time (best of `repeats`),
/// sizes in bytes, times in seconds.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// The material measured: its short name (`nickel`, the file stem of
    /// a `.bsdf` file, ...).
    pub material: String,
    /// The material as `--material` names it, e.g. `builtin:nickel`,
    /// `nbrdf:gray-plastic`.
    pub material_spec: String,
    /// Uniform pairs per timed run.
    pub samples: usize,
    /// Runs per figure (the best is kept).
    pub repeats: usize,
    /// Rayon threads used by the `*_all_threads` figures and the builds.
    pub threads: usize,
    /// The 1-minute load average when the run started (Linux
    /// `/proc/loadavg`), `null` where unavailable: a loaded machine gives
    /// lower rates.
    pub load_average: Option<f64>,
    /// The core clock in GHz just before the BRDF samplers are timed
    /// (`clock_ghz_start`) and just after (`clock_ghz_end`), estimated from
    /// a chain of dependent integer additions (`acdf_core::simd::clock`); `null` off
    /// x86-64. One call of `sample` is a chain of dependent steps of a
    /// nearly fixed number of cycles, so its rate follows the clock, which
    /// varies between runs on a shared machine; the table printed beside the
    /// JSON gives each call in cycles.
    pub clock_ghz_start: Option<f64>,
    pub clock_ghz_end: Option<f64>,
    /// The processor the figures were measured on: its model name (Linux
    /// `/proc/cpuinfo`; `unknown` elsewhere), then its family and model
    /// numbers and the vector extensions the batch paths can use, e.g.
    /// `AMD EPYC (family 26, model 2), avx2, avx512f`: a rate means little
    /// without the processor it was measured on.
    pub cpu: String,
    /// The 2D distributions of one slice (256 θ_h × 32 φ_h).
    pub distributions: Vec<DistributionBench>,
    /// The BRDF samplers: `uniform` and `adaptive:dp` at the isotropic
    /// resolution 32x1x256x32, then `uniform` at the paper's 32x16x256x32,
    /// `adaptive:chi2` at 32x1x256x32 and, for an isotropic material,
    /// `outgoing:chi2`.
    pub samplers: Vec<SamplerBench>,
    /// The full 4D builds from a MERL-layout table.
    pub builds: Vec<BuildBench>,
}

/// Throughput of one 2D distribution.
#[derive(Debug, Clone, Serialize)]
pub struct DistributionBench {
    /// `piecewise_constant_2d` or `adaptive_2d`.
    pub name: String,
    /// Cells along x (φ_h) and y (θ_h) of the tabulated slice.
    pub nx: usize,
    pub ny: usize,
    /// `sample_batch` on one thread, samples per second.
    pub samples_per_second_one_thread: f64,
    /// `sample_batch` on chunks spread over all threads, samples per second.
    pub samples_per_second_all_threads: f64,
    /// `Distribution2D::storage_bytes` of the distribution.
    pub storage_bytes: usize,
}

/// Throughput of one BRDF sampler, on one thread.
#[derive(Debug, Clone, Serialize)]
pub struct SamplerBench {
    /// The sampler name (`uniform`, `adaptive:dp`).
    pub name: String,
    /// Its resolution, e.g. `32x1x256x32`.
    pub resolution: String,
    /// `sample` called per draw, outgoing direction changing every draw.
    pub sample_per_second: f64,
    /// `sample_each` over the same (wo, u) pairs, samples per second.
    pub sample_each_per_second: f64,
    /// `sample_batch` for one outgoing direction, samples per second.
    pub sample_batch_per_second: f64,
    /// `pdf` called per (wo, wi) pair, densities per second.
    pub pdf_per_second: f64,
    /// `pdf_each` over the same pairs, densities per second.
    pub pdf_each_per_second: f64,
    /// `pdf_batch` for the one outgoing direction of `sample_batch`, over
    /// its draws, densities per second.
    pub pdf_batch_per_second: f64,
    /// `BxdfSampler::storage_bytes` with every slice built.
    pub storage_bytes: usize,
}

/// Time to build every slice of a sampler from a MERL-layout table.
#[derive(Debug, Clone, Serialize)]
pub struct BuildBench {
    /// The sampler name (`uniform`, `adaptive:dp`).
    pub name: String,
    /// The resolution built, e.g. `32x16x256x32`.
    pub resolution: String,
    /// Wall-clock seconds of `build_all` (all threads), best of `repeats`.
    pub seconds: f64,
    /// `BxdfSampler::storage_bytes` once built.
    pub storage_bytes: usize,
}

/// The best (shortest) wall-clock seconds of `repeats` calls of `run`.
fn best_seconds(repeats: usize, mut run: impl FnMut()) -> f64 {
    (0..repeats.max(1))
        .map(|_| {
            let start = Instant::now();
            run();
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
        .max(1e-9)
}

/// The `cpu` field of [`BenchReport`].
fn cpu_description() -> String {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let field = |key: &str| {
        info.lines()
            .find(|l| l.split(':').next().is_some_and(|k| k.trim() == key))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_string())
    };
    let mut s = field("model name").unwrap_or_else(|| "unknown".to_string());
    if let (Some(family), Some(model)) = (field("cpu family"), field("model")) {
        s.push_str(&format!(" (family {family}, model {model})"));
    }
    // The features the hot paths use, as `acdf_core::cpu` finds them
    // (`ACDF_CPU=portable` turns them off): AVX2 with FMA, and the AVX-512
    // mask compares (F, VL and BW).
    let features = acdf_core::cpu::features();
    if features.avx2_fma {
        s.push_str(", avx2");
    }
    if features.mask_compares {
        s.push_str(", avx512f");
    }
    s
}

/// Chunk of draws per `sample_batch` call (and per rayon task).
const CHUNK: usize = 4096;

/// Time `sample_batch` of one distribution on one thread and on all.
fn bench_distribution(
    name: &str,
    dist: &dyn Distribution2D,
    (nx, ny): (usize, usize),
    u: &[Vec2],
    repeats: usize,
) -> DistributionBench {
    let mut out = vec![Sample2D::default(); u.len()];
    let one = best_seconds(repeats, || {
        for (uc, oc) in u.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            dist.sample_batch(uc, oc);
        }
        std::hint::black_box(&out);
    });
    let all = best_seconds(repeats, || {
        u.par_chunks(CHUNK)
            .zip(out.par_chunks_mut(CHUNK))
            .for_each(|(uc, oc)| dist.sample_batch(uc, oc));
        std::hint::black_box(&out);
    });
    let n = u.len() as f64;
    DistributionBench {
        name: name.to_string(),
        nx,
        ny,
        samples_per_second_one_thread: n / one,
        samples_per_second_all_threads: n / all,
        storage_bytes: dist.storage_bytes(),
    }
}

/// Outgoing directions for the per-call figures: θ_o from 5° to 80°, φ_o
/// spread over the circle.
fn outgoing_directions(count: usize) -> Vec<Vec3> {
    (0..count)
        .map(|k| {
            let t = (k as f32 + 0.5) / count as f32;
            spherical_direction(
                (5.0 + 75.0 * t).to_radians(),
                std::f32::consts::TAU * (k as f32 * 0.618_034).fract(),
            )
        })
        .collect()
}

/// Time `sample`, `sample_each`, `sample_batch`, `pdf`, `pdf_each` and
/// `pdf_batch` of a built sampler on one thread.
fn bench_sampler<S: BxdfSampler + ?Sized>(
    sampler: &S,
    resolution: String,
    u: &[Vec2],
    repeats: usize,
) -> SamplerBench {
    let directions = outgoing_directions(64);
    let wos: Vec<Vec3> = (0..u.len())
        .map(|k| directions[k % directions.len()])
        .collect();
    let n = u.len() as f64;
    let mut drawn: Vec<(Vec3, Vec3)> = Vec::with_capacity(u.len());
    let per_call = best_seconds(repeats, || {
        drawn.clear();
        for (&wo, &u) in wos.iter().zip(u) {
            if let Some(s) = sampler.sample(wo, u) {
                drawn.push((wo, s.wi));
            }
        }
        std::hint::black_box(&drawn);
    });
    let mut out = vec![None; u.len()];
    let each = best_seconds(repeats, || {
        for ((wc, uc), oc) in wos
            .chunks(CHUNK)
            .zip(u.chunks(CHUNK))
            .zip(out.chunks_mut(CHUNK))
        {
            sampler.sample_each(wc, uc, oc);
        }
        std::hint::black_box(&out);
    });
    let wo = spherical_direction(0.6, 1.3);
    let batch = best_seconds(repeats, || {
        for (uc, oc) in u.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            sampler.sample_batch(wo, uc, oc);
        }
        std::hint::black_box(&out);
    });
    let batch_wi: Vec<Vec3> = out.iter().flatten().map(|s| s.wi).collect();
    let pdf = best_seconds(repeats, || {
        let mut total = 0.0f32;
        for &(wo, wi) in &drawn {
            total += sampler.pdf(wo, wi);
        }
        std::hint::black_box(total);
    });
    let (drawn_wo, drawn_wi): (Vec<Vec3>, Vec<Vec3>) = drawn.iter().copied().unzip();
    let mut densities = vec![0.0f32; drawn.len().max(batch_wi.len())];
    let pdf_each = best_seconds(repeats, || {
        for ((wc, ic), oc) in drawn_wo
            .chunks(CHUNK)
            .zip(drawn_wi.chunks(CHUNK))
            .zip(densities.chunks_mut(CHUNK))
        {
            sampler.pdf_each(wc, ic, oc);
        }
        std::hint::black_box(&densities);
    });
    let pdf_batch = best_seconds(repeats, || {
        for (ic, oc) in batch_wi.chunks(CHUNK).zip(densities.chunks_mut(CHUNK)) {
            sampler.pdf_batch(wo, ic, oc);
        }
        std::hint::black_box(&densities);
    });
    SamplerBench {
        name: sampler.name().to_string(),
        resolution,
        sample_per_second: n / per_call,
        sample_each_per_second: n / each,
        sample_batch_per_second: n / batch,
        pdf_per_second: drawn.len().max(1) as f64 / pdf,
        pdf_each_per_second: drawn.len().max(1) as f64 / pdf_each,
        pdf_batch_per_second: batch_wi.len().max(1) as f64 / pdf_batch,
        storage_bytes: sampler.storage_bytes(),
    }
}

/// Time `build_all` of a fresh sampler made by `make`, best of `repeats`.
fn bench_build<B: SliceBuilder>(
    repeats: usize,
    make: impl Fn() -> Result<TabulatedBrdfSampler<B>>,
) -> Result<BuildBench> {
    let mut seconds = f64::INFINITY;
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let sampler = make()?;
        let start = Instant::now();
        sampler.build_all()?;
        seconds = seconds.min(start.elapsed().as_secs_f64());
        last = Some(sampler);
    }
    let sampler = last.ok_or_else(|| Error::InvalidArgument {
        what: "repeats",
        value: repeats.to_string(),
        reason: "nothing was built".into(),
    })?;
    Ok(BuildBench {
        name: sampler.name().to_string(),
        resolution: sampler.resolution().to_string(),
        seconds,
        storage_bytes: sampler.storage_bytes(),
    })
}

/// The material `name` names: a SPEC, or a bare built-in name.
fn material_spec(name: &str) -> Result<MaterialSpec> {
    match name.parse::<MaterialSpec>() {
        Ok(spec) => Ok(spec),
        Err(e) if !name.contains(':') && !name.contains('.') => {
            format!("builtin:{name}").parse().map_err(|_| e)
        }
        Err(e) => Err(e),
    }
}

/// Run every measurement of `config`.
pub fn run_bench(config: &BenchConfig) -> Result<BenchReport> {
    if config.samples == 0 {
        return Err(Error::InvalidArgument {
            what: "samples",
            value: "0".into(),
            reason: "must be at least 1".into(),
        });
    }
    if config.repeats == 0 {
        return Err(Error::InvalidArgument {
            what: "repeats",
            value: "0".into(),
            reason: "must be at least 1 run per figure".into(),
        });
    }
    // Per draw: its uniform pair, and the samples, directions and densities
    // the batch runs write (under 64 bytes in all).
    acdf_io::limits::check_memory(
        "the benchmark's draws (--samples)",
        acdf_io::limits::bytes_of(config.samples as u64, 64),
    )?;
    let load_average = load_average();
    let spec = material_spec(&config.material)?;
    let material = load_material(&spec, config.nbrdf_weights.as_deref())?;
    let brdf: Arc<dyn Brdf> = material.brdf.clone();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(config.seed);
    let u: Vec<Vec2> = (0..config.samples)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect();
    let repeats = config.repeats;

    // (a), (b): one slice, middle outgoing cell, as both distributions.
    let res = effective_resolution(&material, Resolution::ISOTROPIC);
    let values = tabulate_slice(&*brdf, &res, res.theta_o / 2, 0);
    let (nx, ny) = (res.phi_h, res.theta_h);
    let uniform_2d = PiecewiseConstant2D::new(&values, nx, ny)?;
    let adaptive_builder = AdaptiveBuilder::by_name("dp", None)?;
    let adaptive_2d: AdaptiveCdf2D = adaptive_builder.build_slice(&values, nx, ny)?;
    let distributions = vec![
        bench_distribution("piecewise_constant_2d", &uniform_2d, (nx, ny), &u, repeats),
        bench_distribution("adaptive_2d", &adaptive_2d, (nx, ny), &u, repeats),
    ];

    // (c): the samplers, every slice built before timing.
    let uniform = UniformBrdfSampler::new(brdf.clone(), res, PiecewiseConstantBuilder)?;
    uniform.build_all()?;
    let adaptive = TabulatedBrdfSampler::new(brdf.clone(), res, adaptive_builder.clone())?;
    adaptive.build_all()?;
    let clock_ghz_start = clock_ghz();
    let mut samplers = vec![
        bench_sampler(&uniform, uniform.resolution().to_string(), &u, repeats),
        bench_sampler(&adaptive, adaptive.resolution().to_string(), &u, repeats),
    ];
    drop((uniform, adaptive));
    // Then the 32x16x256x32 table of Lawrence et al. against the
    // configuration this project recommends: the same calls over tables
    // some 70 times apart in size.
    let seed = UniformBrdfSampler::new(
        brdf.clone(),
        effective_resolution(&material, Resolution::PAPER),
        PiecewiseConstantBuilder,
    )?;
    seed.build_all()?;
    samplers.push(bench_sampler(
        &seed,
        seed.resolution().to_string(),
        &u,
        repeats,
    ));
    drop(seed);
    let chi2 =
        TabulatedBrdfSampler::new(brdf.clone(), res, AdaptiveBuilder::by_name("chi2", None)?)?;
    chi2.build_all()?;
    samplers.push(bench_sampler(
        &chi2,
        chi2.resolution().to_string(),
        &u,
        repeats,
    ));
    drop(chi2);
    if material.brdf.is_isotropic() {
        let outgoing = make_sampler("outgoing:chi2", &material, &SamplerOptions::default())?;
        outgoing.build_all()?;
        let resolution = outgoing.resolution_label();
        samplers.push(bench_sampler(&outgoing, resolution, &u, repeats));
    }
    let clock_ghz_end = clock_ghz();

    // (d): the full 4D builds from a MERL-layout table.
    let merl: Arc<dyn Brdf> = match spec {
        MaterialSpec::Merl(_) | MaterialSpec::Nbrdf(_) => brdf.clone(),
        _ => Arc::new(MerlTable::tabulate(&*brdf)),
    };
    let build_res = config.build_resolution;
    let builds = vec![
        bench_build(repeats, || {
            Ok(UniformBrdfSampler::new(
                merl.clone(),
                build_res,
                PiecewiseConstantBuilder,
            )?)
        })?,
        bench_build(repeats, || {
            Ok(TabulatedBrdfSampler::new(
                merl.clone(),
                build_res,
                adaptive_builder.clone(),
            )?)
        })?,
    ];

    Ok(BenchReport {
        material: material.label(),
        material_spec: spec.to_string(),
        samples: config.samples,
        repeats,
        threads: rayon::current_num_threads(),
        load_average,
        clock_ghz_start,
        clock_ghz_end,
        cpu: cpu_description(),
        distributions,
        samplers,
        builds,
    })
}

/// The report as a plain-text table (millions per second, MB, seconds).
pub fn format_bench(report: &BenchReport) -> String {
    let mut s = format!(
        "material {}, {} samples, best of {}, {} threads, load average {}\ncpu {}\n",
        report.material_spec,
        report.samples,
        report.repeats,
        report.threads,
        report
            .load_average
            .map_or_else(|| "unknown".to_string(), |l| format!("{l:.2}")),
        report.cpu
    );
    s.push_str(&format!(
        "{:<24} {:>10} {:>12} {:>12}\n",
        "distribution", "size", "M/s 1 thr", "M/s all"
    ));
    for d in &report.distributions {
        s.push_str(&format!(
            "{:<24} {:>10} {:>12.2} {:>12.2}   {} bytes\n",
            d.name,
            format!("{}x{}", d.ny, d.nx),
            d.samples_per_second_one_thread / 1e6,
            d.samples_per_second_all_threads / 1e6,
            d.storage_bytes
        ));
    }
    s.push_str(&format!(
        "{:<14} {:>17} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}   (M/s, one thread)\n",
        "sampler", "resolution", "sample", "each", "batch", "pdf", "pdf each", "pdf batch"
    ));
    for b in &report.samplers {
        s.push_str(&format!(
            "{:<14} {:>17} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>9.2}   {} bytes\n",
            b.name,
            b.resolution,
            b.sample_per_second / 1e6,
            b.sample_each_per_second / 1e6,
            b.sample_batch_per_second / 1e6,
            b.pdf_per_second / 1e6,
            b.pdf_each_per_second / 1e6,
            b.pdf_batch_per_second / 1e6,
            b.storage_bytes
        ));
    }
    if let (Some(start), Some(end)) = (report.clock_ghz_start, report.clock_ghz_end) {
        // Cycles per call at the mean of the two readings: a figure that
        // does not move with the clock, as the rates above do.
        let hz = (start + end) / 2.0 * 1e9;
        s.push_str(&format!(
            "clock {start:.2} GHz before the samplers, {end:.2} after; cycles per call:\n"
        ));
        for b in &report.samplers {
            s.push_str(&format!(
                "{:<14} {:>17} {:>9.0} {:>9.0}   (sample, pdf)\n",
                b.name,
                b.resolution,
                hz / b.sample_per_second,
                hz / b.pdf_per_second
            ));
        }
    }
    s.push_str(&format!(
        "{:<24} {:>12} {:>12}\n",
        "build (MERL table)", "resolution", "seconds"
    ));
    for b in &report.builds {
        s.push_str(&format!(
            "{:<24} {:>12} {:>12.3}   {} bytes\n",
            b.name, b.resolution, b.seconds, b.storage_bytes
        ));
    }
    s
}

/// The arguments of `acdf bench`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The material to measure: any SPEC the other commands take
    /// (`builtin:NAME`, `nbrdf:NAME`, a MERL `.binary` or RGL `.bsdf`
    /// path); a bare built-in name such as `nickel` is `builtin:NAME`.
    #[arg(long, value_name = "SPEC", default_value = "nickel")]
    material: String,
    /// The Neural-BRDF weight file for `nbrdf:` materials.
    #[arg(long, value_name = "PATH")]
    nbrdf_weights: Option<std::path::PathBuf>,
    /// Uniform pairs per timed run.
    #[arg(long, default_value_t = 1_000_000)]
    samples: usize,
    /// Runs per figure; the best is reported.
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// Resolution θ_o×φ_o×θ_h×φ_h of the timed 4D builds (default the
    /// paper's 32x16x256x32).
    #[arg(long, value_name = "RES", default_value = "32x16x256x32")]
    build_resolution: String,
    /// Also write the results as JSON (fields documented on
    /// `BenchReport`).
    #[arg(long, value_name = "FILE")]
    json: Option<std::path::PathBuf>,
}

/// Measure, print the table, and write the JSON if asked.
pub fn run(a: Args) -> Result<()> {
    use std::io::Write;
    let build_resolution: Resolution =
        a.build_resolution
            .parse()
            .map_err(|e: acdf_core::Error| Error::InvalidArgument {
                what: "build resolution",
                value: a.build_resolution.clone(),
                reason: e.to_string(),
            })?;
    let config = BenchConfig {
        material: a.material,
        nbrdf_weights: a.nbrdf_weights,
        samples: a.samples,
        repeats: a.repeats,
        build_resolution,
        ..BenchConfig::default()
    };
    let pb = crate::common::spinner("measuring");
    let report = run_bench(&config);
    pb.finish_and_clear();
    let report = report?;
    let mut out = crate::common::stdout();
    write!(out, "{}", format_bench(&report))?;
    out.flush()?;
    if let Some(path) = &a.json {
        crate::common::write_json(path, &report)?;
    }
    Ok(())
}
