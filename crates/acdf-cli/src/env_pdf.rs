//! `acdf env-pdf`: an environment sampler's solid-angle density of
//! directions read from stdin.

use std::io::Write;

use acdf::error::Result;
use acdf_core::SphereSampler;

use crate::common::{for_each_direction, stdout};
use crate::env_common::EnvQueryArgs;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    query: EnvQueryArgs,
}

/// One pdf per `x,y,z` line of stdin.
pub fn run(a: Args) -> Result<()> {
    let (s, normal) = a.query.sampler()?;
    let mut out = stdout();
    for_each_direction(|dir| Ok(writeln!(out, "{}", s.pdf(normal, dir))?))?;
    out.flush()?;
    Ok(())
}
