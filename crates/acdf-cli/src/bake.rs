//! `acdf bake`: a material (normally `nbrdf:NAME`) into a MERL `.binary`
//! file.

use std::path::PathBuf;
use std::time::Instant;

use acdf::error::Result;
use acdf::material::{bake_material, write_merl};
use acdf::spec::MaterialSpec;

use crate::common::{spinner, MaterialArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    material: MaterialArgs,
    /// The MERL file to write.
    #[arg(long, value_name = "FILE.binary")]
    out: PathBuf,
}

/// Tabulate the material in the MERL layout and write the file.
pub fn run(a: Args) -> Result<()> {
    let spec: MaterialSpec = a.material.material.parse()?;
    let pb = spinner(&format!("baking {spec}"));
    let start = Instant::now();
    let table = bake_material(&spec, a.material.nbrdf_weights.as_deref());
    pb.finish_and_clear();
    let table = table?;
    write_merl(&table, &a.out)?;
    eprintln!(
        "baked {spec} into {} in {:.1} s",
        a.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
