//! The names of materials and samplers on the command line. This is a
//! contract other tools rely on: `builtin:NAME`, `nbrdf:NAME`, a path ending
//! in `.binary` (MERL) or `.bsdf` (RGL) for materials; for samplers, the
//! families of the registry's table ([`SAMPLERS`](crate::registry::SAMPLERS):
//! `cosine`, `uniform`, `adaptive`, `rgl`), the adaptive one as `adaptive`
//! or `adaptive:SIMPLIFIER` with a simplifier of the adaptive plug-in's table
//! ([`SIMPLIFIERS`]). [`sampler_names`] lists them all.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use acdf_adaptive_cdf::simplify::{
    simplifier_entry, SimplifierEntry, SIMPLIFIERS, SIMPLIFIER_NAMES,
};
use acdf_tabulated::Resolution;

use crate::error::Error;
use crate::registry::{family, sampler_names, SamplerFamily, ADAPTIVE, OUTGOING};

/// The names of the analytic built-in materials.
pub const BUILTIN_MATERIALS: [&str; 5] = [
    "nickel",
    "blue-metallic-paint",
    "gray-plastic",
    "lambert",
    "near-mirror",
];

/// The materials `acdf report` uses when none is given: these MERL
/// materials as `nbrdf:NAME` when the Neural-BRDF weights are found, else
/// the built-in stand-ins of the same names (`builtin:NAME`).
pub const DEFAULT_REPORT_MATERIALS: [&str; 3] = ["nickel", "blue-metallic-paint", "gray-plastic"];

/// Where a BRDF comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MaterialSpec {
    /// `builtin:NAME`: an analytic stand-in.
    Builtin(String),
    /// A MERL `.binary` file.
    Merl(PathBuf),
    /// An RGL `.bsdf` file.
    Rgl(PathBuf),
    /// `nbrdf:NAME`: a MERL material as a Neural-BRDF network.
    Nbrdf(String),
}

impl FromStr for MaterialSpec {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self, Error> {
        let unknown = |reason: &str| Error::UnknownMaterial {
            spec: s.to_string(),
            reason: reason.to_string(),
        };
        if let Some(name) = s.strip_prefix("builtin:") {
            if BUILTIN_MATERIALS.contains(&name) {
                return Ok(MaterialSpec::Builtin(name.to_string()));
            }
            return Err(unknown(&format!(
                "the built-in materials are {}",
                BUILTIN_MATERIALS.join(", ")
            )));
        }
        if let Some(name) = s.strip_prefix("nbrdf:") {
            if name.is_empty() {
                return Err(unknown(
                    "nbrdf: needs a MERL material name, e.g. nbrdf:nickel",
                ));
            }
            return Ok(MaterialSpec::Nbrdf(name.to_string()));
        }
        let lower = s.to_ascii_lowercase();
        if lower.ends_with(".binary") {
            return Ok(MaterialSpec::Merl(PathBuf::from(s)));
        }
        if lower.ends_with(".bsdf") {
            return Ok(MaterialSpec::Rgl(PathBuf::from(s)));
        }
        Err(unknown(
            "expected builtin:NAME, nbrdf:NAME, or a path ending in .binary (MERL) or .bsdf (RGL)",
        ))
    }
}

impl fmt::Display for MaterialSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MaterialSpec::Builtin(n) => write!(f, "builtin:{n}"),
            MaterialSpec::Nbrdf(n) => write!(f, "nbrdf:{n}"),
            MaterialSpec::Merl(p) | MaterialSpec::Rgl(p) => write!(f, "{}", p.display()),
        }
    }
}

impl MaterialSpec {
    /// A short label for tables: the built-in or network name, or the file
    /// stem.
    pub fn label(&self) -> String {
        match self {
            MaterialSpec::Builtin(n) | MaterialSpec::Nbrdf(n) => n.clone(),
            MaterialSpec::Merl(p) | MaterialSpec::Rgl(p) => p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| p.display().to_string()),
        }
    }
}

