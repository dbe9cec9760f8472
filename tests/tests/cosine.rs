//! The cosine sampler joins the battery. It ignores the BRDF, so every
//! ordinary and extreme BRDF gives the same sampler; the BRDFs still drive
//! the weight check f cos θ_i / pdf.

use acdf_conformance::{brdfs, sampler_battery};
use acdf_cosine::CosineSampler;

sampler_battery!(
    cosine,
    build = |_| Ok(CosineSampler),
    brdfs = brdfs::ordinary_brdfs()
);
