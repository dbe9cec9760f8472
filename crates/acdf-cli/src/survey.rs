//! `acdf survey`: every sampler on all 100 MERL materials of the
//! Neural-BRDF file, against the 32x16x256x32 table of Lawrence et al.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Instant;

use acdf::env::Sky;
use acdf::error::{Error, Result};
use acdf::material::{load_material, load_nbrdf_library, nbrdf_weights_path, Material};
use acdf::registry::SamplerOptions;
use acdf::spec::{MaterialSpec, SamplerAt};
use acdf_experiments::efficiency::EfficiencyConfig;
use acdf_experiments::frontier::{
    check_levels, format_frontier, frontier_families, frontier_material, plot_frontier,
    summarize_frontier, write_frontier_csv, FamilySummary, FrontierConfig, FrontierRow,
};
use acdf_experiments::survey::{
    format_summary, plot_survey, summarize, survey_labels, survey_material, write_csv, SummaryRow,
    SurveyConfig, SurveyRow, TARGET_LABEL,
};
use serde::Serialize;

use crate::common::{bar, load_average, parse_list, write_file, write_json, MeasureArgs};

/// What the survey's columns are: the long help's epilogue.
pub const COLUMNS: &str = "\
For each material (nbrdf:NAME, baked into a MERL table) and sampler: storage; compression, the \
reference's storage over the sampler's; the noise-free relative variance and firefly measure \
(quadrature, as in `acdf report --help`); the sampler's own time (sample + pdf, fastest of \
--timing-repeats repeats, the material's samplers in turns); relative efficiency, \
(r_ref t_ref) / (r t), split into its variance part r_ref / r and its time part t_ref / t; \
build time. The samplers: the reference (default uniform@32x16x256x32), uniform at the \
default 32x1x256x32, every simplifier at its default tolerance, adaptive:chi2 at the tolerance \
that keeps --target-efficiency of the reference's efficiency (searched), outgoing:chi2 at its default tolerance, cosine. The summary \
gives per sampler the median, the 10th percentile and the worst material of the relative \
efficiency, and the compression among the materials where it keeps the target.

With --frontier, the survey measures the storage frontier instead: for each material and family \
(cosine, uniform, lobes, every adaptive simplifier, outgoing:chi2), the least storage that \
reaches each level of the reference's efficiency, or `not reached`. A family without a \
tolerance has one point; one with a tolerance is searched as by --target-efficiency, once per \
level, and the least storage among every tolerance tried that reaches a level is its frontier \
there (so it never shrinks as the level rises). It writes PREFIX.csv (one row per material, \
family and level), PREFIX.json (with a summary), PREFIX.svg and PREFIX.png (storage against \
level, one curve per family, for the median and the worst material) and prints the summary: \
per family the median and worst storage at each level, and the materials that reach \
--target-efficiency within 1,024 and 4,096 bytes and at the family's default.";

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The Neural-BRDF weight file (default
    /// ../shared/data/merl-neural-brdf/merl_nbrdf_weights.f32 when present).
    #[arg(long, value_name = "PATH")]
    nbrdf_weights: Option<PathBuf>,
    /// Only these materials, comma-separated: names of the weight file, or
    /// material specs such as builtin:nickel (default: every material of
    /// the weight file).
    #[arg(long, value_name = "LIST")]
    materials: Option<String>,
    /// Tabulation θ_o×φ_o×θ_h×φ_h of the samplers other than the
    /// reference (default 32x1x256x32).
    #[arg(long, value_name = "RES")]
    resolution: Option<String>,
    /// Measure the storage frontier at these levels of the reference's
    /// efficiency instead of the survey's table (alone: 0.5,0.8,0.95,1,2;
    /// --target-efficiency is added to them).
    #[arg(long, value_name = "LEVELS", num_args = 0..=1, default_missing_value = "0.5,0.8,0.95,1,2")]
    frontier: Option<String>,
    /// Where --frontier writes: PREFIX.csv, PREFIX.json, PREFIX.svg,
    /// PREFIX.png (default OUT/frontier).
    #[arg(long, value_name = "PREFIX", requires = "frontier")]
    frontier_out: Option<PathBuf>,
    /// Only these families of --frontier, comma-separated, as its rows name
    /// them (e.g. outgoing:chi2,lobes; default: every family).
    #[arg(long, value_name = "LIST", requires = "frontier")]
    families: Option<String>,
    /// The fraction of the reference's efficiency adaptive:chi2 is tuned to
    /// keep, and the line of the summary's counts.
    #[arg(long, value_name = "E", default_value_t = 0.95)]
    target_efficiency: f64,
    /// The reference, NAME@RES.
    #[arg(long, value_name = "SAMPLER", default_value = "uniform@32x16x256x32")]
    reference: String,
    /// Output directory: survey.csv, survey.json, survey.svg, survey.png.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Draws per outgoing direction in each timed repeat.
    #[arg(long, value_name = "N", default_value_t = 1 << 9)]
    timing_samples: usize,
    /// Timed repeats per sampler, the fastest kept.
    #[arg(long, value_name = "N", default_value_t = 20)]
    timing_repeats: usize,
    /// Quadrature cells per outgoing direction, θ_h rows x φ_h columns
    /// over the half vector (coarser than report's default: the relative
    /// variances of the report's materials are within 1.2% of the finest
    /// grid's).
    #[arg(long, value_name = "NVxNX", default_value = "512x256")]
    quadrature: String,
}

