//! `acdf sample`: draw incident directions for one outgoing direction.

use std::io::Write;

use acdf::error::Result;
use acdf::spec::parse_direction_degrees;
use acdf_core::{BxdfSampler, Vec2};
use rand::{Rng, SeedableRng};

use crate::common::{material, sampler, stdout, MaterialArgs, SamplerArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    material: MaterialArgs,
    #[command(flatten)]
    sampler: SamplerArgs,
    /// Outgoing direction THETA_DEG,PHI_DEG.
    #[arg(long, value_name = "T,P", allow_hyphen_values = true)]
    wo: String,
    /// Number of draws.
    #[arg(long, default_value_t = 1000)]
    n: usize,
    /// Seed of the uniform numbers (PCG64).
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// CSV `wi_x,wi_y,wi_z,pdf,valid` on stdout, a failed draw `0,0,0,0,0`.
pub fn run(a: Args) -> Result<()> {
    let wo = parse_direction_degrees(&a.wo)?;
    let m = material(&a.material)?;
    let s = sampler(&a.sampler, &m)?;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(a.seed);
    let mut out = stdout();
    writeln!(out, "wi_x,wi_y,wi_z,pdf,valid")?;
    for _ in 0..a.n {
        let u = Vec2::new(rng.random(), rng.random());
        match s.sample(wo, u) {
            Some(d) => writeln!(out, "{},{},{},{},1", d.wi.x, d.wi.y, d.wi.z, d.pdf)?,
            None => writeln!(out, "0,0,0,0,0")?,
        }
    }
    out.flush()?;
    Ok(())
}