/// A simplifier of the adaptive sampler, by its command-line name: a checked
/// handle to an entry of the adaptive plug-in's table
/// ([`acdf_adaptive_cdf::simplify::SIMPLIFIERS`]), the one list of
/// simplifier names from which parsing, help texts and error messages
/// derive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SimplifierName(&'static str);

impl SimplifierName {
    /// Every simplifier, in the table's order.
    pub fn all() -> impl Iterator<Item = SimplifierName> {
        SIMPLIFIERS.iter().map(|e| SimplifierName(e.name))
    }

    /// The simplifiers `acdf report` compares by default (marked `in_report`
    /// in the table).
    pub fn in_report() -> impl Iterator<Item = SimplifierName> {
        SIMPLIFIERS
            .iter()
            .filter(|e| e.in_report)
            .map(|e| SimplifierName(e.name))
    }

    /// The simplifier of the plain name `adaptive`: the table's first.
    pub fn default_simplifier() -> SimplifierName {
        SimplifierName(SIMPLIFIERS[0].name)
    }

    /// The command-line name: `dp`, `vw`, `chi2`, ...
    pub fn short(self) -> &'static str {
        self.0
    }

    /// The table entry: description, default set, constructor.
    pub fn entry(self) -> &'static SimplifierEntry {
        simplifier_entry(self.0).expect("a SimplifierName names a table entry")
    }

    /// The simplifier called `name`, if the table has one.
    pub fn find(name: &str) -> Option<SimplifierName> {
        simplifier_entry(name).map(|e| SimplifierName(e.name))
    }

    /// The names of every simplifier, comma-separated, for help and error
    /// texts.
    pub fn list() -> String {
        SIMPLIFIER_NAMES.join(", ")
    }
}

impl fmt::Display for SimplifierName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.0)
    }
}

/// A sampler as named on the command line: a family of the registry's table
/// ([`SAMPLERS`](crate::registry::SAMPLERS)) and, for a family with
/// simplifiers, its simplifier; for a family that samples BRDF ×
/// environment (`environment` in the table), the BRDF sampler it wraps,
/// `FAMILY:BRDF_SAMPLER`. Parsing and display derive from the two tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SamplerSpec {
    family: &'static str,
    simplifier: Option<SimplifierName>,
    /// The wrapped BRDF sampler's family and simplifier (environment
    /// families only).
    base: Option<(&'static str, Option<SimplifierName>)>,
}

impl SamplerSpec {
    /// `uniform`: the reference of the relative columns of reports.
    pub const UNIFORM: SamplerSpec = SamplerSpec::plain("uniform");
    /// `cosine`: the table-free reference.
    pub const COSINE: SamplerSpec = SamplerSpec::plain("cosine");

    const fn plain(family: &'static str) -> Self {
        SamplerSpec {
            family,
            simplifier: None,
            base: None,
        }
    }

    /// The adaptive sampler with `simplifier`.
    pub fn adaptive(simplifier: SimplifierName) -> Self {
        SamplerSpec {
            family: ADAPTIVE,
            simplifier: Some(simplifier),
            base: None,
        }
    }

    /// The spec of a family of the table: with the family's first simplifier
    /// when it takes one.
    pub fn of_family(family: &'static SamplerFamily) -> Self {
        SamplerSpec {
            family: family.name,
            simplifier: family.simplifiers.then(SimplifierName::default_simplifier),
            base: family.environment.then(|| {
                let base = SamplerSpec::default_product_base();
                (base.family, base.simplifier)
            }),
        }
    }

    /// The BRDF sampler a product sampler wraps when none is named:
    /// `outgoing:chi2` (its tables build in a fraction of a second for an
    /// analytic material and its batch densities are the fastest).
    pub fn default_product_base() -> SamplerSpec {
        SamplerSpec {
            family: OUTGOING,
            simplifier: SimplifierName::find("chi2"),
            base: None,
        }
    }

