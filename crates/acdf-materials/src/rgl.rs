//! RGL measured materials: the `tensor_file` `.bsdf` format of the RGL
//! Material Database (Dupuy and Jakob 2018) and its evaluation.
//!
//! A file stores, per incident direction slice (φ_i, θ_i), a visible-normal
//! density (`vndf`) over the unit square of microfacet normals, a luminance
//! density and RGB values over the *warped* square that the vndf's inverse
//! CDF produces, plus the isotropic NDF D and the projected area σ. The
//! cosine-weighted BRDF is
//!
//! f_r(ω_i, ω_o) cos θ_o = R(s) · D(u_m) / (4 σ(u_i)),
//!
//! with ω_m = normalize(ω_i + ω_o), u_m its (u_θ, u_φ) coordinates
//! (u_θ = sqrt(2θ/π), u_φ = (φ + π)/2π, φ relative to φ_i for isotropic
//! files), and s the image of u_m under the vndf's CDFs.
//!
//! # Direction convention
//!
//! The format is written from the point of view of Mitsuba, where the given
//! direction is `si.wi` (ω_i above) and the sampled one is ω_o. acdf calls
//! the given direction `wo` and the sampled one `wi`. So everywhere in this
//! module **ω_i (the file's parameter direction) is our `wo`** and **ω_o is
//! our `wi`**: the slices are chosen by `wo`, and the cosine in the formula
//! above is `wi.z`. [`RglBrdf::eval`] therefore returns
//! f_r = (R D / 4σ) / wi.z, without cosine, as the [`Brdf`] contract asks.
//!
//! # Negative RGB values
//!
//! The measured RGB can be negative (out-of-gamut spectra; `chm_mint` reaches
//! about −127 in f_r cos). [`RglBrdf::eval`] clamps each channel at 0, as the
//! authors' reference loader does and as the `Brdf` contract requires.
//! [`RglBrdf::fr_cos_unclipped`] and [`RglBrdf::eval_unclipped`] give the raw
//! values that Mitsuba 3 reports, for reference tests.
//!
//! # Densities
//!
//! `vndf` and `luminance` are normalised per slice so that their bilinear
//! interpolants integrate to 1, then blended linearly between the slices
//! around (φ_i, θ_i) ([`ParamBlend`], [`BilinearStack`]). The fitted tables
//! hold a few tiny negative entries (down to −7e-11 in `ilm_solo_m_68`'s
//! luminance); they are read as 0. NaN or infinity anywhere is an error.
//!
//! The sampler built into the format (luminance warp, then vndf warp) lives in
//! the `acdf-rgl` plug-in; everything it needs is public here: the
//! normalised [`BilinearStack`]s, the slice weights [`ParamBlend`], and
//! [`RglBrdf::lookup`] / [`RglBrdf::incident`] / [`RglBrdf::microfacet_normal`].

mod bilinear;
mod tensor;
#[cfg(test)]
mod tests;

pub use bilinear::{Bilinear2D, BilinearGrid, BilinearStack, BlendedBilinear, ParamBlend};
pub use tensor::{write_tensor_file, Dtype, TensorField, TensorFile, TENSOR_MAGIC};

use acdf_core::{Brdf, Rgb, Vec3};
use glam::{DVec2, DVec3};
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::path::{Path, PathBuf};

/// The folder of the RGL files inside the shared data directory.
pub const DATA_DIR: &str = "rgl-material-database";

/// The stems of the seven isotropic RGL files in the shared data (each is
/// `<stem>.bsdf` in [`DATA_DIR`]).
pub const SHARED_FILES: [&str; 7] = [
    "acrylic_felt_white_rgb",
    "cg_sunflower_rgb",
    "chm_mint_rgb",
    "ilm_l3_37_matte_rgb",
    "ilm_solo_m_68_rgb",
    "paper_white_rgb",
    "vch_golden_yellow_rgb",
];

/// The shared folder of RGL files, if the shared data is present (see
/// [`crate::shared_data_dir`]).
pub fn shared_dir() -> Option<PathBuf> {
    let dir = crate::shared_data_dir()?.join(DATA_DIR);
    dir.is_dir().then_some(dir)
}

