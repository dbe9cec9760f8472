//! `acdf report`: the results table, storage, compression and estimator
//! efficiency of every sampler, per material.

use std::path::PathBuf;
use std::time::Instant;

use acdf::env::Sky;
use acdf::error::Result;
use acdf::material::{load_material, Material};
use acdf::registry::{report_default_help, report_samplers, sampler_help, sampler_long_help};
use acdf::report::{format_missed_table, format_table, report_material, ReportRow};
use acdf::spec::{SamplerSpec, DEFAULT_REPORT_MATERIALS};

use crate::common::{bar, write_json, MeasureArgs, TableArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Materials (repeatable; default: builtin:nickel,
    /// builtin:blue-metallic-paint, builtin:gray-plastic).
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
}

fn sampler_list_help(long: bool) -> String {
    format!(
        "Samplers to compare (repeatable; default: {}, the first of them the reference of the \
         relative columns). {}",
        report_default_help(),
        if long {
            sampler_long_help(false)
        } else {
            sampler_help(false)
        }
    )
}

/// Load every material and parse every sampler name before measuring, then
/// measure the materials one after the other.
pub fn run(a: Args) -> Result<()> {
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
    // Each material's samplers, then its timing step.
    let total: usize = materials.iter().map(|m| samplers(m).len() + 1).sum();
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
        let r = report_material(m, &samplers(m), &env, &options, &config, |s| {
            pb.set_message(format!("{label}: {s}"));
            pb.inc(1);
        })?;
        rows.extend(r);
    }
    pb.finish_and_clear();
    println!();
    print!("{}", format_table(&rows));
    println!(
        "\nmissed (max): the largest share of f cos θ_i where the pdf is 0, over θ_o in {{{}}}° at \
         φ_o = 1 rad (midpoint rule, 256 x 512 cells in cos θ_i x φ_i)",
        acdf::efficiency::MISSED_SHARE_THETA_O.map(|t| t.to_string()).join(", ")
    );
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
