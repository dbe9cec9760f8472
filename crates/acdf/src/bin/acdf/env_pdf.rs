//! `acdf env-pdf`: an environment sampler's solid-angle density of
//! directions read from stdin.

use std::io::Write;

use acdf::env_registry::{make_env_sampler, parse_sphere_direction_degrees};
use acdf::error::Result;
use acdf_core::SphereSampler;

use crate::common::{for_each_direction, stdout};
use crate::env_common::{load_map, EnvFileArg, EnvSamplerArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    env: EnvFileArg,
    #[arg(
        long,
        value_name = "NAME",
        default_value = "adaptive",
        help = crate::env_common::sampler_help(),
        long_help = crate::env_common::sampler_long_help()
    )]
    sampler: String,
    #[command(flatten)]
    options: EnvSamplerArgs,
    /// Shading normal THETA_DEG,PHI_DEG in the map's frame (θ from +z in
    /// [0, 180], φ from +x towards +y); none by default.
    #[arg(long, value_name = "T,P", allow_hyphen_values = true)]
    normal: Option<String>,
}

/// One pdf per `x,y,z` line of stdin.
pub fn run(a: Args) -> Result<()> {
    let normal = a
        .normal
        .as_deref()
        .map(parse_sphere_direction_degrees)
        .transpose()?;
    let options = a.options.options()?;
    let map = load_map(&a.env.env, a.options.repair)?;
    let s = make_env_sampler(&a.sampler, &map, &options)?;
    let mut out = stdout();
    for_each_direction(|dir| Ok(writeln!(out, "{}", s.pdf(normal, dir))?))?;
    out.flush()?;
    Ok(())
}