    /// The BRDF sampler wrapped by a family that samples BRDF ×
    /// environment; `None` for the other families.
    pub fn base(&self) -> Option<SamplerSpec> {
        self.base.map(|(family, simplifier)| SamplerSpec {
            family,
            simplifier,
            base: None,
        })
    }

    /// The sampler family's entry in the registry table.
    pub fn family(&self) -> &'static SamplerFamily {
        family(self.family).expect("a SamplerSpec names a registry family")
    }

    /// The simplifier of an adaptive sampler.
    pub fn simplifier(&self) -> Option<SimplifierName> {
        self.simplifier
    }
}

impl FromStr for SamplerSpec {
    type Err = Error;

    /// A family's name, or for a family with simplifiers `FAMILY` (its first
    /// simplifier) or `FAMILY:SIMPLIFIER`.
    ///
    /// A family that samples BRDF × environment takes `FAMILY` (with
    /// [`default_product_base`](Self::default_product_base)) or
    /// `FAMILY:BRDF_SAMPLER`, any other family's name.
    fn from_str(s: &str) -> Result<Self, Error> {
        let (head, tail) = s.split_once(':').unwrap_or((s, ""));
        if let Some(f) = family(head).filter(|f| f.environment) {
            let base = if s.contains(':') {
                tail.parse::<SamplerSpec>()
                    .ok()
                    .filter(|b| !b.family().environment)
                    .ok_or_else(|| Error::UnknownSampler {
                        name: s.to_string(),
                        known: sampler_names().join(", "),
                    })?
            } else {
                SamplerSpec::default_product_base()
            };
            return Ok(SamplerSpec {
                family: f.name,
                simplifier: None,
                base: Some((base.family, base.simplifier)),
            });
        }
        let (family, simplifier) = parse_family_name(
            s,
            |head| family(head).map(|f| (f.name, f.simplifiers)),
            sampler_names,
        )?;
        Ok(SamplerSpec {
            family,
            simplifier,
            base: None,
        })
    }
}

/// Parse `FAMILY` or `FAMILY:SIMPLIFIER`: `family` gives a family's name
/// and whether it takes a simplifier (the plain name then stands for the
/// table's first); anything else is [`Error::UnknownSampler`] listing
/// `names()`. Shared by the BRDF and the environment registries.
pub(crate) fn parse_family_name(
    s: &str,
    family: impl Fn(&str) -> Option<(&'static str, bool)>,
    names: impl Fn() -> Vec<String>,
) -> Result<(&'static str, Option<SimplifierName>), Error> {
    let (head, tail) = match s.split_once(':') {
        Some((h, t)) => (h, Some(t)),
        None => (s, None),
    };
    let unknown = || Error::UnknownSampler {
        name: s.to_string(),
        known: names().join(", "),
    };
    let (name, simplifiers) = family(head).ok_or_else(unknown)?;
    let simplifier = match (simplifiers, tail) {
        (false, None) => None,
        (false, Some(_)) => return Err(unknown()),
        (true, None) => Some(SimplifierName::default_simplifier()),
        (true, Some(t)) => Some(SimplifierName::find(t).ok_or_else(unknown)?),
    };
    Ok((name, simplifier))
}

impl fmt::Display for SamplerSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(base) = self.base() {
            return write!(f, "{}:{base}", self.family);
        }
        match self.simplifier {
            Some(s) => write!(f, "{}:{s}", self.family),
            None => f.write_str(self.family),
        }
    }
}

/// A sampler at a tabulation resolution, `NAME` or `NAME@RES` (e.g.
/// `uniform@32x16x256x32`): the reference of relative columns
/// (`--reference`). Without `@RES` the sampler takes the command's
/// resolution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SamplerAt {
    pub sampler: SamplerSpec,
    pub resolution: Option<Resolution>,
}

impl SamplerAt {
    /// `uniform@32x16x256x32`: the uniform table at the resolution of
    /// Lawrence et al., the reference of `--target-efficiency` and of
    /// `acdf survey`.
    pub const PAPER_UNIFORM: SamplerAt = SamplerAt {
        sampler: SamplerSpec::UNIFORM,
        resolution: Some(Resolution::PAPER),
    };

