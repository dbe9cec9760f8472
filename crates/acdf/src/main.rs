//! The `acdf` command: draw samples, evaluate densities and BRDFs, bake
//! Neural-BRDF networks into MERL files, and run the experiments (results
//! table, tolerance sweep, sphere renders). Every failure is one line on
//! stderr and exit status 1.

// The `bench` subcommand's measurements: a module of the binary, so that
// the library's public surface is unchanged.
mod bench;

use std::io::{BufRead, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use acdf::efficiency::EfficiencyConfig;
use acdf::env::{EnvMap, Environment, Sky};
use acdf::error::{Error, Result};
use acdf::material::{bake_material, load_material, write_merl, Material};
use acdf::registry::{load_sampler, make_sampler_spec, save_sampler, AnySampler, SamplerOptions};
use acdf::render::{render_equal_samples, render_equal_time, Film};
use acdf::report::{format_table, report_material, ReportRow};
use acdf::spec::{
    parse_direction_degrees, MaterialSpec, SamplerSpec, SimplifierName, DEFAULT_REPORT_MATERIALS,
};
use acdf::sweep::{default_tolerance, plot_sweep, run_sweep, write_csv, TOLERANCE_FACTORS};
use acdf_core::{BxdfSampler, Vec2, Vec3};
use acdf_tabulated::Resolution;
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use rand::{Rng, SeedableRng};

/// Importance sampling of measured BRDFs with adaptive numerical CDFs.
#[derive(Parser, Debug)]
#[command(name = "acdf", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Draw incident directions for one outgoing direction; CSV on stdout
    /// (`wi_x,wi_y,wi_z,pdf,valid`, a failed draw is `0,0,0,0,0`).
    Sample(SampleArgs),
    /// Print the sampler's solid-angle pdf for each `x,y,z` line of stdin.
    Pdf(PdfArgs),
    /// Print f_r (1/sr) as `r,g,b` for each `x,y,z` line of stdin.
    Eval(EvalArgs),
    /// Bake a material (normally `nbrdf:NAME`) into a MERL `.binary` file.
    Bake(BakeArgs),
    /// Build a tabulated sampler (uniform or adaptive) and save it to a file
    /// that `--sampler-file` loads without rebuilding.
    Build(BuildArgs),
    /// The results table: storage, compression and estimator efficiency of
    /// every sampler, per material.
    Report(ReportArgs),
    /// Efficiency against storage for each simplifier over a range of
    /// tolerances: CSV on stdout, CSV/JSON/SVG/PNG in the output directory.
    Sweep(SweepArgs),
    /// Render a sphere lit by an environment with each sampler and compare
    /// with a high-count reference.
    Render(RenderArgs),
    /// Sampling throughput (samples per second) of the 2D distributions and
    /// the BRDF samplers, and the build time of the 4D tables; a table on
    /// stdout, optionally JSON.
    Bench(BenchArgs),
}

#[derive(Args, Debug)]
struct BenchArgs {
    /// Built-in material to measure.
    #[arg(long, value_name = "NAME", default_value = "nickel")]
    material: String,
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
    json: Option<PathBuf>,
}

#[derive(Args, Debug, Clone)]
struct MaterialArgs {
    /// `builtin:NAME` (nickel, blue-metallic-paint, gray-plastic, lambert,
    /// near-mirror), a MERL `.binary` path, an RGL `.bsdf` path, or
    /// `nbrdf:NAME`.
    #[arg(long, value_name = "SPEC")]
    material: String,
    /// The Neural-BRDF weight file for `nbrdf:` materials (default
    /// ../shared/data/merl-neural-brdf/merl_nbrdf_weights.f32 when present).
    #[arg(long, value_name = "PATH")]
    nbrdf_weights: Option<PathBuf>,
}

