//! The argument groups several subcommands share (material, sampler,
//! tables, measurement), and the helpers for progress and output.

use std::io::{BufRead, BufWriter};
use std::path::{Path, PathBuf};
use std::time::Duration;

use acdf::efficiency::EfficiencyConfig;
use acdf::error::{Error, Result};
use acdf::material::{load_material, Material};
use acdf::registry::{
    load_sampler, make_sampler_spec, sampler_help, sampler_long_help, AnySampler, SamplerOps,
    SamplerOptions,
};
use acdf::spec::{MaterialSpec, SamplerSpec};
use acdf_core::Vec3;
use acdf_tabulated::Resolution;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

#[derive(Args, Debug, Clone)]
pub struct MaterialArgs {
    /// `builtin:NAME` (nickel, blue-metallic-paint, gray-plastic, lambert,
    /// near-mirror), a MERL `.binary` path, an RGL `.bsdf` path, or
    /// `nbrdf:NAME`.
    #[arg(long, value_name = "SPEC")]
    pub material: String,
    /// The Neural-BRDF weight file for `nbrdf:` materials (default
    /// ../shared/data/merl-neural-brdf/merl_nbrdf_weights.f32 when present).
    #[arg(long, value_name = "PATH")]
    pub nbrdf_weights: Option<PathBuf>,
}

#[derive(Args, Debug, Clone)]
pub struct SamplerArgs {
    // The help lists the registry's samplers.
    #[arg(
        long,
        value_name = "NAME",
        default_value = "adaptive",
        help = sampler_help(false),
        long_help = sampler_long_help(false)
    )]
    pub sampler: String,
    /// Load a sampler saved by `acdf build` instead of building one (the
    /// file must have been built for `--material`).
    #[arg(long, value_name = "FILE", conflicts_with = "sampler")]
    pub sampler_file: Option<PathBuf>,
    #[command(flatten)]
    pub tables: TableArgs,
}

#[derive(Args, Debug, Clone)]
pub struct TableArgs {
    /// Simplifier tolerance of adaptive samplers (default: the simplifier's
    /// own).
    #[arg(long, value_name = "X")]
    pub tolerance: Option<f64>,
    /// Tabulation θ_o×φ_o×θ_h×φ_h (default 32x1x256x32, the isotropic
    /// configuration).
    #[arg(long, value_name = "RES", conflicts_with = "paper")]
    pub resolution: Option<String>,
    /// Use the paper's resolution 32x16x256x32.
    #[arg(long)]
    pub paper: bool,
    /// Probability of drawing from the cosine lobe instead of the table.
    #[arg(long, value_name = "A", default_value_t = 0.0)]
    pub cosine_mix: f32,
}

impl TableArgs {
    pub fn options(&self) -> Result<SamplerOptions> {
        let resolution = match (&self.resolution, self.paper) {
            (_, true) => Resolution::PAPER,
            (Some(r), false) => {
                r.parse()
                    .map_err(|e: acdf_core::Error| Error::InvalidArgument {
                        what: "resolution",
                        value: r.clone(),
                        reason: e.to_string(),
                    })?
            }
            (None, false) => Resolution::ISOTROPIC,
        };
        validate_tolerance(self.tolerance)?;
        Ok(SamplerOptions {
            resolution,
            tolerance: self.tolerance,
            cosine_mix: self.cosine_mix,
        })
    }
}

/// A simplifier tolerance from the command line: none, or a non-negative
/// number.
pub fn validate_tolerance(tolerance: Option<f64>) -> Result<()> {
    match tolerance {
        Some(t) if t.is_nan() || t < 0.0 => Err(Error::InvalidArgument {
            what: "tolerance",
            value: t.to_string(),
            reason: "must be a non-negative number".into(),
        }),
        _ => Ok(()),
    }
}

#[derive(Args, Debug, Clone)]
pub struct MeasureArgs {
    /// Draws per outgoing direction for the variance (12 directions).
    #[arg(long, value_name = "N", default_value_t = 1 << 17)]
    pub samples: usize,
    /// Draws per outgoing direction in each timed pass.
    #[arg(long, value_name = "N", default_value_t = 1 << 13)]
    pub timing_samples: usize,
    /// Timed passes per sampler, the fastest kept; a report takes the
    /// passes of a material's samplers in turns.
    #[arg(long, value_name = "N", default_value_t = 3)]
    pub timing_passes: usize,
    /// Seed of the uniform numbers.
    #[arg(long, default_value_t = 2005)]
    pub seed: u64,
}

impl MeasureArgs {
    pub fn config(&self) -> Result<EfficiencyConfig> {
        if self.samples < 2 || self.timing_samples < 1 || self.timing_passes < 1 {
            return Err(Error::InvalidArgument {
                what: "sample count",
                value: format!(
                    "{}/{}/{}",
                    self.samples, self.timing_samples, self.timing_passes
                ),
                reason: "need at least 2 draws for a variance, 1 to time and 1 timed pass".into(),
            });
        }
        Ok(EfficiencyConfig {
            samples_per_direction: self.samples,
            timing_samples_per_direction: self.timing_samples,
            timing_passes: self.timing_passes,
            seed: self.seed,
            ..EfficiencyConfig::default()
        })
    }