    /// `sampler` at the command's resolution.
    pub fn plain(sampler: SamplerSpec) -> SamplerAt {
        SamplerAt {
            sampler,
            resolution: None,
        }
    }
}

impl FromStr for SamplerAt {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self, Error> {
        let (name, resolution) = match s.split_once('@') {
            Some((name, res)) => {
                let res: Resolution =
                    res.parse()
                        .map_err(|e: acdf_core::Error| Error::InvalidArgument {
                            what: "resolution",
                            value: res.to_string(),
                            reason: e.to_string(),
                        })?;
                (name, Some(res))
            }
            None => (s, None),
        };
        Ok(SamplerAt {
            sampler: name.parse()?,
            resolution,
        })
    }
}

impl fmt::Display for SamplerAt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.resolution {
            Some(r) => write!(f, "{}@{r}", self.sampler),
            None => write!(f, "{}", self.sampler),
        }
    }
}

/// Parse `THETA_DEG,PHI_DEG` into a unit direction of the local frame.
/// The angles are read and turned into a direction in `f64`, then narrowed,
/// so that any θ below 90° (89.99999999 included) gives a direction above
/// the horizon.
pub fn parse_direction_degrees(s: &str) -> Result<acdf_core::Vec3, Error> {
    let (theta, phi) = parse_angles_degrees(s, 0.0..90.0, "[0, 90) degrees (above the horizon)")?;
    let (sin_t, cos_t) = theta.to_radians().sin_cos();
    let (sin_p, cos_p) = phi.to_radians().sin_cos();
    Ok(normalized_direction(sin_t * cos_p, sin_t * sin_p, cos_t))
}

/// The finite angles (θ, φ) of `THETA_DEG,PHI_DEG`, θ in `range` (which
/// `range_text` describes); anything else is [`Error::InvalidArgument`].
pub(crate) fn parse_angles_degrees(
    s: &str,
    range: impl std::ops::RangeBounds<f64>,
    range_text: &str,
) -> Result<(f64, f64), Error> {
    let bad = |reason: String| Error::InvalidArgument {
        what: "direction",
        value: shorten(s),
        reason,
    };
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 2 {
        return Err(bad(format!(
            "expected THETA_DEG,PHI_DEG (two numbers), got {} fields",
            parts.len()
        )));
    }
    let number = |name: &str, t: &str| -> Result<f64, Error> {
        let v: f64 = t
            .parse()
            .map_err(|_| bad(format!("{name} `{}` is not a number", shorten(t))))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(bad(format!(
                "{name} `{}` is not a finite number",
                shorten(t)
            )))
        }
    };
    let theta = number("theta", parts[0])?;
    let phi = number("phi", parts[1])?;
    if !range.contains(&theta) {
        return Err(bad(format!("theta {theta} is not in {range_text}")));
    }
    Ok((theta, phi))
}

/// The unit direction along (x, y, z), computed in `f64` before it is
/// narrowed to `f32`: any finite input works, 1e-30 and 1e300 alike (the
/// components are scaled by the largest before normalising). The zero
/// vector gives zero.
///
/// A direction that is already of unit length to `f32` precision (within
/// [`UNIT_LENGTH_TOLERANCE`] of 1 in squared length, as every direction
/// `acdf sample` prints is) is kept as given, narrowed to `f32` and not
/// normalised again: normalising moves its components by an ulp, and at
/// grazing angles, where the half vector of wo and wi is the small
/// difference of nearly opposite vectors, an ulp of wi is a different
/// direction. So `acdf sample | acdf pdf` looks up exactly the direction
/// that was drawn.
pub fn direction_from_xyz(x: f64, y: f64, z: f64) -> acdf_core::Vec3 {
    let narrowed = acdf_core::Vec3::new(x as f32, y as f32, z as f32);
    let squared = narrowed.as_dvec3().length_squared();
    if (squared - 1.0).abs() <= UNIT_LENGTH_TOLERANCE {
        return narrowed;
    }
    normalized_direction(x, y, z)
}