#[derive(Args, Debug, Clone)]
struct SamplerArgs {
    /// cosine, uniform, adaptive (Douglas-Peucker), adaptive:dp, adaptive:vw,
    /// adaptive:rw, adaptive:optimal, adaptive:chi2, or rgl (for .bsdf
    /// materials).
    #[arg(long, value_name = "NAME", default_value = "adaptive")]
    sampler: String,
    /// Load a sampler saved by `acdf build` instead of building one (the
    /// file must have been built for `--material`).
    #[arg(long, value_name = "FILE", conflicts_with = "sampler")]
    sampler_file: Option<PathBuf>,
    #[command(flatten)]
    tables: TableArgs,
}

#[derive(Args, Debug)]
struct BuildArgs {
    #[command(flatten)]
    material: MaterialArgs,
    /// uniform, adaptive (Douglas-Peucker), adaptive:dp, adaptive:vw,
    /// adaptive:rw, adaptive:optimal or adaptive:chi2.
    #[arg(long, value_name = "NAME", default_value = "adaptive")]
    sampler: String,
    #[command(flatten)]
    tables: TableArgs,
    /// The sampler file to write (atomically: a temporary file, then a
    /// rename).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
}

#[derive(Args, Debug, Clone)]
struct TableArgs {
    /// Simplifier tolerance of adaptive samplers (default: the simplifier's
    /// own).
    #[arg(long, value_name = "X")]
    tolerance: Option<f64>,
    /// Tabulation θ_o×φ_o×θ_h×φ_h (default 32x1x256x32, the isotropic
    /// configuration).
    #[arg(long, value_name = "RES", conflicts_with = "paper")]
    resolution: Option<String>,
    /// Use the paper's resolution 32x16x256x32.
    #[arg(long)]
    paper: bool,
    /// Probability of drawing from the cosine lobe instead of the table.
    #[arg(long, value_name = "A", default_value_t = 0.0)]
    cosine_mix: f32,
}

impl TableArgs {
    fn options(&self) -> Result<SamplerOptions> {
        let resolution = match (&self.resolution, self.paper) {
            (_, true) => Resolution::PAPER,
            (Some(r), false) => {
                r.parse()
                    .map_err(|e: acdf_core::Error| Error::InvalidArgument {
                        what: "resolution",
                        value: r.clone(),
                        reason: e.to_string(),
                    })?
            }
            (None, false) => Resolution::ISOTROPIC,
        };
        if let Some(t) = self.tolerance {
            if t.is_nan() || t < 0.0 {
                return Err(Error::InvalidArgument {
                    what: "tolerance",
                    value: t.to_string(),
                    reason: "must be a non-negative number".into(),
                });
            }
        }
        Ok(SamplerOptions {
            resolution,
            tolerance: self.tolerance,
            cosine_mix: self.cosine_mix,
        })
    }
}

#[derive(Args, Debug)]
struct SampleArgs {
    #[command(flatten)]
    material: MaterialArgs,
    #[command(flatten)]
    sampler: SamplerArgs,
    /// Outgoing direction THETA_DEG,PHI_DEG.
    #[arg(long, value_name = "T,P", allow_hyphen_values = true)]
    wo: String,
    /// Number of draws.
    #[arg(long, default_value_t = 1000)]
    n: usize,
    /// Seed of the uniform numbers (PCG64).
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(Args, Debug)]
struct PdfArgs {
    #[command(flatten)]
    material: MaterialArgs,
    #[command(flatten)]
    sampler: SamplerArgs,
    /// Outgoing direction THETA_DEG,PHI_DEG.
    #[arg(long, value_name = "T,P", allow_hyphen_values = true)]
    wo: String,
}

#[derive(Args, Debug)]
struct EvalArgs {
    #[command(flatten)]
    material: MaterialArgs,
    /// Outgoing direction THETA_DEG,PHI_DEG.
    #[arg(long, value_name = "T,P", allow_hyphen_values = true)]
    wo: String,
}

#[derive(Args, Debug)]
struct BakeArgs {
    #[command(flatten)]
    material: MaterialArgs,
    /// The MERL file to write.
    #[arg(long, value_name = "FILE.binary")]
    out: PathBuf,
}

