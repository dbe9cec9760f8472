//! The arguments and helpers the environment subcommands (`env-sample`,
//! `env-pdf`, `env-report`) share: reading a map, naming a sampler, and the
//! one function through which they write files.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use acdf::env_registry::{
    env_sampler_help, env_sampler_long_help, make_env_sampler, parse_sphere_direction_degrees,
    AnyEnvSampler, EnvSamplerOptions,
};
use acdf::error::{Error, Result};
use acdf::lights::{EnvMap, NormalGrid};
use acdf_core::Vec3;
use clap::Args;

#[derive(Args, Debug, Clone)]
pub struct EnvSamplerArgs {
    /// Simplifier tolerance of the adaptive and oriented samplers (default:
    /// the simplifier's own; 0.005 for chi2).
    #[arg(long, value_name = "X")]
    pub tolerance: Option<f64>,
    /// The oriented sampler's cells of normals, ROWSxCOLUMNS (equal area:
    /// rows in cos θ, columns in φ).
    #[arg(long, value_name = "RxC", default_value = "16x32")]
    pub normal_cells: String,
    /// The oriented sampler's defensive share: the probability of drawing
    /// from the plain luminance table whatever the normal, in [0, 1] (each
    /// normal's own table already covers every texel it sees).
    #[arg(long, value_name = "A", default_value_t = acdf::env_registry::DEFAULT_DEFENSIVE)]
    pub defensive: f32,
    /// Replace NaN, infinite and negative texels by 0 (with a warning on
    /// stderr) instead of rejecting the map.
    #[arg(long)]
    pub repair: bool,
}

impl EnvSamplerArgs {
    /// The sampler options, with the first grid of `--normal-cells`.
    pub fn options(&self) -> Result<EnvSamplerOptions> {
        Ok(self.options_for(self.grids()?[0]))
    }

    /// The sampler options with the normal grid `grid`.
    pub fn options_for(&self, grid: NormalGrid) -> EnvSamplerOptions {
        EnvSamplerOptions {
            tolerance: self.tolerance,
            normal_cells: grid,
            defensive: self.defensive,
        }
    }

    /// Every grid of `--normal-cells` (a comma-separated list of RxC).
    pub fn grids(&self) -> Result<Vec<NormalGrid>> {
        crate::common::validate_tolerance(self.tolerance)?;
        if !(0.0..=1.0).contains(&self.defensive) {
            return Err(Error::InvalidArgument {
                what: "defensive share",
                value: self.defensive.to_string(),
                reason: "must be in [0, 1]".into(),
            });
        }
        crate::common::parse_list(
            &self.normal_cells,
            "normal cells",
            "expected ROWSxCOLUMNS, e.g. 8x16, at least 1x1 and at most 65536 cells",
            |t| {
                let (r, c) = t.split_once('x')?;
                NormalGrid::new(r.trim().parse().ok()?, c.trim().parse().ok()?).ok()
            },
        )
    }
}

/// Read the map at `path`: a typed error for a file that cannot be read or
/// decoded, is not a lat-long map, has NaN, infinite or negative texels
/// (unless `repair`, which sets them to 0 and says so on stderr), or is
/// black everywhere (nothing to sample).
pub fn load_map(path: &Path, repair: bool) -> Result<Arc<EnvMap>> {
    let map = if repair {
        let (map, repairs) = EnvMap::open_repaired(path)?;
        if !repairs.is_empty() {
            eprintln!(
                "acdf: warning: {}: set {} non-finite and {} negative channel values to 0",
                path.display(),
                repairs.non_finite,
                repairs.negative
            );
        }
        map
    } else {
        EnvMap::open(path)?
    };
    acdf::env_registry::check_not_black(&map, path)?;
    Ok(Arc::new(map))
}

/// Write `bytes` to `path` atomically, creating its directory
/// ([`crate::common::write_file`]): every file the environment subcommands
/// write goes through here.
pub fn write_output(path: &Path, bytes: &[u8]) -> Result<()> {
    crate::common::write_file(path, bytes)
}

/// A label for a map in tables: the file stem without a trailing `_1k`.
pub fn map_label(path: &Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string());
    stem.strip_suffix("_1k").map(str::to_string).unwrap_or(stem)
}

/// What `env-sample` and `env-pdf` share: one map, one sampler, a normal.
#[derive(Args, Debug, Clone)]
pub struct EnvQueryArgs {
    /// The environment map: a lat-long Radiance `.hdr` or OpenEXR `.exr`,
    /// +z up, row 0 at the zenith, φ = 0 along +x at the left edge.
    #[arg(long, value_name = "FILE")]
    pub env: PathBuf,
    #[arg(
        long,
        value_name = "NAME",
        default_value = "adaptive",
        help = env_sampler_help(),
        long_help = env_sampler_long_help()
    )]
    pub sampler: String,
    #[command(flatten)]
    pub options: EnvSamplerArgs,
    /// Shading normal THETA_DEG,PHI_DEG in the map's frame (θ from +z in
    /// [0, 180], φ from +x towards +y); none by default.
    #[arg(long, value_name = "T,P", allow_hyphen_values = true)]
    pub normal: Option<String>,
}

impl EnvQueryArgs {
    /// The sampler for the map, and the normal: the arguments are checked
    /// before the map is read.
    pub fn sampler(&self) -> Result<(AnyEnvSampler, Option<Vec3>)> {
        let normal = self
            .normal
            .as_deref()
            .map(parse_sphere_direction_degrees)
            .transpose()?;
        let options = self.options.options()?;
        let map = load_map(&self.env, self.options.repair)?;
        Ok((make_env_sampler(&self.sampler, &map, &options)?, normal))
    }
}
