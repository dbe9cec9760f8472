//! The registry of environment samplers: every concrete sampler of
//! directions over the sphere behind one enum, [`AnyEnvSampler`], and one
//! table of families, [`ENV_SAMPLERS`], from which the names of
//! `acdf env-sample`, `acdf env-pdf` and `acdf env-report` ([`EnvSamplerSpec`]
//! parsing, [`env_sampler_names`]), their help and error texts, the default
//! set of `env-report` and building ([`make_env_sampler`]) derive. The
//! families with simplifiers take their names from the adaptive plug-in's
//! table ([`SIMPLIFIERS`](acdf_adaptive_cdf::simplify::SIMPLIFIERS)), as the
//! BRDF registry ([`SAMPLERS`](crate::registry::SAMPLERS)) does.

use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_adaptive_env::{
    adaptive_env_sampler, oriented_env_sampler, AdaptiveEnvSampler, OrientedEnvSampler,
};
use acdf_core::{SphereSample, SphereSampler, Vec2, Vec3};
use acdf_lights::{EnvMap, NormalGrid, TableKind};
use acdf_uniform::{uniform_env_sampler, UniformEnvSampler};

use crate::error::{Error, Result};
use crate::registry::format_long_help;
use crate::spec::{parse_angles_degrees, parse_family_name, SimplifierName};

/// Options of the environment samplers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvSamplerOptions {
    /// Simplifier tolerance of the adaptive and oriented samplers; `None`
    /// for the simplifier's own default ([`ENV_CHI2_TOLERANCE`] for `chi2`).
    pub tolerance: Option<f64>,
    /// The cells of normals of the oriented sampler.
    pub normal_cells: NormalGrid,
    /// The oriented sampler's defensive share.
    pub defensive: f32,
}

impl Default for EnvSamplerOptions {
    /// Default tolerances, 16 × 32 normal cells, defensive share
    /// [`DEFAULT_DEFENSIVE`].
    fn default() -> Self {
        EnvSamplerOptions {
            tolerance: None,
            normal_cells: NormalGrid::DEFAULT,
            defensive: DEFAULT_DEFENSIVE,
        }
    }
}

/// The oriented sampler's default defensive share (none: each normal's
/// table covers every texel the normal sees).
pub const DEFAULT_DEFENSIVE: f32 = OrientedEnvSampler::DEFAULT_DEFENSIVE;

/// One of acdf's environment samplers, dispatched statically.
#[derive(Debug)]
pub enum AnyEnvSampler {
    /// `uniform`, `uniform-comp`: piecewise-constant over the texels.
    Uniform(UniformEnvSampler),
    /// `adaptive:S`, `adaptive-comp:S`: curve-simplified CDFs of the texels.
    Adaptive(AdaptiveEnvSampler),
    /// `oriented:S`: one adaptive table per region of normals.
    Oriented(OrientedEnvSampler),
}

macro_rules! dispatch {
    ($self:ident, $s:ident => $e:expr) => {
        match $self {
            AnyEnvSampler::Uniform($s) => $e,
            AnyEnvSampler::Adaptive($s) => $e,
            AnyEnvSampler::Oriented($s) => $e,
        }
    };
}

impl SphereSampler for AnyEnvSampler {
    fn name(&self) -> &str {
        dispatch!(self, s => s.name())
    }
    #[inline]
    fn sample(&self, normal: Option<Vec3>, u: Vec2) -> Option<SphereSample> {
        dispatch!(self, s => s.sample(normal, u))
    }
    #[inline]
    fn pdf(&self, normal: Option<Vec3>, dir: Vec3) -> f32 {
        dispatch!(self, s => s.pdf(normal, dir))
    }
    fn storage_bytes(&self) -> usize {
        dispatch!(self, s => s.storage_bytes())
    }
    fn sample_batch(&self, normal: Option<Vec3>, u: &[Vec2], out: &mut [Option<SphereSample>]) {
        dispatch!(self, s => s.sample_batch(normal, u, out))
    }
    fn pdf_batch(&self, normal: Option<Vec3>, dir: &[Vec3], out: &mut [f32]) {
        dispatch!(self, s => s.pdf_batch(normal, dir, out))
    }
}

impl AnyEnvSampler {
    /// A short description of the tables: the texel grid for `uniform`, the
    /// kept vertices (marginal × mean conditional) for adaptive tables, and
    /// for `oriented` the nodes built so far out of all.
    pub fn table_label(&self) -> String {
        match self {
            AnyEnvSampler::Uniform(s) => {
                let (w, h) = s.grid().size();
                format!("{w}x{h}")
            }
            AnyEnvSampler::Adaptive(s) => {
                let d = s.distribution();
                format!(
                    "{}x{:.1}",
                    d.marginal_vertex_count(),
                    d.mean_conditional_vertices()
                )
            }
            AnyEnvSampler::Oriented(s) => {
                let g = s.normal_grid();
                format!(
                    "{}x{} cells, {}/{} built",
                    g.rows,
                    g.columns,
                    s.built_nodes(),
                    s.node_count()
                )
            }
        }
    }