#[derive(Args, Debug)]
struct ReportArgs {
    /// Materials (repeatable; default: builtin:nickel,
    /// builtin:blue-metallic-paint, builtin:gray-plastic).
    #[arg(long, value_name = "SPEC")]
    material: Vec<String>,
    /// The Neural-BRDF weight file for `nbrdf:` materials.
    #[arg(long, value_name = "PATH")]
    nbrdf_weights: Option<PathBuf>,
    /// Also write the rows as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    #[command(flatten)]
    measure: MeasureArgs,
    #[command(flatten)]
    tables: TableArgs,
}

#[derive(Args, Debug, Clone)]
struct MeasureArgs {
    /// Draws per outgoing direction for the variance (12 directions).
    #[arg(long, value_name = "N", default_value_t = 1 << 17)]
    samples: usize,
    /// Draws per outgoing direction in each timed pass.
    #[arg(long, value_name = "N", default_value_t = 1 << 13)]
    timing_samples: usize,
    /// Timed passes per sampler, the fastest kept; a report takes the
    /// passes of a material's samplers in turns.
    #[arg(long, value_name = "N", default_value_t = 3)]
    timing_passes: usize,
    /// Seed of the uniform numbers.
    #[arg(long, default_value_t = 2005)]
    seed: u64,
}

impl MeasureArgs {
    fn config(&self) -> Result<EfficiencyConfig> {
        if self.samples < 2 || self.timing_samples < 1 || self.timing_passes < 1 {
            return Err(Error::InvalidArgument {
                what: "sample count",
                value: format!(
                    "{}/{}/{}",
                    self.samples, self.timing_samples, self.timing_passes
                ),
                reason: "need at least 2 draws for a variance, 1 to time and 1 timed pass".into(),
            });
        }
        Ok(EfficiencyConfig {
            samples_per_direction: self.samples,
            timing_samples_per_direction: self.timing_samples,
            timing_passes: self.timing_passes,
            seed: self.seed,
            ..EfficiencyConfig::default()
        })
    }

    fn describe(&self, config: &EfficiencyConfig) -> String {
        format!(
            "variance: {} outgoing directions x {} draws = {} draws per sampler (seed {}); \
             time: best of {} single-thread passes of {} x {} draws",
            config.outgoing.len(),
            config.samples_per_direction,
            config.total_samples(),
            config.seed,
            config.timing_passes,
            config.outgoing.len(),
            config.timing_samples_per_direction
        )
    }
}

#[derive(Args, Debug)]
struct SweepArgs {
    #[command(flatten)]
    material: MaterialArgs,
    /// Simplifiers to sweep, comma-separated.
    #[arg(long, value_name = "LIST", default_value = "dp,vw,rw,optimal")]
    simplifiers: String,
    /// Tolerances, comma-separated (default: each simplifier's default
    /// tolerance times 1/16, 1/8, ..., 8).
    #[arg(long, value_name = "LIST")]
    tolerances: Option<String>,
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    #[command(flatten)]
    measure: SweepMeasureArgs,
    /// Tabulation θ_o×φ_o×θ_h×φ_h (default 32x1x256x32).
    #[arg(long, value_name = "RES", conflicts_with = "paper")]
    resolution: Option<String>,
    /// Use the paper's resolution 32x16x256x32.
    #[arg(long)]
    paper: bool,
}

#[derive(Args, Debug, Clone)]
struct SweepMeasureArgs {
    /// Draws per outgoing direction for the variance (12 directions).
    #[arg(long, value_name = "N", default_value_t = 1 << 15)]
    samples: usize,
    /// Draws per outgoing direction in each timed pass.
    #[arg(long, value_name = "N", default_value_t = 1 << 12)]
    timing_samples: usize,
    /// Timed passes per sampler, the fastest kept; the samplers take turns.
    #[arg(long, value_name = "N", default_value_t = 3)]
    timing_passes: usize,
    /// Seed of the uniform numbers.
    #[arg(long, default_value_t = 2005)]
    seed: u64,
}

