//! The sampler registry: every concrete sampler behind one enum,
//! [`AnySampler`], and one table of sampler families, [`SAMPLERS`], from
//! which the command line's names ([`SamplerSpec`] parsing,
//! [`sampler_names`]), its help and error texts, the default samplers of
//! `acdf report` and `acdf render`, building ([`make_sampler`]) and loading
//! ([`load_sampler`]) derive. The adaptive family's names come from the
//! adaptive plug-in's own table of simplifiers
//! ([`SIMPLIFIERS`](acdf_adaptive_cdf::simplify::SIMPLIFIERS)).
//!
//! The operations the registry needs beyond sampling (building every table,
//! the resolution label, the material a table was built for, the mean kept
//! vertices, saving) are the local trait [`SamplerOps`], dispatched over
//! [`AnySampler`] by `enum_dispatch`. The `BxdfSampler` impl of
//! [`AnySampler`] cannot be: `enum_dispatch` must see the trait's
//! definition, and `BxdfSampler` lives in acdf-core; a local mirror trait
//! would need a blanket impl over every `BxdfSampler`, which collides
//! (coherence) with `AnySampler`'s own `BxdfSampler` impl. The
//! `any_sampler!` macro writes that dispatch instead (one `match` per
//! method, no vtable), from the same list of variants.

use std::path::Path;
use std::sync::Arc;

use acdf_adaptive::{average_resolution, AdaptiveBrdfSampler};
use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_core::{Brdf, BxdfSample, BxdfSampler, Vec2, Vec3};
use acdf_cosine::CosineSampler;
use acdf_lobes::LobesSampler;
use acdf_outgoing::anisotropic::{ANISOTROPIC_FINE_PER_CELL, FINE_PHI_PER_CELL};
use acdf_outgoing::FINE_PER_CELL;
use acdf_outgoing::{AnisotropicOutgoingSampler, OutgoingBuilder, OutgoingSampler};
use acdf_product::{ProductEnv, ProductOptions, ProductSampler};
use acdf_rgl::RglSampler;
use acdf_tabulated::persist::{self, PersistError};
use acdf_tabulated::{tabulate_slice, Resolution, SliceBuilder, TabulatedBrdfSampler};
use acdf_uniform::{PiecewiseConstantBuilder, UniformBrdfSampler};
use enum_dispatch::enum_dispatch;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::material::Material;
use crate::spec::{SamplerSpec, SimplifierName};
/// Options shared by the tabulated samplers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SamplerOptions {
    /// Tabulation counts θ_o × φ_o × θ_h × φ_h.
    pub resolution: Resolution,
    /// Simplifier tolerance of the adaptive sampler; `None` for the
    /// simplifier's default.
    pub tolerance: Option<f64>,
    /// Probability a of drawing from the cosine lobe instead of the table:
    /// p = (1 − a) p_table + a cos θ_i / π.
    pub cosine_mix: f32,
}

impl Default for SamplerOptions {
    /// The isotropic resolution 32x1x256x32, default tolerances, no cosine
    /// mixing.
    fn default() -> Self {
        SamplerOptions {
            resolution: Resolution::ISOTROPIC,
            tolerance: None,
            cosine_mix: 0.0,
        }
    }
}

/// What the registry does with a sampler beyond sampling; every method has
/// the answer of a sampler without tables as its default.
#[enum_dispatch]
pub trait SamplerOps {
    /// Build every table now (in parallel) rather than on first use, so that
    /// `storage_bytes` reports the whole sampler and timings exclude
    /// building.
    fn build_all(&self) -> Result<()> {
        Ok(())
    }

    /// A short description of the tables: the resolution θ_o×φ_o×θ_h×φ_h
    /// for the uniform sampler; for adaptive ones θ_o×φ_o× the mean kept
    /// marginal vertices × the mean kept conditional vertices (over the
    /// slices built so far); `-` for samplers without tables.
    fn resolution_label(&self) -> String {
        "-".to_string()
    }

    /// The name of the material a tabulated sampler was built for (for a
    /// sampler loaded from a file, the name recorded in it); `None` for
    /// samplers without tables.
    fn material_name(&self) -> Option<&str> {
        None
    }

    /// The fingerprint ([`acdf_core::Brdf::fingerprint`]) of the material a
    /// tabulated sampler was built for (for a sampler loaded from a file,
    /// the one recorded in it); `None` for samplers without tables.
    fn material_fingerprint(&self) -> Option<u64> {
        None
    }

    /// For adaptive samplers, (mean marginal vertices, mean conditional
    /// vertices) over the slices built so far.
    fn mean_vertices(&self) -> Option<(f64, f64)> {
        None
    }

    /// Build every table and write the sampler file; `None` for samplers
    /// that have no file format.
    fn write_file(&self, _path: &Path) -> Option<std::result::Result<(), PersistError>> {
        None
    }
}

impl SamplerOps for CosineSampler {}

impl SamplerOps for LobesSampler {
    fn resolution_label(&self) -> String {
        format!("{} GGX", self.lobes().count())
    }
    fn material_name(&self) -> Option<&str> {
        Some(&self.material().name)
    }
    fn material_fingerprint(&self) -> Option<u64> {
        Some(self.material().fingerprint)
    }
    fn write_file(&self, path: &Path) -> Option<std::result::Result<(), PersistError>> {
        Some(self.save(path))
    }
}

impl SamplerOps for ProductSampler {
    /// The map's blocks.
    fn resolution_label(&self) -> String {
        let (c, r) = self.env().blocks();
        format!("{c}x{r} blocks")
    }
}

impl SamplerOps for RglSampler {
    fn resolution_label(&self) -> String {
        let (a, b) = self.brdf().grid_size();
        format!("{a}x{b} grid")
    }
}

impl SamplerOps for UniformBrdfSampler {
    fn build_all(&self) -> Result<()> {
        Ok(TabulatedBrdfSampler::build_all(self)?)
    }
    fn resolution_label(&self) -> String {
        self.resolution().to_string()
    }
    fn material_name(&self) -> Option<&str> {
        Some(self.brdf().name())
    }
    fn material_fingerprint(&self) -> Option<u64> {
        Some(self.brdf().fingerprint())
    }
    fn write_file(&self, path: &Path) -> Option<std::result::Result<(), PersistError>> {
        Some(self.save(path))
    }
}