/// (x, y, z) normalised in `f64`, then narrowed to `f32`; zero for the
/// zero vector or a non-finite one.
fn normalized_direction(x: f64, y: f64, z: f64) -> acdf_core::Vec3 {
    let largest = x.abs().max(y.abs()).max(z.abs());
    if !(largest > 0.0 && largest.is_finite()) {
        return acdf_core::Vec3::ZERO;
    }
    let v = glam::DVec3::new(x / largest, y / largest, z / largest);
    (v / v.length()).as_vec3()
}

/// How far from 1 the squared length of an input direction may be for
/// [`direction_from_xyz`] to keep it as given: 4e-6, a few times what a
/// unit vector rounded to `f32` and printed can be off by.
pub const UNIT_LENGTH_TOLERANCE: f64 = 4e-6;

/// `s` for an error message: whole when short, otherwise its first 32
/// characters and its length, so that a huge argument or line is not echoed.
pub fn shorten(s: &str) -> String {
    const SHOWN: usize = 32;
    if s.chars().count() <= SHOWN {
        return s.to_string();
    }
    let head: String = s.chars().take(SHOWN).collect();
    format!("{head}... ({} bytes)", s.len())
}

/// The field count of a line of directions when no header names columns:
/// `x,y,z`.
pub const DIRECTION_FIELDS: usize = 3;