    pub fn describe(&self, config: &EfficiencyConfig) -> String {
        format!(
            "variance: {} outgoing directions x {} draws = {} draws per sampler (seed {}); \
             time: best of {} single-thread passes of {} x {} draws",
            config.outgoing.len(),
            config.samples_per_direction,
            config.total_samples(),
            config.seed,
            config.timing_passes,
            config.outgoing.len(),
            config.timing_samples_per_direction
        )
    }
}

/// A progress bar on stderr (drawn only when stderr is a terminal).
pub fn bar(len: u64, what: &str) -> ProgressBar {
    let style = ProgressStyle::with_template("{msg:40!} [{bar:30}] {pos}/{len} {elapsed}")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    let pb = ProgressBar::new(len).with_style(style);
    pb.set_message(what.to_string());
    pb
}

/// A spinner on stderr for a step of unknown length.
pub fn spinner(what: &str) -> ProgressBar {
    let pb = ProgressBar::new_spinner();
    pb.set_message(what.to_string());
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// The material `--material` names.
pub fn material(args: &MaterialArgs) -> Result<Material> {
    let spec: MaterialSpec = args.material.parse()?;
    load_material(&spec, args.nbrdf_weights.as_deref())
}

/// The sampler `--sampler` names, or the one `--sampler-file` holds (which
/// must have been built for `material`).
pub fn sampler(args: &SamplerArgs, material: &Material) -> Result<AnySampler> {
    let Some(path) = &args.sampler_file else {
        let spec: SamplerSpec = args.sampler.parse()?;
        return make_sampler_spec(spec, material, &args.tables.options()?);
    };
    let loaded = load_sampler(path)?;
    match loaded.material_name() {
        Some(name) if name != material.brdf.name() => Err(Error::Incompatible {
            sampler: path.display().to_string(),
            material: material.spec.to_string(),
            reason: format!("the file was built for material `{name}`"),
        }),
        _ => Ok(loaded),
    }
}

/// Buffered, locked standard output.
pub fn stdout() -> BufWriter<std::io::StdoutLock<'static>> {
    BufWriter::new(std::io::stdout().lock())
}

/// Write `value` as pretty JSON to `path`, creating its directory.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let text = serde_json::to_string_pretty(value)?;
    std::fs::write(path, text + "\n").map_err(|e| Error::io(path, e))
}

/// Read `x,y,z` lines from stdin (further columns, blank lines, `#`
/// comments and a `wi_x,...` or `x,...` header are ignored) and call `each` with the
/// normalised direction (zero if it has no length).
pub fn for_each_direction(mut each: impl FnMut(Vec3) -> Result<()>) -> Result<()> {
    let stdin = std::io::stdin();
    for (k, line) in stdin.lock().lines().enumerate() {
        let line = line?;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') || t.starts_with("wi_x") || t.starts_with("x,") {
            continue;
        }
        let fields: Vec<&str> = t.split(',').map(str::trim).collect();
        if fields.len() < 3 {
            return Err(Error::Input {
                line: k + 1,
                reason: format!("expected x,y,z, got `{t}`"),
            });
        }
        let mut v = [0.0f32; 3];
        for (slot, f) in v.iter_mut().zip(&fields) {
            *slot = f.parse().map_err(|_| Error::Input {
                line: k + 1,
                reason: format!("`{f}` is not a number"),
            })?;
            if !slot.is_finite() {
                return Err(Error::Input {
                    line: k + 1,
                    reason: format!("`{f}` is not finite"),
                });
            }
        }
        each(Vec3::from(v).normalize_or_zero())?;
    }
    Ok(())
}

/// The comma-separated items of `s`, each parsed by `parse`; an empty list,
/// or an item that does not parse, is an [`Error::InvalidArgument`] whose
/// reason is `unknown` for the latter.
pub fn parse_list<T>(
    s: &str,
    what: &'static str,
    unknown: &str,
    parse: impl Fn(&str) -> Option<T>,
) -> Result<Vec<T>> {
    let items: Vec<&str> = s
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .collect();
    if items.is_empty() {
        return Err(Error::InvalidArgument {
            what,
            value: s.to_string(),
            reason: "empty list".into(),
        });
    }
    items
        .into_iter()
        .map(|t| {
            parse(t).ok_or_else(|| Error::InvalidArgument {
                what,
                value: t.to_string(),
                reason: unknown.to_string(),
            })
        })
        .collect()
}

/// `s` with every character other than ASCII letters, digits, `-` and `_`
/// replaced by `-`, for file names.
pub fn file_stem_safe(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect()
}
