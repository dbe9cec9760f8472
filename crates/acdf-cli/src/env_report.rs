//! `acdf env-report`: storage, irradiance variance, time and efficiency of
//! every environment sampler on each map.

use std::path::PathBuf;

use acdf::env_registry::{
    env_sampler_help, env_sampler_long_help, report_env_samplers, EnvSamplerSpec,
};
use acdf::error::{Error, Result};
use acdf_experiments::env_report::{
    env_figure, format_env_table, report_map, EnvReportConfig, ReportedSampler,
};
use acdf_experiments::plot::figure_svg;

use crate::common::spinner;
use crate::env_common::{load_map, map_label, write_output, EnvSamplerArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Environment maps (lat-long `.hdr` or `.exr`), one table block each.
    #[arg(long, value_name = "FILE", num_args = 1.., required = true)]
    env: Vec<PathBuf>,
    /// Samplers to compare (repeatable; default: uniform, adaptive with
    /// every simplifier of the report, oriented, uniform-comp,
    /// adaptive-comp).
    #[arg(
        long = "sampler",
        value_name = "NAME",
        help = env_sampler_help(),
        long_help = env_sampler_long_help()
    )]
    samplers: Vec<String>,
    #[command(flatten)]
    options: EnvSamplerArgs,
    /// Monte Carlo draws per normal for the check beside the quadrature.
    #[arg(long, value_name = "N", default_value_t = 1 << 14)]
    mc_samples: usize,
    /// Draws per timed pass.
    #[arg(long, value_name = "N", default_value_t = 1 << 16)]
    timing_samples: usize,
    /// Timed passes per sampler, taken by the samplers in turns, the
    /// fastest kept.
    #[arg(long, value_name = "N", default_value_t = 9)]
    timing_passes: usize,
    /// Seed of the uniform numbers.
    #[arg(long, default_value_t = 2005)]
    seed: u64,
    /// Also write the rows, with every normal's figures, as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Also draw the relative variance against storage as an SVG figure.
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
}

/// The table on stdout; JSON and SVG where asked.
pub fn run(a: Args) -> Result<()> {
    let grids = a.options.grids()?;
    let specs: Vec<EnvSamplerSpec> = if a.samplers.is_empty() {
        report_env_samplers()
    } else {
        a.samplers
            .iter()
            .map(|s| s.parse())
            .collect::<Result<_>>()?
    };
    if a.mc_samples < 2 || a.timing_samples < 1 || a.timing_passes < 1 {
        return Err(Error::InvalidArgument {
            what: "sample count",
            value: format!("{}/{}/{}", a.mc_samples, a.timing_samples, a.timing_passes),
            reason: "need at least 2 Monte Carlo draws, 1 to time and 1 timed pass".into(),
        });
    }
    // The timed draws' uniform pairs are kept (8 bytes a draw); the Monte
    // Carlo draws are made one at a time.
    acdf_io::limits::check_memory(
        "the timed draws (--timing-samples)",
        acdf_io::limits::bytes_of(a.timing_samples as u64, 8),
    )?;
    let config = EnvReportConfig {
        mc_samples: a.mc_samples,
        timing_samples: a.timing_samples,
        timing_passes: a.timing_passes,
        seed: a.seed,
        ..EnvReportConfig::default()
    };
    // Read every map first, so a bad file fails before minutes of work.
    let maps = a
        .env
        .iter()
        .map(|p| Ok((p.clone(), load_map(p, a.options.repair)?)))
        .collect::<Result<Vec<_>>>()?;
    println!(
        "irradiance E(n) = ∫ Y(L) max(0, n·ω) dω over {} normals (32 Fibonacci, the 2 poles); \
         variance by quadrature over the texels, Monte Carlo check with {} draws per normal \
         (seed {}); time: sample + radiance lookup, best of {} single-thread passes of {} draws \
         taken by the samplers in turns",
        config.normals.len(),
        config.mc_samples,
        config.seed,
        config.timing_passes,
        config.timing_samples
    );
    // Every sampler once, the oriented ones once per grid of normals
    // (labelled with it when there are several).
    let mut samplers = Vec::new();
    for spec in &specs {
        if spec.family().name == "oriented" {
            for grid in &grids {
                let mut r = ReportedSampler::new(*spec, a.options.options_for(*grid));
                if grids.len() > 1 {
                    r.label = format!("{spec} ({}x{})", grid.rows, grid.columns);
                }
                samplers.push(r);
            }
        } else {
            samplers.push(ReportedSampler::new(*spec, a.options.options_for(grids[0])));
        }
    }
    let mut rows = Vec::new();
    for (path, map) in &maps {
        let label = map_label(path);
        let pb = spinner(&label);
        let map_rows = report_map(&label, path.clone(), map.clone(), &samplers, &config, |m| {
            pb.set_message(m.to_string())
        })?;
        pb.finish_and_clear();
        print!("{}", format_env_table(&map_rows));
        println!();
        rows.extend(map_rows);
    }
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&rows)? + "\n";
        write_output(path, text.as_bytes())?;
    }
    if let Some(path) = &a.plot {
        let svg = figure_svg(&env_figure(&rows))?;
        write_output(path, svg.as_bytes())?;
    }
    Ok(())
}
