//! The argument groups several subcommands share (material, sampler,
//! tables, measurement), and the helpers for progress and output.

use std::io::{BufRead, BufWriter, Read};
use std::path::{Path, PathBuf};
use std::time::Duration;

use acdf::core::HemisphereGrid;
use acdf::env_registry::parse_sphere_direction_degrees;
use acdf::error::{Error, Result};
use acdf::material::{load_material, Material};
use acdf::registry::{
    load_sampler_for, make_sampler_in, sampler_help, sampler_long_help, AnySampler, ProductSetting,
    SamplerOptions,
};
use acdf::spec::{parse_direction_line, MaterialSpec, SamplerAt, SamplerSpec, DIRECTION_FIELDS};
use acdf_core::Vec3;
use acdf_experiments::efficiency::EfficiencyConfig;
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
    #[command(flatten)]
    pub product: ProductArgs,
}

/// The environment of the `product` sampler, which draws wi in proportion
/// to the BRDF sampler's density times the map's luminance at one shading
/// point.
#[derive(Args, Debug, Clone)]
pub struct ProductArgs {
    /// The environment map of `--sampler product[:BRDF_SAMPLER]`: a
    /// lat-long `.hdr` or `.exr` (+z up, row 0 at the zenith, φ = 0 along
    /// +x at the left edge, as `acdf env-sample --env`).
    #[arg(long, value_name = "FILE")]
    pub envmap: Option<PathBuf>,
    /// The shading normal of `--sampler product`, THETA_DEG,PHI_DEG in the
    /// map's frame (as `acdf env-sample --normal`). `--wo` and the
    /// directions drawn are in the normal's local frame: z the normal, x =
    /// (1 + σ n_x² a, σ n_x n_y a, −σ n_x) and y = (n_x n_y a, σ + n_y² a,
    /// −n_y) in the map's frame, σ = ±1 the sign of n_z (its sign bit at 0), a = −1 /
    /// (σ + n_z), the two swapped when that frame is left-handed
    /// (`acdf_core::Frame::from_z`, the frame `acdf render` shades in); at
    /// the normal 0,0 the local axes are the map's.
    #[arg(long, value_name = "T,P", allow_hyphen_values = true)]
    pub normal: Option<String>,
    /// The product sampler's defensive share δ in [0, 1]: the probability
    /// of drawing from the BRDF sampler itself, which keeps the density
    /// positive wherever the BRDF sampler's is.
    #[arg(long, value_name = "D", default_value_t = acdf::product::ProductOptions::default().defensive)]
    pub product_defensive: f32,
    /// The product sampler's blocks: the map is cut into N × N/2 blocks of
    /// texels (at most its own size), each weighed per query by the BRDF
    /// sampler's density at 2 × 2 points.
    #[arg(long, value_name = "N", default_value_t = acdf::product::ProductOptions::default().block_columns)]
    pub product_blocks: usize,
}

impl ProductArgs {
    /// The product's setting when `--envmap` is given (the map read and
    /// cut into blocks); a typed error for one of `--envmap` and `--normal`
    /// without the other, a bad normal or bad options.
    pub fn setting(&self) -> Result<Option<ProductSetting>> {
        let (path, normal) = match (&self.envmap, &self.normal) {
            (None, None) => return Ok(None),
            (Some(path), Some(normal)) => (path, normal),
            (Some(_), None) | (None, Some(_)) => {
                return Err(Error::InvalidArgument {
                    what: "--envmap and --normal",
                    value: format!("{:?}, {:?}", self.envmap, self.normal),
                    reason: "the product sampler needs both".into(),
                })
            }
        };
        let normal = parse_sphere_direction_degrees(normal)?;
        let options = acdf::product::ProductOptions {
            defensive: self.product_defensive,
            block_columns: self.product_blocks,
            ..Default::default()
        };
        options.validate()?;
        let map = acdf::env_registry::load_env_map(path)?;
        Ok(Some(ProductSetting::new(map, normal, options)?))
    }
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
    /// Probability of drawing from the cosine lobe instead of the table
    /// (default 0).
    #[arg(long, value_name = "A")]
    pub cosine_mix: Option<f32>,
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
            cosine_mix: self.cosine_mix.unwrap_or(0.0),
        })
    }
}

/// A simplifier tolerance from the command line: none, or a finite,
/// non-negative number (an infinite tolerance would keep only the ends of
/// every curve: a flat table, never what a user means).
pub fn validate_tolerance(tolerance: Option<f64>) -> Result<()> {
    match tolerance {
        Some(t) if !(t.is_finite() && t >= 0.0) => Err(Error::InvalidArgument {
            what: "tolerance",
            value: t.to_string(),
            reason: "must be a finite, non-negative number".into(),
        }),
        _ => Ok(()),
    }
}

