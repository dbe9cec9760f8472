//! `acdf env-sample`: draw directions towards an environment map.

use std::io::Write;

use acdf::env_registry::{make_env_sampler, parse_sphere_direction_degrees};
use acdf::error::Result;
use acdf_core::{SphereSampler, Vec2};
use rand::{Rng, SeedableRng};

use crate::common::stdout;
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
    /// Number of draws.
    #[arg(long, default_value_t = 1000)]
    n: usize,
    /// Seed of the uniform numbers (PCG64).
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// CSV `x,y,z,pdf` on stdout, a failed draw `0,0,0,0`.
pub fn run(a: Args) -> Result<()> {
    let normal = a
        .normal
        .as_deref()
        .map(parse_sphere_direction_degrees)
        .transpose()?;
    let options = a.options.options()?;
    let map = load_map(&a.env.env, a.options.repair)?;
    let s = make_env_sampler(&a.sampler, &map, &options)?;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(a.seed);
    let mut out = stdout();
    writeln!(out, "x,y,z,pdf")?;
    for _ in 0..a.n {
        let u = Vec2::new(rng.random(), rng.random());
        match s.sample(normal, u) {
            Some(d) => writeln!(out, "{},{},{},{}", d.dir.x, d.dir.y, d.dir.z, d.pdf)?,
            None => writeln!(out, "0,0,0,0")?,
        }
    }
    out.flush()?;
    Ok(())
}