/// Everything that can be wrong with an RGL tensor file.
#[derive(Debug, thiserror::Error)]
pub enum RglError {
    /// The file could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// An error in the file at `path`; [`RglError::kind`] gives the inner one.
    #[error("{}: {error}", path.display())]
    InFile { path: PathBuf, error: Box<RglError> },
    /// The first 12 bytes are not `tensor_file\0`.
    #[error("not a tensor file: the magic `tensor_file\\0` is missing")]
    BadMagic,
    /// A major version other than 1.
    #[error("unsupported tensor_file version {major}.{minor} (expected 1.x)")]
    Version { major: u8, minor: u8 },
    /// A malformed field descriptor (truncated, non-UTF-8 or duplicate name).
    #[error("field descriptor {index}: {reason}")]
    Field { index: usize, reason: String },
    /// An unknown dtype code, or a dtype the field cannot have.
    #[error("field `{field}`: {reason}")]
    Dtype { field: String, reason: String },
    /// A shape that overflows or does not fit the other fields.
    #[error("field `{field}`: bad shape: {reason}")]
    Shape { field: String, reason: String },
    /// A data block that does not lie inside the file.
    #[error(
        "field `{field}`: {len} bytes at offset {offset} lie outside the file ({file_len} bytes)"
    )]
    OutOfBounds {
        field: String,
        offset: u64,
        len: u64,
        file_len: u64,
    },
    /// A field's data overlaps the header or another field.
    #[error("field `{field}`: its data at offset {offset} overlaps {other}")]
    Overlap {
        field: String,
        offset: u64,
        other: String,
    },
    /// Reading the file hit a bound or failed ([`acdf_io::fsio`]).
    #[error("{0}")]
    File(#[from] acdf_io::fsio::FsError),
    /// A field the evaluation needs is absent.
    #[error("missing field `{0}`")]
    MissingField(String),
    /// NaN or infinity in a numeric field.
    #[error("field `{field}`: value {value} at index {index} is not finite")]
    NonFinite {
        field: String,
        index: usize,
        value: f64,
    },
    /// Values the evaluation cannot use (a negative density, parameter values
    /// that do not increase, ...).
    #[error("field `{field}`: {reason}")]
    Invalid { field: String, reason: String },
}

impl RglError {
    /// The error without the file name around it.
    pub fn kind(&self) -> &RglError {
        match self {
            RglError::InFile { error, .. } => error.kind(),
            e => e,
        }
    }

    /// Attach the file name (once).
    pub(crate) fn in_file(self, path: &Path) -> RglError {
        match self {
            e @ (RglError::InFile { .. } | RglError::Io { .. } | RglError::File(_)) => e,
            e => RglError::InFile {
                path: path.to_path_buf(),
                error: Box::new(e),
            },
        }
    }
}

/// u_θ(θ) = sqrt(2θ/π).
#[inline]
pub fn u_theta(theta: f64) -> f64 {
    (theta.max(0.0) / FRAC_PI_2).sqrt()
}

/// u_φ(φ) = (φ + π) / 2π.
#[inline]
pub fn u_phi(phi: f64) -> f64 {
    (phi + PI) / TAU
}

/// The Jacobian from the (u_θ, u_φ) square of half vectors to the solid
/// angle of ω_o: J = max(2π² u_θ sin θ_m, 1e-6) · 4 (ω_i · ω_m). A density q
/// over the square becomes q / J per steradian of ω_o.
#[inline]
pub fn rgl_jacobian(u_theta_m: f64, sin_theta_m: f64, cos_d: f64) -> f64 {
    (2.0 * PI * PI * u_theta_m * sin_theta_m).max(1e-6) * 4.0 * cos_d
}

/// The given direction in the file's terms: the unit ω_i (our `wo`), its
/// angles and square coordinates, and the slice weights at (φ_i, θ_i).
#[derive(Debug, Clone, Copy)]
pub struct RglIncident {
    pub w: DVec3,
    pub theta: f64,
    /// atan2(y, x) ∈ [−π, π].
    pub phi: f64,
    /// (u_θ(θ_i), u_φ(φ_i)).
    pub u: DVec2,
    pub blend: ParamBlend,
}

