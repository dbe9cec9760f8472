//! `acdf render`: a sphere lit by an environment, rendered with each
//! sampler and compared with a high-count reference.

use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use acdf::env::{EnvMap, Environment, Sky};
use acdf::error::{Error, Result};
use acdf::material::Material;
use acdf::registry::{
    make_sampler_spec, render_default_help, render_samplers, sampler_help, sampler_long_help,
    AnySampler, SamplerOps, SamplerOptions,
};
use acdf::render::{render_equal_samples, render_equal_time, Film};
use acdf::spec::SamplerSpec;

use crate::common::{bar, file_stem_safe, material, spinner, stdout, MaterialArgs, TableArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    material: MaterialArgs,
    // The help lists the default set and every sampler, from the registry.
    #[arg(long, value_name = "LIST", help = samplers_help(false), long_help = samplers_help(true))]
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

fn samplers_help(long: bool) -> String {
    format!(
        "Samplers to compare, comma-separated (default: {}). {}",
        render_default_help(),
        if long {
            sampler_long_help(false)
        } else {
            sampler_help(false)
        }
    )
}

/// One compared sampler's result: its name, samples per pixel, seconds and
/// RMSE against the reference.
struct Compared {
    spec: SamplerSpec,
    spp: usize,
    seconds: f64,
    rmse: f64,
}

/// What every step of a render shares: the arguments, the material, the
/// environment and the sampler options.
struct Scene<'a> {
    a: &'a Args,
    m: Material,
    env: Box<dyn Environment>,
    options: SamplerOptions,
    /// The material's label, safe for file names.
    label: String,
}

