//! `acdf survey`: every sampler on all 100 MERL materials of the
//! Neural-BRDF file, against the 32x16x256x32 table of Lawrence et al.

use std::path::PathBuf;
use std::time::Instant;

use acdf::env::Sky;
use acdf::error::{Error, Result};
use acdf::material::{load_material, load_nbrdf_library, nbrdf_weights_path};
use acdf::registry::SamplerOptions;
use acdf::spec::{MaterialSpec, SamplerAt};
use acdf_experiments::efficiency::EfficiencyConfig;
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
efficiency, and the compression among the materials where it keeps the target.";

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The Neural-BRDF weight file (default
    /// ../shared/data/merl-neural-brdf/merl_nbrdf_weights.f32 when present).
    #[arg(long, value_name = "PATH")]
    nbrdf_weights: Option<PathBuf>,
    /// Only these materials, comma-separated (default: every material of
    /// the weight file).
    #[arg(long, value_name = "LIST")]
    materials: Option<String>,
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

/// What survey.json holds.
#[derive(Serialize)]
struct SurveyFile<'a> {
    reference: String,
    target_efficiency: f64,
    quadrature: String,
    timing_samples_per_direction: usize,
    timing_repeats: usize,
    threads: usize,
    seconds: f64,
    load_average_start: Option<f64>,
    load_average_end: Option<f64>,
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
    let weights =
        nbrdf_weights_path(a.nbrdf_weights.as_deref()).ok_or_else(|| Error::Material {
            spec: "nbrdf".into(),
            message: "no Neural-BRDF weights: pass --nbrdf-weights or set ACDF_SHARED_DATA".into(),
        })?;
    let library = load_nbrdf_library(&weights).map_err(|message| Error::Material {
        spec: weights.display().to_string(),
        message,
    })?;
    let names: Vec<String> = match &a.materials {
        Some(list) => parse_list(list, "material", "not a material of the weight file", |n| {
            library.names().iter().find(|k| *k == n).cloned()
        })?,
        None => library.names().to_vec(),
    };
    let config = SurveyConfig {
        reference,
        options: SamplerOptions::default(),
        target: a.target_efficiency,
        efficiency,
    };
    let labels = survey_labels(&reference);
    let env = Sky::dome();
    let load_start = load_average();
    eprintln!(
        "survey of {} materials x {} samplers against {reference}; {}; load average {}",
        names.len(),
        labels.len(),
        measure.describe(&config.efficiency),
        load_start.map_or("unknown".into(), |l| format!("{l:.2}"))
    );
    let pb = bar(names.len() as u64, "survey");
    let start = Instant::now();
    let mut rows: Vec<SurveyRow> = Vec::new();
    let mut hint = None;
    for name in &names {
        let spec = MaterialSpec::Nbrdf(name.clone());
        let result = load_material(&spec, Some(&weights)).and_then(|m| {
            survey_material(&m, &env, &config, hint, |what| {
                pb.set_message(format!("{name}: {what}"));
            })
        });
        match result {
            Ok(r) => {
                hint = r
                    .iter()
                    .find(|r| r.sampler == TARGET_LABEL)
                    .and_then(|r| r.tolerance)
                    .filter(|t| *t > 0.0);
                rows.extend(r);
            }
            Err(e) => {
                pb.finish_and_clear();
                return Err(e);
            }
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let summary = summarize(&rows, &labels, config.target);
    let file = SurveyFile {
        reference: reference.to_string(),
        target_efficiency: config.target,
        quadrature: a.quadrature.clone(),
        timing_samples_per_direction: a.timing_samples,
        timing_repeats: a.timing_repeats,
        threads: rayon::current_num_threads(),
        seconds,
        load_average_start: load_start,
        load_average_end: load_average(),
        summary: &summary,
        rows: &rows,
    };
    let base = a.out.join("survey");
    let mut csv = Vec::new();
    write_csv(&rows, &mut csv)?;
    let paths = [
        base.with_extension("csv"),
        base.with_extension("json"),
        base.with_extension("svg"),
        base.with_extension("png"),
    ];
    write_file(&paths[0], &csv)?;
    write_json(&paths[1], &file)?;
    let title = format!(
        "{} MERL materials: compression and efficiency against {reference}",
        names.len()
    );
    let (svg, png) = plot_survey(&rows, &labels, &title, &paths[2])?;
    write_file(&paths[2], svg.as_bytes())?;
    write_file(&paths[3], &png)?;
    println!(
        "{} materials x {} samplers in {seconds:.0} s ({} threads, load average {} at the start, {} at the end); reference {reference}",
        names.len(),
        labels.len(),
        rayon::current_num_threads(),
        load_start.map_or("unknown".into(), |l| format!("{l:.2}")),
        file.load_average_end.map_or("unknown".into(), |l| format!("{l:.2}"))
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
        names.len(),
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
