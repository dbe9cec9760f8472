//! `acdf pdf`: the sampler's solid-angle density of directions read from
//! stdin.

use std::io::Write;

use acdf::error::Result;
use acdf::spec::parse_direction_degrees;
use acdf_core::BxdfSampler;

use crate::common::{for_each_direction, material, sampler, stdout, MaterialArgs, SamplerArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    material: MaterialArgs,
    #[command(flatten)]
    sampler: SamplerArgs,
    /// Outgoing direction THETA_DEG,PHI_DEG.
    #[arg(long, value_name = "T,P", allow_hyphen_values = true)]
    wo: String,
}

/// One pdf per `x,y,z` line of stdin.
pub fn run(a: Args) -> Result<()> {
    let wo = parse_direction_degrees(&a.wo)?;
    let m = material(&a.material)?;
    let s = sampler(&a.sampler, &m)?;
    let mut out = stdout();
    for_each_direction(|wi| Ok(writeln!(out, "{}", s.pdf(wo, wi))?))?;
    out.flush()?;
    Ok(())
}
