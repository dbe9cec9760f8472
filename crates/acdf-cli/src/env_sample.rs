//! `acdf env-sample`: draw directions towards an environment map.

use std::io::Write;

use acdf::error::Result;
use acdf_core::{SphereSampler, Vec2};
use rand::{Rng, SeedableRng};

use crate::common::stdout;
use crate::env_common::EnvQueryArgs;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    query: EnvQueryArgs,
    /// Number of draws.
    #[arg(long, default_value_t = 1000)]
    n: usize,
    /// Seed of the uniform numbers (PCG64).
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// CSV `x,y,z,pdf` on stdout, a failed draw `0,0,0,0`.
pub fn run(a: Args) -> Result<()> {
    let (s, normal) = a.query.sampler()?;
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