    /// For `oriented`, (nodes built so far, all nodes).
    pub fn built_nodes(&self) -> Option<(usize, usize)> {
        match self {
            AnyEnvSampler::Oriented(s) => Some((s.built_nodes(), s.node_count())),
            _ => None,
        }
    }

    /// Whether the sampler draws the compensated density (for multiple
    /// importance sampling; biased alone).
    pub fn is_compensated(&self) -> bool {
        self.name().contains("-comp")
    }
}

/// One family of environment samplers: one line of [`ENV_SAMPLERS`].
#[derive(Debug)]
pub struct EnvSamplerFamily {
    /// The name on the command line (`--sampler NAME`).
    pub name: &'static str,
    /// One line for help texts.
    pub description: &'static str,
    /// Whether the family takes a simplifier, `NAME:SIMPLIFIER`, from the
    /// adaptive plug-in's table (the plain `NAME` is its first).
    pub simplifiers: bool,
    /// Which of its samplers `acdf env-report` compares by default.
    pub in_report: InReport,
    /// Build it for a map.
    pub build: EnvBuildFn,
}

/// A family's samplers in `acdf env-report`'s default set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InReport {
    /// None.
    No,
    /// The plain name (with the first simplifier, for a family with
    /// simplifiers).
    Plain,
    /// Every simplifier marked `in_report` in the adaptive plug-in's table.
    Simplifiers,
}

/// Builds a family's sampler for a map, with a simplifier for families
/// that take one.
pub type EnvBuildFn =
    fn(Option<SimplifierName>, &Arc<EnvMap>, &EnvSamplerOptions) -> Result<AnyEnvSampler>;

/// The builder of an adaptive table with `simplifier` (the table's first
/// when `None`) at the options' tolerance, or the simplifier's default
/// ([`ENV_CHI2_TOLERANCE`] for `chi2`).
fn adaptive_builder(
    simplifier: Option<SimplifierName>,
    options: &EnvSamplerOptions,
) -> Result<AdaptiveBuilder> {
    let simplifier = simplifier.unwrap_or_else(SimplifierName::default_simplifier);
    let tolerance = options
        .tolerance
        .or((simplifier.short() == "chi2").then_some(ENV_CHI2_TOLERANCE));
    Ok(AdaptiveBuilder::by_name(simplifier.short(), tolerance)?)
}

/// The tolerance of `chi2` on environment tables when none is given: a
/// budget of 0.5% on the chi-square divergence that simplification adds to
/// the luminance table, the largest tried (0.05, 0.02, 0.01, 0.005) at
/// which the irradiance variance stayed within 5% of the uniform table's
/// on every shared map (measured in `docs/environment.md`). `chi2`'s own
/// default (1.5e-3, chosen on BRDF slices of 256 x 32 cells) keeps far
/// more of a 1024 x 512 map than its variance needs, and builds far more
/// slowly: the simplifier runs a shortest path over the 1024 columns of
/// every marginal segment's conditional, and a smaller budget keeps more
/// segments.
pub const ENV_CHI2_TOLERANCE: f64 = 0.005;