impl SamplerOps for AdaptiveBrdfSampler {
    fn build_all(&self) -> Result<()> {
        Ok(TabulatedBrdfSampler::build_all(self)?)
    }
    fn resolution_label(&self) -> String {
        let r = self.resolution();
        let (m, c) = average_resolution(self);
        format!("{}x{}x{m:.1}x{c:.1}", r.theta_o, r.phi_o)
    }
    fn material_name(&self) -> Option<&str> {
        Some(self.brdf().name())
    }
    fn material_fingerprint(&self) -> Option<u64> {
        Some(self.brdf().fingerprint())
    }
    fn mean_vertices(&self) -> Option<(f64, f64)> {
        Some(average_resolution(self))
    }
    fn write_file(&self, path: &Path) -> Option<std::result::Result<(), PersistError>> {
        Some(self.save(path))
    }
}

impl SamplerOps for OutgoingSampler {
    fn resolution_label(&self) -> String {
        let (m, c) = OutgoingSampler::mean_vertices(self);
        format!(
            "{}/{}x1x{m:.1}x{c:.1}",
            self.breakpoint_angles().len(),
            self.builder().fine
        )
    }
    fn material_name(&self) -> Option<&str> {
        Some(self.brdf().name())
    }
    fn material_fingerprint(&self) -> Option<u64> {
        Some(self.brdf().fingerprint())
    }
    fn mean_vertices(&self) -> Option<(f64, f64)> {
        Some(OutgoingSampler::mean_vertices(self))
    }
    fn write_file(&self, path: &Path) -> Option<std::result::Result<(), PersistError>> {
        Some(self.save(path))
    }
}

impl SamplerOps for AnisotropicOutgoingSampler {
    /// θ_o breakpoints x mean φ_o breakpoints per θ_o row / fine θ_o x
    /// fine φ_o nodes x the mean kept vertices.
    fn resolution_label(&self) -> String {
        let (m, c) = AnisotropicOutgoingSampler::mean_vertices(self);
        let rows = self.theta_breakpoint_angles().len();
        format!(
            "{rows}x{:.1}/{}x{}x{m:.1}x{c:.1}",
            self.slices().len() as f64 / rows as f64,
            self.builder().fine,
            self.fine_phi()
        )
    }
    fn material_name(&self) -> Option<&str> {
        Some(self.brdf().name())
    }
    fn material_fingerprint(&self) -> Option<u64> {
        Some(self.brdf().fingerprint())
    }
    fn mean_vertices(&self) -> Option<(f64, f64)> {
        Some(AnisotropicOutgoingSampler::mean_vertices(self))
    }
    fn write_file(&self, path: &Path) -> Option<std::result::Result<(), PersistError>> {
        Some(self.save(path))
    }
}

// Every variant takes a doc comment (`+`, not `*`): without an attribute
// the variant's tokens reach `enum_dispatch` with the spans of this macro,
// and the binding it generates for the variant's value no longer resolves.
macro_rules! any_sampler {
    ($($(#[$doc:meta])+ $variant:ident($ty:ty)),+ $(,)?) => {
        /// One of acdf's samplers, dispatched statically.
        #[enum_dispatch(SamplerOps)]
        pub enum AnySampler {
            $($(#[$doc])* $variant($ty)),+
        }

        impl BxdfSampler for AnySampler {
            fn name(&self) -> &str {
                match self { $(AnySampler::$variant(s) => s.name()),+ }
            }
            #[inline]
            fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
                match self { $(AnySampler::$variant(s) => s.sample(wo, u)),+ }
            }
            #[inline]
            fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
                match self { $(AnySampler::$variant(s) => s.pdf(wo, wi)),+ }
            }
            fn storage_bytes(&self) -> usize {
                match self { $(AnySampler::$variant(s) => s.storage_bytes()),+ }
            }
            fn sample_batch(&self, wo: Vec3, u: &[Vec2], out: &mut [Option<BxdfSample>]) {
                match self { $(AnySampler::$variant(s) => s.sample_batch(wo, u, out)),+ }
            }
            fn pdf_batch(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
                match self { $(AnySampler::$variant(s) => s.pdf_batch(wo, wi, out)),+ }
            }
            fn sample_each(&self, wo: &[Vec3], u: &[Vec2], out: &mut [Option<BxdfSample>]) {
                match self { $(AnySampler::$variant(s) => s.sample_each(wo, u, out)),+ }
            }
            fn pdf_each(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
                match self { $(AnySampler::$variant(s) => s.pdf_each(wo, wi, out)),+ }
            }
        }
    };
}

any_sampler! {
    /// `cosine`: p = cos θ_i / π.
    Cosine(CosineSampler),
    /// `uniform`: piecewise-constant tabulated CDFs.
    Uniform(UniformBrdfSampler),
    /// `adaptive:SIMPLIFIER`: curve-simplified tabulated CDFs.
    Adaptive(AdaptiveBrdfSampler),
    /// `rgl`: the RGL `.bsdf` file's own sampler.
    Rgl(RglSampler),
    /// `lobes`: a cosine lobe and up to three GGX lobes fitted per material.
    Lobes(LobesSampler),
    /// `outgoing:SIMPLIFIER`: θ_o breakpoints per material, blended slices.
    Outgoing(OutgoingSampler),
    /// `outgoing:SIMPLIFIER` for an anisotropic material: θ_o × φ_o
    /// breakpoints, four blended slices.
    OutgoingAnisotropic(AnisotropicOutgoingSampler),
    /// `product:BRDF_SAMPLER`: a BRDF sampler's density times an
    /// environment map's luminance at one shading normal.
    Product(ProductSampler),
}

impl std::fmt::Debug for AnySampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "AnySampler({})", self.name())
    }
}

