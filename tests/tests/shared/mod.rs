//! The measured materials of the shared data, for the test files that run
//! the battery on them (`mod shared;`). Each helper gives `None` after
//! printing `skipping: ...` when the data is absent, and fails instead with
//! `ACDF_REQUIRE_DATA=1` ([`acdf_materials::testing::skip_without_data`]).

// Each test file uses the helpers it needs.
#![allow(dead_code)]

use acdf_core::Brdf;
use acdf_materials::rgl::RglBrdf;
use std::sync::Arc;

/// The MERL material `name` of the Neural-BRDF file, baked into a MERL
/// table as `acdf` evaluates it.
pub fn nbrdf(name: &str) -> Option<Arc<dyn Brdf>> {
    match acdf_materials::nbrdf::NbrdfLibrary::load_shared() {
        Ok(library) => {
            let network = library.material(name).expect("a material of the file");
            Some(Arc::new(network.bake()))
        }
        Err(e) => {
            acdf_materials::testing::skip_without_data(format_args!(
                "the Neural-BRDF data is not available ({e})"
            ));
            None
        }
    }
}

/// The RGL file `STEM.bsdf` of the shared RGL folder.
pub fn rgl(stem: &str) -> Option<Arc<RglBrdf>> {
    let Some(dir) = acdf_materials::rgl::shared_dir() else {
        acdf_materials::testing::skip_without_data(
            "shared RGL data not found (set ACDF_SHARED_DATA)",
        );
        return None;
    };
    let path = dir.join(format!("{stem}.bsdf"));
    if !path.is_file() {
        acdf_materials::testing::skip_without_data(format_args!("{} not found", path.display()));
        return None;
    }
    Some(Arc::new(
        RglBrdf::open(&path).expect("the shared RGL file loads"),
    ))
}