/// The quantities shared by evaluation and pdf for a pair (ω_i, ω_o).
#[derive(Debug, Clone, Copy)]
pub struct RglLookup {
    pub incident: RglIncident,
    /// ω_m = normalize(ω_i + ω_o).
    pub wm: DVec3,
    /// The half vector's square coordinates (u_θ, u_φ).
    pub u_m: DVec2,
    /// The warped sample point: u_m mapped through the vndf's CDFs.
    pub s: DVec2,
    /// The normalised vndf density at u_m.
    pub vndf_pdf: f64,
    /// [`rgl_jacobian`] at ω_m.
    pub jacobian: f64,
}

/// A measured RGL material read from a `tensor_file` `.bsdf`.
#[derive(Debug, Clone)]
pub struct RglBrdf {
    name: String,
    /// The hash of every field evaluation reads.
    fingerprint: u64,
    description: String,
    phi_i: Vec<f32>,
    theta_i: Vec<f32>,
    sigma: BilinearGrid,
    ndf: BilinearGrid,
    vndf: BilinearStack,
    luminance: BilinearStack,
    rgb: BilinearGrid,
    isotropic: bool,
}

/// A float field with `ndim` dimensions, every value finite.
fn float_field(
    file: &TensorFile,
    name: &str,
    ndim: usize,
) -> Result<(Vec<usize>, Vec<f32>), RglError> {
    let f = file.require(name)?;
    if !f.dtype.is_float() {
        return Err(RglError::Dtype {
            field: name.into(),
            reason: format!("expected a float dtype, found {:?}", f.dtype),
        });
    }
    if f.shape.len() != ndim {
        return Err(RglError::Shape {
            field: name.into(),
            reason: format!("expected {ndim} dimensions, found {:?}", f.shape),
        });
    }
    let values = f.to_f32();
    if let Some((index, &v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        // Report the value as stored, not its f32 rounding.
        let value = f.to_f64().get(index).copied().unwrap_or(v as f64);
        return Err(RglError::NonFinite {
            field: name.into(),
            index,
            value,
        });
    }
    Ok((f.shape.clone(), values))
}

fn shape_error(field: &str, reason: String) -> RglError {
    RglError::Shape {
        field: field.into(),
        reason,
    }
}

fn invalid(field: &str) -> impl Fn(acdf_core::Error) -> RglError + '_ {
    move |e| RglError::Invalid {
        field: field.into(),
        reason: e.to_string(),
    }
}

/// Every value of `field` in [lo, hi] (with a relative margin of 1e-6 for
/// the f32 rounding of the bounds), named in the error as `range`.
fn within(field: &str, values: &[f32], lo: f64, hi: f64, range: &str) -> Result<(), RglError> {
    let margin = 1e-6 * lo.abs().max(hi.abs());
    match values
        .iter()
        .enumerate()
        .find(|(_, &v)| !((v as f64) >= lo - margin && (v as f64) <= hi + margin))
    {
        Some((index, v)) => Err(RglError::Invalid {
            field: field.into(),
            reason: format!("value {v:?} at index {index} is outside {range}"),
        }),
        None => Ok(()),
    }
}

/// Some value of each slice of `per` values is positive: a table (or slice)
/// of zeros describes no material.
fn not_all_zero(field: &str, values: &[f32], per: usize) -> Result<(), RglError> {
    for (slice, chunk) in values.chunks(per.max(1)).enumerate() {
        if !chunk.iter().any(|&v| v > 0.0) {
            let what = if chunk.len() == values.len() {
                "every value".to_string()
            } else {
                format!("every value of slice {slice}")
            };
            return Err(RglError::Invalid {
                field: field.into(),
                reason: format!("{what} is zero or negative: the table describes no material"),
            });
        }
    }
    Ok(())
}

