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

use crate::common::{material, spinner, MaterialArgs, TableArgs};

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
}

/// Build, save, and load back once to report the load time against the
/// build time.
pub fn run(a: Args) -> Result<()> {
    let spec: SamplerSpec = a.sampler.parse()?;
    if !is_saveable(&spec) {
        return Err(not_saveable(&spec.to_string()));
    }
    let m = material(&a.material)?;
    let s = make_sampler_spec(spec, &m, &a.tables.options()?)?;
    let pb = spinner("building tables");
    let started = Instant::now();
    s.build_all()?;
    let build = started.elapsed();
    pb.finish_and_clear();
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
