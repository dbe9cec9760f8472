//! `acdf sweep`: efficiency against storage for every sampler of the
//! registry, each simplifier over a range of tolerances.

use std::io::Write;
use std::path::{Path, PathBuf};

use acdf::env::Sky;
use acdf::error::Result;
use acdf::spec::SimplifierName;
use acdf_experiments::sweep::{
    plot_sweep, run_sweep, sweep_tolerances, write_csv, SweepPlan, SweepPoint, TOLERANCE_FACTORS,
};

use crate::common::{
    bar, file_stem_safe, material, parse_list, stdout, write_file, write_json, MaterialArgs,
    MeasureArgs, TableArgs, TargetArgs,
};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    material: MaterialArgs,
    // The help lists the adaptive plug-in's simplifiers.
    #[arg(long, value_name = "LIST", help = simplifiers_help())]
    simplifiers: Option<String>,
    /// Tolerances, comma-separated (default: each simplifier's default
    /// tolerance times 1/16, 1/8, ..., 8); for isotropic materials the
    /// outgoing sampler is swept with the same simplifiers at these
    /// tolerances times its scale (6).
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
    #[command(flatten)]
    target: TargetArgs,
}

fn simplifiers_help() -> String {
    format!(
        "Simplifiers to sweep, comma-separated (default: all of them), of {}",
        SimplifierName::list()
    )
}

/// [`MeasureArgs`] with the sweep's smaller defaults.
#[derive(clap::Args, Debug, Clone)]
struct SweepMeasureArgs {
    /// Monte Carlo draws per outgoing direction for the cross-check (12
    /// directions); 0 skips it.
    #[arg(long, value_name = "N", default_value_t = 1 << 14)]
    samples: usize,
    /// Draws per outgoing direction in each timed repeat.
    #[arg(long, value_name = "N", default_value_t = 1 << 9)]
    timing_samples: usize,
    /// Timed repeats per sampler, the fastest kept; the samplers take turns.
    #[arg(long, value_name = "N", default_value_t = 28, alias = "timing-passes")]
    timing_repeats: usize,
    /// Quadrature cells per outgoing direction, θ_h rows x φ_h columns
    /// over the half vector.
    #[arg(long, value_name = "NVxNX", default_value = "1024x512")]
    quadrature: String,
    /// Seed of the uniform numbers.
    #[arg(long, default_value_t = 2005)]
    seed: u64,
}

/// Measure every sampler and every simplifier at every tolerance, then
/// write the CSV, JSON, SVG and PNG and print the CSV.
pub fn run(a: Args) -> Result<()> {
    // The output folder first: a path taken by a file fails before the
    // measurements, not after.
    acdf_io::fsio::ensure_folder(&a.out)?;
    let m = material(&a.material)?;
    let unknown = format!(
        "not recognised; the simplifiers are {}",
        SimplifierName::list()
    );
    let simplifiers = match &a.simplifiers {
        Some(list) => parse_list(list, "simplifier", &unknown, SimplifierName::find)?,
        None => SimplifierName::all().collect(),
    };
    let fixed: Option<Vec<f64>> = a
        .tolerances
        .as_deref()
        .map(|s| {
            parse_list(s, "tolerance", "not a finite, non-negative number", |t| {
                t.parse::<f64>().ok().filter(|x| x.is_finite() && *x >= 0.0)
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
        timing_repeats: a.measure.timing_repeats,
        quadrature: a.measure.quadrature.clone(),
        seed: a.measure.seed,
    };
    let config = measure.config()?;
    let target = a.target.target()?;
    let reference = a.target.reference()?;
    let per_simplifier = fixed.as_ref().map_or(TOLERANCE_FACTORS.len(), Vec::len);
    // The reference and plain samplers (about three), every simplifier at
    // every tolerance, the quadrature and the timing.
    let total = 3 + simplifiers.len() * per_simplifier + 2;
    eprintln!("{}", measure.describe(&config));
    eprintln!("reference {reference}");
    let tolerances =
        |s: SimplifierName| -> Result<Vec<f64>> { Ok(sweep_tolerances(fixed.as_deref(), s)) };
    let plan = SweepPlan {
        simplifiers: &simplifiers,
        tolerances: &tolerances,
        reference,
        options,
        target,
    };
    let pb = bar(total as u64, "sweep");
    let result = run_sweep(&m, &Sky::dome(), &plan, &config, |what| {
        pb.set_message(what.to_string());
        if !what.starts_with("target:") {
            pb.inc(1);
        }
    });
    pb.finish_and_clear();
    let (points, outcomes) = result?;
    for o in &outcomes {
        eprintln!("{}", o.describe(&reference.to_string()));
    }
    let title = format!(
        "{}: efficiency against storage ({}, reference {reference})",
        m.label(),
        options.resolution
    );
    write_outputs(&points, &a.out, &m.label(), &title)
}

/// `sweep-LABEL.{csv,json,svg,png}` in `dir`, and the CSV on stdout.
fn write_outputs(points: &[SweepPoint], dir: &Path, label: &str, title: &str) -> Result<()> {
    let base = dir.join(format!("sweep-{}", file_stem_safe(label)));
    let csv_path = base.with_extension("csv");
    let mut csv = Vec::new();
    write_csv(points, &mut csv)?;
    write_file(&csv_path, &csv)?;
    let json_path = base.with_extension("json");
    write_json(&json_path, &points)?;
    let (svg_path, png_path) = (base.with_extension("svg"), base.with_extension("png"));
    let (svg, png) = plot_sweep(points, title, &svg_path)?;
    write_file(&svg_path, svg.as_bytes())?;
    write_file(&png_path, &png)?;
    let mut out = stdout();
    out.write_all(&csv)?;
    out.flush()?;
    for p in [&csv_path, &json_path, &svg_path, &png_path] {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}