/// Render the reference, then each sampler; write one PNG each and the
/// side-by-side composite, and print the RMSE table.
pub fn run(a: Args) -> Result<()> {
    check_sizes(&a)?;
    let m = material(&a.material)?;
    let options = a.tables.options()?;
    let specs: Vec<SamplerSpec> = match &a.samplers {
        Some(list) => list
            .split(',')
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(str::parse)
            .collect::<Result<_>>()?,
        None => render_samplers(&m),
    };
    let reference_spec: SamplerSpec = a.reference_sampler.parse()?;
    let env: Box<dyn Environment> = match &a.envmap {
        Some(p) => Box::new(EnvMap::open(p)?),
        None => Box::new(Sky::default()),
    };
    std::fs::create_dir_all(&a.out).map_err(|e| Error::io(&a.out, e))?;
    let label = file_stem_safe(&m.label());
    let scene = Scene {
        a: &a,
        m,
        env,
        options,
        label,
    };

    let reference = scene.reference(reference_spec)?;
    let (ref_path, ref_img) = scene.save(&reference, "reference")?;
    let mut panels = vec![(format!("reference {} spp", a.ref_spp), ref_img)];
    let mut written = vec![ref_path];
    let mut results = Vec::new();
    for spec in specs {
        let start = Instant::now();
        let film = scene.render(spec)?;
        let seconds = start.elapsed().as_secs_f64();
        let (path, img) = scene.save(&film, &spec.to_string())?;
        panels.push((format!("{spec} {} spp", film.samples_per_pixel()), img));
        written.push(path);
        results.push(Compared {
            spec,
            spp: film.samples_per_pixel(),
            seconds,
            rmse: film.rmse(&reference),
        });
    }
    let composite = acdf::plot::side_by_side(&panels)?;
    let side = a.out.join(format!("{}-side-by-side.png", scene.label));
    acdf::plot::write_png(&side, &composite)?;
    written.push(side);
    scene.print_results(&results)?;
    for p in written {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}

/// The longest `--seconds` per sampler accepted: a year.
const MAX_SECONDS: f64 = 365.0 * 24.0 * 3600.0;

/// Sizes, times and exposures that cannot render anything are errors
/// before any work, and so is a render larger than the memory limit.
fn check_sizes(a: &Args) -> Result<()> {
    if a.width == 0 || a.spp == 0 || a.ref_spp == 0 {
        return Err(Error::InvalidArgument {
            what: "render size",
            value: format!("width {} spp {} ref-spp {}", a.width, a.spp, a.ref_spp),
            reason: "all must be at least 1".into(),
        });
    }
    if a.equal_time && !(a.seconds > 0.0 && a.seconds <= MAX_SECONDS) {
        return Err(Error::InvalidArgument {
            what: "seconds",
            value: format!("{:?}", a.seconds),
            reason: format!("must be a positive number of seconds, at most {MAX_SECONDS:e}"),
        });
    }
    if !(a.exposure.is_finite() && a.exposure >= 0.0) {
        return Err(Error::InvalidArgument {
            what: "exposure",
            value: a.exposure.to_string(),
            reason: "must be a finite number, 0 or more".into(),
        });
    }
    // The film, and every image kept for the composite (one per sampler,
    // the reference and the composite itself, which is as wide as all).
    let images = 2 * (a.samplers.as_deref().map_or(4, |l| l.split(',').count()) + 1);
    acdf_core::limits::check_memory(
        &format!("a render of {0}x{0} pixels", a.width),
        acdf::render::render_memory_estimate(a.width, a.width, images),
    )?;
    Ok(())
}

impl Scene<'_> {
    /// The sampler `spec` with every table built.
    fn build(&self, spec: SamplerSpec) -> Result<AnySampler> {
        let s = make_sampler_spec(spec, &self.m, &self.options)?;
        let pb = spinner(&format!("building {spec}"));
        let r = s.build_all();
        pb.finish_and_clear();
        r.map(|_| s)
    }

    /// The reference image: `ref_spp` samples per pixel of `spec`.
    fn reference(&self, spec: SamplerSpec) -> Result<Film> {
        let a = self.a;
        let sampler = self.build(spec)?;
        let pb = bar(a.ref_spp as u64, &format!("reference ({spec})"));
        let start = Instant::now();
        let film = render_equal_samples(
            self.m.brdf.as_ref(),
            &sampler,
            self.env.as_ref(),
            a.width,
            a.ref_spp,
            (a.ref_spp / 16).max(1),
            a.seed ^ 0xA5A5_5A5A,
            |done| pb.set_position(done as u64),
        );
        pb.finish_and_clear();
        eprintln!(
            "reference: {spec}, {} spp in {:.1} s",
            a.ref_spp,
            start.elapsed().as_secs_f64()
        );
        Ok(film)
    }

    /// The image of one compared sampler, at equal samples or equal time.
    fn render(&self, spec: SamplerSpec) -> Result<Film> {
        let a = self.a;
        let s = self.build(spec)?;
        let (brdf, env) = (self.m.brdf.as_ref(), self.env.as_ref());
        Ok(if a.equal_time {
            let pb = bar(100, &format!("{spec} ({:.1} s)", a.seconds));
            let seconds = Duration::from_secs_f64(a.seconds);
            let film = render_equal_time(brdf, &s, env, a.width, seconds, a.seed, |f| {
                pb.set_position((f * 100.0) as u64)
            });
            pb.finish_and_clear();
            film
        } else {
            let pb = bar(a.spp as u64, &spec.to_string());
            let passes = (a.spp / 8).max(1);
            let film =
                render_equal_samples(brdf, &s, env, a.width, a.spp, passes, a.seed, |done| {
                    pb.set_position(done as u64)
                });
            pb.finish_and_clear();
            film
        })
    }

    /// Write `film` as `LABEL-NAME.png`.
    fn save(&self, film: &Film, name: &str) -> Result<(PathBuf, image::RgbImage)> {
        let img = film.to_rgb8(self.a.exposure);
        let path = self
            .a
            .out
            .join(format!("{}-{}.png", self.label, file_stem_safe(name)));
        acdf::plot::write_png(&path, &img)?;
        Ok((path, img))
    }

    /// The header line and the CSV of the results, RMSE also relative to
    /// the uniform sampler's when it was compared.
    fn print_results(&self, results: &[Compared]) -> Result<()> {
        let a = self.a;
        let uniform_rmse = results
            .iter()
            .find(|r| r.spec == SamplerSpec::UNIFORM)
            .map(|r| r.rmse);
        let mut out = stdout();
        writeln!(
            out,
            "{} ({}), {}x{} px, {}",
            self.m.label(),
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
        for r in results {
            let rel = uniform_rmse
                .filter(|u| *u > 0.0)
                .map(|u| format!("{:.3}", r.rmse / u))
                .unwrap_or_default();
            writeln!(
                out,
                "{},{},{:.3},{:.6},{rel}",
                r.spec, r.spp, r.seconds, r.rmse
            )?;
        }
        out.flush()?;
        Ok(())
    }
}
