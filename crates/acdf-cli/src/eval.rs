//! `acdf eval`: the BRDF f_r of directions read from stdin.

use std::io::Write;

use acdf::error::Result;
use acdf::spec::parse_direction_degrees;

use crate::common::{for_each_direction, material, stdout, MaterialArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    material: MaterialArgs,
    /// Outgoing direction THETA_DEG,PHI_DEG.
    #[arg(long, value_name = "T,P", allow_hyphen_values = true)]
    wo: String,
}

/// `r,g,b` of f_r (1/sr) per `x,y,z` line of stdin.
pub fn run(a: Args) -> Result<()> {
    let wo = parse_direction_degrees(&a.wo)?;
    let m = material(&a.material)?;
    let mut out = stdout();
    for_each_direction(|wi| {
        let f = m.brdf.eval(wo, wi);
        Ok(writeln!(out, "{},{},{}", f.x, f.y, f.z)?)
    })?;
    out.flush()?;
    Ok(())
}
