//! `acdf report`: the results table, storage, compression, noise-free
//! relative variance, firefly measure and efficiency of every sampler, per
//! material.

use std::path::PathBuf;
use std::time::Instant;

use acdf::env::Sky;
use acdf::error::Result;
use acdf::material::{load_material, nbrdf_weights_path, Material};
use acdf::registry::{report_default_help, report_samplers, sampler_help, sampler_long_help};
use acdf::spec::{SamplerSpec, DEFAULT_REPORT_MATERIALS};
use acdf_experiments::report::{
    format_missed_table, format_table, report_material, report_steps, Progress, ReportPlan,
    ReportRow,
};

use crate::common::{bar, write_json, MeasureArgs, TableArgs, TargetArgs};

/// How the columns of `acdf report` (and the fields of `acdf sweep`) are
/// computed: the long help's epilogue.
pub const COLUMNS: &str = "\
How the columns are computed. The estimator is the one-sample estimate of reflected luminance \
Y = Y(f ⊙ L) cos θ_i / p (Y the Rec. 709 luminance, L the procedural sky without its sun, a \
failed draw counting 0) at 12 outgoing directions (θ_o 10, 30, 50, 70° × φ_o 0, 120, 240°); F \
is the reflected luminance it estimates.
  rel. variance    Var(Y) / F², by quadrature: the midpoint rule on --quadrature half-vector \
cells per direction (θ_h = 90° v², φ_h from φ_o), averaged over the directions. Deterministic; \
N samples have a relative error of sqrt(rel. variance / N).
  Monte Carlo (±)  the same from --samples draws per direction (a cross-check), ± three \
standard errors: the error such an estimate has at that number of draws, from the estimator's \
fourth moment by the same quadrature. Where much of the variance comes from draws rarer than one \
in --samples, the draws cannot show it, the estimate usually comes out low and the ± is large.
  firefly          the largest weight f cos θ_i / p at a quadrature point over the mean weight \
(1 when p is proportional to f cos θ_i), the largest over the directions.
  ns/sample        the sampler's own work per draw, sample + pdf, on one thread: the fastest of \
--timing-repeats repeats of 12 x --timing-samples draws, the samplers of a material in turns.
  ns/eval          one BRDF evaluation at the drawn directions (for nbrdf: materials a lookup \
in the baked MERL table): the same for every sampler, so not part of the efficiency.
  efficiency       1 / (rel. variance × ns/sample), per second; rel. eff. divides it by the \
reference's (--reference).
  compression      the reference's storage over the sampler's.
  missed (max)     the share of Y(f) cos θ_i where p = 0, the bias of the sampler used alone \
(midpoint rule on 256 x 512 equal-area cells), the largest over θ_o 0 to 89.5° at φ_o = 1 rad.";

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Materials (repeatable; default: nbrdf:nickel, nbrdf:blue-metallic-paint
    /// and nbrdf:gray-plastic when the Neural-BRDF weights are found, else
    /// the built-in stand-ins of the same names; the first line of the
    /// output says which).
    #[arg(long, value_name = "SPEC")]
    material: Vec<String>,
    /// The Neural-BRDF weight file for `nbrdf:` materials.
    #[arg(long, value_name = "PATH")]
    nbrdf_weights: Option<PathBuf>,
    // The help lists the default set and every sampler, from the registry.
    #[arg(long, value_name = "NAME", help = sampler_list_help(false), long_help = sampler_list_help(true))]
    sampler: Vec<String>,
    /// Also print the missed share of every sampler at each outgoing angle
    /// (the column `missed (max)` is the largest of them).
    #[arg(long)]
    missed_by_angle: bool,
    /// Also write the rows as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    #[command(flatten)]
    measure: MeasureArgs,
    #[command(flatten)]
    tables: TableArgs,
    #[command(flatten)]
    target: TargetArgs,
}

fn sampler_list_help(long: bool) -> String {
    format!(
        "Samplers to compare (repeatable; default: {}). {}",
        report_default_help(),
        if long {
            sampler_long_help(false)
        } else {
            sampler_help(false)
        }
    )
}