fn increasing_axis(field: &str, values: Vec<f32>) -> Result<Vec<f32>, RglError> {
    if values.is_empty() || values.windows(2).any(|w| w[1] <= w[0]) {
        return Err(RglError::Invalid {
            field: field.into(),
            reason: format!(
                "parameter values must be non-empty and strictly increasing: {values:?}"
            ),
        });
    }
    Ok(values)
}

impl RglBrdf {
    /// Read the file at `path`; the material's name is the file stem.
    pub fn open(path: impl AsRef<Path>) -> Result<RglBrdf, RglError> {
        let path = path.as_ref();
        let file = TensorFile::read(path)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "rgl".into());
        RglBrdf::from_tensor(&file, &name).map_err(|e| e.in_file(path))
    }

    /// Build from a parsed tensor file, checking every shape against the
    /// others: `phi_i: [n_phi]`, `theta_i: [n_theta]` (both strictly
    /// increasing), `sigma` and `ndf: [rows >= 2, cols >= 2]`,
    /// `vndf: [n_phi, n_theta, ny, nx]`, `luminance: [n_phi, n_theta, n, m]`
    /// and `rgb: [n_phi, n_theta, 3, n, m]`; all finite. Negative entries of
    /// the densities `vndf` and `luminance` are read as 0.
    pub fn from_tensor(file: &TensorFile, name: &str) -> Result<RglBrdf, RglError> {
        let (_, phi_i) = float_field(file, "phi_i", 1)?;
        let (_, theta_i) = float_field(file, "theta_i", 1)?;
        let phi_i = increasing_axis("phi_i", phi_i)?;
        let theta_i = increasing_axis("theta_i", theta_i)?;
        within("theta_i", &theta_i, 0.0, FRAC_PI_2, "[0, π/2] rad")?;
        within("phi_i", &phi_i, -TAU, TAU, "[-2π, 2π] rad")?;
        let (np, nt) = (phi_i.len(), theta_i.len());
        let slices = np * nt;

        let grid = |field: &str| -> Result<BilinearGrid, RglError> {
            let (shape, values) = float_field(file, field, 2)?;
            // The projected area and the NDF are non-negative and not zero
            // everywhere; sigma divides f_r.
            if let Some((index, v)) = values.iter().enumerate().find(|(_, &v)| v < 0.0) {
                return Err(RglError::Invalid {
                    field: field.into(),
                    reason: format!("value {v:?} at index {index} is negative"),
                });
            }
            not_all_zero(field, &values, values.len())?;
            BilinearGrid::new(1, shape[1], shape[0], values).map_err(invalid(field))
        };
        let sigma = grid("sigma")?;
        let ndf = grid("ndf")?;

        let stack = |field: &str| -> Result<(BilinearStack, usize, usize), RglError> {
            let (shape, values) = float_field(file, field, 4)?;
            if shape[0] != np || shape[1] != nt {
                return Err(shape_error(
                    field,
                    format!("{shape:?} does not start with [n_phi_i, n_theta_i] = [{np}, {nt}]"),
                ));
            }
            let (ny, nx) = (shape[2], shape[3]);
            if nx < 2 || ny < 2 {
                return Err(shape_error(
                    field,
                    format!("grid {ny} × {nx} is below 2 × 2"),
                ));
            }
            // The fitted densities hold tiny negative values (down to about
            // -7e-11 in ilm_solo_m_68's luminance); a density cannot be
            // negative, so they count as zero, which moves the normalisation
            // by far less than f32 rounding.
            let values: Vec<f32> = values.into_iter().map(|v| v.max(0.0)).collect();
            // An all-zero slice would be replaced by the uniform density
            // without a word.
            not_all_zero(field, &values, nx * ny)?;
            let s = BilinearStack::new(slices, nx, ny, &values).map_err(invalid(field))?;
            Ok((s, nx, ny))
        };
        let (vndf, _, _) = stack("vndf")?;
        let (luminance, nx, ny) = stack("luminance")?;

        let (shape, values) = float_field(file, "rgb", 5)?;
        if shape != [np, nt, 3, ny, nx] {
            return Err(shape_error(
                "rgb",
                format!(
                    "{shape:?} is not [n_phi_i, n_theta_i, 3, n, m] = [{np}, {nt}, 3, {ny}, {nx}]"
                ),
            ));
        }
        not_all_zero("rgb", &values, values.len())?;
        let rgb = BilinearGrid::new(slices * 3, nx, ny, values).map_err(invalid("rgb"))?;

        // The material's content: every field evaluation reads.
        let mut h = acdf_core::Fingerprinter::new();
        h.bytes(b"rgl");
        for field in [
            "phi_i",
            "theta_i",
            "sigma",
            "ndf",
            "vndf",
            "luminance",
            "rgb",
        ] {
            let f = file.require(field)?;
            h.bytes(field.as_bytes());
            h.bytes(&[f.dtype.code()]);
            for &n in &f.shape {
                h.u64(n as u64);
            }
            h.bytes(f.bytes());
        }
        let fingerprint = h.finish();

        let description = file
            .field("description")
            .map(|f| String::from_utf8_lossy(f.bytes()).into_owned())
            .unwrap_or_default();
        Ok(RglBrdf {
            name: name.to_string(),
            fingerprint,
            description,
            isotropic: np <= 2,
            phi_i,
            theta_i,
            sigma,
            ndf,
            vndf,
            luminance,
            rgb,
        })
    }

    /// The description string stored in the file.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// The incident azimuths of the slices (rad).
    pub fn phi_i(&self) -> &[f32] {
        &self.phi_i
    }

    /// The incident elevations of the slices (rad).
    pub fn theta_i(&self) -> &[f32] {
        &self.theta_i
    }

    /// σ(u_θ, u_φ), the projected microfacet area (raw interpolant).
    pub fn sigma(&self) -> &BilinearGrid {
        &self.sigma
    }

    /// D(u_θ, u_φ), the microfacet distribution in 1/sr (raw interpolant).
    pub fn ndf(&self) -> &BilinearGrid {
        &self.ndf
    }

    /// The normalised visible-normal densities, one per (φ_i, θ_i) slice.
    pub fn vndf(&self) -> &BilinearStack {
        &self.vndf
    }

    /// The normalised luminance densities over the warped square.
    pub fn luminance_density(&self) -> &BilinearStack {
        &self.luminance
    }

    /// The raw RGB grids, slice index 3 · (slice of the blend) + channel.
    pub fn rgb(&self) -> &BilinearGrid {
        &self.rgb
    }

    /// The luminance / RGB grid size (nx, ny).
    pub fn grid_size(&self) -> (usize, usize) {
        (self.luminance.nx(), self.luminance.ny())
    }

    /// Heap bytes of all tables.
    pub fn storage_bytes(&self) -> usize {
        self.sigma.storage_bytes()
            + self.ndf.storage_bytes()
            + self.vndf.storage_bytes()
            + self.luminance.storage_bytes()
            + self.rgb.storage_bytes()
            + 4 * (self.phi_i.len() + self.theta_i.len())
    }

    /// The given direction `wo` (the file's ω_i) with its angles, square
    /// coordinates and slice weights; `None` unless `wo` is finite, non-zero
    /// and strictly above the horizon.
    pub fn incident(&self, wo: Vec3) -> Option<RglIncident> {
        let w = wo.as_dvec3().try_normalize()?;
        // try_normalize rejected non-finite input, so z is a number.
        if w.z <= 0.0 {
            return None;
        }
        let theta = (w.x * w.x + w.y * w.y).sqrt().atan2(w.z);
        let phi = w.y.atan2(w.x);
        let blend = ParamBlend::new(&self.phi_i, &self.theta_i, phi, theta);
        Some(RglIncident {
            w,
            theta,
            phi,
            u: DVec2::new(u_theta(theta), u_phi(phi)),
            blend,
        })
    }

    /// The half vector for square coordinates u_m: θ_m = u_m.x² π/2,
    /// φ_m = 2π u_m.y − π, plus φ_i for isotropic files.
    pub fn microfacet_normal(&self, incident: &RglIncident, u_m: DVec2) -> DVec3 {
        let theta = u_m.x * u_m.x * FRAC_PI_2;
        let mut phi = TAU * u_m.y - PI;
        if self.isotropic {
            phi += incident.phi;
        }
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        DVec3::new(st * cp, st * sp, ct)
    }

    /// Steps 1–3 of the evaluation for the pair (ω_i = `wo`, ω_o = `wi`):
    /// ω_m, u_m, the warped point s and the vndf density at u_m. `None` when
    /// either direction is not finite, zero, or at or below the horizon.
    pub fn lookup(&self, wo: Vec3, wi: Vec3) -> Option<RglLookup> {
        let incident = self.incident(wo)?;
        let out = wi.as_dvec3().try_normalize()?;
        if out.z <= 0.0 {
            return None;
        }
        // Both are above the horizon, so the sum has z > 0 and normalises.
        let wm = (incident.w + out).try_normalize()?;
        // Unit vectors: no overflow for hypot to guard against.
        let sin_m = (wm.x * wm.x + wm.y * wm.y).sqrt();
        let theta_m = sin_m.atan2(wm.z);
        let phi_m = wm.y.atan2(wm.x);
        let rel = if self.isotropic {
            phi_m - incident.phi
        } else {
            phi_m
        };
        let v = u_phi(rel);
        let u_m = DVec2::new(u_theta(theta_m), v - v.floor());
        let (s, vndf_pdf) = self.vndf.at(incident.blend).invert(u_m);
        let jacobian = rgl_jacobian(u_m.x, sin_m, incident.w.dot(wm));
        Some(RglLookup {
            incident,
            wm,
            u_m,
            s,
            vndf_pdf,
            jacobian,
        })
    }

    /// f_r cos θ of the sampled direction, R(s) D(u_m) / (4 σ(u_i)) per
    /// channel, unclipped (what Mitsuba 3 returns); 0 where [`lookup`]
    /// is `None` or σ is not positive.
    ///
    /// [`lookup`]: RglBrdf::lookup
    pub fn fr_cos_unclipped(&self, wo: Vec3, wi: Vec3) -> DVec3 {
        let Some(l) = self.lookup(wo, wi) else {
            return DVec3::ZERO;
        };
        let sigma = self.sigma.eval(0, l.incident.u);
        let d = self.ndf.eval(0, l.u_m);
        if sigma <= 0.0 || sigma.is_nan() {
            return DVec3::ZERO;
        }
        let mut r = DVec3::ZERO;
        for (slice, w) in l.incident.blend.terms() {
            for c in 0..3 {
                r[c] += w * self.rgb.eval(3 * slice + c, l.s);
            }
        }
        let v = r * (d / (4.0 * sigma));
        if v.is_finite() {
            v
        } else {
            DVec3::ZERO
        }
    }

    /// f_r = [`fr_cos_unclipped`](Self::fr_cos_unclipped) / cos θ of `wi`,
    /// unclipped; the division is guarded so the result stays finite in f32.
    pub fn eval_unclipped(&self, wo: Vec3, wi: Vec3) -> DVec3 {
        let fc = self.fr_cos_unclipped(wo, wi);
        if fc == DVec3::ZERO {
            return fc;
        }
        let cos = wi.as_dvec3().normalize_or_zero().z;
        if cos <= 0.0 {
            return DVec3::ZERO;
        }
        let limit = f32::MAX as f64;
        (fc / cos).clamp(DVec3::splat(-limit), DVec3::splat(limit))
    }
}

impl Brdf for RglBrdf {
    fn name(&self) -> &str {
        &self.name
    }

    /// f_r(wo, wi) = max(R_c, 0) D / (4 σ cos θ_i) per channel, with the
    /// file's ω_i = `wo` and ω_o = `wi` (see the module documentation).
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_unclipped(wo, wi).max(DVec3::ZERO).as_vec3()
    }

    fn is_isotropic(&self) -> bool {
        self.isotropic
    }

    /// The hash of the file's fields that evaluation reads (not its name or
    /// description).
    fn fingerprint(&self) -> u64 {
        self.fingerprint
    }
}