/// One family of samplers: one line of [`SAMPLERS`].
#[derive(Debug)]
pub struct SamplerFamily {
    /// The name on the command line (`--sampler NAME`).
    pub name: &'static str,
    /// One line for help texts.
    pub description: &'static str,
    /// Whether the family takes a simplifier, `NAME:SIMPLIFIER`, from the
    /// adaptive plug-in's table (the plain `NAME` is its first).
    pub simplifiers: bool,
    /// The family's place in `acdf report`'s default set, `None` for none;
    /// a family with simplifiers brings those marked `in_report` in their
    /// table.
    pub report_rank: Option<u8>,
    /// Whether `acdf render` compares it by default (in the table's order;
    /// with its first simplifier).
    pub in_render: bool,
    /// Whether it samples BRDF × environment at one shading point: it is
    /// built by [`make_sampler_in`] from a map and a normal (its
    /// `build` refuses with [`Error::NeedsEnvironment`]) and named
    /// `NAME[:BRDF_SAMPLER]`, the BRDF sampler it wraps.
    pub environment: bool,
    /// Whether it can be used with a material (`None`: with every one), and
    /// why not.
    pub requires: Option<Requirement>,
    /// The kind recorded in its sampler files, for a family that can be
    /// saved ([`save_sampler`], [`load_sampler`]).
    pub file_kind: Option<&'static str>,
    /// Build it for a material.
    pub build: fn(&SamplerSpec, &Material, &SamplerOptions) -> Result<AnySampler>,
    /// Read a sampler file of `file_kind`.
    pub load: Option<LoadFn>,
}

/// Reads the bytes of a sampler file into a sampler.
pub type LoadFn = fn(&[u8]) -> std::result::Result<AnySampler, PersistError>;

/// A condition a material must meet for a family's samplers.
#[derive(Debug)]
pub struct Requirement {
    /// Whether `material` meets it.
    pub met: fn(&Material) -> bool,
    /// Why the sampler cannot be used otherwise.
    pub reason: &'static str,
    /// The materials it serves, for the help texts of default sets.
    pub serves: &'static str,
}

/// The name of the family with simplifiers.
pub const ADAPTIVE: &str = "adaptive";

/// The name of the outgoing family ([`OutgoingSampler`]), which takes the
/// same simplifiers.
pub const OUTGOING: &str = "outgoing";

/// Every sampler family, in the order of help texts and of `acdf render`'s
/// default set.
pub static SAMPLERS: &[SamplerFamily] = &[
    SamplerFamily {
        name: "cosine",
        description: "cosine-weighted hemisphere, no tables",
        simplifiers: false,
        report_rank: Some(2),
        in_render: true,
        environment: false,
        requires: None,
        file_kind: None,
        build: |_, _, _| Ok(CosineSampler.into()),
        load: None,
    },
    SamplerFamily {
        name: "uniform",
        description: "uniformly tabulated CDFs",
        simplifiers: false,
        report_rank: Some(0),
        in_render: true,
        environment: false,
        requires: None,
        file_kind: Some("uniform"),
        build: |_, m, o| {
            let sampler =
                UniformBrdfSampler::new(m.brdf.clone(), tables(m, o), PiecewiseConstantBuilder)?;
            Ok(sampler.with_cosine_mix(o.cosine_mix)?.into())
        },
        load: Some(|bytes| Ok(UniformBrdfSampler::from_bytes(bytes)?.into())),
    },
    SamplerFamily {
        name: ADAPTIVE,
        description: "curve-simplified tabulated CDFs, adaptive:SIMPLIFIER",
        simplifiers: true,
        report_rank: Some(1),
        in_render: true,
        environment: false,
        requires: None,
        file_kind: Some("adaptive"),
        build: |spec, m, o| {
            let simplifier = spec
                .simplifier()
                .unwrap_or_else(SimplifierName::default_simplifier);
            let builder = AdaptiveBuilder::by_name(simplifier.short(), o.tolerance)?;
            let sampler = TabulatedBrdfSampler::new(m.brdf.clone(), tables(m, o), builder)?;
            Ok(sampler.with_cosine_mix(o.cosine_mix)?.into())
        },
        load: Some(|bytes| Ok(AdaptiveBrdfSampler::from_bytes(bytes)?.into())),
    },
    SamplerFamily {
        name: OUTGOING,
        description: "adaptive outgoing angles: slices at θ_o breakpoints (and φ_o ones for \
                      anisotropic materials) chosen per material, blended, 16-bit, \
                      outgoing:SIMPLIFIER",
        simplifiers: true,
        report_rank: None,
        in_render: false,
        environment: false,
        requires: None,
        file_kind: Some(acdf_outgoing::persist::KIND),
        build: |spec, m, o| {
            let simplifier = spec
                .simplifier()
                .unwrap_or_else(SimplifierName::default_simplifier);
            if m.brdf.is_isotropic() {
                let fine = o.resolution.theta_o.saturating_mul(FINE_PER_CELL);
                let builder = OutgoingBuilder::by_name(simplifier.short(), o.tolerance, fine)?;
                let sampler = OutgoingSampler::new(m.brdf.clone(), o.resolution, builder)?;
                Ok(sampler.with_cosine_mix(o.cosine_mix)?.into())
            } else {
                let r = effective_resolution(m, o.resolution);
                let fine = r.theta_o.saturating_mul(ANISOTROPIC_FINE_PER_CELL);
                let fine_phi = r.phi_o.saturating_mul(FINE_PHI_PER_CELL);
                let builder =
                    OutgoingBuilder::anisotropic_by_name(simplifier.short(), o.tolerance, fine)?;
                let sampler =
                    AnisotropicOutgoingSampler::new(m.brdf.clone(), r, builder, fine_phi)?;
                Ok(sampler.with_cosine_mix(o.cosine_mix)?.into())
            }
        },
        load: Some(|bytes| {
            if acdf_outgoing::anisotropic::persist::is_anisotropic(bytes)? {
                Ok(AnisotropicOutgoingSampler::from_bytes(bytes)?.into())
            } else {
                Ok(OutgoingSampler::from_bytes(bytes)?.into())
            }
        }),
    },
    SamplerFamily {
        name: "rgl",
        description: "the RGL .bsdf file's own sampler, for .bsdf materials only",
        simplifiers: false,
        report_rank: Some(3),
        in_render: true,
        environment: false,
        requires: Some(Requirement {
            met: |m| m.rgl.is_some(),
            reason: "the rgl sampler needs an RGL .bsdf material",
            serves: ".bsdf materials",
        }),
        file_kind: None,
        build: |spec, m, _| match &m.rgl {
            Some(rgl) => Ok(RglSampler::new(rgl.clone()).into()),
            None => Err(incompatible(spec, m)),
        },
        load: None,
    },
    SamplerFamily {
        name: acdf_lobes::persist::KIND,
        description: "a cosine lobe and up to 3 GGX lobes fitted per material, 32 bytes",
        simplifiers: false,
        report_rank: Some(4),
        in_render: false,
        environment: false,
        requires: None,
        file_kind: Some(acdf_lobes::persist::KIND),
        build: |_, m, _| Ok(LobesSampler::new(m.brdf.as_ref())?.into()),
        load: Some(|bytes| Ok(LobesSampler::from_bytes(bytes)?.into())),
    },
    SamplerFamily {
        name: PRODUCT,
        description: "BRDF × environment at one shading normal: blocks of the map weighed by \
                      a BRDF sampler's density, texels by their light, with a defensive share \
                      of the BRDF sampler; needs --envmap and --normal, product:BRDF_SAMPLER \
                      (alone, product:outgoing:chi2)",
        simplifiers: false,
        report_rank: None,
        in_render: false,
        environment: true,
        requires: None,
        file_kind: None,
        build: |spec, _, _| {
            Err(Error::NeedsEnvironment {
                sampler: spec.to_string(),
                context: "which this command does not take".into(),
            })
        },
        load: None,
    },
];