/// The materials to report on and the line that says what they are.
fn materials(a: &Args) -> (Vec<String>, String) {
    if !a.material.is_empty() {
        return (
            a.material.clone(),
            format!("materials: {} (as given)", a.material.join(", ")),
        );
    }
    let weights = nbrdf_weights_path(a.nbrdf_weights.as_deref()).filter(|p| p.is_file());
    match weights {
        Some(path) => {
            (
                DEFAULT_REPORT_MATERIALS
                    .iter()
                    .map(|n| format!("nbrdf:{n}"))
                    .collect(),
                format!(
                "materials: measured, {} (the MERL measurements as Neural-BRDF networks from {}, \
                 baked into MERL tables)",
                DEFAULT_REPORT_MATERIALS.map(|n| format!("nbrdf:{n}")).join(", "),
                path.display()
            ),
            )
        }
        None => {
            (
                DEFAULT_REPORT_MATERIALS
                    .iter()
                    .map(|n| format!("builtin:{n}"))
                    .collect(),
                format!(
                "materials: built-in analytic stand-ins, {} (no Neural-BRDF weights found: pass \
                 --nbrdf-weights, set ACDF_SHARED_DATA or put the shared data beside the \
                 repository)",
                DEFAULT_REPORT_MATERIALS.map(|n| format!("builtin:{n}")).join(", ")
            ),
            )
        }
    }
}

/// Load every material and parse every sampler name before measuring, then
/// measure the materials one after the other.
pub fn run(a: Args) -> Result<()> {
    let options = a.tables.options()?;
    let config = a.measure.config()?;
    let target = a.target.target()?;
    let reference = a.target.reference()?;
    let (names, which) = materials(&a);
    let materials: Vec<Material> = names
        .iter()
        .map(|n| load_material(&n.parse()?, a.nbrdf_weights.as_deref()))
        .collect::<Result<_>>()?;
    let chosen: Vec<SamplerSpec> = a.sampler.iter().map(|s| s.parse()).collect::<Result<_>>()?;
    let samplers = |m: &Material| {
        if chosen.is_empty() {
            report_samplers(m)
        } else {
            chosen.clone()
        }
    };
    let env = Sky::dome();
    let total: usize = materials
        .iter()
        .map(|m| report_steps(samplers(m).len()))
        .sum();
    println!("{which}");
    println!("{}", a.measure.describe(&config));
    println!(
        "efficiency = 1 / (relative variance x sampler time); environment: procedural sky without \
         its sun; resolution {}; reference {}{}",
        options.resolution,
        reference,
        target.map_or(String::new(), |t| format!(
            "; adaptive tolerances chosen for {t} x its efficiency"
        )),
    );
    let pb = bar(total as u64, "report");
    let start = Instant::now();
    let mut rows: Vec<ReportRow> = Vec::new();
    for m in &materials {
        let label = m.label();
        let specs = samplers(m);
        let plan = ReportPlan {
            samplers: &specs,
            reference,
            options,
            target,
        };
        let r = report_material(m, &plan, &env, &config, |p| match p {
            Progress::Step(s) => {
                pb.set_message(format!("{label}: {s}"));
                pb.inc(1);
            }
            Progress::Detail(s) => pb.set_message(format!("{label}: {s}")),
        });
        match r {
            Ok(r) => rows.extend(r),
            Err(e) => {
                pb.finish_and_clear();
                return Err(e);
            }
        }
    }
    pb.finish_and_clear();
    println!();
    print!("{}", format_table(&rows));
    println!(
        "\nmissed (max): the largest share of f cos θ_i where the pdf is 0, over θ_o in {{{}}}° at \
         φ_o = 1 rad (midpoint rule, 256 x 512 cells in cos θ_i x φ_i); `acdf report --help` says \
         how every column is computed",
        acdf_experiments::efficiency::MISSED_SHARE_THETA_O
            .map(|t| t.to_string())
            .join(", ")
    );
    let outcomes: Vec<String> = rows
        .iter()
        .filter_map(|r| {
            r.target
                .as_ref()
                .map(|t| format!("{}: {}", r.material, t.describe(&r.reference)))
        })
        .collect();
    if !outcomes.is_empty() {
        println!("\ntarget efficiency:\n{}", outcomes.join("\n"));
    }
    if a.missed_by_angle {
        println!();
        print!("{}", format_missed_table(&rows));
    }
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