/// One line of directions as `acdf pdf` and `acdf eval` read them: `None`
/// for a blank line or a `#` comment; otherwise exactly `columns` comma-
/// separated fields (3 unless a header line such as `acdf sample`'s
/// `wi_x,wi_y,wi_z,pdf,valid` named more) whose first three are the finite
/// numbers x, y, z, read as `f64`, giving the unit direction
/// ([`direction_from_xyz`]). An error is the reason, for the caller to put
/// beside the line number.
pub fn parse_direction_line(line: &str, columns: usize) -> Result<Option<acdf_core::Vec3>, String> {
    let t = line.trim();
    if t.is_empty() || t.starts_with('#') {
        return Ok(None);
    }
    let fields: Vec<&str> = t.split(',').map(str::trim).collect();
    if fields.len() != columns {
        return Err(format!(
            "expected {columns} comma-separated fields ({}), got {}: `{}`",
            if columns == DIRECTION_FIELDS {
                "x,y,z".to_string()
            } else {
                format!("x,y,z and {} more, as the header names", columns - 3)
            },
            fields.len(),
            shorten(t)
        ));
    }
    let mut v = [0.0f64; 3];
    for (slot, f) in v.iter_mut().zip(&fields) {
        *slot = f
            .parse()
            .map_err(|_| format!("`{}` is not a number", shorten(f)))?;
        if !slot.is_finite() {
            return Err(format!("`{}` is not a finite number", shorten(f)));
        }
    }
    Ok(Some(direction_from_xyz(v[0], v[1], v[2])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn material_names_parse() {
        assert_eq!(
            "builtin:nickel".parse::<MaterialSpec>().unwrap(),
            MaterialSpec::Builtin("nickel".into())
        );
        assert_eq!(
            "a/b/x.binary".parse::<MaterialSpec>().unwrap(),
            MaterialSpec::Merl("a/b/x.binary".into())
        );
        assert_eq!(
            "x.bsdf".parse::<MaterialSpec>().unwrap().label(),
            "x".to_string()
        );
        assert!("builtin:unobtainium".parse::<MaterialSpec>().is_err());
        assert!("nickel".parse::<MaterialSpec>().is_err());
        assert!("nbrdf:".parse::<MaterialSpec>().is_err());
    }

    #[test]
    fn sampler_names_round_trip() {
        for name in sampler_names() {
            let spec: SamplerSpec = name.parse().unwrap();
            // `adaptive` alone prints as the simplifier it stands for,
            // `product` alone as the BRDF sampler it wraps.
            if (spec.family().simplifiers || spec.family().environment) && !name.contains(':') {
                continue;
            }
            assert_eq!(spec.to_string(), name);
        }
        assert_eq!(
            "adaptive".parse::<SamplerSpec>().unwrap(),
            SamplerSpec::adaptive(SimplifierName::find("dp").unwrap())
        );
        let product: SamplerSpec = "product:adaptive:vw".parse().unwrap();
        assert_eq!(product.to_string(), "product:adaptive:vw");
        assert_eq!(product.base().unwrap().to_string(), "adaptive:vw");
        assert_eq!(
            "product".parse::<SamplerSpec>().unwrap().to_string(),
            "product:outgoing:chi2"
        );
        assert_eq!(
            "product:cosine".parse::<SamplerSpec>().unwrap().base(),
            Some(SamplerSpec::COSINE)
        );
        for bad in [
            "adaptive:xx",
            "uniform:dp",
            "",
            "adaptive:",
            "product:",
            "product:product",
            "product:bogus",
        ] {
            assert!(matches!(
                bad.parse::<SamplerSpec>(),
                Err(Error::UnknownSampler { .. })
            ));
        }
    }

    /// Finding 9 of issue 29: directions are read in f64 (1e-30 and 1e150
    /// are valid components, 89.99999999° a valid angle) and a line must
    /// have exactly its fields.
    #[test]
    fn directions_are_read_in_f64_and_lines_need_their_fields() {
        let diagonal = acdf_core::Vec3::new(1.0, 0.0, 1.0).normalize();
        for line in [
            "1e-30,0,1e-30",
            "1e150,0,1e150",
            "1e-320,0,1e-320",
            " 3 , 0 , 3 ",
        ] {
            let v = parse_direction_line(line, 3).unwrap().unwrap();
            assert!((v - diagonal).length() < 1e-6, "{line}: {v}");
        }
        assert_eq!(
            parse_direction_line("0,0,0", 3).unwrap(),
            Some(acdf_core::Vec3::ZERO)
        );
        assert_eq!(parse_direction_line("  # note", 3).unwrap(), None);
        for bad in [
            "0,0,1,5",
            "0,0,1,abc",
            "0,0",
            "0,0,inf",
            "0,nan,1",
            "1e999,0,1",
        ] {
            assert!(parse_direction_line(bad, 3).is_err(), "{bad}");
        }
        assert!(parse_direction_line("0,0,1,0.3,1", 5).is_ok());
        let long = "9".repeat(10_000_000);
        let e = parse_direction_line(&format!("{long},0"), 3).unwrap_err();
        assert!(e.len() < 200, "the error echoes the whole token");
        let wo = parse_direction_degrees("89.99999999,0").unwrap();
        assert!(wo.z > 0.0 && acdf_core::is_valid_outgoing(wo), "{wo}");
    }

    #[test]
    fn samplers_at_a_resolution_parse() {
        let paper: SamplerAt = "uniform@32x16x256x32".parse().unwrap();
        assert_eq!(paper, SamplerAt::PAPER_UNIFORM);
        assert_eq!(paper.to_string(), "uniform@32x16x256x32");
        let plain: SamplerAt = "adaptive:chi2".parse().unwrap();
        assert_eq!(plain.resolution, None);
        assert!(matches!(
            "uniform@32x0x256x32".parse::<SamplerAt>(),
            Err(Error::InvalidArgument { .. })
        ));
        assert!(matches!(
            "nope@32x1x256x32".parse::<SamplerAt>(),
            Err(Error::UnknownSampler { .. })
        ));
    }

    #[test]
    fn directions_parse_and_reject_the_lower_hemisphere() {
        let w = parse_direction_degrees("0,0").unwrap();
        assert!((w - acdf_core::Vec3::Z).length() < 1e-6);
        assert!(parse_direction_degrees("90,0").is_err());
        assert!(parse_direction_degrees("nan,0").is_err());
        assert!(parse_direction_degrees("30").is_err());
    }
}