/// The name of the family that samples BRDF × environment
/// ([`ProductSampler`]).
pub const PRODUCT: &str = "product";

/// The environment a product sampler is formed for: the map's blocks
/// (built once per map), the shading normal in the map's frame, and the
/// product's options.
#[derive(Debug, Clone)]
pub struct ProductSetting {
    /// The map cut into blocks.
    pub env: Arc<ProductEnv>,
    /// The shading normal, in the map's frame.
    pub normal: Vec3,
    /// Grid, points per cell, sub-cells, draws and shares.
    pub options: ProductOptions,
}

impl ProductSetting {
    /// Cut `map` into the blocks of `options`, for the product at `normal`.
    pub fn new(
        map: Arc<acdf_lights::EnvMap>,
        normal: Vec3,
        options: ProductOptions,
    ) -> Result<Self> {
        options.validate()?;
        Ok(ProductSetting {
            env: Arc::new(ProductEnv::new(
                map,
                options.block_columns,
                options.points_per_side,
                options.sub_cells,
            )?),
            normal,
            options,
        })
    }
}

/// Build the sampler `spec` names for `material`: for a family that samples
/// BRDF × environment, its BRDF sampler built as [`make_sampler_spec`]
/// builds it and wrapped with `setting` (a typed error without one); for
/// any other family, [`make_sampler_spec`] (a typed error with one, which
/// it would ignore).
pub fn make_sampler_in(
    spec: SamplerSpec,
    material: &Material,
    options: &SamplerOptions,
    setting: Option<&ProductSetting>,
) -> Result<AnySampler> {
    match (spec.base(), setting) {
        (Some(base), Some(setting)) => {
            let brdf = make_sampler_spec(base, material, options)?;
            brdf.build_all()?;
            Ok(ProductSampler::new(
                Arc::new(brdf),
                setting.env.clone(),
                setting.normal,
                setting.options,
            )?
            .into())
        }
        (Some(_), None) => Err(Error::NeedsEnvironment {
            sampler: spec.to_string(),
            context: "and was given neither".into(),
        }),
        (None, Some(_)) => Err(Error::InvalidArgument {
            what: "--envmap and --normal",
            value: spec.to_string(),
            reason: format!("only the {PRODUCT} sampler takes an environment map and a normal"),
        }),
        (None, None) => make_sampler_spec(spec, material, options),
    }
}

/// The family called `name`.
pub fn family(name: &str) -> Option<&'static SamplerFamily> {
    SAMPLERS.iter().find(|f| f.name == name)
}

/// Every sampler name the command line accepts, in the table's order: each
/// family's name, and for the family with simplifiers also
/// `NAME:SIMPLIFIER` for every simplifier.
pub fn sampler_names() -> Vec<String> {
    named(false).into_iter().map(|(name, _)| name).collect()
}

/// The names of the samplers that can be saved to a file (`acdf build`).
pub fn saved_sampler_names() -> Vec<String> {
    named(true).into_iter().map(|(name, _)| name).collect()
}

/// (name, one-line description) of every sampler name, or of those with a
/// file format.
fn named(saved_only: bool) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for f in SAMPLERS
        .iter()
        .filter(|f| !saved_only || f.file_kind.is_some())
    {
        if f.simplifiers {
            let first = SimplifierName::default_simplifier();
            out.push((
                f.name.to_string(),
                format!("{}; alone, {}:{first}", f.description, f.name),
            ));
            out.extend(
                acdf_adaptive_cdf::simplify::SIMPLIFIERS
                    .iter()
                    .map(|e| (format!("{}:{}", f.name, e.name), e.description.to_string())),
            );
        } else {
            out.push((f.name.to_string(), f.description.to_string()));
        }
    }
    out
}

/// The short help of a `--sampler` option (`-h`): the names, from the
/// tables.
pub fn sampler_help(saved_only: bool) -> String {
    let names: Vec<String> = named(saved_only).into_iter().map(|(n, _)| n).collect();
    format!("One of {}", names.join(", "))
}

/// The long help of a `--sampler` option (`--help`): one name per line with
/// its description, from the tables.
pub fn sampler_long_help(saved_only: bool) -> String {
    format_long_help(&named(saved_only))
}

/// `One of:` and one `name  description` line per name, the names padded to
/// the longest: the long help of a `--sampler` option.
pub(crate) fn format_long_help(named: &[(String, String)]) -> String {
    let width = named.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
    let lines: Vec<String> = named
        .iter()
        .map(|(n, d)| format!("  {n:width$}  {d}"))
        .collect();
    format!("One of:\n{}", lines.join("\n"))
}

/// Build the sampler named `name` (see [`SamplerSpec`]) for `material`.
pub fn make_sampler(
    name: &str,
    material: &Material,
    options: &SamplerOptions,
) -> Result<AnySampler> {
    let spec: SamplerSpec = name.parse()?;
    make_sampler_spec(spec, material, options)
}