/// How a survey or frontier run measured, as both JSON files give it.
#[derive(Serialize)]
struct RunFacts {
    quadrature: String,
    timing_samples_per_direction: usize,
    timing_repeats: usize,
    seconds: f64,
    load_average_start: Option<f64>,
    load_average_end: Option<f64>,
}

impl RunFacts {
    /// The facts of a run of `a` that took `seconds`, the load average
    /// read now as its end.
    fn new(a: &Args, seconds: f64, load_average_start: Option<f64>) -> RunFacts {
        RunFacts {
            quadrature: a.quadrature.clone(),
            timing_samples_per_direction: a.timing_samples,
            timing_repeats: a.timing_repeats,
            seconds,
            load_average_start,
            load_average_end: load_average(),
        }
    }
}

/// What survey.json holds.
#[derive(Serialize)]
struct SurveyFile<'a> {
    reference: String,
    target_efficiency: f64,
    threads: usize,
    #[serde(flatten)]
    run: RunFacts,
    summary: &'a [SummaryRow],
    rows: &'a [SurveyRow],
}

pub fn run(a: Args) -> Result<()> {
    // The output folder first: a path taken by a file fails before the
    // measurements, not after.
    acdf_io::fsio::ensure_folder(&a.out)?;
    let reference: SamplerAt = a.reference.parse()?;
    if !(a.target_efficiency.is_finite() && a.target_efficiency > 0.0) {
        return Err(Error::InvalidArgument {
            what: "target efficiency",
            value: a.target_efficiency.to_string(),
            reason: "must be a positive number".into(),
        });
    }
    let measure = MeasureArgs {
        samples: 0,
        timing_samples: a.timing_samples,
        timing_repeats: a.timing_repeats,
        quadrature: a.quadrature.clone(),
        seed: 2005,
    };
    let efficiency = EfficiencyConfig {
        time_eval: false,
        ..measure.config()?
    };
    let (specs, weights) = survey_materials(&a)?;
    let options = SamplerOptions {
        resolution: match &a.resolution {
            Some(r) => r
                .parse()
                .map_err(|e: acdf_core::Error| Error::InvalidArgument {
                    what: "resolution",
                    value: r.clone(),
                    reason: e.to_string(),
                })?,
            None => SamplerOptions::default().resolution,
        },
        ..SamplerOptions::default()
    };
    if let Some(levels) = &a.frontier {
        let config = FrontierConfig {
            reference,
            options,
            levels: frontier_levels(levels, a.target_efficiency)?,
            efficiency,
            families: a
                .families
                .as_deref()
                .map(frontier_family_names)
                .transpose()?,
        };
        return run_frontier(&a, &specs, weights.as_deref(), &config, &measure);
    }
    let config = SurveyConfig {
        reference,
        options,
        target: a.target_efficiency,
        efficiency,
    };
    let labels = survey_labels(&reference);
    let env = Sky::dome();
    let load_start = load_average();
    eprintln!(
        "survey of {} materials x {} samplers against {reference}; {}; load average {}",
        specs.len(),
        labels.len(),
        measure.describe(&config.efficiency),
        load_start.map_or("unknown".into(), |l| format!("{l:.2}"))
    );
    let mut rows: Vec<SurveyRow> = Vec::new();
    let mut hint = None;
    let seconds = each_material(&specs, weights.as_deref(), "survey", |m, progress| {
        let r = survey_material(m, &env, &config, hint, progress)?;
        hint = r
            .iter()
            .find(|r| r.sampler == TARGET_LABEL)
            .and_then(|r| r.tolerance)
            .filter(|t| *t > 0.0);
        rows.extend(r);
        Ok(())
    })?;
    let summary = summarize(&rows, &labels, config.target);
    let file = SurveyFile {
        reference: reference.to_string(),
        target_efficiency: config.target,
        threads: rayon::current_num_threads(),
        run: RunFacts::new(&a, seconds, load_start),
        summary: &summary,
        rows: &rows,
    };
    let mut csv = Vec::new();
    write_csv(&rows, &mut csv)?;
    let title = format!(
        "{} MERL materials: compression and efficiency against {reference}",
        specs.len()
    );
    let paths = write_outputs(&a.out.join("survey"), &csv, &file, |svg| {
        plot_survey(&rows, &labels, &title, svg)
    })?;
    println!(
        "{} materials x {} samplers in {seconds:.0} s ({} threads, load average {} at the start, {} at the end); reference {reference}",
        specs.len(),
        labels.len(),
        rayon::current_num_threads(),
        load_start.map_or("unknown".into(), |l| format!("{l:.2}")),
        file.run.load_average_end.map_or("unknown".into(), |l| format!("{l:.2}"))
    );
    println!();
    print!("{}", format_summary(&summary, config.target));
    let not_reached: Vec<&str> = rows
        .iter()
        .filter(|r| r.target_reached == Some(false))
        .map(|r| r.material.as_str())
        .collect();
    println!(
        "\nadaptive:chi2@target: no tolerance reaches {} x the reference on {} of {} materials{}",
        config.target,
        not_reached.len(),
        specs.len(),
        if not_reached.is_empty() {
            String::new()
        } else {
            format!(" ({})", not_reached.join(", "))
        }
    );
    for p in &paths {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// Load each material in turn and pass it to `f` with a progress callback
/// (shown on a progress bar beside the material's name); the seconds taken.
fn each_material(
    specs: &[MaterialSpec],
    weights: Option<&Path>,
    what: &str,
    mut f: impl FnMut(&Material, &mut dyn FnMut(&str)) -> Result<()>,
) -> Result<f64> {
    let pb = bar(specs.len() as u64, what);
    let start = Instant::now();
    for spec in specs {
        let name = spec.label();
        let mut progress = |what: &str| pb.set_message(format!("{name}: {what}"));
        if let Err(e) = load_material(spec, weights).and_then(|m| f(&m, &mut progress)) {
            pb.finish_and_clear();
            return Err(e);
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(start.elapsed().as_secs_f64())
}

/// The materials of the survey, and the Neural-BRDF weight file when one
/// of them needs it: `--materials` (names of the weight file, or specs
/// with a `:`) or every material of the weight file.
fn survey_materials(a: &Args) -> Result<(Vec<MaterialSpec>, Option<PathBuf>)> {
    let needs_weights = a.materials.as_deref().is_none_or(|list| {
        list.split(',')
            .any(|t| !t.trim().is_empty() && !t.contains(':'))
    });
    let weights = nbrdf_weights_path(a.nbrdf_weights.as_deref());
    let library = if needs_weights {
        let path = weights.as_deref().ok_or_else(|| Error::Material {
            spec: "nbrdf".into(),
            message: "no Neural-BRDF weights: pass --nbrdf-weights or set ACDF_SHARED_DATA".into(),
        })?;
        Some(load_nbrdf_library(path).map_err(|message| Error::Material {
            spec: path.display().to_string(),
            message,
        })?)
    } else {
        None
    };
    let specs = match (&a.materials, &library) {
        (Some(list), _) => parse_list(
            list,
            "material",
            "not a material of the weight file nor a material spec (e.g. builtin:nickel)",
            |n| {
                if n.contains(':') {
                    n.parse().ok()
                } else {
                    let names = library.as_ref()?.names();
                    names
                        .iter()
                        .find(|k| *k == n)
                        .map(|k| MaterialSpec::Nbrdf(k.clone()))
                }
            },
        )?,
        (None, Some(library)) => library
            .names()
            .iter()
            .map(|n| MaterialSpec::Nbrdf(n.clone()))
            .collect(),
        (None, None) => unreachable!("without --materials the weight file is loaded"),
    };
    Ok((specs, weights))
}

/// The levels of `--frontier`, checked and sorted, with `target` (the
/// level of the summary's counts) among them.
fn frontier_levels(list: &str, target: f64) -> Result<Vec<f64>> {
    let mut levels = parse_list(list, "frontier levels", "not a number", |t| {
        t.parse::<f64>().ok()
    })?;
    levels.push(target);
    check_levels(&levels)
}

/// Write PREFIX.csv, PREFIX.json and the figure `plot` draws for its SVG
/// path (PREFIX.svg and PREFIX.png); the four paths.
fn write_outputs<P>(
    prefix: &Path,
    csv: &[u8],
    json: &impl Serialize,
    plot: P,
) -> Result<[PathBuf; 4]>
where
    P: FnOnce(&Path) -> Result<(String, Vec<u8>)>,
{
    let paths = ["csv", "json", "svg", "png"].map(|e| with_suffix(prefix, e));
    write_file(&paths[0], csv)?;
    write_json(&paths[1], json)?;
    let (svg, png) = plot(&paths[2])?;
    write_file(&paths[2], svg.as_bytes())?;
    write_file(&paths[3], &png)?;
    Ok(paths)
}

/// `prefix` with `.ext` appended (not replacing a dot of the prefix).
fn with_suffix(prefix: &Path, ext: &str) -> PathBuf {
    let mut s = OsString::from(prefix.as_os_str());
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

/// What PREFIX.json holds.
#[derive(Serialize)]
struct FrontierFile<'a> {
    reference: String,
    resolution: String,
    levels: &'a [f64],
    count_level: f64,
    #[serde(flatten)]
    run: RunFacts,
    summary: &'a [FamilySummary],
    rows: &'a [FrontierRow],
}

/// The names of `--families`: each a family of the frontier (of a
/// measured material: every family but `rgl`), else
/// [`Error::InvalidArgument`] naming them.
fn frontier_family_names(list: &str) -> Result<Vec<String>> {
    let lambert = load_material(&MaterialSpec::Builtin("lambert".into()), None)?;
    let known: Vec<String> = frontier_families(&lambert)
        .iter()
        .map(|f| f.to_string())
        .collect();
    parse_list(
        list,
        "frontier families",
        "not a family of the frontier",
        |name| known.iter().find(|k| *k == name).cloned(),
    )
}

/// `acdf survey --frontier`: the frontier of every material, its files and
/// its summary.
fn run_frontier(
    a: &Args,
    specs: &[MaterialSpec],
    weights: Option<&Path>,
    config: &FrontierConfig,
    measure: &MeasureArgs,
) -> Result<()> {
    let prefix = a
        .frontier_out
        .clone()
        .unwrap_or_else(|| a.out.join("frontier"));
    if let Some(dir) = prefix.parent().filter(|d| !d.as_os_str().is_empty()) {
        acdf_io::fsio::ensure_folder(dir)?;
    }
    let env = Sky::dome();
    let load_start = load_average();
    eprintln!(
        "frontier of {} materials at levels {:?} of {}; {}; load average {}",
        specs.len(),
        config.levels,
        config.reference,
        measure.describe(&config.efficiency),
        load_start.map_or("unknown".into(), |l| format!("{l:.2}"))
    );
    let mut rows: Vec<FrontierRow> = Vec::new();
    let mut families: Vec<String> = Vec::new();
    let seconds = each_material(specs, weights, "frontier", |m, progress| {
        for f in config.families_of(m) {
            let f = f.to_string();
            if !families.contains(&f) {
                families.push(f);
            }
        }
        rows.extend(frontier_material(m, &env, config, progress)?);
        Ok(())
    })?;
    let summary = summarize_frontier(&rows, &families, &config.levels, a.target_efficiency);
    let file = FrontierFile {
        reference: config.reference.to_string(),
        resolution: config.options.resolution.to_string(),
        levels: &config.levels,
        count_level: a.target_efficiency,
        run: RunFacts::new(a, seconds, load_start),
        summary: &summary,
        rows: &rows,
    };
    let mut csv = Vec::new();
    write_frontier_csv(&rows, &mut csv)?;
    let title = format!(
        "Storage frontier, {} materials: least storage reaching each level of {}'s efficiency",
        specs.len(),
        config.reference
    );
    let paths = write_outputs(&prefix, &csv, &file, |svg| {
        plot_frontier(&summary, &title, svg)
    })?;
    println!(
        "frontier of {} materials x {} families in {seconds:.0} s (load average {} at the start, {} at the end); reference {}",
        specs.len(),
        families.len(),
        load_start.map_or("unknown".into(), |l| format!("{l:.2}")),
        file.run.load_average_end.map_or("unknown".into(), |l| format!("{l:.2}")),
        config.reference
    );
    println!();
    print!("{}", format_frontier(&summary));
    println!();
    for p in &paths {
        println!("wrote {}", p.display());
    }
    Ok(())
}
