//! `acdf build`: a tabulated sampler built and saved to a file that
//! `--sampler-file` loads without rebuilding.

use std::path::PathBuf;
use std::time::Instant;

use acdf::error::{Error, Result};
use acdf::registry::{
    is_saveable, load_sampler, make_sampler_spec, not_saveable, sampler_help, sampler_long_help,
    save_sampler, SamplerOps,
};
use acdf::spec::SamplerSpec;
use acdf_core::BxdfSampler;

use acdf::core::HemisphereGrid;
use acdf::efficiency::{EfficiencyConfig, Integrands};
use acdf::env::Sky;
use acdf::material::Material;
use acdf::registry::{make_sampler_tabulated, AnySampler, SamplerOptions, Tabulation};
use acdf::target::{search_tolerance, Reference};

use crate::common::{material, spinner, MaterialArgs, TableArgs, TargetArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    material: MaterialArgs,
    // The help lists the registry's samplers that have a file format.
    #[arg(
        long,
        value_name = "NAME",
        default_value = "adaptive",
        help = sampler_help(true),
        long_help = sampler_long_help(true)
    )]
    sampler: String,
    #[command(flatten)]
    tables: TableArgs,
    /// The sampler file to write (atomically: a temporary file, then a
    /// rename).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// With --target-efficiency the tolerance of an adaptive sampler is
    /// searched for (see `acdf report --help` for the efficiency), and the
    /// file is written only when the target is reached.
    #[command(flatten)]
    target: TargetArgs,
}

/// Build, save, and load back once to report the load time against the
/// build time.
pub fn run(a: Args) -> Result<()> {
    let spec: SamplerSpec = a.sampler.parse()?;
    if !is_saveable(&spec) {
        return Err(not_saveable(&spec.to_string()));
    }
    let m = material(&a.material)?;
    let options = a.tables.options()?;
    let started = Instant::now();
    let s = match a.target.target()? {
        Some(target) => searched(&a, &m, spec, &options, target)?,
        None => {
            let s = make_sampler_spec(spec, &m, &options)?;
            let pb = spinner("building tables");
            let built = s.build_all();
            pb.finish_and_clear();
            built?;
            s
        }
    };
    let build = started.elapsed();
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

/// The adaptive sampler of `spec`'s simplifier whose tolerance keeps
/// `target` times the reference's efficiency; an error saying what the
/// best tolerance reached when none does.
fn searched(
    a: &Args,
    m: &Material,
    spec: SamplerSpec,
    options: &SamplerOptions,
    target: f64,
) -> Result<AnySampler> {
    spec.simplifier().ok_or_else(|| Error::InvalidArgument {
        what: "sampler",
        value: spec.to_string(),
        reason: "--target-efficiency searches the tolerance of an adaptive sampler".into(),
    })?;
    let reference = a.target.reference()?;
    let reference_options = SamplerOptions {
        resolution: reference.resolution.unwrap_or(options.resolution),
        ..*options
    };
    let pb = spinner("building the reference");
    // The survey's settings: a quadrature within 1.2% of the finest on
    // the report's materials, and a shorter timing.
    let config = EfficiencyConfig {
        samples_per_direction: 0,
        grid: HemisphereGrid::HalfVector { n_v: 512, n_x: 256 },
        timing_samples_per_direction: 1 << 11,
        timing_repeats: 5,
        ..EfficiencyConfig::default()
    };
    let reference_tables = Tabulation::new(m, reference_options.resolution);
    let reference_sampler =
        make_sampler_tabulated(reference.sampler, m, &reference_options, &reference_tables)?;
    drop(reference_tables);
    pb.set_message("tabulating");
    let tables = Tabulation::new(m, options.resolution);
    pb.set_message("quadrature");
    let integrands = Integrands::new(m.brdf.as_ref(), &Sky::dome(), &config);
    let relative_variance = integrands.noise_free(&reference_sampler).relative_variance;
    let result = search_tolerance(
        m,
        spec,
        options,
        &Reference {
            sampler: &reference_sampler,
            relative_variance,
        },
        &integrands,
        &tables,
        &config,
        target,
        |t| pb.set_message(format!("{spec}: tolerance {t:.3e}")),
    );
    pb.finish_and_clear();
    let (outcome, sampler) = result?;
    if !outcome.reached {
        let c = &outcome.chosen;
        return Err(Error::TargetNotReached {
            sampler: spec.to_string(),
            target,
            reference: reference.to_string(),
            best: format!(
                "the best found is {:.3} at tolerance {:.3e} ({} tolerances tried)",
                c.relative_efficiency,
                c.tolerance,
                outcome.tried.len()
            ),
        });
    }
    println!("{}", outcome.describe(&reference.to_string()));
    Ok(sampler)
}