/// [`make_sampler`] for an already parsed name.
pub fn make_sampler_spec(
    spec: SamplerSpec,
    material: &Material,
    options: &SamplerOptions,
) -> Result<AnySampler> {
    let family = spec.family();
    if !usable(family, material) {
        return Err(incompatible(&spec, material));
    }
    (family.build)(&spec, material, options)
}

/// The tabulated slices of one material at one resolution, made once and
/// shared by every uniform and adaptive sampler built from them
/// ([`make_sampler_tabulated`]): a sweep or a survey builds a dozen
/// samplers of a material at the same resolution, and tabulating (with
/// its support pass) is most of what a build costs.
pub struct Tabulation {
    resolution: Resolution,
    slices: Vec<Vec<f32>>,
    /// Seconds the tabulation took (in parallel).
    pub seconds: f64,
}

impl Tabulation {
    /// Tabulate every slice of `material` at the resolution its tabulated
    /// samplers use for `requested` ([`effective_resolution`]), in parallel:
    /// the tables `build_all` would make.
    pub fn new(material: &Material, requested: Resolution) -> Tabulation {
        let resolution = effective_resolution(material, requested);
        let start = std::time::Instant::now();
        let slices = (0..resolution.slices())
            .into_par_iter()
            .map(|index| {
                let (i, j) = (index / resolution.phi_o, index % resolution.phi_o);
                tabulate_slice(material.brdf.as_ref(), &resolution, i, j)
            })
            .collect();
        Tabulation {
            resolution,
            slices,
            seconds: start.elapsed().as_secs_f64(),
        }
    }

    /// [`new`](Self::new) for an isotropic material with several φ_o
    /// slices whose count divides the φ_h columns (as at 32x16x256x32):
    /// the slices of φ_o cell 0 are tabulated, and those of cell j are
    /// the same tables turned by j × (φ_h columns / φ_o cells) columns.
    /// For an isotropic material slice j's outgoing directions, its
    /// support pass included, are those of slice 0 turned by its centre
    /// φ_o = 2πj / n_φo, and its φ_h axis is absolute, so this is the
    /// tabulation of every slice up to float rounding, for 1/n_φo of the
    /// work. Other materials and resolutions are tabulated in full.
    pub fn by_rotation(material: &Material, requested: Resolution) -> Tabulation {
        let resolution = effective_resolution(material, requested);
        let (n_phi_o, n_phi_h) = (resolution.phi_o, resolution.phi_h);
        if !material.brdf.is_isotropic() || n_phi_o < 2 || n_phi_h % n_phi_o != 0 {
            return Tabulation::new(material, requested);
        }
        let start = std::time::Instant::now();
        let base: Vec<Vec<f32>> = (0..resolution.theta_o)
            .into_par_iter()
            .map(|i| tabulate_slice(material.brdf.as_ref(), &resolution, i, 0))
            .collect();
        let step = n_phi_h / n_phi_o;
        let mut slices = Vec::with_capacity(resolution.slices());
        for table in &base {
            for j in 0..n_phi_o {
                let shift = j * step;
                let mut turned = vec![0.0f32; table.len()];
                for (row_out, row_in) in turned
                    .chunks_exact_mut(n_phi_h)
                    .zip(table.chunks_exact(n_phi_h))
                {
                    for (c, v) in row_out.iter_mut().enumerate() {
                        *v = row_in[(c + n_phi_h - shift) % n_phi_h];
                    }
                }
                slices.push(turned);
            }
        }
        Tabulation {
            resolution,
            slices,
            seconds: start.elapsed().as_secs_f64(),
        }
    }

    /// No tables: every sampler made from it is built as usual.
    pub fn empty() -> Tabulation {
        Tabulation {
            resolution: Resolution {
                theta_o: 0,
                ..Resolution::ISOTROPIC
            },
            slices: Vec::new(),
            seconds: 0.0,
        }
    }

    /// The resolution tabulated.
    pub fn resolution(&self) -> Resolution {
        self.resolution
    }

    /// A sampler whose slices `builder` makes from these tables (in
    /// parallel).
    fn sampler<B: SliceBuilder>(
        &self,
        material: &Material,
        builder: B,
        cosine_mix: f32,
    ) -> Result<TabulatedBrdfSampler<B>> {
        let r = self.resolution;
        let dists = self
            .slices
            .par_iter()
            .map(|values| builder.build_slice(values, r.phi_h, r.theta_h))
            .collect::<std::result::Result<Vec<_>, _>>()?;
        let sampler =
            TabulatedBrdfSampler::from_built_slices(material.brdf.clone(), r, builder, dists)?;
        Ok(sampler.with_cosine_mix(cosine_mix)?)
    }
}

/// [`make_sampler_spec`] with every table built, taking a uniform or
/// adaptive sampler's slices from `tables` when they are at its
/// resolution: the same sampler as building it alone, without tabulating
/// again. Other samplers are built as usual.
pub fn make_sampler_tabulated(
    spec: SamplerSpec,
    material: &Material,
    options: &SamplerOptions,
    tables: &Tabulation,
) -> Result<AnySampler> {
    let shared = tables.resolution == self::tables(material, options);
    match (spec.family().name, spec.simplifier()) {
        ("uniform", None) if shared => Ok(tables
            .sampler(material, PiecewiseConstantBuilder, options.cosine_mix)?
            .into()),
        (ADAPTIVE, Some(simplifier)) if shared => {
            let builder = AdaptiveBuilder::by_name(simplifier.short(), options.tolerance)?;
            Ok(tables
                .sampler(material, builder, options.cosine_mix)?
                .into())
        }
        _ => {
            let sampler = make_sampler_spec(spec, material, options)?;
            sampler.build_all()?;
            Ok(sampler)
        }
    }
}

/// The error for a sampler whose family's requirement `material` does not
/// meet.
fn incompatible(spec: &SamplerSpec, material: &Material) -> Error {
    let reason = spec.family().requires.as_ref().map_or("", |r| r.reason);
    Error::Incompatible {
        sampler: spec.to_string(),
        material: material.spec.to_string(),
        reason: reason.into(),
    }
}

/// The resolution of a tabulated sampler of `material` at `options`.
fn tables(material: &Material, options: &SamplerOptions) -> Resolution {
    effective_resolution(material, options.resolution)
}