#[derive(Args, Debug, Clone)]
pub struct MeasureArgs {
    /// Monte Carlo draws per outgoing direction for the cross-check of the
    /// relative variance (12 directions); 0 skips it.
    #[arg(long, value_name = "N", default_value_t = 1 << 17)]
    pub samples: usize,
    /// Draws per outgoing direction in each timed repeat.
    #[arg(long, value_name = "N", default_value_t = 1 << 9)]
    pub timing_samples: usize,
    /// Timed repeats per sampler, the fastest kept; the samplers of a
    /// material take their repeats in turns.
    #[arg(long, value_name = "N", default_value_t = 45, alias = "timing-passes")]
    pub timing_repeats: usize,
    /// Quadrature cells per outgoing direction, θ_h rows x φ_h columns
    /// over the half vector.
    #[arg(long, value_name = "NVxNX", default_value = "1024x512")]
    pub quadrature: String,
    /// Seed of the uniform numbers.
    #[arg(long, default_value_t = 2005)]
    pub seed: u64,
}

impl MeasureArgs {
    pub fn config(&self) -> Result<EfficiencyConfig> {
        if self.samples == 1 || self.timing_samples < 1 || self.timing_repeats < 1 {
            return Err(Error::InvalidArgument {
                what: "sample count",
                value: format!(
                    "{}/{}/{}",
                    self.samples, self.timing_samples, self.timing_repeats
                ),
                reason: "need 0 or at least 2 draws for a variance, 1 to time and 1 timed repeat"
                    .into(),
            });
        }
        let config = EfficiencyConfig {
            samples_per_direction: self.samples,
            timing_samples_per_direction: self.timing_samples,
            timing_repeats: self.timing_repeats,
            grid: parse_quadrature(&self.quadrature)?,
            seed: self.seed,
            ..EfficiencyConfig::default()
        };
        config.check_memory()?;
        Ok(config)
    }

    pub fn describe(&self, config: &EfficiencyConfig) -> String {
        let cells = match config.grid {
            HemisphereGrid::HalfVector { n_v, n_x } => format!("{n_v} x {n_x} half-vector cells"),
            HemisphereGrid::EqualArea { n_cos, n_phi } => {
                format!("{n_cos} x {n_phi} equal-area cells")
            }
        };
        let mc = if config.samples_per_direction > 0 {
            format!(
                "{} draws per sampler (seed {})",
                config.total_samples(),
                config.seed
            )
        } else {
            "off".to_string()
        };
        format!(
            "relative variance and firefly: quadrature on {cells} at each of {} outgoing \
             directions; Monte Carlo check: {mc}; time: fastest of {} single-thread repeats of \
             {} x {} draws (sample + pdf; BRDF evaluation apart)",
            config.outgoing.len(),
            config.timing_repeats,
            config.outgoing.len(),
            config.timing_samples_per_direction
        )
    }
}

/// `NVxNX`, the cells of the half-vector quadrature.
fn parse_quadrature(s: &str) -> Result<HemisphereGrid> {
    let bad = |reason: &str| Error::InvalidArgument {
        what: "quadrature",
        value: s.to_string(),
        reason: reason.to_string(),
    };
    let (v, x) = s
        .split_once('x')
        .ok_or_else(|| bad("expected NVxNX, e.g. 1024x128"))?;
    let count = |t: &str| {
        t.trim()
            .parse::<usize>()
            .ok()
            .filter(|&n| (1..=1 << 14).contains(&n))
            .ok_or_else(|| bad("each count must be a whole number from 1 to 16384"))
    };
    Ok(HemisphereGrid::HalfVector {
        n_v: count(v)?,
        n_x: count(x)?,
    })
}

/// `--target-efficiency` and `--reference`, shared by `build`, `report`
/// and `sweep`.
#[derive(Args, Debug, Clone)]
pub struct TargetArgs {
    /// Instead of a tolerance, a quality target: for each adaptive sampler,
    /// the largest tolerance (least storage) whose noise-free efficiency is
    /// at least E times the reference's, found by a search over the
    /// tolerance (steps of 4 from the simplifier's default, then 3
    /// bisections). When no tolerance reaches it, the best found is
    /// reported.
    #[arg(long, value_name = "E")]
    pub target_efficiency: Option<f64>,
    /// The reference of the relative efficiency and the compression,
    /// `NAME` or `NAME@RES` (default: uniform at the command's resolution;
    /// with --target-efficiency, uniform@32x16x256x32, the table of
    /// Lawrence et al.).
    #[arg(long, value_name = "SAMPLER")]
    pub reference: Option<String>,
}

