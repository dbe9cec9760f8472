//! The names of materials and samplers on the command line. This is a
//! contract other tools rely on: `builtin:NAME`, `nbrdf:NAME`, a path ending
//! in `.binary` (MERL) or `.bsdf` (RGL) for materials; `cosine`, `uniform`,
//! `adaptive[:dp|vw|rw|optimal]` and `rgl` for samplers.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use crate::error::Error;

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

/// The curve simplifiers of the adaptive sampler, by their command-line
/// names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SimplifierName {
    /// `dp`: Douglas-Peucker, the default.
    DouglasPeucker,
    /// `vw`: Visvalingam-Whyatt.
    VisvalingamWhyatt,
    /// `rw`: Reumann-Witkam.
    ReumannWitkam,
    /// `optimal`: the fewest vertices within the tolerance.
    Optimal,
    /// `chi2`: the fewest vertices within a chi-square divergence budget,
    /// the variance the simplification adds.
    ChiSquare,
}

impl SimplifierName {
    /// All simplifiers, in the order of reports.
    pub const ALL: [SimplifierName; 5] = [
        SimplifierName::DouglasPeucker,
        SimplifierName::VisvalingamWhyatt,
        SimplifierName::ReumannWitkam,
        SimplifierName::Optimal,
        SimplifierName::ChiSquare,
    ];

    /// `dp`, `vw`, `rw`, `optimal` or `chi2`.
    pub fn short(self) -> &'static str {
        match self {
            SimplifierName::DouglasPeucker => "dp",
            SimplifierName::VisvalingamWhyatt => "vw",
            SimplifierName::ReumannWitkam => "rw",
            SimplifierName::Optimal => "optimal",
            SimplifierName::ChiSquare => "chi2",
        }
    }
}

/// A sampler as named on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SamplerSpec {
    /// `cosine`.
    Cosine,
    /// `uniform`: the uniformly tabulated CDFs.
    Uniform,
    /// `adaptive` (Douglas-Peucker) or `adaptive:SIMPLIFIER`.
    Adaptive(SimplifierName),
    /// `rgl`: the `.bsdf` file's own sampler.
    Rgl,
}

impl FromStr for SamplerSpec {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self, Error> {
        Ok(match s {
            "cosine" => SamplerSpec::Cosine,
            "uniform" => SamplerSpec::Uniform,
            "adaptive" | "adaptive:dp" => SamplerSpec::Adaptive(SimplifierName::DouglasPeucker),
            "adaptive:vw" => SamplerSpec::Adaptive(SimplifierName::VisvalingamWhyatt),
            "adaptive:rw" => SamplerSpec::Adaptive(SimplifierName::ReumannWitkam),
            "adaptive:optimal" => SamplerSpec::Adaptive(SimplifierName::Optimal),
            "adaptive:chi2" => SamplerSpec::Adaptive(SimplifierName::ChiSquare),
            "rgl" => SamplerSpec::Rgl,
            _ => return Err(Error::UnknownSampler(s.to_string())),
        })
    }
}

impl fmt::Display for SamplerSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SamplerSpec::Cosine => f.write_str("cosine"),
            SamplerSpec::Uniform => f.write_str("uniform"),
            SamplerSpec::Adaptive(s) => write!(f, "adaptive:{}", s.short()),
            SamplerSpec::Rgl => f.write_str("rgl"),
        }
    }
}

/// Parse `THETA_DEG,PHI_DEG` into a unit direction of the local frame.
pub fn parse_direction_degrees(s: &str) -> Result<acdf_core::Vec3, Error> {
    let bad = |reason: &str| Error::InvalidArgument {
        what: "direction",
        value: s.to_string(),
        reason: reason.to_string(),
    };
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 2 {
        return Err(bad("expected THETA_DEG,PHI_DEG"));
    }
    let theta: f32 = parts[0].parse().map_err(|_| bad("theta is not a number"))?;
    let phi: f32 = parts[1].parse().map_err(|_| bad("phi is not a number"))?;
    if !theta.is_finite() || !phi.is_finite() {
        return Err(bad("angles must be finite"));
    }
    if !(0.0..90.0).contains(&theta) {
        return Err(bad("theta must be in [0, 90) degrees (above the horizon)"));
    }
    Ok(acdf_core::geometry::spherical_direction(
        theta.to_radians(),
        phi.to_radians(),
    ))
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
        for name in [
            "cosine",
            "uniform",
            "adaptive:dp",
            "adaptive:vw",
            "adaptive:rw",
            "adaptive:optimal",
            "rgl",
        ] {
            assert_eq!(name.parse::<SamplerSpec>().unwrap().to_string(), name);
        }
        assert_eq!(
            "adaptive".parse::<SamplerSpec>().unwrap(),
            SamplerSpec::Adaptive(SimplifierName::DouglasPeucker)
        );
        assert!("adaptive:xx".parse::<SamplerSpec>().is_err());
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