/// The resolution a tabulated sampler of `material` uses: `requested`, except
/// that an anisotropic material cannot use one φ_o slice and gets the paper's
/// 16 instead.
pub fn effective_resolution(material: &Material, requested: Resolution) -> Resolution {
    if !material.brdf.is_isotropic() && requested.phi_o == 1 {
        Resolution {
            phi_o: Resolution::PAPER.phi_o,
            ..requested
        }
    } else {
        requested
    }
}

/// Whether `family` can be used with `material`.
fn usable(family: &SamplerFamily, material: &Material) -> bool {
    match &family.requires {
        Some(r) => (r.met)(material),
        None => true,
    }
}

/// The families of `acdf report`'s default set, in rank order.
fn report_families() -> Vec<&'static SamplerFamily> {
    let mut families: Vec<&SamplerFamily> = SAMPLERS
        .iter()
        .filter(|f| f.report_rank.is_some())
        .collect();
    families.sort_by_key(|f| f.report_rank);
    families
}

/// A family's samplers in `acdf report`'s default set: for the family with
/// simplifiers, those marked `in_report` in the adaptive plug-in's table.
fn report_specs(family: &'static SamplerFamily) -> Vec<SamplerSpec> {
    if family.simplifiers {
        SimplifierName::in_report()
            .map(SamplerSpec::adaptive)
            .collect()
    } else {
        vec![SamplerSpec::of_family(family)]
    }
}

/// The families of `acdf render`'s default set, in the table's order.
fn render_families() -> Vec<&'static SamplerFamily> {
    SAMPLERS.iter().filter(|f| f.in_render).collect()
}

/// The samplers a report compares for `material` by default: the families
/// with a `report_rank`, in rank order (uniform, the adaptive simplifiers
/// marked `in_report`, cosine, `rgl` for RGL materials, and lobes).
pub fn report_samplers(material: &Material) -> Vec<SamplerSpec> {
    report_families()
        .into_iter()
        .filter(|f| usable(f, material))
        .flat_map(report_specs)
        .collect()
}

/// The samplers `acdf render` compares for `material` by default: the
/// families marked `in_render`, in the table's order (cosine, uniform,
/// adaptive, and `rgl` for RGL materials).
pub fn render_samplers(material: &Material) -> Vec<SamplerSpec> {
    render_families()
        .into_iter()
        .filter(|f| usable(f, material))
        .map(SamplerSpec::of_family)
        .collect()
}

/// The samplers of every family without simplifiers that can be used with
/// `material`, in the table's order (`cosine`, `uniform`, `rgl` for RGL
/// materials, and `lobes`): with every simplifier of the adaptive family, the
/// samplers the registry knows.
pub fn plain_samplers(material: &Material) -> Vec<SamplerSpec> {
    SAMPLERS
        .iter()
        .filter(|f| !f.simplifiers && !f.environment && usable(f, material))
        .map(SamplerSpec::of_family)
        .collect()
}

/// `acdf report`'s default set for help texts, e.g. `uniform, adaptive:dp,
/// ..., rgl (for .bsdf materials)`.
pub fn report_default_help() -> String {
    describe_set(report_families(), report_specs)
}

/// `acdf render`'s default set for help texts.
pub fn render_default_help() -> String {
    describe_set(render_families(), |f| vec![SamplerSpec::of_family(f)])
}

fn describe_set(
    families: Vec<&'static SamplerFamily>,
    specs: impl Fn(&'static SamplerFamily) -> Vec<SamplerSpec>,
) -> String {
    let mut parts = Vec::new();
    for f in families {
        for spec in specs(f) {
            parts.push(match &f.requires {
                Some(r) => format!("{spec} (for {})", r.serves),
                None => spec.to_string(),
            });
        }
    }
    parts.join(", ")
}

/// Build every table of a tabulated sampler and save it to `path` in the
/// sampler file format (`acdf_tabulated::persist`), so a renderer can load it
/// without rebuilding. Samplers without tables have nothing to save and give
/// [`Error::NotSaveable`]; a failure to write names the file.
pub fn save_sampler(sampler: &AnySampler, path: &Path) -> Result<()> {
    match sampler.write_file(path) {
        Some(written) => written.map_err(|source| match source {
            PersistError::File(e) => Error::File(e),
            source => Error::SamplerFile {
                path: path.to_path_buf(),
                source,
            },
        }),
        None => Err(not_saveable(sampler.name())),
    }
}

/// Whether the samplers `spec` names can be saved to a file.
pub fn is_saveable(spec: &SamplerSpec) -> bool {
    spec.family().file_kind.is_some()
}

/// The error for a sampler without a file format.
pub fn not_saveable(sampler: &str) -> Error {
    Error::NotSaveable {
        sampler: sampler.to_string(),
        kinds: file_kinds().join(", "),
    }
}

/// Load a sampler saved by [`save_sampler`] for use with `material`: the
/// fingerprint recorded in the file must be the material's
/// ([`acdf_core::Brdf::fingerprint`]), whatever the names, or the result is
/// [`Error::SamplerMaterialMismatch`].
pub fn load_sampler_for(path: &Path, material: &Material) -> Result<AnySampler> {
    let loaded = load_sampler(path)?;
    let fingerprint = material.brdf.fingerprint();
    match loaded.material_fingerprint() {
        Some(recorded) if recorded != fingerprint => Err(Error::SamplerMaterialMismatch {
            path: path.to_path_buf(),
            recorded: loaded.material_name().unwrap_or("?").to_string(),
            recorded_fingerprint: recorded,
            material: material.spec.to_string(),
            fingerprint,
        }),
        _ => Ok(loaded),
    }
}

/// The kinds of sampler files, from the table.
fn file_kinds() -> Vec<&'static str> {
    SAMPLERS.iter().filter_map(|f| f.file_kind).collect()
}

/// Load a sampler saved by [`save_sampler`]; the kind recorded in the file
/// picks the family, and a kind no family reads is
/// [`Error::UnknownSamplerKind`].
pub fn load_sampler(path: &Path) -> Result<AnySampler> {
    let file_error = |source| match source {
        PersistError::File(e) => Error::File(e),
        source => Error::SamplerFile {
            path: path.to_path_buf(),
            source,
        },
    };
    let bytes = persist::read_file(path).map_err(file_error)?;
    let kind = persist::peek_kind(&bytes).map_err(file_error)?;
    let load = SAMPLERS
        .iter()
        .find(|f| f.file_kind == Some(kind.as_str()))
        .and_then(|f| f.load)
        .ok_or_else(|| Error::UnknownSamplerKind {
            path: path.to_path_buf(),
            kind: kind.clone(),
            known: file_kinds().join(", "),
        })?;
    load(&bytes).map_err(file_error)
}

