//! `acdf render`: a sphere (optionally on a ground plane) lit by an
//! environment map, rendered with BRDF sampling, light sampling and their
//! MIS combinations, compared with a reference; or, with
//! `--export-mitsuba`, the same scene written for Mitsuba 3.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use acdf::env::{Environment, Sky};
use acdf::env_registry::{make_env_sampler, AnyEnvSampler, EnvSamplerOptions};
use acdf::error::{Error, Result};
use acdf::lights::{EnvMap, EnvironmentLight};
use acdf::material::Material;
use acdf::product::{ProductEnv, ProductOptions};
use acdf::registry::{make_sampler, sampler_help, AnySampler, SamplerOps};
use acdf_core::{BxdfSampler, Rgb, SphereSampler, Vec3};
use acdf_experiments::plot::{Figure, Panel, Series, Style};
use acdf_materials::analytic::Lambert;
use acdf_render::render::{
    render, render_memory_estimate, Budget, Camera, Film, Geometry, PixelSampling, ProductLight,
    Progress, Rendered, Shader, Strategy, Surface, DEFAULT_MIS_FRACTION, PLANE_ALBEDO,
    PRODUCT_LIGHT_SHARE,
};

use crate::common::{bar, file_stem_safe, material, spinner, stdout, MaterialArgs, TableArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    material: MaterialArgs,
    /// An .exr or .hdr latitude-longitude environment map, +z up (default:
    /// the procedural sky with a sun, baked into a 512x256 map).
    #[arg(long, value_name = "FILE")]
    envmap: Option<PathBuf>,
    /// Put the sphere on a square ground plane (a Lambertian grey).
    #[arg(long)]
    plane: bool,
    // The help lists every sampler, from the registry.
    #[arg(long, value_name = "NAME", default_value = "adaptive", help = brdf_help())]
    brdf_sampler: String,
    /// The environment sampler of light sampling (any of `acdf env-sample
    /// --help`: uniform, adaptive:S, oriented:S, ...).
    #[arg(long, value_name = "NAME", default_value = "adaptive")]
    env_sampler: String,
    /// The environment sampler MIS pairs with the BRDF sampler (default:
    /// the compensated form of --env-sampler: uniform-comp for uniform,
    /// adaptive-comp:S for adaptive:S, the sampler itself otherwise).
    #[arg(long, value_name = "NAME")]
    mis_env_sampler: Option<String>,
    // The help names every strategy, from `Strategy::ALL`.
    #[arg(long, value_name = "LIST", default_value_t = Strategy::all_names(), help = strategies_help())]
    strategies: String,
    /// The probability c with which mis-one-sample draws from the BRDF
    /// sampler (the environment sampler otherwise), in [0, 1]; each draw is
    /// divided by the mixture density c p_brdf + (1 - c) p_light.
    #[arg(long, value_name = "C", default_value_t = DEFAULT_MIS_FRACTION)]
    mis_fraction: f32,
    /// Block columns of the map for product and mis-product (block rows:
    /// half as many), from 1 to 1024; each pixel's query weighs every block
    /// above its horizon by the BRDF sampler's density.
    #[arg(long, value_name = "N", default_value_t = ProductOptions::default().block_columns)]
    product_blocks: usize,
    /// Evaluation points of the BRDF factor per block side for product and
    /// mis-product (S² per block and shading point), from 1 to 1024.
    #[arg(long, value_name = "S", default_value_t = 1)]
    product_points: usize,
    /// Directions drawn per shading point by product and mis-product (of
    /// each technique), averaged: several share one camera ray.
    #[arg(long, value_name = "K", default_value_t = 1)]
    product_draws: usize,
    /// Draws of the BRDF sampler per shading point of a product query that
    /// estimate each block's BRDF mass times its light, from 0 (the point
    /// densities alone) to 65,536; they see a lobe narrower than a block.
    /// At equal CPU time they did not pay in the renders of
    /// docs/rendering.md.
    #[arg(long, value_name = "N", default_value_t = ProductOptions::default().mass_draws)]
    product_mass_draws: usize,
    /// How many mass draws must land in a block before their estimate
    /// counts half: a block of c draws weighs the larger of its point
    /// estimate (--product-points) and c / (c + C) × its mass estimate.
    #[arg(long, value_name = "C", default_value_t = ProductOptions::default().mass_prior)]
    product_mass_prior: f32,
    /// Sub-cells per block side (fewer where a block has fewer texels), from
    /// 1 to 4: inside a drawn block, a sub-cell is drawn by its light
    /// times the BRDF density at its centre (1: texels by light alone).
    /// 1 by default here: the sub-cells' tables and look-ups cost more CPU
    /// time than they saved in the renders of docs/rendering.md (the
    /// product sampler's own default is 4).
    #[arg(long, value_name = "K", default_value_t = 1)]
    product_sub_cells: usize,
    /// The share, in [0, 1], of the sub-cell draws inside a block by light
    /// alone, which keeps every lit sub-cell drawable.
    #[arg(long, value_name = "G", default_value_t = ProductOptions::default().refine_light_share)]
    product_light_share: f32,
    /// Also write the equal-sample, equal-time and equal-CPU-time tables
    /// as JSON, with the scene, the reference and each strategy's timings.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Where in its pixel each camera sample goes: `stratified` (a
    /// shifted two-dimensional Kronecker sequence per pixel) or
    /// `independent` (uniform points), or `centre` (every sample through
    /// the pixel's centre: no antialiasing, so the error is the direction
    /// samplers' alone).
    #[arg(long, value_name = "KIND", default_value = "stratified", value_parser = pixel_sampling)]
    pixel_sampling: PixelSampling,
    /// Image width in pixels.
    #[arg(long, default_value_t = 128)]
    width: usize,
    /// Image height in pixels (default: the width).
    #[arg(long)]
    height: Option<usize>,
    /// Samples per pixel of each strategy: the equal-sample table.
    #[arg(long, default_value_t = 16)]
    spp: usize,
    /// Seconds of rendering per strategy, after --spp: the equal-time table
    /// (wall clock, on every thread). The equal-CPU-time table, printed
    /// always, instead takes the samples per pixel S seconds (1 without
    /// --seconds) of one thread buy, by each strategy's CPU time per camera
    /// sample, the fastest of --timing-repeats passes on one thread: spp =
    /// (S / pixels - setup per pixel) / t_sample. With independent pixel
    /// samples the RMSE at --spp is scaled to them (RMSE_at_spp * sqrt(spp
    /// at --spp / spp)); otherwise each strategy is rendered anew at
    /// floor(spp). A thread that waits for a core does not advance its CPU
    /// clock, so it depends less on the machine's load than the wall-clock
    /// table.
    #[arg(long, value_name = "S")]
    seconds: Option<f64>,
    /// Timed passes (at least 8192 camera samples each) of the CPU time per
    /// camera sample, at least 1; the fastest counts.
    #[arg(long, value_name = "N", default_value_t = 9)]
    timing_repeats: usize,
    /// Samples per pixel of the reference (MIS with the power heuristic),
    /// computed once and cached in the output directory.
    #[arg(long, default_value_t = 1024)]
    ref_spp: usize,
    /// A reference image (linear OpenEXR of the same size) instead.
    #[arg(long, value_name = "FILE.exr")]
    reference: Option<PathBuf>,
    /// Exposure applied before clamping and sRGB encoding.
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Seed of the uniform numbers.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Threads (0: all cores; at most four per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Write the scene for Mitsuba 3 (DIR/scene.xml, DIR/envmap.exr) and
    /// stop; the material must be an RGL .bsdf file or builtin:lambert.
    #[arg(long, value_name = "DIR")]
    export_mitsuba: Option<PathBuf>,
    #[command(flatten)]
    tables: TableArgs,
}

fn strategies_help() -> String {
    format!(
        "Strategies, comma-separated: {}. brdf and light draw from one sampler; \
         mis-balance and mis-power draw once from each and weigh the two by their heuristic; \
         mis-one-sample draws once, from the BRDF sampler with probability --mis-fraction, \
         and divides by the mixture density; mis-adaptive is mis-one-sample with c chosen per \
         pixel, among {}, as the one whose second moment the pixel's earlier samples estimate \
         the least; product draws from the product of the BRDF sampler's density and the map \
         (one query per pixel, formed over four points of the pixel, --product-blocks), and \
         mis-product draws once, from the MIS partner of the environment with probability \
         {PRODUCT_LIGHT_SHARE} and from the product otherwise, and divides by the mixture density \
         (the ground plane is shaded by mis-power under both)",
        Strategy::all_names().replace(',', ", "),
        acdf_render::render::FRACTIONS
            .map(|c| c.to_string())
            .join(", ")
    )
}

fn brdf_help() -> String {
    format!(
        "The BRDF sampler of BRDF sampling and of MIS. {}",
        sampler_help(false)
    )
}

/// The longest `--seconds` accepted: a year.
const MAX_SECONDS: f64 = 365.0 * 24.0 * 3600.0;

/// The most `--threads` accepted: four per core. More threads than that
/// only contend for the cores, and each takes a stack: an unchecked count
/// started thousands before the system refused.
fn max_threads() -> usize {
    4 * std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The shortest `--seconds` accepted: a millisecond. Shorter budgets are
/// below what the clock resolves, and the equal-CPU-time model divides by
/// the budget (a subnormal one made every modelled RMSE infinite).
const MIN_SECONDS: f64 = 1e-3;

/// The side of the map the procedural sky is baked into (width; the height
/// is half).
const SKY_MAP_WIDTH: usize = 512;

/// One strategy's result.
struct Result1 {
    strategy: Strategy,
    samplers: String,
    rendered: Rendered,
    rmse_at_spp: f64,
    rmse_last: f64,
    /// CPU seconds per camera sample on one thread, fastest of the repeats.
    seconds_per_sample: f64,
    /// CPU seconds per pixel formed once, whatever its samples (the
    /// product queries), on one thread.
    seconds_per_pixel_setup: f64,
    /// The samples per pixel the CPU budget buys, and the RMSE of a render
    /// of that many (infinite when it buys none).
    spp_in_budget: f64,
    rmse_in_budget: f64,
}

pub fn run(a: Args) -> Result<()> {
    let height = check_sizes(&a)?;
    let strategies = parse_strategies(&a.strategies)?;
    let m = material(&a.material)?;
    // A map given on the command line is read as every environment command
    // reads one (a black map, with nothing to sample, is refused).
    let map = match &a.envmap {
        Some(p) => crate::env_common::load_map(p, false)?,
        None => Arc::new(sky_map()?),
    };
    if let Some(dir) = &a.export_mitsuba {
        let path = acdf_render::mitsuba::export(
            dir,
            &acdf_render::mitsuba::ExportScene {
                material: &m.spec,
                map: &map,
                plane: a.plane,
                width: a.width,
                height,
                spp: a.spp,
            },
        )?;
        eprintln!("wrote {}", path.display());
        return Ok(());
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .build()
        .map_err(|e| Error::InvalidArgument {
            what: "threads",
            value: a.threads.to_string(),
            reason: e.to_string(),
        })?;
    pool.install(|| run_scene(&a, height, &strategies, &m, map))
}

fn run_scene(
    a: &Args,
    height: usize,
    strategies: &[Strategy],
    m: &Material,
    map: Arc<EnvMap>,
) -> Result<()> {
    let options = a.tables.options()?;
    let env_options = EnvSamplerOptions::default();
    let mis_env_name = a
        .mis_env_sampler
        .clone()
        .unwrap_or_else(|| compensated_name(&a.env_sampler));
    let pb = spinner(&format!(
        "building {}, {}, {}",
        a.brdf_sampler, a.env_sampler, mis_env_name
    ));
    let brdf_sampler = make_sampler(&a.brdf_sampler, m, &options)?;
    brdf_sampler.build_all()?;
    let env = make_env_sampler(&a.env_sampler, &map, &env_options)?;
    let mis_env = make_env_sampler(&mis_env_name, &map, &env_options)?;
    pb.finish_and_clear();
    let light = EnvironmentLight::new(map.clone(), env);
    let mis_light = EnvironmentLight::new(map.clone(), mis_env);
    let plane_brdf =
        Lambert::new("plane", Rgb::splat(PLANE_ALBEDO)).map_err(|e| Error::Material {
            spec: "the ground plane".into(),
            message: e.to_string(),
        })?;
    let plane = Surface {
        brdf: &plane_brdf,
        sampler: &acdf::cosine::CosineSampler,
    };
    let sphere = Surface {
        brdf: m.brdf.as_ref(),
        sampler: &brdf_sampler,
    };
    let geometry = Geometry { plane: a.plane };
    let product_options = ProductOptions {
        block_columns: a.product_blocks,
        points_per_side: a.product_points,
        mass_draws: a.product_mass_draws,
        mass_prior: a.product_mass_prior,
        sub_cells: a.product_sub_cells,
        refine_light_share: a.product_light_share,
        ..ProductOptions::default()
    };
    let product_env = if strategies.iter().any(|s| s.is_product()) {
        product_options.validate()?;
        Some(ProductEnv::new(
            map.clone(),
            product_options.block_columns,
            product_options.points_per_side,
            product_options.sub_cells,
        )?)
    } else {
        None
    };
    let product = product_env.as_ref().map(|env| ProductLight {
        env,
        options: product_options,
        draws: a.product_draws,
    });
    let shader = |strategy: Strategy| Shader {
        geometry,
        sphere,
        plane,
        light: if strategy.is_mis() || strategy.is_product() {
            &mis_light
        } else {
            &light
        },
        strategy,
        mis_fraction: a.mis_fraction,
        product,
    };
    let camera = Camera {
        pixel_sampling: a.pixel_sampling,
        ..Camera::default()
    };
    let size = (a.width, height);
    acdf_io::fsio::ensure_folder(&a.out)?;
    // The folder of --json too, so that a path that cannot be written fails
    // before the renders, not after them.
    if let Some(dir) = a.json.as_deref().and_then(Path::parent) {
        if !dir.as_os_str().is_empty() {
            acdf_io::fsio::ensure_folder(dir)?;
        }
    }
    let label = file_stem_safe(&m.label());
    let samplers_of = |s: Strategy| match s {
        Strategy::Brdf => a.brdf_sampler.clone(),
        Strategy::Light => light.sampler().name().to_string(),
        Strategy::Adaptive => format!(
            "{}+{} c per pixel",
            a.brdf_sampler,
            mis_light.sampler().name()
        ),
        Strategy::OneSample => format!(
            "{}+{} c={}",
            a.brdf_sampler,
            mis_light.sampler().name(),
            a.mis_fraction
        ),
        Strategy::Product | Strategy::MisProduct => {
            let (c, r) = product_env.as_ref().map_or((0, 0), |e| e.blocks());
            let product = format!(
                "product:{} {c}x{r} blocks d={}",
                a.brdf_sampler, product_options.defensive
            );
            if s == Strategy::MisProduct {
                format!(
                    "{product}+{} c={PRODUCT_LIGHT_SHARE}",
                    mis_light.sampler().name()
                )
            } else {
                product
            }
        }
        _ => format!("{}+{}", a.brdf_sampler, mis_light.sampler().name()),
    };

    // The reference.
    let reference = match &a.reference {
        Some(p) => read_exr(p, size)?,
        None => {
            let key = format!(
                "acdf render reference v1: material {} envmap {:?} size {}x{} plane {} spp {} seed {} samplers {}+{} tables {:?}{}",
                m.spec, a.envmap, size.0, size.1, a.plane, a.ref_spp, a.seed,
                a.brdf_sampler, mis_env_name, options,
                // Independent and stratified samples have the same mean
                // image, so they share a reference; the centre's is another.
                match a.pixel_sampling {
                    PixelSampling::Centre => " pixels centre",
                    _ => "",
                }
            );
            let exr = a.out.join(format!("{label}-reference.exr"));
            let key_path = a.out.join(format!("{label}-reference.key"));
            // The cache is two files of the output folder; where either is
            // there but not a regular file (a FIFO, a device, a link to
            // one, a folder), the cache is neither read nor written.
            let unusable: Vec<&PathBuf> = [&key_path, &exr]
                .into_iter()
                .filter(|p| std::fs::symlink_metadata(p).is_ok() && !is_regular_file(p))
                .collect();
            for p in &unusable {
                eprintln!(
                    "acdf: note: {} is not a regular file; the reference is rendered and not cached",
                    p.display()
                );
            }
            let cache = unusable.is_empty();
            let cached = cache && cached_key_matches(&key_path, &key) && is_regular_file(&exr);
            if cached {
                eprintln!("reference: cached {}", exr.display());
                read_exr(&exr, size)?
            } else {
                let pb = bar(100, &format!("reference ({} spp)", a.ref_spp));
                let r = render(
                    &shader(Strategy::Power),
                    &camera,
                    size,
                    Budget {
                        spp: a.ref_spp,
                        time: None,
                    },
                    a.seed ^ 0xA5A5_5A5A,
                    None,
                    |f| pb.set_position((f * 100.0) as u64),
                );
                pb.finish_and_clear();
                eprintln!(
                    "reference: {} spp of mis-power in {:.1} s",
                    a.ref_spp, r.seconds
                );
                if cache {
                    write_exr(&exr, &r.last)?;
                    acdf_io::fsio::write_atomic(&key_path, |w| w.write_all(key.as_bytes()))?;
                }
                r.last
            }
        }
    };

    let cpu_budget = a.seconds.unwrap_or(1.0);
    let mut results = Vec::new();
    for &strategy in strategies {
        let pb = bar(
            100,
            &format!("{} ({})", strategy.name(), samplers_of(strategy)),
        );
        let mut r = render(
            &shader(strategy),
            &camera,
            size,
            Budget {
                spp: a.spp,
                time: a.seconds.map(Duration::from_secs_f64),
            },
            a.seed,
            Some(&reference),
            |f| pb.set_position((f * 100.0) as u64),
        );
        pb.finish_and_clear();
        // After the render, so that tables built on first use are built.
        let seconds_per_sample = shader(strategy).seconds_per_camera_sample(
            &camera,
            size,
            a.seed,
            a.timing_repeats,
            Some(r.last.moments()),
            Some(r.last.queries()),
        );
        let seconds_per_pixel_setup = shader(strategy).seconds_per_pixel_setup(
            &camera,
            size,
            a.seed,
            a.timing_repeats,
            Some(r.last.queries()),
        );
        // The queries are no longer needed; the render at equal CPU time
        // and the next strategy's take their memory.
        r.at_spp.drop_queries();
        r.last.drop_queries();
        let rmse_at_spp = r.at_spp.rmse(&reference).unwrap_or(f64::NAN);
        // Equal CPU time: the samples per pixel the budget buys after each
        // pixel's setup. With independent pixel samples the error falls as
        // 1/sqrt(samples) and the RMSE at --spp is scaled to them; a
        // stratified pattern's falls faster, so it is rendered anew at the
        // whole number.
        let independent = a.pixel_sampling == PixelSampling::Independent;
        let bought = (cpu_budget / (size.0 * size.1) as f64 - seconds_per_pixel_setup).max(0.0)
            / seconds_per_sample.max(1e-300);
        let spp_in_budget = if independent { bought } else { bought.floor() };
        let rmse_in_budget = if bought.is_nan() || bought < 1.0 {
            f64::INFINITY
        } else if independent {
            rmse_at_spp * (r.at_spp.samples_per_pixel() as f64 / bought).sqrt()
        } else {
            let spp = spp_in_budget.min(u32::MAX as f64) as usize;
            let pb = bar(
                100,
                &format!("{} at equal CPU time ({spp} spp)", strategy.name()),
            );
            let mut b = render(
                &shader(strategy),
                &camera,
                size,
                Budget { spp, time: None },
                a.seed ^ EQUAL_CPU_SEED,
                None,
                |f| pb.set_position((f * 100.0) as u64),
            );
            pb.finish_and_clear();
            b.last.drop_queries();
            b.last.rmse(&reference).unwrap_or(f64::NAN)
        };
        let rmse_last = r.last.rmse(&reference).unwrap_or(f64::NAN);
        results.push(Result1 {
            strategy,
            samplers: samplers_of(strategy),
            rendered: r,
            rmse_at_spp,
            rmse_last,
            seconds_per_sample,
            seconds_per_pixel_setup,
            spp_in_budget,
            rmse_in_budget,
        });
    }

    let mut written = Vec::new();
    // Per strategy: EXR and PNG of the final film; the side-by-side.
    let ref_png = a.out.join(format!("{label}-reference.png"));
    acdf_experiments::plot::write_png(&ref_png, &reference.to_rgb8(a.exposure))?;
    written.push(ref_png);
    let err_scale = error_scale(&results);
    let mut tiles = vec![("reference".to_string(), reference.to_rgb8(a.exposure))];
    let mut errors = vec![(
        format!("white: error {err_scale:.3}"),
        image::RgbImage::from_pixel(a.width as u32, height as u32, image::Rgb([255, 255, 255])),
    )];
    for r in &results {
        let film = &r.rendered.last;
        let stem = format!("{label}-{}", r.strategy.name());
        let exr = a.out.join(format!("{stem}.exr"));
        write_exr(&exr, film)?;
        let png = a.out.join(format!("{stem}.png"));
        let img = film.to_rgb8(a.exposure);
        acdf_experiments::plot::write_png(&png, &img)?;
        written.extend([exr, png]);
        tiles.push((r.strategy.name().to_string(), img));
        errors.push((
            format!("{} spp {:.4}", film.samples_per_pixel(), r.rmse_last),
            film.error_image(&reference, err_scale),
        ));
    }
    let side = stack(
        &acdf_experiments::plot::side_by_side(&tiles)?,
        &acdf_experiments::plot::side_by_side(&errors)?,
    );
    let side_path = a.out.join(format!("{label}-side-by-side.png"));
    acdf_experiments::plot::write_png(&side_path, &side)?;
    written.push(side_path);
    written.extend(convergence_plot(a, &label, m, &results)?);

    let tables = tables(a, size, &results);
    print_tables(a, size, m, &brdf_sampler, &light, &mis_light, &tables)?;
    if let Some(path) = &a.json {
        let ref_path = match &a.reference {
            Some(p) => p.clone(),
            None => a.out.join(format!("{label}-reference.exr")),
        };
        let report = JsonReport {
            material: m.spec.to_string(),
            envmap: a
                .envmap
                .as_ref()
                .map_or("procedural sky".into(), |p| p.display().to_string()),
            plane: a.plane,
            width: size.0,
            height: size.1,
            reference: ref_path.display().to_string(),
            reference_spp: a.reference.is_none().then_some(a.ref_spp),
            brdf_sampler: a.brdf_sampler.clone(),
            env_sampler: light.sampler().name().to_string(),
            mis_env_sampler: mis_light.sampler().name().to_string(),
            product_blocks: product_env.as_ref().map(|e| e.blocks()),
            seed: a.seed,
            timings: results
                .iter()
                .map(|r| JsonTiming {
                    strategy: r.strategy.name(),
                    samplers: r.samplers.clone(),
                    cpu_seconds_per_camera_sample: r.seconds_per_sample,
                    cpu_seconds_per_pixel_setup: r.seconds_per_pixel_setup,
                })
                .collect(),
            tables,
        };
        crate::common::write_json(path, &report)?;
        written.push(path.clone());
    }
    for p in written {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}

/// The scale of the error maps: four times the smallest RMSE, so that
/// the best strategy's errors show and worse ones saturate.
fn error_scale(results: &[Result1]) -> f32 {
    let m = results
        .iter()
        .map(|r| r.rmse_last)
        .filter(|x| x.is_finite() && *x > 0.0)
        .fold(f64::INFINITY, f64::min);
    if m.is_finite() {
        (4.0 * m) as f32
    } else {
        1.0
    }
}

/// `top` above `bottom`, on white.
fn stack(top: &image::RgbImage, bottom: &image::RgbImage) -> image::RgbImage {
    let w = top.width().max(bottom.width());
    let mut out =
        image::RgbImage::from_pixel(w, top.height() + bottom.height(), image::Rgb([255; 3]));
    image::imageops::replace(&mut out, top, 0, 0);
    image::imageops::replace(&mut out, bottom, 0, top.height() as i64);
    out
}

fn convergence_plot(
    a: &Args,
    label: &str,
    m: &Material,
    results: &[Result1],
) -> Result<Vec<PathBuf>> {
    let series = results
        .iter()
        .map(|r| Series {
            label: format!("{} ({})", r.strategy.name(), r.samplers),
            points: r
                .rendered
                .curve
                .iter()
                .map(|p: &Progress| (p.seconds, p.rmse))
                .collect(),
            style: Style::Line,
        })
        .collect();
    let figure = Figure {
        title: format!(
            "{}: RMSE against rendering time ({})",
            m.label(),
            a.envmap
                .as_deref()
                .and_then(Path::file_stem)
                .map_or("procedural sky".into(), |s| s
                    .to_string_lossy()
                    .into_owned())
        ),
        panels: vec![Panel {
            x_label: "seconds".into(),
            y_label: "RMSE (linear radiance)".into(),
            series,
            markers: vec![],
            notes: vec![],
            legend: true,
        }],
    };
    let png = a.out.join(format!("{label}-convergence.png"));
    let svg = a.out.join(format!("{label}-convergence.svg"));
    let (svg_text, png_bytes) = acdf_experiments::plot::figure_bytes(&figure, &png)?;
    acdf_io::fsio::write_atomic(&png, |w| w.write_all(&png_bytes))?;
    acdf_io::fsio::write_atomic(&svg, |w| w.write_all(svg_text.as_bytes()))?;
    Ok(vec![png, svg])
}

/// One row of a results table.
#[derive(serde::Serialize)]
struct Row {
    strategy: &'static str,
    samplers: String,
    /// Samples per pixel (modelled, so fractional, at equal CPU time).
    spp: f64,
    seconds: f64,
    rmse: f64,
    /// The RMSE over the best of brdf and light in the same table.
    rmse_vs_best_single: Option<f64>,
    camera_samples_per_s: f64,
}

/// One table: equal samples, equal time, or equal CPU time.
#[derive(serde::Serialize)]
struct Table {
    /// `equal_samples`, `equal_time` or `equal_cpu_time`.
    kind: &'static str,
    title: String,
    /// The seconds of the equal-time and equal-CPU-time tables.
    seconds: Option<f64>,
    rows: Vec<Row>,
    /// Decimals of the spp column in the CSV.
    #[serde(skip)]
    spp_decimals: usize,
}

/// One strategy's timings on one thread.
#[derive(serde::Serialize)]
struct JsonTiming {
    strategy: &'static str,
    samplers: String,
    cpu_seconds_per_camera_sample: f64,
    cpu_seconds_per_pixel_setup: f64,
}

/// What `--json` writes.
#[derive(serde::Serialize)]
struct JsonReport {
    material: String,
    envmap: String,
    plane: bool,
    width: usize,
    height: usize,
    /// The reference image (linear OpenEXR).
    reference: String,
    /// Its samples per pixel, when acdf rendered it.
    reference_spp: Option<usize>,
    brdf_sampler: String,
    env_sampler: String,
    mis_env_sampler: String,
    product_blocks: Option<(usize, usize)>,
    seed: u64,
    timings: Vec<JsonTiming>,
    tables: Vec<Table>,
}

/// The tables of `results`: equal samples, equal time (with --seconds),
/// and equal CPU time, modelled.
fn tables(a: &Args, size: (usize, usize), results: &[Result1]) -> Vec<Table> {
    let pixels = (size.0 * size.1) as f64;
    let table = |kind, title, seconds, spp_decimals, row: &dyn Fn(&Result1) -> (f64, f64, f64)| {
        let best = results
            .iter()
            .filter(|r| r.strategy.is_single())
            .map(|r| row(r).2)
            .fold(f64::INFINITY, f64::min);
        let rows = results
            .iter()
            .map(|r| {
                let (spp, seconds, rmse) = row(r);
                Row {
                    strategy: r.strategy.name(),
                    samplers: r.samplers.clone(),
                    spp,
                    seconds,
                    rmse,
                    rmse_vs_best_single: (best.is_finite() && best > 0.0).then(|| rmse / best),
                    camera_samples_per_s: spp * pixels / seconds.max(1e-9),
                }
            })
            .collect();
        Table {
            kind,
            title,
            seconds,
            rows,
            spp_decimals,
        }
    };
    let mut out = vec![table(
        "equal_samples",
        format!("equal samples ({} spp)", a.spp),
        None,
        0,
        &|r| {
            (
                r.rendered.at_spp.samples_per_pixel() as f64,
                r.rendered.seconds_at_spp,
                r.rmse_at_spp,
            )
        },
    )];
    if let Some(s) = a.seconds {
        out.push(table(
            "equal_time",
            format!("equal time ({s} s)"),
            Some(s),
            0,
            &|r| {
                (
                    r.rendered.last.samples_per_pixel() as f64,
                    r.rendered.seconds,
                    r.rmse_last,
                )
            },
        ));
    }
    // Equal CPU time: each strategy rendered anew at the samples per pixel
    // `budget` seconds of one thread buy after each pixel's setup.
    let budget = a.seconds.unwrap_or(1.0);
    let how = if a.pixel_sampling == PixelSampling::Independent {
        format!(
            "modelled: RMSE at {} spp x sqrt({} / spp in budget), spp in budget = (budget / pixels - \
             CPU s per pixel setup) / CPU s per camera sample",
            a.spp, a.spp
        )
    } else {
        "rendered at spp = floor((budget / pixels - CPU s per pixel setup) / CPU s per camera sample)"
            .to_string()
    };
    let mut cpu = table(
        "equal_cpu_time",
        format!(
            "equal CPU time ({budget} s of one thread, {how}; fastest of {} timed passes)",
            a.timing_repeats
        ),
        Some(budget),
        usize::from(a.pixel_sampling == PixelSampling::Independent),
        &|r| (r.spp_in_budget, budget, r.rmse_in_budget),
    );
    // What a camera sample costs, setup aside (as before the setup was
    // counted).
    for (row, r) in cpu.rows.iter_mut().zip(results) {
        row.camera_samples_per_s = 1.0 / r.seconds_per_sample.max(1e-300);
    }
    out.push(cpu);
    out
}

fn print_tables(
    a: &Args,
    size: (usize, usize),
    m: &Material,
    brdf: &AnySampler,
    light: &EnvironmentLight<AnyEnvSampler>,
    mis_light: &EnvironmentLight<AnyEnvSampler>,
    tables: &[Table],
) -> Result<()> {
    let mut out = stdout();
    writeln!(
        out,
        "{} under {}, {}x{} px{}; storage: {} {} B, {} {} B, {} {} B",
        m.label(),
        a.envmap
            .as_deref()
            .map_or("the procedural sky".into(), |p| p.display().to_string()),
        size.0,
        size.1,
        if a.plane { ", ground plane" } else { "" },
        a.brdf_sampler,
        BxdfSampler::storage_bytes(brdf),
        light.sampler().name(),
        light.sampler().storage_bytes(),
        mis_light.sampler().name(),
        mis_light.sampler().storage_bytes(),
    )?;
    for t in tables {
        writeln!(out, "{}", t.title)?;
        writeln!(
            out,
            "strategy,samplers,spp,seconds,rmse,rmse_vs_best_single,camera_samples_per_s"
        )?;
        for r in &t.rows {
            writeln!(
                out,
                "{},{},{:.*},{:.3},{:.6},{},{:.4e}",
                r.strategy,
                r.samplers,
                t.spp_decimals,
                r.spp,
                r.seconds,
                r.rmse,
                r.rmse_vs_best_single
                    .map_or(String::new(), |x| format!("{x:.3}")),
                r.camera_samples_per_s
            )?;
        }
    }
    out.flush()?;
    Ok(())
}

/// Mixed into `--seed` for the renders at equal CPU time, so that they
/// are not the equal-sample renders' first passes again.
const EQUAL_CPU_SEED: u64 = 0xC0DE_0000_0000_0001;

/// The pixel sampling of its command-line name.
fn pixel_sampling(name: &str) -> std::result::Result<PixelSampling, String> {
    PixelSampling::from_name(name).ok_or_else(|| {
        format!(
            "the pixel samplings are {}",
            PixelSampling::NAMES.join(", ")
        )
    })
}

/// The strategies of a comma-separated list.
fn parse_strategies(list: &str) -> Result<Vec<Strategy>> {
    let all: Vec<&str> = Strategy::ALL.iter().map(|s| s.name()).collect();
    let v: Vec<Strategy> = list
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| {
            Strategy::from_name(t).ok_or_else(|| Error::InvalidArgument {
                what: "strategy",
                value: t.to_string(),
                reason: format!("the strategies are {}", all.join(", ")),
            })
        })
        .collect::<Result<_>>()?;
    if v.is_empty() {
        return Err(Error::InvalidArgument {
            what: "strategies",
            value: list.to_string(),
            reason: format!("name at least one of {}", all.join(", ")),
        });
    }
    Ok(v)
}

/// The compensated form of an environment sampler's name, for MIS.
fn compensated_name(name: &str) -> String {
    if name == "uniform" {
        "uniform-comp".into()
    } else if name == "adaptive" || name.starts_with("adaptive:") {
        name.replacen("adaptive", "adaptive-comp", 1)
    } else {
        name.to_string()
    }
}

/// The procedural sky baked into a lat-long map in acdf's convention (the
/// sky's own `+y` up becomes `+z`; its sun stands on the camera's side).
fn sky_map() -> Result<EnvMap> {
    let sky = Sky::default();
    let grid = acdf::lights::LatLong::new(SKY_MAP_WIDTH, SKY_MAP_WIDTH / 2);
    Ok(EnvMap::from_fn(
        SKY_MAP_WIDTH,
        SKY_MAP_WIDTH / 2,
        |k, j| {
            let d = grid.texel_direction(k, j);
            sky.radiance(Vec3::new(d.x, d.z, -d.y))
        },
    )?)
}

/// The height, after checking sizes, times and exposure, and the memory a
/// render takes.
fn check_sizes(a: &Args) -> Result<usize> {
    let height = a.height.unwrap_or(a.width);
    if a.width == 0 || height == 0 || a.spp == 0 || a.ref_spp == 0 {
        return Err(Error::InvalidArgument {
            what: "render size",
            value: format!(
                "width {} height {height} spp {} ref-spp {}",
                a.width, a.spp, a.ref_spp
            ),
            reason: "all must be at least 1".into(),
        });
    }
    if let Some(s) = a.seconds {
        if !((MIN_SECONDS..=MAX_SECONDS).contains(&s)) {
            return Err(Error::InvalidArgument {
                what: "seconds",
                value: format!("{s:?}"),
                reason: format!(
                    "must be a number of seconds from {MIN_SECONDS:e} to {MAX_SECONDS:e}"
                ),
            });
        }
    }
    let most = max_threads();
    if a.threads > most {
        return Err(Error::InvalidArgument {
            what: "threads",
            value: a.threads.to_string(),
            reason: format!(
                "at most {most} (four per core of this machine), or 0 for one per core"
            ),
        });
    }
    if !(1..=1024).contains(&a.product_draws) {
        return Err(Error::InvalidArgument {
            what: "product-draws",
            value: a.product_draws.to_string(),
            reason: "must be from 1 to 1024".into(),
        });
    }
    if a.timing_repeats == 0 {
        return Err(Error::InvalidArgument {
            what: "timing-repeats",
            value: "0".into(),
            reason: "need at least 1 timed pass".into(),
        });
    }
    if !(0.0..=1.0).contains(&a.mis_fraction) {
        return Err(Error::InvalidArgument {
            what: "mis-fraction",
            value: a.mis_fraction.to_string(),
            reason: "must be a probability, from 0 to 1".into(),
        });
    }
    if !(a.exposure.is_finite() && a.exposure >= 0.0) {
        return Err(Error::InvalidArgument {
            what: "exposure",
            value: a.exposure.to_string(),
            reason: "must be a finite number, 0 or more".into(),
        });
    }
    // The reference and, per strategy, two films (at --spp and the last),
    // its PNG, its error map and their tiles in the composite (twice); and
    // one film at a time at equal CPU time.
    let n = a.strategies.split(',').count() + 2;
    // With a product strategy, at most one query per pixel is kept at a
    // time: a share and a CDF value per block.
    let blocks = a.product_blocks.clamp(1, 1024);
    let query_bytes = if a.strategies.contains("product") {
        (a.width as u64)
            .saturating_mul(height as u64)
            .saturating_mul((blocks * (blocks / 2).max(1) * 8 + 64) as u64)
    } else {
        0
    };
    acdf_io::limits::check_memory(
        &format!("a render of {}x{height} pixels", a.width),
        render_memory_estimate(a.width, height, 2 * n, 6 * n).saturating_add(query_bytes),
    )?;
    Ok(height)
}

fn image_error(path: &Path, message: impl std::fmt::Display) -> Error {
    Error::Image {
        path: path.to_path_buf(),
        message: message.to_string(),
    }
}

/// Write a film's radiance as OpenEXR, atomically.
fn write_exr(path: &Path, film: &Film) -> Result<()> {
    let bytes = acdf_render::mitsuba::exr_bytes(&film.to_rgb32f(), path)?;
    Ok(acdf_io::fsio::write_atomic(path, |w| w.write_all(&bytes))?)
}

/// Whether the cached reference's key file holds `key`: read only when it
/// is a regular file, and no more than the key's length of it.
fn cached_key_matches(path: &Path, key: &str) -> bool {
    let bound = key.len() as u64 + 1;
    acdf_io::fsio::Input::open_regular(path).is_ok_and(|mut input| {
        input
            .read_rest(bound, "the size of a reference key")
            .is_ok_and(|bytes| bytes == key.as_bytes())
    })
}

/// Whether `path` is a regular file (after symbolic links).
fn is_regular_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file())
}

/// Read a linear RGB image of `size` as a film: only from a regular file,
/// and its size is read from the header and compared before the pixels
/// are read.
fn read_exr(path: &Path, size: (usize, usize)) -> Result<Film> {
    let mut input = acdf_io::fsio::Input::open_regular(path)?;
    // The first 64 KiB hold any image header this reads.
    let mut bytes = input.read_up_to(1 << 16)?;
    let (w, h) = image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .map_err(|e| image_error(path, e))?
        .into_dimensions()
        .map_err(|e| image_error(path, e))?;
    if (w as usize, h as usize) != size {
        return Err(image_error(
            path,
            format!(
                "the reference is {w}x{h} pixels, the render {}x{}",
                size.0, size.1
            ),
        ));
    }
    let rest = input.read_rest(
        acdf_io::limits::memory_limit().saturating_sub(bytes.len() as u64),
        "the memory limit (acdf --memory-limit raises it)",
    )?;
    bytes.extend_from_slice(&rest);
    let img = image::load_from_memory(&bytes)
        .map_err(|e| image_error(path, e))?
        .to_rgb32f();
    let radiance: Vec<Vec3> = img.pixels().map(|p| Vec3::from(p.0)).collect();
    if radiance
        .iter()
        .any(|v| !v.is_finite() || v.min_element() < 0.0)
    {
        return Err(image_error(
            path,
            "the reference has NaN, infinite or negative values",
        ));
    }
    Ok(Film::from_radiance(size.0, size.1, &radiance))
}