/// Every environment sampler family, in the order of help texts and of
/// `acdf env-report`.
pub static ENV_SAMPLERS: &[EnvSamplerFamily] = &[
    EnvSamplerFamily {
        name: "uniform",
        description: "piecewise-constant over the texels, luminance x solid angle",
        simplifiers: false,
        in_report: InReport::Plain,
        build: |_, m, _| Ok(AnyEnvSampler::Uniform(uniform_env_sampler(m, TableKind::Luminance)?)),
    },
    EnvSamplerFamily {
        name: "adaptive",
        description: "curve-simplified CDFs of the uniform table, adaptive:SIMPLIFIER",
        simplifiers: true,
        in_report: InReport::Simplifiers,
        build: |s, m, o| {
            let b = adaptive_builder(s, o)?;
            Ok(AnyEnvSampler::Adaptive(adaptive_env_sampler(
                m,
                TableKind::Luminance,
                &b,
            )?))
        },
    },
    EnvSamplerFamily {
        name: "oriented",
        description: "an adaptive table of L max(0, n.w) per region of normals, built on first use, oriented:SIMPLIFIER",
        simplifiers: true,
        in_report: InReport::Plain,
        build: |s, m, o| {
            let b = adaptive_builder(s, o)?;
            Ok(AnyEnvSampler::Oriented(oriented_env_sampler(
                m.clone(),
                b,
                o.normal_cells,
                o.defensive,
            )?))
        },
    },
    EnvSamplerFamily {
        name: "uniform-comp",
        description: "uniform, compensated (luminance above the mean) for MIS",
        simplifiers: false,
        in_report: InReport::Plain,
        build: |_, m, _| {
            Ok(AnyEnvSampler::Uniform(uniform_env_sampler(
                m,
                TableKind::Compensated,
            )?))
        },
    },
    EnvSamplerFamily {
        name: "adaptive-comp",
        description: "adaptive, compensated for MIS, adaptive-comp:SIMPLIFIER",
        simplifiers: true,
        in_report: InReport::Plain,
        build: |s, m, o| {
            let b = adaptive_builder(s, o)?;
            Ok(AnyEnvSampler::Adaptive(adaptive_env_sampler(
                m,
                TableKind::Compensated,
                &b,
            )?))
        },
    },
];

/// The family called `name`.
pub fn env_family(name: &str) -> Option<&'static EnvSamplerFamily> {
    ENV_SAMPLERS.iter().find(|f| f.name == name)
}

/// An environment sampler as named on the command line: a family of
/// [`ENV_SAMPLERS`] and, for a family with simplifiers, its simplifier.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EnvSamplerSpec {
    family: &'static str,
    simplifier: Option<SimplifierName>,
}

impl EnvSamplerSpec {
    /// `uniform`, the reference of the relative columns.
    pub const UNIFORM: EnvSamplerSpec = EnvSamplerSpec {
        family: "uniform",
        simplifier: None,
    };

    /// The spec of a family: with the first simplifier when it takes one.
    pub fn of_family(family: &'static EnvSamplerFamily) -> Self {
        EnvSamplerSpec {
            family: family.name,
            simplifier: family.simplifiers.then(SimplifierName::default_simplifier),
        }
    }

    /// The family's entry of [`ENV_SAMPLERS`].
    pub fn family(&self) -> &'static EnvSamplerFamily {
        env_family(self.family).expect("an EnvSamplerSpec names a family of the table")
    }

    /// The simplifier, for a family that takes one.
    pub fn simplifier(&self) -> Option<SimplifierName> {
        self.simplifier
    }
}

impl FromStr for EnvSamplerSpec {
    type Err = Error;

    /// A family's name, or for a family with simplifiers `FAMILY` (its
    /// default simplifier) or `FAMILY:SIMPLIFIER`.
    fn from_str(s: &str) -> Result<Self> {
        let (family, simplifier) = parse_family_name(
            s,
            |head| env_family(head).map(|f| (f.name, f.simplifiers)),
            env_sampler_names,
        )?;
        Ok(EnvSamplerSpec { family, simplifier })
    }
}

impl fmt::Display for EnvSamplerSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.simplifier {
            Some(s) => write!(f, "{}:{s}", self.family),
            None => f.write_str(self.family),
        }
    }
}

/// (name, description) of every environment sampler name: each family, and
/// for a family with simplifiers `FAMILY:SIMPLIFIER` for every simplifier.
fn named() -> Vec<(String, String)> {
    let mut out = Vec::new();
    for f in ENV_SAMPLERS {
        match f.simplifiers.then(SimplifierName::default_simplifier) {
            Some(d) => {
                out.push((
                    f.name.to_string(),
                    format!("{}; alone, {}:{d}", f.description, f.name),
                ));
                out.extend(
                    SimplifierName::all()
                        .map(|s| (format!("{}:{s}", f.name), s.entry().description.to_string())),
                );
            }
            None => out.push((f.name.to_string(), f.description.to_string())),
        }
    }
    out
}

/// Every environment sampler name the command line accepts.
pub fn env_sampler_names() -> Vec<String> {
    named().into_iter().map(|(n, _)| n).collect()
}

/// The short help of an environment `--sampler` option.
pub fn env_sampler_help() -> String {
    format!("One of {}", env_sampler_names().join(", "))
}

/// The long help of an environment `--sampler` option: one name per line
/// with its description.
pub fn env_sampler_long_help() -> String {
    format_long_help(&named())
}