/// Shared ownership of a built sampler, for experiments that hand it to
/// several threads.
pub type SharedSampler = Arc<AnySampler>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::load_material;
    use crate::spec::MaterialSpec;

    fn nickel() -> Material {
        load_material(&MaterialSpec::Builtin("nickel".into()), None).unwrap()
    }

    /// Every name builds a sampler that calls itself by that name, so tables
    /// and JSON use the command-line names.
    #[test]
    fn every_name_builds_the_sampler_it_names() {
        let m = nickel();
        let options = SamplerOptions::default();
        for name in sampler_names()
            .into_iter()
            .filter(|n| n != "rgl" && n != ADAPTIVE && n != OUTGOING && n != PRODUCT)
        {
            let s = make_sampler(&name, &m, &options).unwrap();
            assert_eq!(s.name(), name);
            let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
            let d = s.sample(wo, Vec2::new(0.3, 0.6)).unwrap();
            assert!((s.pdf(wo, d.wi) - d.pdf).abs() <= 1e-4 * d.pdf, "{name}");
        }
        assert_eq!(
            make_sampler("adaptive", &m, &options).unwrap().name(),
            "adaptive:dp"
        );
        assert_eq!(
            make_sampler("outgoing", &m, &options).unwrap().name(),
            "outgoing:dp"
        );
        assert!(matches!(
            make_sampler("rgl", &m, &options),
            Err(Error::Incompatible { .. })
        ));
        let unknown = make_sampler("nope", &m, &options).unwrap_err();
        assert!(matches!(unknown, Error::UnknownSampler { .. }));
        for name in sampler_names() {
            assert!(
                unknown.to_string().contains(&name),
                "{unknown} lacks {name}"
            );
        }
    }

    /// `product` is built only with an environment, wraps the BRDF sampler
    /// it names, draws with the density it reports, and stays out of the
    /// default sets and the plain samplers; other samplers refuse an
    /// environment.
    #[test]
    fn product_samplers_need_an_environment() {
        let m = nickel();
        let options = SamplerOptions {
            resolution: "8x1x32x8".parse().unwrap(),
            ..SamplerOptions::default()
        };
        let map = acdf_lights::EnvMap::from_fn(32, 16, |k, j| {
            acdf_core::Rgb::splat(if (k, j) == (3, 4) { 500.0 } else { 0.2 })
        })
        .unwrap();
        let setting = ProductSetting::new(
            Arc::new(map),
            Vec3::new(0.2, 0.3, 0.9),
            ProductOptions::default(),
        )
        .unwrap();
        let spec: SamplerSpec = "product:adaptive:chi2".parse().unwrap();
        assert!(matches!(
            make_sampler_in(spec, &m, &options, None),
            Err(Error::NeedsEnvironment { .. })
        ));
        assert!(matches!(
            make_sampler("product", &m, &options),
            Err(Error::NeedsEnvironment { .. })
        ));
        assert!(matches!(
            make_sampler_in(SamplerSpec::COSINE, &m, &options, Some(&setting)),
            Err(Error::InvalidArgument { .. })
        ));
        let s = make_sampler_in(spec, &m, &options, Some(&setting)).unwrap();
        assert_eq!(s.name(), "product:adaptive:chi2");
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let d = s.sample(wo, Vec2::new(0.3, 0.6)).unwrap();
        assert_eq!(s.pdf(wo, d.wi), d.pdf);
        for f in [report_samplers(&m), render_samplers(&m), plain_samplers(&m)] {
            assert!(f.iter().all(|s| s.family().name != PRODUCT));
        }
    }

    /// The default sets of `acdf report` and `acdf render`, in their order.
    #[test]
    fn default_sets_keep_their_order() {
        let names = |specs: Vec<SamplerSpec>| -> Vec<String> {
            specs.iter().map(ToString::to_string).collect()
        };
        let m = nickel();
        assert_eq!(
            names(report_samplers(&m)),
            [
                "uniform",
                "adaptive:dp",
                "adaptive:vw",
                "adaptive:rw",
                "adaptive:optimal",
                "adaptive:chi2",
                "cosine",
                "lobes"
            ]
        );
        assert_eq!(
            names(render_samplers(&m)),
            ["cosine", "uniform", "adaptive:dp"]
        );
    }

    /// A sampler file of a kind no family reads is a typed error naming the
    /// kind found and the kinds known, not a misread.
    #[test]
    fn unknown_file_kinds_are_typed_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mystery.acdfs");
        let mut body = persist::ByteWriter::new();
        body.string("mystery");
        let bytes = persist::seal(&body.into_bytes());
        std::fs::write(&path, bytes).unwrap();
        match load_sampler(&path) {
            Err(e @ Error::UnknownSamplerKind { .. }) => {
                let text = e.to_string();
                assert!(text.contains("\"mystery\""), "{text}");
                for kind in file_kinds() {
                    assert!(text.contains(kind), "{text} lacks {kind}");
                }
            }
            other => panic!("expected UnknownSamplerKind, got {other:?}"),
        }
    }

    /// A sampler built from a shared tabulation is the one built alone:
    /// same storage, same densities.
    #[test]
    fn samplers_from_a_shared_tabulation_are_those_built_alone() {
        let m = nickel();
        let options = SamplerOptions {
            resolution: "8x1x32x8".parse().unwrap(),
            tolerance: None,
            cosine_mix: 0.1,
        };
        let tables = Tabulation::new(&m, options.resolution);
        for name in ["uniform", "adaptive:chi2", "adaptive:dp", "cosine"] {
            let spec: SamplerSpec = name.parse().unwrap();
            let shared = make_sampler_tabulated(spec, &m, &options, &tables).unwrap();
            let alone = make_sampler_spec(spec, &m, &options).unwrap();
            alone.build_all().unwrap();
            assert_eq!(shared.storage_bytes(), alone.storage_bytes(), "{name}");
            let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
            for k in 0..50 {
                let u = Vec2::new((k as f32 + 0.5) / 50.0, (k as f32 * 0.618).fract());
                let (a, b) = (shared.sample(wo, u), alone.sample(wo, u));
                assert_eq!(a, b, "{name}");
                if let Some(s) = a {
                    assert_eq!(shared.pdf(wo, s.wi), alone.pdf(wo, s.wi), "{name}");
                }
            }
        }
    }

    /// The turned tables of [`Tabulation::by_rotation`] are those
    /// tabulated slice by slice, to float rounding (relative to each
    /// slice's largest value).
    #[test]
    fn turned_tabulations_match_the_tabulated_slices() {
        let m = nickel();
        let res: Resolution = "6x4x32x8".parse().unwrap();
        let turned = Tabulation::by_rotation(&m, res);
        let direct = Tabulation::new(&m, res);
        assert_eq!(turned.slices.len(), direct.slices.len());
        for (k, (a, b)) in turned.slices.iter().zip(&direct.slices).enumerate() {
            let scale = b.iter().copied().fold(0.0f32, f32::max).max(1e-30);
            let worst = a
                .iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs() / scale)
                .fold(0.0f32, f32::max);
            assert!(worst < 1e-4, "slice {k}: {worst}");
            // The support differs at most in cells of next to no mass,
            // where rounding decides whether a point lies above the
            // horizon.
            for (x, y) in a.iter().zip(b) {
                if (*x == 0.0) != (*y == 0.0) {
                    assert!(x.max(*y) < 1e-6 * scale, "slice {k}: {x} against {y}");
                }
            }
        }
    }

    /// Building every slice makes an adaptive sampler report its storage,
    /// and that storage shrinks as the tolerance grows.
    #[test]
    fn adaptive_storage_shrinks_with_tolerance() {
        let m = nickel();
        let storage = |t: f64| {
            let s = make_sampler(
                "adaptive:dp",
                &m,
                &SamplerOptions {
                    tolerance: Some(t),
                    ..SamplerOptions::default()
                },
            )
            .unwrap();
            s.build_all().unwrap();
            assert!(s.mean_vertices().unwrap().0 >= 2.0);
            s.storage_bytes()
        };
        assert!(storage(1e-4) > storage(1e-2));
    }

    /// nickel, but claiming to depend on both azimuths.
    struct Anisotropic(Arc<dyn acdf_core::Brdf>);
    impl acdf_core::Brdf for Anisotropic {
        fn name(&self) -> &str {
            "anisotropic"
        }
        fn eval(&self, wo: Vec3, wi: Vec3) -> acdf_core::Rgb {
            self.0.eval(wo, wi)
        }
        fn is_isotropic(&self) -> bool {
            false
        }
    }

    #[test]
    fn anisotropic_materials_get_phi_o_slices() {
        let m = nickel();
        assert_eq!(
            effective_resolution(&m, Resolution::ISOTROPIC),
            Resolution::ISOTROPIC
        );
        let aniso = Material {
            brdf: Arc::new(Anisotropic(m.brdf.clone())),
            ..m
        };
        assert_eq!(
            effective_resolution(&aniso, Resolution::ISOTROPIC).phi_o,
            Resolution::PAPER.phi_o
        );
        // Without the adjustment the uniform plug-in would reject it.
        assert!(make_sampler("uniform", &aniso, &SamplerOptions::default()).is_ok());
    }

    /// A lobes sampler saves and loads through the registry with the same
    /// draws, and its file is refused for another material.
    #[test]
    fn lobes_files_load_with_the_same_draws() {
        let m = nickel();
        let s = make_sampler("lobes", &m, &SamplerOptions::default()).unwrap();
        assert_eq!(s.storage_bytes(), acdf_lobes::STORAGE_BYTES);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lobes.acdfs");
        save_sampler(&s, &path).unwrap();
        let loaded = load_sampler_for(&path, &m).unwrap();
        assert!(matches!(loaded, AnySampler::Lobes(_)));
        let wo = Vec3::new(0.3, -0.4, 0.8).normalize();
        for k in 0..50 {
            let u = Vec2::new((k as f32 + 0.5) / 50.0, (k as f32 * 0.618).fract());
            assert_eq!(loaded.sample(wo, u), s.sample(wo, u));
        }
        let lambert = load_material(&MaterialSpec::Builtin("lambert".into()), None).unwrap();
        assert!(matches!(
            load_sampler_for(&path, &lambert),
            Err(Error::SamplerMaterialMismatch { .. })
        ));
    }

    /// `outgoing:SIMPLIFIER` builds the anisotropic outgoing sampler for an
    /// anisotropic material (the isotropic one for an isotropic material),
    /// and its file loads back as the same variant with the same draws.
    #[test]
    fn anisotropic_materials_get_the_anisotropic_outgoing_sampler() {
        let m = nickel();
        let options = SamplerOptions {
            resolution: "8x1x32x8".parse().unwrap(),
            ..SamplerOptions::default()
        };
        let iso = make_sampler("outgoing:chi2", &m, &options).unwrap();
        assert!(matches!(iso, AnySampler::Outgoing(_)));
        let aniso = Material {
            brdf: Arc::new(Anisotropic(m.brdf.clone())),
            ..m
        };
        let s = make_sampler("outgoing:chi2", &aniso, &options).unwrap();
        assert_eq!(s.name(), "outgoing:chi2");
        let AnySampler::OutgoingAnisotropic(inner) = &s else {
            panic!("expected the anisotropic outgoing sampler, got {s:?}");
        };
        // 8 θ_o cells and the paper's 16 φ_o cells, two nodes per cell.
        assert_eq!((inner.builder().fine, inner.fine_phi()), (16, 32));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("aniso.acdfs");
        save_sampler(&s, &path).unwrap();
        let loaded = load_sampler_for(&path, &aniso).unwrap();
        assert!(matches!(loaded, AnySampler::OutgoingAnisotropic(_)));
        assert_eq!(loaded.storage_bytes(), s.storage_bytes());
        let wo = Vec3::new(0.3, -0.4, 0.8).normalize();
        for k in 0..50 {
            let u = Vec2::new((k as f32 + 0.5) / 50.0, (k as f32 * 0.618).fract());
            assert_eq!(loaded.sample(wo, u), s.sample(wo, u));
        }
    }
}
