//! `acdf sweep`: efficiency against storage for each simplifier over a
//! range of tolerances.

use std::io::Write;
use std::path::{Path, PathBuf};

use acdf::env::Sky;
use acdf::error::{Error, Result};
use acdf::spec::SimplifierName;
use acdf::sweep::{
    default_tolerance, plot_sweep, run_sweep, write_csv, SweepPoint, TOLERANCE_FACTORS,
};

use crate::common::{
    bar, file_stem_safe, material, parse_list, stdout, write_json, MaterialArgs, MeasureArgs,
    TableArgs,
};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    material: MaterialArgs,
    // The help lists the adaptive plug-in's simplifiers.
    #[arg(long, value_name = "LIST", default_value = "dp,vw,rw,optimal", help = simplifiers_help())]
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

fn simplifiers_help() -> String {
    format!(
        "Simplifiers to sweep, comma-separated, of {}",
        SimplifierName::list()
    )
}

/// [`MeasureArgs`] with the sweep's smaller defaults.
#[derive(clap::Args, Debug, Clone)]
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

/// Measure the references and every simplifier at every tolerance, then
/// write the CSV, JSON, SVG and PNG and print the CSV.
pub fn run(a: Args) -> Result<()> {
    let m = material(&a.material)?;
    let unknown = format!(
        "not recognised; the simplifiers are {}",
        SimplifierName::list()
    );
    let simplifiers = parse_list(&a.simplifiers, "simplifier", &unknown, SimplifierName::find)?;
    let fixed: Option<Vec<f64>> = a
        .tolerances
        .as_deref()
        .map(|s| {
            parse_list(s, "tolerance", "not recognised", |t| {
                t.parse::<f64>().ok().filter(|x| *x >= 0.0)
            })
        })
        .transpose()?;
    let tables = TableArgs {
        tolerance: None,
        resolution: a.resolution.clone(),
        paper: a.paper,
        cosine_mix: None,
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
                let d = default_tolerance(s);
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
    let title = format!(
        "{}: efficiency against storage ({})",
        m.label(),
        options.resolution
    );
    write_outputs(&points, &a.out, &m.label(), &title)
}

/// `sweep-LABEL.{csv,json,svg,png}` in `dir`, and the CSV on stdout.
fn write_outputs(points: &[SweepPoint], dir: &Path, label: &str, title: &str) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let base = dir.join(format!("sweep-{}", file_stem_safe(label)));
    let csv_path = base.with_extension("csv");
    let mut csv = Vec::new();
    write_csv(points, &mut csv)?;
    acdf_core::fsio::write_atomic(&csv_path, |w| w.write_all(&csv))?;
    let json_path = base.with_extension("json");
    write_json(&json_path, &points)?;
    let (svg, png) = (base.with_extension("svg"), base.with_extension("png"));
    plot_sweep(points, title, &svg, &png)?;
    let mut out = stdout();
    out.write_all(&csv)?;
    out.flush()?;
    for p in [&csv_path, &json_path, &svg, &png] {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}