impl TargetArgs {
    /// The target, checked: a finite positive number.
    pub fn target(&self) -> Result<Option<f64>> {
        self.target_efficiency
            .map(acdf_experiments::target::check_target)
            .transpose()
    }

    /// The reference: `--reference`, or the default for the mode.
    pub fn reference(&self) -> Result<SamplerAt> {
        match &self.reference {
            Some(r) => r.parse(),
            None if self.target_efficiency.is_some() => Ok(SamplerAt::PAPER_UNIFORM),
            None => Ok(SamplerAt::plain(SamplerSpec::UNIFORM)),
        }
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
/// must have been built for a material of the same content as `material`,
/// and fixes the options of its tables: giving one is an error).
pub fn sampler(args: &SamplerArgs, material: &Material) -> Result<AnySampler> {
    let Some(path) = &args.sampler_file else {
        let spec: SamplerSpec = args.sampler.parse()?;
        let options = args.tables.options()?;
        let setting = match spec.base() {
            // Checked before the map is read.
            Some(_) if args.product.envmap.is_none() || args.product.normal.is_none() => {
                return Err(Error::NeedsEnvironment {
                    sampler: spec.to_string(),
                    context: "and was not given both".into(),
                })
            }
            _ => args.product.setting()?,
        };
        return make_sampler_in(spec, material, &options, setting.as_ref());
    };
    if args.product.envmap.is_some() {
        return Err(Error::InvalidArgument {
            what: "--envmap",
            value: path.display().to_string(),
            reason: "a sampler file is not a product sampler: the product is formed from \
                     --sampler product[:BRDF_SAMPLER]"
                .into(),
        });
    }
    let t = &args.tables;
    for (given, option) in [
        (t.tolerance.is_some(), "--tolerance"),
        (t.resolution.is_some(), "--resolution"),
        (t.paper, "--paper"),
        (t.cosine_mix.is_some(), "--cosine-mix"),
    ] {
        if given {
            return Err(Error::FixedBySamplerFile {
                option,
                path: path.clone(),
            });
        }
    }
    load_sampler_for(path, material)
}

/// Buffered, locked standard output.
pub fn stdout() -> BufWriter<std::io::StdoutLock<'static>> {
    BufWriter::new(std::io::stdout().lock())
}

/// Write `bytes` to `path` atomically (`acdf_io::fsio::write_atomic`),
/// creating its directory: the one place where the report, sweep, survey
/// and bench outputs reach the file system.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        acdf_io::fsio::ensure_folder(dir)?;
    }
    Ok(acdf_io::fsio::write_atomic(path, |w| w.write_all(bytes))?)
}

/// Write `value` as pretty JSON to `path` ([`write_file`]).
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    write_file(path, (text + "\n").as_bytes())
}

/// The longest line of standard input read, in bytes.
pub const MAX_LINE_BYTES: usize = 4096;

/// Read `x,y,z` lines from stdin and call `each` with the unit direction of
/// each (zero if it has no length), by [`parse_direction_line`]: blank
/// lines and `#` comments are skipped; a header line starting `wi_x` or `x,`
/// (as `acdf sample` and `acdf env-sample` write) sets how many fields the lines after it have,
/// otherwise every line has exactly three. A line longer than
/// [`MAX_LINE_BYTES`], or not UTF-8, is an error naming its number.
pub fn for_each_direction(mut each: impl FnMut(Vec3) -> Result<()>) -> Result<()> {
    let stdin = std::io::stdin();
    let mut input = stdin.lock();
    let mut columns = DIRECTION_FIELDS;
    let mut buffer = Vec::new();
    for line in 1.. {
        let error = |reason: String| Error::Input { line, reason };
        buffer.clear();
        (&mut input)
            .take(MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut buffer)
            .map_err(|e| error(format!("cannot read standard input: {e}")))?;
        if buffer.is_empty() {
            break;
        }
        if buffer.len() > MAX_LINE_BYTES && buffer.last() != Some(&b'\n') {
            return Err(error(format!(
                "longer than {MAX_LINE_BYTES} bytes; a line holds one direction x,y,z"
            )));
        }
        let text =
            std::str::from_utf8(&buffer).map_err(|_| error("is not UTF-8 text".to_string()))?;
        let head = text.trim_start();
        if head.starts_with("wi_x") || head.starts_with("x,") {
            columns = text.split(',').count().max(DIRECTION_FIELDS);
            continue;
        }
        if let Some(wi) = parse_direction_line(text, columns).map_err(error)? {
            each(wi)?;
        }
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

/// The 1-minute load average from `/proc/loadavg`, if readable.
pub fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}