#[derive(Args, Debug)]
struct RenderArgs {
    #[command(flatten)]
    material: MaterialArgs,
    /// Samplers to compare, comma-separated (default: cosine, uniform,
    /// adaptive, and rgl for .bsdf materials).
    #[arg(long, value_name = "LIST")]
    samplers: Option<String>,
    /// The sampler of the reference image.
    #[arg(long, value_name = "NAME", default_value = "uniform")]
    reference_sampler: String,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 128)]
    width: usize,
    /// Samples per pixel of each compared sampler.
    #[arg(long, default_value_t = 16)]
    spp: usize,
    /// Samples per pixel of the reference.
    #[arg(long, default_value_t = 1024)]
    ref_spp: usize,
    /// Give every sampler the same time instead of the same sample count.
    #[arg(long)]
    equal_time: bool,
    /// Seconds per sampler with --equal-time.
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    seconds: f64,
    /// An .exr or .hdr latitude-longitude environment (default: the
    /// procedural sky with a sun).
    #[arg(long, value_name = "FILE")]
    envmap: Option<PathBuf>,
    /// Exposure applied before clamping and sRGB encoding.
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Seed of the uniform numbers.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    #[command(flatten)]
    tables: TableArgs,
}

fn main() -> ExitCode {
    // A bug should still be one line on stderr, not a backtrace.
    std::panic::set_hook(Box::new(|info| {
        let message = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".to_string());
        let place = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!(
            "acdf: internal error{place}: {}",
            message.replace('\n', " ")
        );
    }));
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        // A closed pipe (e.g. `acdf sample ... | head`) is not a failure.
        Err(Error::Stream(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("acdf: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Sample(a) => cmd_sample(a),
        Command::Pdf(a) => cmd_pdf(a),
        Command::Eval(a) => cmd_eval(a),
        Command::Bake(a) => cmd_bake(a),
        Command::Build(a) => cmd_build(a),
        Command::Report(a) => cmd_report(a),
        Command::Sweep(a) => cmd_sweep(a),
        Command::Render(a) => cmd_render(a),
        Command::Bench(a) => cmd_bench(a),
    }
}

/// A progress bar on stderr (drawn only when stderr is a terminal).
fn bar(len: u64, what: &str) -> ProgressBar {
    let style = ProgressStyle::with_template("{msg:40!} [{bar:30}] {pos}/{len} {elapsed}")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    let pb = ProgressBar::new(len).with_style(style);
    pb.set_message(what.to_string());
    pb
}

fn spinner(what: &str) -> ProgressBar {
    let pb = ProgressBar::new_spinner();
    pb.set_message(what.to_string());
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

fn material(args: &MaterialArgs) -> Result<Material> {
    let spec: MaterialSpec = args.material.parse()?;
    load_material(&spec, args.nbrdf_weights.as_deref())
}

fn sampler(args: &SamplerArgs, material: &Material) -> Result<AnySampler> {
    let Some(path) = &args.sampler_file else {
        let spec: SamplerSpec = args.sampler.parse()?;
        return make_sampler_spec(spec, material, &args.tables.options()?);
    };
    let loaded = load_sampler(path)?;
    match loaded.material_name() {
        Some(name) if name != material.brdf.name() => Err(Error::Incompatible {
            sampler: path.display().to_string(),
            material: material.spec.to_string(),
            reason: format!("the file was built for material `{name}`"),
        }),
        _ => Ok(loaded),
    }
}

/// Build, save, and load back once to report the load time against the
/// build time.
fn cmd_build(a: BuildArgs) -> Result<()> {
    let m = material(&a.material)?;
    let spec: SamplerSpec = a.sampler.parse()?;
    let s = make_sampler_spec(spec, &m, &a.tables.options()?)?;
    let pb = spinner("building tables");
    let started = Instant::now();
    s.build_all()?;
    let build = started.elapsed();
    pb.finish_and_clear();
    let started = Instant::now();
    save_sampler(&s, &a.out)?;
    let save = started.elapsed();
    let started = Instant::now();
    let loaded = load_sampler(&a.out)?;
    let load = started.elapsed();
    let file_bytes = std::fs::metadata(&a.out)
        .map_err(|e| Error::io(&a.out, e))?
        .len();
    println!(
        "{} for {} ({}): storage {} bytes, file {} bytes; built in {:.3} s, saved in {:.3} s, loaded in {:.3} s",
        loaded.name(),
        m.spec,
        s.resolution_label(),
        s.storage_bytes(),
        file_bytes,
        build.as_secs_f64(),
        save.as_secs_f64(),
        load.as_secs_f64(),
    );
    Ok(())
}

fn stdout() -> BufWriter<std::io::StdoutLock<'static>> {
    BufWriter::new(std::io::stdout().lock())
}

fn cmd_sample(a: SampleArgs) -> Result<()> {
    let wo = parse_direction_degrees(&a.wo)?;
    let m = material(&a.material)?;
    let s = sampler(&a.sampler, &m)?;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(a.seed);
    let mut out = stdout();
    writeln!(out, "wi_x,wi_y,wi_z,pdf,valid")?;
    for _ in 0..a.n {
        let u = Vec2::new(rng.random(), rng.random());
        match s.sample(wo, u) {
            Some(d) => writeln!(out, "{},{},{},{},1", d.wi.x, d.wi.y, d.wi.z, d.pdf)?,
            None => writeln!(out, "0,0,0,0,0")?,
        }
    }
    out.flush()?;
    Ok(())
}

/// Read `x,y,z` lines from stdin (further columns, blank lines, `#`
/// comments and a `wi_x,...` header are ignored) and call `each` with the
/// normalised direction (zero if it has no length).
fn for_each_direction(mut each: impl FnMut(Vec3) -> Result<()>) -> Result<()> {
    let stdin = std::io::stdin();
    for (k, line) in stdin.lock().lines().enumerate() {
        let line = line?;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') || t.starts_with("wi_x") {
            continue;
        }
        let fields: Vec<&str> = t.split(',').map(str::trim).collect();
        if fields.len() < 3 {
            return Err(Error::Input {
                line: k + 1,
                reason: format!("expected x,y,z, got `{t}`"),
            });
        }
        let mut v = [0.0f32; 3];
        for (slot, f) in v.iter_mut().zip(&fields) {
            *slot = f.parse().map_err(|_| Error::Input {
                line: k + 1,
                reason: format!("`{f}` is not a number"),
            })?;
            if !slot.is_finite() {
                return Err(Error::Input {
                    line: k + 1,
                    reason: format!("`{f}` is not finite"),
                });
            }
        }
        each(Vec3::from(v).normalize_or_zero())?;
    }
    Ok(())
}

fn cmd_pdf(a: PdfArgs) -> Result<()> {
    let wo = parse_direction_degrees(&a.wo)?;
    let m = material(&a.material)?;
    let s = sampler(&a.sampler, &m)?;
    let mut out = stdout();
    for_each_direction(|wi| Ok(writeln!(out, "{}", s.pdf(wo, wi))?))?;
    out.flush()?;
    Ok(())
}

fn cmd_eval(a: EvalArgs) -> Result<()> {
    let wo = parse_direction_degrees(&a.wo)?;
    let m = material(&a.material)?;
    let mut out = stdout();
    for_each_direction(|wi| {
        let f = m.brdf.eval(wo, wi);
        Ok(writeln!(out, "{},{},{}", f.x, f.y, f.z)?)
    })?;
    out.flush()?;
    Ok(())
}

fn cmd_bake(a: BakeArgs) -> Result<()> {
    let spec: MaterialSpec = a.material.material.parse()?;
    let pb = spinner(&format!("baking {spec}"));
    let start = Instant::now();
    let table = bake_material(&spec, a.material.nbrdf_weights.as_deref());
    pb.finish_and_clear();
    let table = table?;
    write_merl(&table, &a.out)?;
    eprintln!(
        "baked {spec} into {} in {:.1} s",
        a.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn cmd_bench(a: BenchArgs) -> Result<()> {
    let build_resolution: Resolution =
        a.build_resolution
            .parse()
            .map_err(|e: acdf_core::Error| Error::InvalidArgument {
                what: "build resolution",
                value: a.build_resolution.clone(),
                reason: e.to_string(),
            })?;
    let config = bench::BenchConfig {
        material: a.material,
        samples: a.samples,
        repeats: a.repeats,
        build_resolution,
        ..bench::BenchConfig::default()
    };
    let pb = spinner("measuring");
    let report = bench::run_bench(&config);
    pb.finish_and_clear();
    let report = report?;
    let mut out = stdout();
    write!(out, "{}", bench::format_bench(&report))?;
    out.flush()?;
    if let Some(path) = &a.json {
        write_json(path, &report)?;
    }
    Ok(())
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let text = serde_json::to_string_pretty(value)?;
    std::fs::write(path, text + "\n").map_err(|e| Error::io(path, e))
}

fn cmd_report(a: ReportArgs) -> Result<()> {
    let options = a.tables.options()?;
    let config = a.measure.config()?;
    let names: Vec<String> = if a.material.is_empty() {
        DEFAULT_REPORT_MATERIALS
            .iter()
            .map(|n| format!("builtin:{n}"))
            .collect()
    } else {
        a.material.clone()
    };
    // Load (and so validate) every material before measuring anything.
    let materials: Vec<Material> = names
        .iter()
        .map(|n| load_material(&n.parse()?, a.nbrdf_weights.as_deref()))
        .collect::<Result<_>>()?;
    let env = Sky::dome();
    // Each material's samplers, then its timing step.
    let total: usize = materials
        .iter()
        .map(|m| acdf::registry::report_samplers(m).len() + 1)
        .sum();
    println!("{}", a.measure.describe(&config));
    println!(
        "efficiency = 1 / (variance x time per sample), environment: procedural sky without its sun; \
         resolution {}",
        options.resolution
    );
    let pb = bar(total as u64, "report");
    let start = Instant::now();
    let mut rows: Vec<ReportRow> = Vec::new();
    for m in &materials {
        let label = m.label();
        let r = report_material(m, &env, &options, &config, |s| {
            pb.set_message(format!("{label}: {s}"));
            pb.inc(1);
        })?;
        rows.extend(r);
    }
    pb.finish_and_clear();
    println!();
    print!("{}", format_table(&rows));
    println!(
        "\n{} rows (material x sampler) measured in {:.1} s",
        rows.len(),
        start.elapsed().as_secs_f64()
    );
    if let Some(path) = &a.json {
        write_json(path, &rows)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

fn parse_list<T>(s: &str, what: &'static str, parse: impl Fn(&str) -> Option<T>) -> Result<Vec<T>> {
    let items: Vec<&str> = s
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .collect();
    if items.is_empty() {
        return Err(Error::InvalidArgument {
            what,
            value: s.to_string(),
            reason: "empty list".into(),
        });
    }
    items
        .into_iter()
        .map(|t| {
            parse(t).ok_or_else(|| Error::InvalidArgument {
                what,
                value: t.to_string(),
                reason: "not recognised".into(),
            })
        })
        .collect()
}

fn file_stem_safe(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect()
}

fn cmd_sweep(a: SweepArgs) -> Result<()> {
    let m = material(&a.material)?;
    let simplifiers = parse_list(&a.simplifiers, "simplifier", |t| {
        SimplifierName::ALL.into_iter().find(|s| s.short() == t)
    })?;
    let fixed: Option<Vec<f64>> = a
        .tolerances
        .as_deref()
        .map(|s| {
            parse_list(s, "tolerance", |t| {
                t.parse::<f64>().ok().filter(|x| *x >= 0.0)
            })
        })
        .transpose()?;
    let tables = TableArgs {
        tolerance: None,
        resolution: a.resolution.clone(),
        paper: a.paper,
        cosine_mix: 0.0,
    };
    let options = tables.options()?;
    let measure = MeasureArgs {
        samples: a.measure.samples,
        timing_samples: a.measure.timing_samples,
        timing_passes: a.measure.timing_passes,
        seed: a.measure.seed,
    };
    let config = measure.config()?;
    let per_simplifier = fixed.as_ref().map_or(TOLERANCE_FACTORS.len(), Vec::len);
    // The two references, every simplifier at every tolerance, then the timing.
    let total = 2 + simplifiers.len() * per_simplifier + 1;
    eprintln!("{}", measure.describe(&config));
    let pb = bar(total as u64, "sweep");
    let points = run_sweep(
        &m,
        &Sky::dome(),
        &options,
        &simplifiers,
        |s| match &fixed {
            Some(t) => Ok(t.clone()),
            None => {
                let d = default_tolerance(s)?;
                Ok(TOLERANCE_FACTORS.iter().map(|f| f * d).collect())
            }
        },
        &config,
        |what| {
            pb.set_message(what.to_string());
            pb.inc(1);
        },
    );
    pb.finish_and_clear();
    let points = points?;
    std::fs::create_dir_all(&a.out).map_err(|e| Error::io(&a.out, e))?;
    let base = a.out.join(format!("sweep-{}", file_stem_safe(&m.label())));
    let csv_path = base.with_extension("csv");
    let mut csv = Vec::new();
    write_csv(&points, &mut csv)?;
    std::fs::write(&csv_path, &csv).map_err(|e| Error::io(&csv_path, e))?;
    let json_path = base.with_extension("json");
    write_json(&json_path, &points)?;
    let (svg, png) = (base.with_extension("svg"), base.with_extension("png"));
    plot_sweep(
        &points,
        &format!(
            "{}: efficiency against storage ({})",
            m.label(),
            options.resolution
        ),
        &svg,
        &png,
    )?;
    let mut out = stdout();
    out.write_all(&csv)?;
    out.flush()?;
    for p in [&csv_path, &json_path, &svg, &png] {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}

fn cmd_render(a: RenderArgs) -> Result<()> {
    if a.width == 0 || a.spp == 0 || a.ref_spp == 0 {
        return Err(Error::InvalidArgument {
            what: "render size",
            value: format!("width {} spp {} ref-spp {}", a.width, a.spp, a.ref_spp),
            reason: "all must be at least 1".into(),
        });
    }
    if a.equal_time && !(a.seconds > 0.0 && a.seconds.is_finite()) {
        return Err(Error::InvalidArgument {
            what: "seconds",
            value: a.seconds.to_string(),
            reason: "must be a positive number".into(),
        });
    }
    let m = material(&a.material)?;
    let options = a.tables.options()?;
    let specs: Vec<SamplerSpec> = match &a.samplers {
        Some(list) => list
            .split(',')
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(str::parse)
            .collect::<Result<_>>()?,
        None => {
            let mut v = vec![
                SamplerSpec::Cosine,
                SamplerSpec::Uniform,
                SamplerSpec::Adaptive(SimplifierName::DouglasPeucker),
            ];
            if m.rgl.is_some() {
                v.push(SamplerSpec::Rgl);
            }
            v
        }
    };
    let reference_spec: SamplerSpec = a.reference_sampler.parse()?;
    let env: Box<dyn Environment> = match &a.envmap {
        Some(p) => Box::new(EnvMap::open(p)?),
        None => Box::new(Sky::default()),
    };
    std::fs::create_dir_all(&a.out).map_err(|e| Error::io(&a.out, e))?;
    let label = file_stem_safe(&m.label());

    let build = |spec: SamplerSpec| -> Result<AnySampler> {
        let s = make_sampler_spec(spec, &m, &options)?;
        let pb = spinner(&format!("building {spec}"));
        let r = s.build_all();
        pb.finish_and_clear();
        r.map(|_| s)
    };

    let reference_sampler = build(reference_spec)?;
    let pb = bar(a.ref_spp as u64, &format!("reference ({reference_spec})"));
    let start = Instant::now();
    let reference = render_equal_samples(
        m.brdf.as_ref(),
        &reference_sampler,
        env.as_ref(),
        a.width,
        a.ref_spp,
        (a.ref_spp / 16).max(1),
        a.seed ^ 0xA5A5_5A5A,
        |done| pb.set_position(done as u64),
    );
    pb.finish_and_clear();
    eprintln!(
        "reference: {reference_spec}, {} spp in {:.1} s",
        a.ref_spp,
        start.elapsed().as_secs_f64()
    );
    let save = |film: &Film, name: &str| -> Result<(PathBuf, image::RgbImage)> {
        let img = film.to_rgb8(a.exposure);
        let path = a.out.join(format!("{label}-{}.png", file_stem_safe(name)));
        img.save(&path).map_err(|e| Error::Image {
            path: path.clone(),
            message: e.to_string(),
        })?;
        Ok((path, img))
    };
    let (ref_path, ref_img) = save(&reference, "reference")?;
    let mut panels = vec![(format!("reference {} spp", a.ref_spp), ref_img)];
    let mut written = vec![ref_path];

    let mut results = Vec::new();
    for spec in specs {
        let s = build(spec)?;
        let start = Instant::now();
        let film = if a.equal_time {
            let pb = bar(100, &format!("{spec} ({:.1} s)", a.seconds));
            let film = render_equal_time(
                m.brdf.as_ref(),
                &s,
                env.as_ref(),
                a.width,
                Duration::from_secs_f64(a.seconds),
                a.seed,
                |f| pb.set_position((f * 100.0) as u64),
            );
            pb.finish_and_clear();
            film
        } else {
            let pb = bar(a.spp as u64, &spec.to_string());
            let film = render_equal_samples(
                m.brdf.as_ref(),
                &s,
                env.as_ref(),
                a.width,
                a.spp,
                (a.spp / 8).max(1),
                a.seed,
                |done| pb.set_position(done as u64),
            );
            pb.finish_and_clear();
            film
        };
        let seconds = start.elapsed().as_secs_f64();
        let rmse = film.rmse(&reference);
        let (path, img) = save(&film, &spec.to_string())?;
        panels.push((format!("{spec} {} spp", film.samples_per_pixel()), img));
        written.push(path);
        results.push((spec, film.samples_per_pixel(), seconds, rmse));
    }
    let composite = acdf::plot::side_by_side(&panels)?;
    let side = a.out.join(format!("{label}-side-by-side.png"));
    composite.save(&side).map_err(|e| Error::Image {
        path: side.clone(),
        message: e.to_string(),
    })?;
    written.push(side);

    let uniform_rmse = results
        .iter()
        .find(|r| r.0 == SamplerSpec::Uniform)
        .map(|r| r.3);
    let mut out = stdout();
    writeln!(
        out,
        "{} ({}), {}x{} px, {}",
        m.label(),
        if a.envmap.is_some() {
            "environment map"
        } else {
            "procedural sky"
        },
        a.width,
        a.width,
        if a.equal_time {
            format!("equal time {:.2} s per sampler", a.seconds)
        } else {
            format!("equal samples {} spp", a.spp)
        }
    )?;
    writeln!(out, "sampler,spp,seconds,rmse,rmse_vs_uniform")?;
    for (spec, spp, seconds, rmse) in &results {
        let rel = uniform_rmse
            .filter(|u| *u > 0.0)
            .map(|u| format!("{:.3}", rmse / u))
            .unwrap_or_default();
        writeln!(out, "{spec},{spp},{seconds:.3},{rmse:.6},{rel}")?;
    }
    out.flush()?;
    for p in written {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}
