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

use acdf_adaptive::simplify::{simplifier_entry, SimplifierEntry, SIMPLIFIERS, SIMPLIFIER_NAMES};

use crate::error::Error;
use crate::registry::{family, sampler_names, SamplerFamily, ADAPTIVE};

/// The names of the analytic built-in materials.
pub const BUILTIN_MATERIALS: [&str; 5] = [
    "nickel",
    "blue-metallic-paint",
    "gray-plastic",
    "lambert",
    "near-mirror",
];

/// The built-in stand-ins `acdf report` uses when no material is given.
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
/// ([`acdf_adaptive::simplify::SIMPLIFIERS`]), the one list of
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
/// ([`SAMPLERS`](crate::registry::SAMPLERS)) and, for the adaptive family,
/// its simplifier. Parsing and display derive from the two tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SamplerSpec {
    family: &'static str,
    simplifier: Option<SimplifierName>,
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
        }
    }

    /// The adaptive sampler with `simplifier`.
    pub fn adaptive(simplifier: SimplifierName) -> Self {
        SamplerSpec {
            family: ADAPTIVE,
            simplifier: Some(simplifier),
        }
    }

    /// The spec of a family of the table: with the family's first simplifier
    /// when it takes one.
    pub fn of_family(family: &'static SamplerFamily) -> Self {
        SamplerSpec {
            family: family.name,
            simplifier: family.simplifiers.then(SimplifierName::default_simplifier),
        }
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
    fn from_str(s: &str) -> Result<Self, Error> {
        let (family, simplifier) = parse_family_name(
            s,
            |head| family(head).map(|f| (f.name, f.simplifiers)),
            sampler_names,
        )?;
        Ok(SamplerSpec { family, simplifier })
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
        match self.simplifier {
            Some(s) => write!(f, "{}:{s}", self.family),
            None => f.write_str(self.family),
        }
    }
}

/// Parse `THETA_DEG,PHI_DEG` into a unit direction of the local frame.
pub fn parse_direction_degrees(s: &str) -> Result<acdf_core::Vec3, Error> {
    let (theta, phi) = parse_angles_degrees(s, 0.0..90.0, "[0, 90) degrees (above the horizon)")?;
    Ok(acdf_core::geometry::spherical_direction(
        (theta as f32).to_radians(),
        (phi as f32).to_radians(),
    ))
}

/// The finite angles (θ, φ) of `THETA_DEG,PHI_DEG`, θ in `range` (which
/// `range_text` describes); anything else is [`Error::InvalidArgument`].
pub(crate) fn parse_angles_degrees(
    s: &str,
    range: impl std::ops::RangeBounds<f64>,
    range_text: &str,
) -> Result<(f64, f64), Error> {
    let bad = |reason: &str| Error::InvalidArgument {
        what: "direction",
        value: s.to_string(),
        reason: reason.to_string(),
    };
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 2 {
        return Err(bad("expected THETA_DEG,PHI_DEG"));
    }
    let theta: f64 = parts[0].parse().map_err(|_| bad("theta is not a number"))?;
    let phi: f64 = parts[1].parse().map_err(|_| bad("phi is not a number"))?;
    if !theta.is_finite() || !phi.is_finite() {
        return Err(bad("angles must be finite"));
    }
    if !range.contains(&theta) {
        return Err(bad(&format!("theta must be in {range_text}")));
    }
    Ok((theta, phi))
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
            // `adaptive` alone prints as the simplifier it stands for.
            if spec.family().simplifiers && !name.contains(':') {
                continue;
            }
            assert_eq!(spec.to_string(), name);
        }
        assert_eq!(
            "adaptive".parse::<SamplerSpec>().unwrap(),
            SamplerSpec::adaptive(SimplifierName::find("dp").unwrap())
        );
        for bad in ["adaptive:xx", "uniform:dp", "", "adaptive:"] {
            assert!(matches!(
                bad.parse::<SamplerSpec>(),
                Err(Error::UnknownSampler { .. })
            ));
        }
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
