//! The arguments and helpers the environment subcommands (`env-sample`,
//! `env-pdf`, `env-report`) share: reading a map, naming a sampler, and the
//! one function through which they write files.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use acdf::env_registry::{env_sampler_help, env_sampler_long_help, EnvSamplerOptions};
use acdf::error::{Error, Result};
use acdf::lights::{EnvMap, NormalGrid};
use clap::Args;

#[derive(Args, Debug, Clone)]
pub struct EnvSamplerArgs {
    /// Simplifier tolerance of the adaptive and oriented samplers (default:
    /// the simplifier's own; 0.02 for chi2).
    #[arg(long, value_name = "X")]
    pub tolerance: Option<f64>,
    /// The oriented sampler's cells of normals, ROWSxCOLUMNS (equal area:
    /// rows in cos θ, columns in φ).
    #[arg(long, value_name = "RxC", default_value = "8x16")]
    pub normal_cells: String,
    /// The oriented sampler's defensive share: the probability of drawing
    /// from the plain luminance table whatever the normal, in (0, 1].
    #[arg(long, value_name = "A", default_value_t = 0.05)]
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
        if let Some(t) = self.tolerance {
            if t.is_nan() || t < 0.0 {
                return Err(Error::InvalidArgument {
                    what: "tolerance",
                    value: t.to_string(),
                    reason: "must be a non-negative number".into(),
                });
            }
        }
        if !(self.defensive > 0.0 && self.defensive <= 1.0) {
            return Err(Error::InvalidArgument {
                what: "defensive share",
                value: self.defensive.to_string(),
                reason: "must be in (0, 1]".into(),
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

/// The sampler help of the environment subcommands, from the registry.
pub fn sampler_help() -> String {
    env_sampler_help()
}

/// The long sampler help of the environment subcommands.
pub fn sampler_long_help() -> String {
    env_sampler_long_help()
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
    if map.is_black() {
        return Err(Error::InvalidArgument {
            what: "environment map",
            value: path.display().to_string(),
            reason: "every texel is 0: a black environment has no light to sample".into(),
        });
    }
    Ok(Arc::new(map))
}

/// Write `bytes` to `path`, creating its directory: every file the
/// environment subcommands write goes through here.
pub fn write_output(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    std::fs::write(path, bytes).map_err(|e| Error::io(path, e))
}

/// A label for a map in tables: the file stem without a trailing `_1k`.
pub fn map_label(path: &Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string());
    stem.strip_suffix("_1k").map(str::to_string).unwrap_or(stem)
}

/// The `--env` argument of the single-map subcommands.
#[derive(Args, Debug, Clone)]
pub struct EnvFileArg {
    /// The environment map: a lat-long Radiance `.hdr` or OpenEXR `.exr`,
    /// +z up, row 0 at the zenith, φ = 0 along +x at the left edge.
    #[arg(long, value_name = "FILE")]
    pub env: PathBuf,
}
