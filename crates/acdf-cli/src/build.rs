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

use acdf::material::Material;
use acdf::registry::{AnySampler, SamplerOptions};
use acdf_experiments::target::{build_for_target, SearchStep};

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
    // The reference is what a target is relative to; without a target it
    // would be ignored, so it is refused (and checked when given).
    let target = a.target.target()?;
    if let Some(r) = &a.target.reference {
        a.target.reference()?;
        if target.is_none() {
            return Err(Error::InvalidArgument {
                what: "reference",
                value: r.clone(),
                reason: "--reference is the sampler a --target-efficiency is relative to; \
                         give a target, or leave the reference out"
                    .into(),
            });
        }
    }
    let m = material(&a.material)?;
    let options = a.tables.options()?;
    let started = Instant::now();
    let s = match target {
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
/// `target` times the reference's efficiency
/// ([`build_for_target`]); an error saying what the best tolerance reached
/// when none does.
fn searched(
    a: &Args,
    m: &Material,
    spec: SamplerSpec,
    options: &SamplerOptions,
    target: f64,
) -> Result<AnySampler> {
    let reference = a.target.reference()?;
    let pb = spinner("building the reference");
    let result = build_for_target(m, spec, options, reference, target, |step| {
        pb.set_message(match step {
            SearchStep::Reference => "building the reference".to_string(),
            SearchStep::Tabulating => "tabulating".to_string(),
            SearchStep::Quadrature => "quadrature".to_string(),
            SearchStep::Tolerance(t) => format!("{spec}: tolerance {t:.3e}"),
        })
    });
    pb.finish_and_clear();
    let (outcome, sampler) = result?;
    outcome.require_reached(&reference.to_string())?;
    println!("{}", outcome.describe(&reference.to_string()));
    Ok(sampler)
}