/// The samplers `acdf env-report` compares by default, in the table's
/// order: each family's plain name or its simplifiers marked `in_report`
/// ([`InReport`]).
pub fn report_env_samplers() -> Vec<EnvSamplerSpec> {
    ENV_SAMPLERS
        .iter()
        .flat_map(|f| match f.in_report {
            InReport::No => vec![],
            InReport::Plain => vec![EnvSamplerSpec::of_family(f)],
            InReport::Simplifiers => SimplifierName::in_report()
                .map(|s| EnvSamplerSpec {
                    family: f.name,
                    simplifier: Some(s),
                })
                .collect(),
        })
        .collect()
}

/// Build the environment sampler named `name` for `map`.
pub fn make_env_sampler(
    name: &str,
    map: &Arc<EnvMap>,
    options: &EnvSamplerOptions,
) -> Result<AnyEnvSampler> {
    let spec: EnvSamplerSpec = name.parse()?;
    make_env_sampler_spec(spec, map, options)
}

/// [`make_env_sampler`] for a parsed name.
pub fn make_env_sampler_spec(
    spec: EnvSamplerSpec,
    map: &Arc<EnvMap>,
    options: &EnvSamplerOptions,
) -> Result<AnyEnvSampler> {
    (spec.family().build)(spec.simplifier(), map, options)
}

/// Parse `THETA_DEG,PHI_DEG` into a unit direction anywhere on the sphere
/// (θ in [0, 180] degrees from `+z`, φ from `+x` towards `+y`), the
/// convention of environment maps ([`acdf_lights::latlong`]).
pub fn parse_sphere_direction_degrees(s: &str) -> Result<Vec3> {
    let (theta, phi) = parse_angles_degrees(s, 0.0..=180.0, "[0, 180] degrees")?;
    let (t, p) = (theta.to_radians(), phi.to_radians());
    Ok(Vec3::new(
        (t.sin() * p.cos()) as f32,
        (t.sin() * p.sin()) as f32,
        t.cos() as f32,
    ))
}

/// Load a lat-long environment map as every acdf command does: read and
/// checked by [`EnvMap::open`] (the size from the header against the memory
/// limit, NaN, infinite and negative texels refused), then refused when it
/// is black everywhere ([`check_not_black`]).
pub fn load_env_map(path: &std::path::Path) -> Result<Arc<EnvMap>> {
    let map = EnvMap::open(path)?;
    check_not_black(&map, path)?;
    Ok(Arc::new(map))
}

/// An error for a map that is black everywhere: it has no light, so there
/// is nothing to sample in proportion to.
pub fn check_not_black(map: &EnvMap, path: &std::path::Path) -> Result<()> {
    if map.is_black() {
        return Err(Error::InvalidArgument {
            what: "environment map",
            value: path.display().to_string(),
            reason: "every texel is 0: a black environment has no light to sample".into(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use acdf_core::Rgb;

    fn map() -> Arc<EnvMap> {
        Arc::new(
            EnvMap::from_fn(32, 16, |k, j| {
                Rgb::splat(if (k, j) == (5, 3) { 50.0 } else { 1.0 })
            })
            .unwrap(),
        )
    }

    /// Every name parses, round-trips, and builds a sampler that calls
    /// itself by that name (the plain name of a family with simplifiers by
    /// its default one).
    #[test]
    fn every_name_builds_the_sampler_it_names() {
        let m = map();
        let o = EnvSamplerOptions::default();
        for name in env_sampler_names() {
            let spec: EnvSamplerSpec = name.parse().unwrap();
            let s = make_env_sampler_spec(spec, &m, &o).unwrap();
            assert_eq!(s.name(), spec.to_string());
            if name.contains(':') {
                assert_eq!(spec.to_string(), name);
            }
            let n = Some(Vec3::new(0.2, 0.3, 0.9).normalize());
            let d = s.sample(n, Vec2::new(0.3, 0.6)).unwrap();
            assert_eq!(s.pdf(n, d.dir), d.pdf, "{name}");
        }
        let unknown = make_env_sampler("nope", &m, &o).unwrap_err();
        for name in env_sampler_names() {
            assert!(unknown.to_string().contains(&name), "{unknown}");
        }
        for bad in ["uniform:chi2", "adaptive:xx", "", "oriented:"] {
            assert!(matches!(
                bad.parse::<EnvSamplerSpec>(),
                Err(Error::UnknownSampler { .. })
            ));
        }
    }

    #[test]
    fn sphere_directions_parse() {
        let d = parse_sphere_direction_degrees("180,0").unwrap();
        assert!((d + Vec3::Z).length() < 1e-6);
        let d = parse_sphere_direction_degrees("90,90").unwrap();
        assert!((d - Vec3::Y).length() < 1e-6);
        for bad in ["181,0", "nan,0", "30", "a,b"] {
            assert!(parse_sphere_direction_degrees(bad).is_err(), "{bad}");
        }
    }
}
