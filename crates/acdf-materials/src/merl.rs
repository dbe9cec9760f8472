//! Tables in the MERL BRDF database layout: reading, writing, evaluating,
//! and tabulating any [`Brdf`] on the same grid.
//!
//! # The MERL `.binary` format
//!
//! A file is a 12-byte header of three little-endian `i32` dimensions, which
//! are always (90, 90, 180), followed by 3 · 90 · 90 · 180 little-endian
//! `f64` values: the whole red plane, then green, then blue. Within a plane
//! the value for the grid point (θ_h index i, θ_d index j, φ_d index k) is at
//! `k + 180 · (j + 90 · i)`. A file is therefore exactly
//! 12 + 3 · 1 458 000 · 8 = 34 992 012 bytes.
//!
//! The stored numbers are raw; the BRDF in 1/sr is raw × (1/1500, 1.15/1500,
//! 1.66/1500) for R, G, B ([`SCALE`]). A negative value marks an entry that
//! was not measured.
//!
//! The grid point with indices (i, j, k) stands for the angles
//!
//! - θ_h = (i / 90)² · π/2 (the index grows as the square root of θ_h, which
//!   puts many entries near the specular peak): [`theta_h_at`];
//! - θ_d = j · π/180, covering [0, π/2): [`theta_d_at`];
//! - φ_d = k · π/180, covering [0, π): [`phi_d_at`]. Reciprocity makes
//!   φ_d and φ_d + π the same entry, so φ_d is folded into [0, π) first.
//!
//! These are the positions that MERL's reference lookup maps back to index
//! (i, j, k) in exact arithmetic (it truncates the continuous index
//! u_h = 90 √(θ_h / (π/2)), u_d = 90 θ_d / (π/2), u_φ = 180 φ_d / π), and the
//! positions [`MerlTable::tabulate`] and the Neural-BRDF baking evaluate at.
//!
//! # In memory
//!
//! A [`MerlTable`] stores the calibrated values as `f32` (17.5 MB instead of
//! 35 MB). Unmeasured entries are remembered in a bit set, so that
//! [`MerlTable::write`] writes them back as raw −1, and are filled for
//! lookups by the rule of [`MerlTable::get`]: the value of the nearest
//! measured entry along θ_d (the lower one on a tie) in the same channel,
//! θ_h and φ_d; 0 when that whole θ_d column is unmeasured. Lookups never
//! return a negative value. Tables start with [`Interpolation::Trilinear`]
//! lookups; [`MerlTable::with_interpolation`] changes that.
//!
//! Tabulating a sampler from a table evaluates it millions of times over
//! rings of half vectors ([`Brdf::luminance_half_ring`]). For that a table
//! keeps, from the first such call on, a plane of the luminances of its
//! entries (5.8 MB), and computes the half/difference angles straight from
//! wo and each half vector; see the method for how closely that agrees
//! with [`MerlTable::eval`].

use std::io::Write;
use std::path::Path;
use std::sync::OnceLock;

use acdf_core::fast::fast_atan2;
use acdf_core::geometry::reflect;
use acdf_core::{luminance, Brdf, HalfDiff, Rgb, Vec3};
use rayon::prelude::*;

use crate::MaterialError;

/// Number of θ_h entries.
pub const THETA_H_RES: usize = 90;
/// Number of θ_d entries.
pub const THETA_D_RES: usize = 90;
/// Number of φ_d entries (over [0, π)).
pub const PHI_D_RES: usize = 180;
/// Entries per colour plane: 90 · 90 · 180.
pub const PLANE_LEN: usize = THETA_H_RES * THETA_D_RES * PHI_D_RES;
/// The header's dimensions, in file order.
pub const DIMENSIONS: [i32; 3] = [THETA_H_RES as i32, THETA_D_RES as i32, PHI_D_RES as i32];
/// Size of a MERL file in bytes: the header and three planes of `f64`.
pub const FILE_LEN: u64 = 12 + 3 * PLANE_LEN as u64 * 8;
/// Calibration: f_r = raw × `SCALE[c]` for c = R, G, B.
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];

const CHANNEL_NAMES: [char; 3] = ['R', 'G', 'B'];
const HALF_PI: f64 = std::f64::consts::FRAC_PI_2;

/// θ_h of the grid index i: (i / 90)² · π/2.
pub fn theta_h_at(i: usize) -> f64 {
    let u = i as f64 / THETA_H_RES as f64;
    u * u * HALF_PI
}

/// θ_d of the grid index j: j · π/180.
pub fn theta_d_at(j: usize) -> f64 {
    j as f64 * (HALF_PI / THETA_D_RES as f64)
}

/// φ_d of the grid index k: k · π/180.
pub fn phi_d_at(k: usize) -> f64 {
    k as f64 * (std::f64::consts::PI / PHI_D_RES as f64)
}

/// Position of (i, j, k) within one colour plane: k + 180 (j + 90 i).
#[inline(always)]
pub fn plane_index(i: usize, j: usize, k: usize) -> usize {
    k + PHI_D_RES * (j + THETA_D_RES * i)
}

/// The continuous θ_h index u_h = 90 √(θ_h / (π/2)) of a finite θ_h
/// (clamped to [0, π/2]), at most 89.
#[inline]
fn theta_h_index(theta_h: f32) -> f32 {
    let half_pi = std::f32::consts::FRAC_PI_2;
    ((theta_h.clamp(0.0, half_pi) / half_pi).sqrt() * THETA_H_RES as f32)
        .min((THETA_H_RES - 1) as f32)
}

/// Largest amount by which cos² + sin² of a half vector handed to
/// [`Brdf::luminance_half_ring`] may miss 1 for the fast path; a half vector
/// off by ε tilts the mirrored wi by about ε rad, so this bounds what the
/// fast path adds to the angle error. Libm or `acdf_core::fast` sines and
/// cosines are within a few 1e-7.
const RING_UNIT_TOLERANCE: f32 = 1e-6;

/// Entries of one θ_h index: 90 · 180.
const SLICE_LEN: usize = THETA_D_RES * PHI_D_RES;

/// Columns per pass of [`Brdf::luminance_half_ring`] for a [`MerlTable`]
/// (the angle buffers live on the stack).
const RING_CHUNK: usize = 64;

/// How [`MerlTable`] turns continuous angles into table values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// The entry whose grid point is nearest in index space: each continuous
    /// index u is rounded. Exact at the grid points, robust to rounding there.
    Nearest,
    /// MERL's reference lookup: each continuous index is truncated, so an
    /// entry covers the cell from its grid point to the next. It is
    /// half a cell off `Nearest` and jumps at the grid points themselves.
    Floor,
    /// Linear in each of the three continuous indices between the eight
    /// surrounding entries (u_h is √θ_h-spaced, so this is linear in √θ_h);
    /// φ_d wraps around from index 179 to 0, θ_h and θ_d clamp at index 89.
    #[default]
    Trilinear,
}

/// One MERL-layout table of calibrated RGB BRDF values (see the module
/// documentation for the layout and the rule for unmeasured entries).
#[derive(Clone)]
pub struct MerlTable {
    name: String,
    /// Three planes of `PLANE_LEN` calibrated values, unmeasured ones filled.
    values: Vec<f32>,
    /// One bit per value in `values`: set when the entry was not measured.
    unmeasured: Vec<u64>,
    interpolation: Interpolation,
    /// The luminance Y of every entry (one plane, `PLANE_LEN` values), made
    /// on the first [`Brdf::luminance_half_ring`] call: a luminance lookup
    /// then reads one plane instead of three.
    luminance: OnceLock<Vec<f32>>,
}

impl std::fmt::Debug for MerlTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MerlTable")
            .field("name", &self.name)
            .field("unmeasured", &self.unmeasured_count())
            .field("interpolation", &self.interpolation)
            .finish()
    }
}

fn name_from_path(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "merl".to_owned())
}

/// Check the header (the first 12 bytes, or fewer when the file is that
/// short) and return the file length it implies; `origin` names the file
/// in errors.
fn check_header(header: &[u8], origin: &Path) -> Result<u64, MaterialError> {
    let path = || origin.to_owned();
    if header.is_empty() {
        return Err(MaterialError::EmptyFile { path: path() });
    }
    if header.len() < 12 {
        return Err(MaterialError::ShortHeader {
            path: path(),
            len: header.len(),
        });
    }
    let mut dims = [0i32; 3];
    for (d, chunk) in dims.iter_mut().zip(header[..12].chunks_exact(4)) {
        *d = i32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
    }
    if dims.iter().any(|&d| d < 0) {
        return Err(MaterialError::NegativeDimensions { path: path(), dims });
    }
    let expected = dims
        .iter()
        .try_fold(3u64 * 8, |acc, &d| acc.checked_mul(d as u64))
        .and_then(|body| body.checked_add(12));
    let Some(expected) = expected else {
        return Err(MaterialError::DimensionOverflow { path: path(), dims });
    };
    if dims != DIMENSIONS {
        return Err(MaterialError::WrongDimensions { path: path(), dims });
    }
    Ok(expected)
}

/// Compare a file's length with the one its header implies.
fn check_length(expected: u64, got: u64, origin: &Path) -> Result<(), MaterialError> {
    let path = || origin.to_owned();
    if got < expected {
        return Err(MaterialError::Truncated {
            path: path(),
            expected,
            got,
        });
    }
    if got > expected {
        return Err(MaterialError::TrailingBytes {
            path: path(),
            expected,
            got,
        });
    }
    Ok(())
}

/// Check the header and the length of a MERL file's bytes; `origin` names
/// the file in errors.
fn check_layout(bytes: &[u8], origin: &Path) -> Result<(), MaterialError> {
    let expected = check_header(&bytes[..bytes.len().min(12)], origin)?;
    check_length(expected, bytes.len() as u64, origin)
}

/// Bytes of memory a table takes while it is read: the file and the
/// values, the bit set of unmeasured entries and the luminance plane.
const READ_BYTES: u64 = FILE_LEN + 4 * (3 * PLANE_LEN as u64) + 4 * PLANE_LEN as u64;

impl MerlTable {
    /// Read a MERL `.binary` file; the table is named after the file stem.
    ///
    /// The 12-byte header is read and checked first, then the size it
    /// implies is compared with the file's (for a regular file, from its
    /// metadata, before the body is read; a pipe or device is read no
    /// further than that size), and only then is the body read, whole, and
    /// converted in one pass: a 35 MB file loads in a small fraction of a
    /// second, and `/dev/zero` is refused after 12 bytes.
    pub fn read(path: impl AsRef<Path>) -> Result<MerlTable, MaterialError> {
        let path = path.as_ref();
        let mut input = acdf_io::fsio::Input::open(path)?;
        let mut bytes = input.read_up_to(12)?;
        let expected = check_header(&bytes, path)?;
        if let Some(len) = input.len() {
            check_length(expected, len, path)?;
        }
        acdf_io::limits::check_memory(
            &format!("reading MERL table {}", path.display()),
            READ_BYTES,
        )?;
        let body = input.read_rest(expected - 12, "the size its header gives")?;
        bytes.extend_from_slice(&body);
        Self::from_bytes(&bytes, path)
    }

    /// Parse the bytes of a MERL file; `origin` names the file in errors and
    /// its stem names the table.
    ///
    /// Value = raw × [`SCALE`] per channel, stored as `f32`; negative raw
    /// values are unmeasured. NaN or an infinity is an error, and so is a
    /// finite value whose calibrated magnitude overflows `f32`. No byte
    /// string makes this panic.
    pub fn from_bytes(bytes: &[u8], origin: impl AsRef<Path>) -> Result<MerlTable, MaterialError> {
        let origin = origin.as_ref();
        check_layout(bytes, origin)?;
        let body = &bytes[12..];
        let mut values = vec![0.0f32; 3 * PLANE_LEN];
        let mut unmeasured = vec![0u64; (3 * PLANE_LEN).div_ceil(64)];
        for (c, (plane_bytes, plane)) in body
            .chunks_exact(8 * PLANE_LEN)
            .zip(values.chunks_exact_mut(PLANE_LEN))
            .enumerate()
        {
            for (n, (raw_bytes, out)) in plane_bytes
                .chunks_exact(8)
                .zip(plane.iter_mut())
                .enumerate()
            {
                let mut b = [0u8; 8];
                b.copy_from_slice(raw_bytes);
                let raw = f64::from_le_bytes(b);
                let bad = |value: f64| (CHANNEL_NAMES[c], n, value);
                if !raw.is_finite() {
                    let (channel, index, value) = bad(raw);
                    return Err(MaterialError::NonFiniteValue {
                        path: origin.to_owned(),
                        channel,
                        index,
                        value,
                    });
                }
                if raw < 0.0 {
                    let flat = c * PLANE_LEN + n;
                    unmeasured[flat / 64] |= 1 << (flat % 64);
                    continue;
                }
                let v = (raw * SCALE[c]) as f32;
                if !v.is_finite() {
                    let (channel, index, value) = bad(raw);
                    return Err(MaterialError::ValueOutOfRange {
                        path: origin.to_owned(),
                        channel,
                        index,
                        value,
                    });
                }
                *out = v;
            }
        }
        let mut table = MerlTable {
            name: name_from_path(origin),
            values,
            unmeasured,
            interpolation: Interpolation::default(),
            luminance: OnceLock::new(),
        };
        table.fill_unmeasured();
        Ok(table)
    }

    /// A table whose entry (i, j, k) is `f(i, j, k)`: calibrated RGB, or
    /// `None` for an unmeasured entry. Evaluated in parallel (rayon), one θ_h
    /// slice per task. Negative or non-finite values are stored as
    /// unmeasured.
    pub fn from_fn<F>(name: impl Into<String>, f: F) -> MerlTable
    where
        F: Fn(usize, usize, usize) -> Option<[f64; 3]> + Sync,
    {
        let slice_len = THETA_D_RES * PHI_D_RES;
        let slices: Vec<Vec<Option<[f32; 3]>>> = (0..THETA_H_RES)
            .into_par_iter()
            .map(|i| {
                let mut out = Vec::with_capacity(slice_len);
                for j in 0..THETA_D_RES {
                    for k in 0..PHI_D_RES {
                        let v = f(i, j, k).and_then(|rgb| {
                            let v = rgb.map(|x| x as f32);
                            v.iter().all(|x| x.is_finite() && *x >= 0.0).then_some(v)
                        });
                        out.push(v);
                    }
                }
                out
            })
            .collect();
        let mut values = vec![0.0f32; 3 * PLANE_LEN];
        let mut unmeasured = vec![0u64; (3 * PLANE_LEN).div_ceil(64)];
        for (i, slice) in slices.iter().enumerate() {
            for (n, v) in slice.iter().enumerate() {
                let at = i * slice_len + n;
                for c in 0..3 {
                    let flat = c * PLANE_LEN + at;
                    match v {
                        Some(rgb) => values[flat] = rgb[c],
                        None => unmeasured[flat / 64] |= 1 << (flat % 64),
                    }
                }
            }
        }
        let mut table = MerlTable {
            name: name.into(),
            values,
            unmeasured,
            interpolation: Interpolation::default(),
            luminance: OnceLock::new(),
        };
        table.fill_unmeasured();
        table
    }

    /// Tabulate any BRDF on the MERL grid: entry (i, j, k) is
    /// `brdf.eval(wo, wi)` with (wi, wo) the directions of
    /// (θ_h, φ_h, θ_d, φ_d) = ([`theta_h_at`]\(i), 0, [`theta_d_at`]\(j),
    /// [`phi_d_at`]\(k)). Grid points where either direction is at or below
    /// the horizon cannot be observed, so, as in measured MERL files, they
    /// are marked unmeasured (and filled by the lookup rule).
    pub fn tabulate(brdf: &dyn Brdf) -> MerlTable {
        MerlTable::from_fn(brdf.name(), |i, j, k| {
            let hd = HalfDiff {
                theta_h: theta_h_at(i) as f32,
                phi_h: 0.0,
                theta_d: theta_d_at(j) as f32,
                phi_d: phi_d_at(k) as f32,
            };
            let (wi, wo) = hd.to_directions();
            if wi.z <= 0.0 || wo.z <= 0.0 {
                return None;
            }
            let f = brdf.eval(wo, wi);
            Some([f.x as f64, f.y as f64, f.z as f64])
        })
    }

    /// The file bytes: header, then raw = value / [`SCALE`] per channel as
    /// little-endian `f64`, with −1 for unmeasured entries. A table read from
    /// a file gives back every measured value exactly (f32 → f64 → f32
    /// survives the scale and its inverse).
    pub fn write_to(&self, mut out: impl Write) -> std::io::Result<()> {
        for d in DIMENSIONS {
            out.write_all(&d.to_le_bytes())?;
        }
        let mut buf = Vec::with_capacity(8 * 4096);
        for (c, plane) in self.values.chunks_exact(PLANE_LEN).enumerate() {
            for (n, &v) in plane.iter().enumerate() {
                let raw = if self.is_unmeasured_flat(c * PLANE_LEN + n) {
                    -1.0
                } else {
                    v as f64 / SCALE[c]
                };
                buf.extend_from_slice(&raw.to_le_bytes());
                if buf.len() >= 8 * 4096 {
                    out.write_all(&buf)?;
                    buf.clear();
                }
            }
        }
        out.write_all(&buf)?;
        out.flush()
    }

    /// Write the table as a MERL `.binary` file (see [`MerlTable::write_to`]),
    /// atomically ([`acdf_io::fsio::write_atomic`]): an interrupted or
    /// failed write leaves the previous file.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<(), MaterialError> {
        Ok(acdf_io::fsio::write_atomic(path.as_ref(), |w| {
            self.write_to(w)
        })?)
    }

    /// Rename the table (it starts as the file stem, or the tabulated BRDF's name).
    pub fn set_name(&mut self, name: impl Into<String>) {
        self.name = name.into();
    }

    /// The lookup used by [`Brdf::eval`].
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Choose the lookup used by [`Brdf::eval`].
    pub fn set_interpolation(&mut self, interpolation: Interpolation) {
        self.interpolation = interpolation;
    }

    /// The same table with another lookup.
    pub fn with_interpolation(mut self, interpolation: Interpolation) -> MerlTable {
        self.interpolation = interpolation;
        self
    }

    fn is_unmeasured_flat(&self, flat: usize) -> bool {
        self.unmeasured[flat / 64] & (1 << (flat % 64)) != 0
    }

    /// Whether entry (i, j, k) of `channel` (0 = R, 1 = G, 2 = B) was not
    /// measured; false for indices out of range.
    pub fn is_unmeasured(&self, channel: usize, i: usize, j: usize, k: usize) -> bool {
        channel < 3
            && i < THETA_H_RES
            && j < THETA_D_RES
            && k < PHI_D_RES
            && self.is_unmeasured_flat(channel * PLANE_LEN + plane_index(i, j, k))
    }

    /// Number of unmeasured values, over all three channels.
    pub fn unmeasured_count(&self) -> usize {
        self.unmeasured
            .iter()
            .map(|w| w.count_ones() as usize)
            .sum()
    }

    /// The calibrated RGB entry (i, j, k), indices clamped to the grid.
    /// An unmeasured channel holds the value of the nearest measured entry
    /// along θ_d (the lower θ_d on a tie) with the same θ_h and φ_d, or 0 if
    /// there is none.
    #[inline]
    pub fn get(&self, i: usize, j: usize, k: usize) -> Rgb {
        let n = plane_index(
            i.min(THETA_H_RES - 1),
            j.min(THETA_D_RES - 1),
            k.min(PHI_D_RES - 1),
        );
        Rgb::new(
            self.values[n],
            self.values[PLANE_LEN + n],
            self.values[2 * PLANE_LEN + n],
        )
    }

    /// Replace each unmeasured value by the nearest measured one along θ_d.
    fn fill_unmeasured(&mut self) {
        if self.unmeasured_count() == 0 {
            return;
        }
        let mut column_valid = [false; THETA_D_RES];
        let mut column = [0.0f32; THETA_D_RES];
        for c in 0..3 {
            for i in 0..THETA_H_RES {
                for k in 0..PHI_D_RES {
                    let flat = |j: usize| c * PLANE_LEN + plane_index(i, j, k);
                    let mut any_valid = false;
                    for j in 0..THETA_D_RES {
                        column_valid[j] = !self.is_unmeasured_flat(flat(j));
                        column[j] = self.values[flat(j)];
                        any_valid |= column_valid[j];
                    }
                    if column_valid.iter().all(|&v| v) {
                        continue;
                    }
                    for j in 0..THETA_D_RES {
                        if column_valid[j] {
                            continue;
                        }
                        let mut filled = 0.0;
                        if any_valid {
                            // Search outwards; the lower side first wins ties.
                            for step in 1..THETA_D_RES {
                                if j >= step && column_valid[j - step] {
                                    filled = column[j - step];
                                    break;
                                }
                                if j + step < THETA_D_RES && column_valid[j + step] {
                                    filled = column[j + step];
                                    break;
                                }
                            }
                        }
                        self.values[flat(j)] = filled;
                    }
                }
            }
        }
    }

    /// f_r at the half/difference angles (θ_h, θ_d, φ_d) by the table's
    /// [`Interpolation`]; φ_d is folded into [0, π) by reciprocity, θ_h and
    /// θ_d are clamped to [0, π/2]. NaN angles give 0.
    pub fn eval_angles(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> Rgb {
        self.eval_angles_with(self.interpolation, theta_h, theta_d, phi_d)
    }

    /// [`MerlTable::eval_angles`] with the given lookup instead of the
    /// table's own.
    pub fn eval_angles_with(
        &self,
        interpolation: Interpolation,
        theta_h: f32,
        theta_d: f32,
        phi_d: f32,
    ) -> Rgb {
        if !(theta_h.is_finite() && theta_d.is_finite() && phi_d.is_finite()) {
            return Rgb::ZERO;
        }
        let half_pi = std::f32::consts::FRAC_PI_2;
        let u_h = theta_h_index(theta_h);
        let u_d = theta_d.clamp(0.0, half_pi) / half_pi * THETA_D_RES as f32;
        // Fold φ_d into [0, π) before scaling, where the subtraction is exact
        // to an ulp of π rather than of 360.
        let phi_d = acdf_core::geometry::wrap_angle(phi_d);
        let pi = std::f32::consts::PI;
        let phi_d = if phi_d >= pi { phi_d - pi } else { phi_d };
        let u_p = phi_d / pi * PHI_D_RES as f32;
        let u_d = u_d.min((THETA_D_RES - 1) as f32);
        let wrap_p = |k: usize| k % PHI_D_RES;
        let f = match interpolation {
            Interpolation::Nearest => self.get(
                u_h.round() as usize,
                u_d.round() as usize,
                wrap_p(u_p.round() as usize),
            ),
            Interpolation::Floor => self.get(u_h as usize, u_d as usize, wrap_p(u_p as usize)),
            Interpolation::Trilinear => {
                let (h0, d0, p0) = (u_h as usize, u_d as usize, u_p as usize);
                let (th, td, tp) = (
                    (u_h - h0 as f32).clamp(0.0, 1.0),
                    (u_d - d0 as f32).clamp(0.0, 1.0),
                    (u_p - p0 as f32).clamp(0.0, 1.0),
                );
                let h1 = (h0 + 1).min(THETA_H_RES - 1);
                let d1 = (d0 + 1).min(THETA_D_RES - 1);
                let (p0, p1) = (wrap_p(p0), wrap_p(p0 + 1));
                let lerp_p =
                    |i: usize, j: usize| self.get(i, j, p0) * (1.0 - tp) + self.get(i, j, p1) * tp;
                let lerp_d = |i: usize| lerp_p(i, d0) * (1.0 - td) + lerp_p(i, d1) * td;
                lerp_d(h0) * (1.0 - th) + lerp_d(h1) * th
            }
        };
        // Entries are finite and non-negative; the min guards the sum of two
        // values near f32::MAX.
        f.max(Rgb::ZERO).min(Rgb::splat(f32::MAX))
    }
}

impl MerlTable {
    /// The luminance plane: Y of entry n, `PLANE_LEN` values, at most
    /// `f32::MAX`, built on first use.
    fn luminance_plane(&self) -> &[f32] {
        self.luminance.get_or_init(|| {
            let (r, rest) = self.values.split_at(PLANE_LEN);
            let (g, b) = rest.split_at(PLANE_LEN);
            r.iter()
                .zip(g)
                .zip(b)
                .map(|((&r, &g), &b)| luminance(Rgb::new(r, g, b)).min(f32::MAX))
                .collect()
        })
    }

    /// The continuous indices (u_d, u_p) of a chunk of a ring, for
    /// [`Brdf::luminance_half_ring`]; u_d is set to −1 for the columns the
    /// fast path leaves out (wi at or below the horizon, wo·h ≤ 0, a column
    /// off the unit circle).
    ///
    /// With h = (s c_φ, s s_φ, c) and wi = 2 (wo·h) h − wo, the difference
    /// vector is d = (wi·t1, wi·t2, wi·h) = (−wo·t1, −wo·t2, wo·h) in the half
    /// frame t1 = (c c_φ, c s_φ, −s), t2 = (−s_φ, c_φ, 0) (reflection about h
    /// negates the part of wo across h). So θ_d = atan2(|wo × h|, wo·h) and,
    /// folded by reciprocity into [0, π), φ_d = atan2(wo·t2, wo·t1) mod π:
    /// no normalisation and no half vector rebuilt from wi + wo. The loop has
    /// no branches and no memory reads, so it vectorises.
    #[inline(always)]
    fn ring_angles(
        wo: Vec3,
        (sin_h, cos_h): (f32, f32),
        columns: &[(f32, f32)],
        u_d: &mut [f32],
        u_p: &mut [f32],
    ) {
        let pi = std::f32::consts::PI;
        let per_theta_d = THETA_D_RES as f32 / std::f32::consts::FRAC_PI_2;
        let per_phi_d = PHI_D_RES as f32 / pi;
        // On the pole `HalfDiff` measures φ_d from the x axis.
        let pole = sin_h == 0.0;
        for ((&(cos_p, sin_p), u_d), u_p) in columns.iter().zip(u_d).zip(u_p) {
            let h = Vec3::new(sin_h * cos_p, sin_h * sin_p, cos_h);
            let wo_h = wo.dot(h);
            let wi_z = 2.0 * wo_h * h.z - wo.z;
            let unit = ((cos_p * cos_p + sin_p * sin_p) - 1.0).abs() <= RING_UNIT_TOLERANCE;
            let theta_d = fast_atan2(wo.cross(h).length(), wo_h);
            let (cos_f, sin_f) = if pole { (1.0, 0.0) } else { (cos_p, sin_p) };
            let x = cos_h * (wo.x * cos_f + wo.y * sin_f) - sin_h * wo.z;
            let y = wo.y * cos_f - wo.x * sin_f;
            let mut phi_d = fast_atan2(y, x);
            if phi_d < 0.0 {
                phi_d += pi;
            }
            if phi_d >= pi {
                phi_d -= pi;
            }
            let fast = wi_z > 0.0 && wo_h > 0.0 && unit;
            *u_d = if fast {
                (theta_d * per_theta_d).min((THETA_D_RES - 1) as f32)
            } else {
                -1.0
            };
            *u_p = phi_d * per_phi_d;
        }
    }
}

/// round(u) for u ≥ 0 (half away from zero, as `f32::round`) without the
/// libm call that `round` is without SSE4.1: the fraction u − trunc(u) is
/// exact.
#[inline(always)]
fn round_non_negative(u: f32) -> usize {
    let t = u as usize;
    t + ((u - t as f32) >= 0.5) as usize
}

/// The entries of one ring's trilinear look-ups in the luminance `plane`:
/// rows `base0` and `base1` (θ_h indices h0 and h0 + 1, weight `th` on the
/// second), continuous (u_d, u_p) per column as in
/// [`MerlTable::eval_angles_with`]. Columns with a negative u_d are left
/// alone (the caller fills them).
#[inline(always)]
fn trilinear_ring(
    plane: &[f32],
    (base0, base1, th): (usize, usize, f32),
    u_d: &[f32],
    u_p: &[f32],
    out: &mut [f32],
) {
    let m = u_d.len().min(u_p.len()).min(out.len()).min(RING_CHUNK);
    // Offsets and weights first, in a loop that vectorises (structure of
    // arrays, and i32 rather than usize: SSE2 converts packed floats to
    // i32 only); the reads after.
    let mut first = [0i32; RING_CHUNK];
    let mut next_p = [0i32; RING_CHUNK];
    let mut next_d = [0i32; RING_CHUNK];
    let mut t_d = [0.0f32; RING_CHUNK];
    let mut t_p = [0.0f32; RING_CHUNK];
    let (n_d, n_p) = (THETA_D_RES as i32, PHI_D_RES as i32);
    for c in 0..m {
        let (u_d, u_p) = (u_d[c].max(0.0), u_p[c]);
        let (d0, p0) = (u_d as i32, u_p as i32);
        t_d[c] = (u_d - d0 as f32).clamp(0.0, 1.0);
        t_p[c] = (u_p - p0 as f32).clamp(0.0, 1.0);
        // 0 ≤ u_p ≤ 180, so one subtraction wraps p0 and p0 + 1.
        let p0 = if p0 >= n_p { p0 - n_p } else { p0 };
        let p1 = if p0 + 1 >= n_p { 0 } else { p0 + 1 };
        first[c] = d0 * n_p + p0;
        next_p[c] = p1 - p0;
        next_d[c] = if d0 + 1 < n_d { n_p } else { 0 };
    }
    let (row0, row1) = (
        &plane[base0..base0 + SLICE_LEN],
        &plane[base1..base1 + SLICE_LEN],
    );
    for c in 0..m {
        // Columns left out (often half the ring for grazing wo) cost no
        // reads.
        if u_d[c] < 0.0 {
            continue;
        }
        let (td, tp) = (t_d[c], t_p[c]);
        let n00 = first[c];
        let n01 = n00 + next_p[c];
        let (n10, n11) = (n00 + next_d[c], n01 + next_d[c]);
        let at = |row: &[f32], n: i32| row[(n as usize).min(SLICE_LEN - 1)];
        let lerp_p = |row: &[f32], a: i32, b: i32| at(row, a) * (1.0 - tp) + at(row, b) * tp;
        let lerp_d = |row: &[f32]| lerp_p(row, n00, n01) * (1.0 - td) + lerp_p(row, n10, n11) * td;
        out[c] = lerp_d(row0) * (1.0 - th) + lerp_d(row1) * th;
    }
}

impl Brdf for MerlTable {
    fn name(&self) -> &str {
        &self.name
    }

    /// f_r(wo, wi) = the table at the half/difference angles of (wi, wo)
    /// (d measured from wi), after normalising both directions; 0 when
    /// either is at or below the horizon, degenerate or not finite.
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let (Some(wo), Some(wi)) = (wo.try_normalize(), wi.try_normalize()) else {
            return Rgb::ZERO;
        };
        if !(wo.z > 0.0 && wi.z > 0.0) {
            return Rgb::ZERO;
        }
        match HalfDiff::from_directions(wi, wo) {
            Some(hd) => self.eval_angles(hd.theta_h, hd.theta_d, hd.phi_d),
            None => Rgb::ZERO,
        }
    }

    fn is_isotropic(&self) -> bool {
        true
    }

    /// The hash of every value, the unmeasured entries and the lookup, so a
    /// table read back from a file acdf wrote has the fingerprint of the
    /// table written.
    fn fingerprint(&self) -> u64 {
        let mut h = acdf_core::Fingerprinter::new();
        h.bytes(b"merl");
        h.bytes(&[self.interpolation as u8]);
        h.f32s(&self.values);
        for word in &self.unmeasured {
            h.u64(*word);
        }
        h.finish()
    }

    /// Every entry (unmeasured ones filled) is 0.
    fn is_zero_everywhere(&self) -> bool {
        self.values.iter().all(|&v| v == 0.0)
    }

    /// The ring of [`Brdf::luminance_half_ring`] read from a plane of
    /// luminances by the table's [`Interpolation`], with the angles of
    /// [`MerlTable::eval`] computed from wo and each half vector directly
    /// ([`fast_atan2`] for θ_d and φ_d, the θ_h index once per ring).
    ///
    /// Its angles are within 5e-7 rad of the exact half/difference angles
    /// of (wo, h_c) (θ_d, φ_d; φ_d within 5e-7 rad + 1e-7 rad / sin θ_d,
    /// being undefined at θ_d = 0), and it agrees with the luminance of
    /// [`MerlTable::eval`] at (wo, reflect(wo, h_c)) to that error plus
    /// `eval`'s own: trilinear values within 1e-5 relative (a luminance of
    /// interpolated colours against an interpolated luminance) plus the
    /// angle errors times the steps between neighbouring entries. `Nearest`
    /// and `Floor` read the same entry except where a continuous index lies
    /// within that error of a rounding (`Nearest`) or integer (`Floor`)
    /// boundary, where the two paths may name neighbouring entries (no flip
    /// in the tests where both errors are below 2e-4 index units). Near
    /// θ_h = 0 and θ_d = π/2 `eval` is the less accurate of the two: it
    /// rebuilds h from wi + wo, which fixes h only to about
    /// 6e-8 / cos θ_d rad and φ_h (hence φ_d) to that over sin θ_h. Inputs
    /// the fast path does not cover (wo not finite, zero or at or below the
    /// horizon, sin θ_h < 0, cos θ_h ≤ 0, a half vector or column whose
    /// squared length misses 1 by more than 1e-6, wo·h ≤ 0) go through
    /// `eval`; columns whose wi is at or below the horizon give 0.
    fn luminance_half_ring(
        &self,
        wo: Vec3,
        (sin_h, cos_h): (f32, f32),
        columns: &[(f32, f32)],
        out: &mut [f32],
    ) {
        let ring_unit = ((sin_h * sin_h + cos_h * cos_h) - 1.0).abs() <= RING_UNIT_TOLERANCE;
        // The angles do not depend on the length of wo, but its products
        // could overflow; `eval` normalises it too.
        let wo = wo.try_normalize().unwrap_or(Vec3::ZERO);
        if !(wo.z > 0.0 && sin_h >= 0.0 && cos_h > 0.0 && ring_unit) {
            for (&(cos_p, sin_p), y) in columns.iter().zip(out.iter_mut()) {
                let h = Vec3::new(sin_h * cos_p, sin_h * sin_p, cos_h);
                *y = luminance(self.eval(wo, reflect(wo, h)));
            }
            return;
        }
        let plane = self.luminance_plane();
        let u_h = theta_h_index(sin_h.atan2(cos_h));
        let row = |i: usize| i.min(THETA_H_RES - 1) * SLICE_LEN;
        let n = columns.len().min(out.len());
        let mut u_d = [0.0f32; RING_CHUNK];
        let mut u_p = [0.0f32; RING_CHUNK];
        for (columns, out) in columns[..n]
            .chunks(RING_CHUNK)
            .zip(out[..n].chunks_mut(RING_CHUNK))
        {
            let m = columns.len();
            let (u_d, u_p) = (&mut u_d[..m], &mut u_p[..m]);
            Self::ring_angles(wo, (sin_h, cos_h), columns, u_d, u_p);
            match self.interpolation {
                Interpolation::Nearest => {
                    let base = row(u_h.round() as usize);
                    for ((&u_d, &u_p), y) in u_d.iter().zip(&*u_p).zip(&mut *out) {
                        let (j, k) = (round_non_negative(u_d), round_non_negative(u_p));
                        *y = plane[base + plane_index(0, j.min(THETA_D_RES - 1), k % PHI_D_RES)];
                    }
                }
                Interpolation::Floor => {
                    let base = row(u_h as usize);
                    for ((&u_d, &u_p), y) in u_d.iter().zip(&*u_p).zip(&mut *out) {
                        let (j, k) = (u_d as usize, u_p as usize);
                        *y = plane[base + plane_index(0, j.min(THETA_D_RES - 1), k % PHI_D_RES)];
                    }
                }
                Interpolation::Trilinear => {
                    let h0 = u_h as usize;
                    let th = (u_h - h0 as f32).clamp(0.0, 1.0);
                    trilinear_ring(plane, (row(h0), row(h0 + 1), th), u_d, u_p, out);
                }
            }
            for ((&(cos_p, sin_p), &u_d), y) in columns.iter().zip(&*u_d).zip(out) {
                *y = if u_d >= 0.0 {
                    y.min(f32::MAX)
                } else {
                    // Below the horizon (or NaN) is 0 either way; the rare
                    // rest (wo·h ≤ 0 with wi above, a column off the unit
                    // circle) goes to the general evaluation.
                    let h = Vec3::new(sin_h * cos_p, sin_h * sin_p, cos_h);
                    let wi = reflect(wo, h);
                    if wi.z > 0.0 {
                        luminance(self.eval(wo, wi))
                    } else {
                        0.0
                    }
                };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analytic;
    use proptest::prelude::*;
    use std::f32::consts::{FRAC_PI_2, PI};
    use std::sync::OnceLock;

    /// Entry (i, j, k) = i + 100 j + 10⁴ k in every channel (exact in f32),
    /// so a lookup's result tells which entries it read.
    fn linear_table() -> &'static MerlTable {
        static TABLE: OnceLock<MerlTable> = OnceLock::new();
        TABLE.get_or_init(|| {
            MerlTable::from_fn("linear", |i, j, k| {
                let v = (i + 100 * j + 10_000 * k) as f64;
                Some([v; 3])
            })
        })
    }

    /// [`linear_table`] with each of the three lookups.
    fn linear_tables() -> &'static [MerlTable; 3] {
        static TABLES: OnceLock<[MerlTable; 3]> = OnceLock::new();
        TABLES.get_or_init(|| {
            [
                Interpolation::Nearest,
                Interpolation::Floor,
                Interpolation::Trilinear,
            ]
            .map(|i| linear_table().clone().with_interpolation(i))
        })
    }

    /// The bytes of a valid MERL file (the tabulated analytic nickel, with
    /// unmeasured entries), built once.
    fn valid_bytes() -> &'static [u8] {
        static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
        BYTES.get_or_init(|| {
            let mut out = Vec::with_capacity(FILE_LEN as usize);
            MerlTable::tabulate(&analytic::nickel())
                .write_to(&mut out)
                .unwrap();
            out
        })
    }

    fn header(dims: [i32; 3]) -> Vec<u8> {
        dims.iter().flat_map(|d| d.to_le_bytes()).collect()
    }

    fn with_value(channel: usize, index: usize, value: f64) -> Vec<u8> {
        let mut b = valid_bytes().to_vec();
        let at = 12 + 8 * (channel * PLANE_LEN + index);
        b[at..at + 8].copy_from_slice(&value.to_le_bytes());
        b
    }

    #[test]
    fn the_valid_file_has_the_documented_size() {
        assert_eq!(valid_bytes().len() as u64, FILE_LEN);
        assert_eq!(FILE_LEN, 34_992_012);
        assert!(MerlTable::from_bytes(valid_bytes(), "ok.binary").is_ok());
    }

    #[test]
    fn malformed_corpus_gives_one_error_kind_each() {
        use MaterialError as E;
        let valid = valid_bytes();
        let mut wrong_dims = header([90, 90, 179]);
        wrong_dims.resize(12 + 3 * 90 * 90 * 179 * 8, 0);
        type Case = (&'static str, Vec<u8>, fn(&MaterialError) -> bool);
        let corpus: Vec<Case> = vec![
            ("empty", vec![], |e| matches!(e, E::EmptyFile { .. })),
            ("short-header", vec![90, 0, 0, 0, 90, 0, 0], |e| {
                matches!(e, E::ShortHeader { len: 7, .. })
            }),
            ("negative-dims", header([90, -90, 180]), |e| {
                matches!(e, E::NegativeDimensions { .. })
            }),
            ("wrong-dims", wrong_dims, |e| {
                matches!(
                    e,
                    E::WrongDimensions {
                        dims: [90, 90, 179],
                        ..
                    }
                )
            }),
            ("zero-dims", header([0, 0, 0]), |e| {
                matches!(e, E::WrongDimensions { .. })
            }),
            ("overflowing-dims", header([i32::MAX; 3]), |e| {
                matches!(e, E::DimensionOverflow { .. })
            }),
            ("header-only", header(DIMENSIONS), |e| {
                matches!(e, E::Truncated { got: 12, .. })
            }),
            (
                "truncated-body",
                valid[..valid.len() - 1].to_vec(),
                |e| matches!(e, E::Truncated { expected, got, .. } if *expected == got + 1),
            ),
            (
                "trailing-bytes",
                [valid, &[0u8][..]].concat(),
                |e| matches!(e, E::TrailingBytes { expected, got, .. } if *got == expected + 1),
            ),
            (
                "nan",
                with_value(1, 1234, f64::NAN),
                |e| matches!(e, E::NonFiniteValue { channel: 'G', index: 1234, value, .. } if value.is_nan()),
            ),
            (
                "plus-inf",
                with_value(0, 7, f64::INFINITY),
                |e| matches!(e, E::NonFiniteValue { channel: 'R', index: 7, value, .. } if *value == f64::INFINITY),
            ),
            (
                "minus-inf",
                with_value(2, PLANE_LEN - 1, f64::NEG_INFINITY),
                |e| matches!(e, E::NonFiniteValue { channel: 'B', value, .. } if *value == f64::NEG_INFINITY),
            ),
            ("too-large-for-f32", with_value(0, 99, 1e300), |e| {
                matches!(
                    e,
                    E::ValueOutOfRange {
                        channel: 'R',
                        index: 99,
                        ..
                    }
                )
            }),
        ];
        let mut messages = Vec::new();
        for (kind, bytes, is_expected) in &corpus {
            let file = format!("corpus/{kind}.binary");
            let err = MerlTable::from_bytes(bytes, &file).unwrap_err();
            assert!(is_expected(&err), "{kind}: got {err:?}");
            let msg = err.to_string();
            assert!(
                msg.contains(&file),
                "{kind}: message `{msg}` does not name the file"
            );
            messages.push(msg);
        }
        let missing = MerlTable::read("/nonexistent/dir/missing.binary").unwrap_err();
        assert!(matches!(missing, E::File(_)), "{missing:?}");
        assert!(missing.to_string().contains("missing.binary"));
        messages.push(missing.to_string());
        let mut unique = messages.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), messages.len(), "{messages:#?}");
    }

    #[test]
    fn write_then_read_round_trips_values_and_unmeasured_entries() {
        let table = MerlTable::tabulate(&analytic::nickel());
        assert!(table.unmeasured_count() > 0);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("nickel-lafortune.binary");
        table.write(&path).unwrap();
        assert_eq!(std::fs::metadata(&path).unwrap().len(), FILE_LEN);
        let back = MerlTable::read(&path).unwrap();
        assert_eq!(back.name(), "nickel-lafortune");
        assert!(
            back.values == table.values,
            "values differ after the round trip"
        );
        assert!(back.unmeasured == table.unmeasured);
    }

    #[test]
    fn negative_raw_values_are_unmeasured_and_filled_along_theta_d() {
        // Column (i = 3, k = 5) in green: only j = 10 (value 1) and j = 20
        // (value 2) are measured.
        let mut bytes = valid_bytes().to_vec();
        let put = |b: &mut Vec<u8>, c: usize, n: usize, raw: f64| {
            let at = 12 + 8 * (c * PLANE_LEN + n);
            b[at..at + 8].copy_from_slice(&raw.to_le_bytes());
        };
        for j in 0..THETA_D_RES {
            let raw = match j {
                10 => 1.0 / SCALE[1],
                20 => 2.0 / SCALE[1],
                _ => -1.0,
            };
            put(&mut bytes, 1, plane_index(3, j, 5), raw);
        }
        // A whole unmeasured column in blue.
        for j in 0..THETA_D_RES {
            put(&mut bytes, 2, plane_index(4, j, 6), -0.5);
        }
        let t = MerlTable::from_bytes(&bytes, "holes.binary").unwrap();
        let g = |j| t.get(3, j, 5).y;
        assert!(t.is_unmeasured(1, 3, 0, 5) && !t.is_unmeasured(1, 3, 10, 5));
        assert!(!t.is_unmeasured(0, 3, 0, 5), "red is measured there");
        for (j, want) in [
            (0, 1.0),
            (10, 1.0),
            (14, 1.0),
            (15, 1.0),
            (16, 2.0),
            (20, 2.0),
            (89, 2.0),
        ] {
            assert!((g(j) - want).abs() < 1e-6, "j = {j}: {} vs {want}", g(j));
        }
        for j in 0..THETA_D_RES {
            assert_eq!(t.get(4, j, 6).z, 0.0);
        }
        // Unmeasured entries go back to disk as -1.
        let mut out = Vec::new();
        t.write_to(&mut out).unwrap();
        let at = 12 + 8 * (PLANE_LEN + plane_index(3, 0, 5));
        assert_eq!(
            f64::from_le_bytes(out[at..at + 8].try_into().unwrap()),
            -1.0
        );
    }

    #[test]
    fn nearest_lookup_returns_the_entry_of_each_grid_point() {
        let t = linear_table()
            .clone()
            .with_interpolation(Interpolation::Nearest);
        let mut checked = 0;
        for i in (0..THETA_H_RES).step_by(7) {
            for j in (0..THETA_D_RES).step_by(5) {
                for k in (0..PHI_D_RES).step_by(11) {
                    let hd = HalfDiff {
                        theta_h: theta_h_at(i) as f32,
                        phi_h: 0.9,
                        theta_d: theta_d_at(j) as f32,
                        phi_d: phi_d_at(k) as f32,
                    };
                    let want = t.get(i, j, k);
                    assert_eq!(t.eval_angles(hd.theta_h, hd.theta_d, hd.phi_d), want);
                    let (wi, wo) = hd.to_directions();
                    // At θ_h = 0 or θ_d = 0 the directions fix only a sum of
                    // azimuths, so only the angle path can name the entry.
                    if i > 0 && j > 0 && wi.z > 1e-3 && wo.z > 1e-3 {
                        assert_eq!(t.eval(wo, wi), want, "(i, j, k) = ({i}, {j}, {k})");
                        // Reciprocity: swapping the directions moves φ_d by π.
                        assert_eq!(t.eval(wi, wo), want);
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 100);
    }

    proptest! {
        /// Trilinear interpolation of data that are linear in the continuous
        /// indices reproduces that linear function (away from the φ_d seam,
        /// where index 179 blends with index 0).
        #[test]
        fn trilinear_reproduces_linear_data(th in 0.0f32..FRAC_PI_2, td in 0.0f32..1.55, pd in 0.0f32..(2.0 * PI)) {
            let t = linear_table();
            let u_h = ((th / FRAC_PI_2).sqrt() * 90.0).min(89.0);
            let u_d = (td / FRAC_PI_2 * 90.0).min(89.0);
            let u_p = (pd % PI) / PI * 180.0;
            prop_assume!(u_p < 178.9 && (pd % PI) < PI - 1e-4);
            let want = u_h + 100.0 * u_d + 10_000.0 * u_p;
            let got = t.eval_angles(th, td, pd).x;
            prop_assert!((got - want).abs() <= 2e-6 * want + 0.1, "{got} vs {want}");
            // Inside a cell, away from the boundaries that rounding could
            // cross, Floor and Nearest name exactly the expected entries.
            let inside = |u: f32| (u.fract() - 0.5).abs() < 0.45 && u < 88.9;
            if inside(u_h) && inside(u_d) && inside(u_p) {
                let floor = t.eval_angles_with(Interpolation::Floor, th, td, pd).x;
                let want_floor = u_h.floor() + 100.0 * u_d.floor() + 10_000.0 * u_p.floor();
                prop_assert_eq!(floor, want_floor);
                let nearest = t.eval_angles_with(Interpolation::Nearest, th, td, pd).x;
                let want_nearest = u_h.round() + 100.0 * u_d.round() + 10_000.0 * u_p.round();
                prop_assert_eq!(nearest, want_nearest);
            }
        }

        #[test]
        fn eval_is_finite_non_negative_and_zero_below_the_horizon(
            ox in -2.0f32..2.0, oy in -2.0f32..2.0, oz in -2.0f32..2.0,
            ix in -2.0f32..2.0, iy in -2.0f32..2.0, iz in -2.0f32..2.0,
        ) {
            let wo = Vec3::new(ox, oy, oz);
            let wi = Vec3::new(ix, iy, iz);
            for t in linear_tables() {
                let f = t.eval(wo, wi);
                prop_assert!(f.is_finite() && f.min_element() >= 0.0);
                if oz <= 0.0 || iz <= 0.0 {
                    prop_assert_eq!(f, Rgb::ZERO);
                }
            }
        }

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..4096)) {
            prop_assert!(MerlTable::from_bytes(&bytes, "random.binary").is_err());
        }

        #[test]
        fn random_headers_never_panic(dims in any::<[i32; 3]>(), extra in 0usize..64) {
            let mut bytes = header(dims);
            bytes.resize(12 + extra, 0xff);
            prop_assert!(MerlTable::from_bytes(&bytes, "header.binary").is_err());
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]
        /// A valid file with a few bytes overwritten and maybe cut or
        /// extended parses or fails with an error, never panics, and every
        /// table it yields evaluates to finite non-negative values.
        #[test]
        fn mutated_files_never_panic(
            edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
            resize in prop_oneof![Just(0i64), -100i64..100],
        ) {
            let mut bytes = valid_bytes().to_vec();
            for (at, value) in edits {
                let n = at.index(bytes.len());
                bytes[n] = value;
            }
            let len = (bytes.len() as i64 + resize) as usize;
            bytes.resize(len, 0x7f);
            if let Ok(t) = MerlTable::from_bytes(&bytes, "mutated.binary") {
                let f = t.eval(Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.2, 0.4, 0.8).normalize());
                prop_assert!(f.is_finite() && f.min_element() >= 0.0);
            }
        }
    }

    #[test]
    fn tabulated_lambert_evaluates_to_its_constant() {
        let t = MerlTable::tabulate(&analytic::lambert());
        assert_eq!(t.name(), "lambert");
        // θ_h = θ_d = 89°-ish: both directions below the horizon.
        assert!(t.is_unmeasured(0, 89, 89, 0));
        assert!(!t.is_unmeasured(0, 0, 0, 0));
        let want = 0.8 / PI;
        for (to, ti, dphi) in [(0.1f32, 0.2f32, 1.0f32), (1.5, 1.5, 3.0), (0.7, 1.56, 0.2)] {
            let wo = acdf_core::geometry::spherical_direction(to, 0.0);
            let wi = acdf_core::geometry::spherical_direction(ti, dphi);
            let f = t.eval(wo, wi);
            assert!((f - Rgb::splat(want)).abs().max_element() < 1e-6, "{f}");
        }
    }
}

#[cfg(test)]
mod tabulation_tests {
    use super::*;
    use crate::analytic;
    use acdf_core::geometry::spherical_direction;
    use rand::{Rng, SeedableRng};

    /// The tabulated blue-metallic-paint (a lobe about 15° wide) evaluated
    /// trilinearly matches the analytic model, which checks that tabulation
    /// and lookup agree on which angle each index stands for.
    #[test]
    fn tabulated_wide_lobe_matches_the_model() {
        let model = analytic::blue_metallic_paint();
        let table = MerlTable::tabulate(&model);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut worst = 0.0f32;
        for _ in 0..2000 {
            let wo = spherical_direction(
                rng.random_range(0.0..1.3),
                rng.random_range(0.0..std::f32::consts::TAU),
            );
            let wi = spherical_direction(
                rng.random_range(0.0..1.3),
                rng.random_range(0.0..std::f32::consts::TAU),
            );
            let want = model.eval(wo, wi);
            let got = table.eval(wo, wi);
            let err = (got - want).abs().max_element() / want.max_element();
            worst = worst.max(err);
        }
        println!("tabulated blue-metallic-paint: worst relative error {worst}");
        assert!(worst < 0.01, "worst relative error {worst}");
    }
}

#[cfg(test)]
mod ring_tests {
    use super::*;
    use crate::analytic;
    use acdf_core::geometry::spherical_direction;
    use rand::{Rng, SeedableRng};
    use std::sync::OnceLock;

    /// A table seen only through `eval`: the default `luminance_half_ring`.
    struct EvalOnly<'a>(&'a MerlTable);

    impl Brdf for EvalOnly<'_> {
        fn name(&self) -> &str {
            self.0.name()
        }
        fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
            self.0.eval(wo, wi)
        }
        fn is_isotropic(&self) -> bool {
            true
        }
    }

    /// Three tables whose entry (i, j, k) is 1 + i, 1 + j and 1 + k in every
    /// channel: a trilinear lookup returns 1 + u_h, 1 + u_d or 1 + u_p (away
    /// from the φ_d seam), so the ring's continuous indices can be read off,
    /// and 0 means "below the horizon".
    fn index_tables() -> &'static [MerlTable; 3] {
        static TABLES: OnceLock<[MerlTable; 3]> = OnceLock::new();
        TABLES.get_or_init(|| {
            [0, 1, 2].map(|axis| {
                MerlTable::from_fn("index", move |i, j, k| {
                    Some([1.0 + [i, j, k][axis] as f64; 3])
                })
            })
        })
    }

    /// The continuous indices (u_h, u_d, u_p) of (wo, h) by the definition,
    /// in f64: wi = reflect(wo, h), d = wi in the frame (t1, t2, h) of
    /// `HalfDiff`, φ_d folded into [0, π); `None` when wi is not above the
    /// horizon.
    fn reference_indices(wo: Vec3, h: Vec3) -> Option<(f64, f64, f64, f64)> {
        use std::f64::consts::{FRAC_PI_2, PI};
        let wo = wo.as_dvec3().normalize();
        let h = h.as_dvec3().normalize();
        let wi = 2.0 * wo.dot(h) * h - wo;
        if wi.z <= 0.0 {
            return None;
        }
        let sin_h = h.x.hypot(h.y);
        let (cos_p, sin_p) = if sin_h > 0.0 {
            (h.x / sin_h, h.y / sin_h)
        } else {
            (1.0, 0.0)
        };
        let t1 = glam::DVec3::new(h.z * cos_p, h.z * sin_p, -sin_h);
        let t2 = glam::DVec3::new(-sin_p, cos_p, 0.0);
        let d = glam::DVec3::new(wi.dot(t1), wi.dot(t2), wi.dot(h));
        let theta_h = sin_h.atan2(h.z);
        let theta_d = d.x.hypot(d.y).atan2(d.z);
        let phi_d = d.y.atan2(d.x).rem_euclid(PI);
        let u_h = ((theta_h / FRAC_PI_2).sqrt() * 90.0).min(89.0);
        let u_d = (theta_d / FRAC_PI_2 * 90.0).min(89.0);
        Some((u_h, u_d, phi_d / PI * 180.0, d.x.hypot(d.y)))
    }

    /// Random (wo, θ_h) with grazing and near-normal outgoing directions and
    /// half vectors near and on the pole mixed in, and a ring of random
    /// columns.
    fn random_case(rng: &mut rand_pcg::Pcg64) -> (Vec3, (f32, f32), Vec<(f32, f32)>) {
        let half_pi = std::f32::consts::FRAC_PI_2;
        let theta_o = match rng.random_range(0..4) {
            0 => rng.random_range(half_pi - 1e-3..half_pi - 1e-6),
            1 => rng.random_range(0.0..1e-4),
            _ => rng.random_range(0.0..half_pi),
        };
        let wo = spherical_direction(theta_o, rng.random_range(0.0..std::f32::consts::TAU));
        let theta_h: f32 = match rng.random_range(0..6) {
            0 => rng.random_range(0.0..1e-4),
            1 => 0.0,
            _ => rng.random_range(0.0..half_pi - 1e-3),
        };
        let columns = (0..8)
            .map(|_| {
                let (s, c) = rng.random_range(0.0..std::f32::consts::TAU).sin_cos();
                (c, s)
            })
            .collect();
        (wo, theta_h.sin_cos(), columns)
    }

    /// The ring's half/difference angles are within 5e-7 rad (θ_h, θ_d) and
    /// 5e-7 rad + 1e-7 / sin θ_d (φ_d, which is undefined at θ_d = 0) of the
    /// f64 definition, for grazing and near-normal wo and half vectors on
    /// and near the pole; 0 exactly where wi is below the horizon.
    #[test]
    fn ring_angles_match_the_definition() {
        let tables = index_tables();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let (mut worst_d, mut worst_p, mut checked) = (0.0f64, 0.0f64, 0);
        let rad_per_u_d = std::f64::consts::FRAC_PI_2 / 90.0;
        let rad_per_u_p = std::f64::consts::PI / 180.0;
        for _ in 0..3000 {
            let (wo, half, columns) = random_case(&mut rng);
            let mut got = [[0.0f32; 8]; 3];
            for (t, g) in tables.iter().zip(&mut got) {
                t.luminance_half_ring(wo, half, &columns, g);
            }
            for (c, &(cos_p, sin_p)) in columns.iter().enumerate() {
                let h = Vec3::new(half.0 * cos_p, half.0 * sin_p, half.1);
                let wi_z = reflect(wo, h).z;
                let Some((u_h, u_d, u_p, sin_d)) = reference_indices(wo, h) else {
                    assert!(got.iter().all(|g| g[c] == 0.0), "{wo} {h}");
                    continue;
                };
                if wi_z < 1e-6 {
                    continue; // on the horizon either answer is right
                }
                let [gh, gd, gp] = [got[0][c], got[1][c], got[2][c]].map(|v| v as f64 - 1.0);
                assert!((gh - u_h).abs() <= 2e-5 + 1e-6 * u_h, "u_h {gh} vs {u_h}");
                let err_d = (gd - u_d).abs() * rad_per_u_d;
                assert!(err_d <= 5e-7, "θ_d off by {err_d} rad at {wo} {h}");
                worst_d = worst_d.max(err_d);
                // Trilinear blends entries 179 and 0 across the seam.
                if u_p < 178.99 && gp < 178.99 {
                    let e = (gp - u_p).abs();
                    let err_p = e.min(180.0 - e) * rad_per_u_p;
                    assert!(
                        err_p <= 5e-7 + 1e-7 / sin_d,
                        "φ_d off by {err_p} rad (sin θ_d {sin_d}) at {wo} {h}"
                    );
                    worst_p = worst_p.max(err_p * sin_d.min(1.0));
                }
                checked += 1;
            }
        }
        println!("worst θ_d error {worst_d:e} rad, worst φ_d error × sin θ_d {worst_p:e}");
        assert!(checked > 10_000, "{checked}");
    }

    /// Bounds on how far `eval`'s and the ring's continuous indices
    /// (u_h, u_d, u_p) can be apart at (θ_h, θ_d): `eval` rebuilds h from
    /// wi + wo, which fixes h to about ε_h = 2e-7 / cos θ_d rad (f32 unit
    /// vectors, |wi + wo| = 2 cos θ_d), and φ_h, hence φ_d, to ε_h / sin θ_h;
    /// both paths add up to 5e-7 rad of trigonometry (over sin θ_d for φ_d).
    /// Twice the sum, in index units.
    fn index_error_bounds(theta_h: f32, theta_d: f32) -> [f32; 3] {
        let half_pi = std::f32::consts::FRAC_PI_2;
        let eps_h = 2e-7 / theta_d.cos().max(1e-9);
        let trig = 5e-7;
        let d_theta_h = eps_h + trig;
        let d_theta_d = eps_h + trig;
        let d_phi_d = eps_h / theta_h.sin().max(1e-9) + trig / theta_d.sin().max(1e-9);
        let du_h = 45.0 / (theta_h.max(1e-12) * half_pi).sqrt() * d_theta_h;
        let per_rad = 90.0 / half_pi;
        [du_h, per_rad * d_theta_d, per_rad * d_phi_d].map(|d| 2.0 * d + 1e-5)
    }

    /// The ring agrees with `eval` on the tabulated nickel, where each
    /// column's tolerance comes from [`index_error_bounds`] at `eval`'s
    /// angles: trilinear values differ by at most 1e-5 relative (a luminance
    /// of interpolated colours against an interpolated luminance) plus, per
    /// axis, the index bound times the largest step between neighbouring
    /// entries of the cells within the bounds; `Nearest` and `Floor` read the very same entry
    /// unless one of `eval`'s continuous indices lies within its bound of a
    /// rounding (`Nearest`) or integer (`Floor`) boundary, where the two
    /// paths may name neighbouring entries. Near the pole and near
    /// θ_d = π/2 the bounds grow because `eval` is the less accurate of the
    /// two there (the ring is checked against f64 in
    /// [`ring_angles_match_the_definition`]).
    #[test]
    fn ring_agrees_with_eval() {
        let nickel = MerlTable::tabulate(&analytic::nickel());
        let plane = nickel.luminance_plane().to_vec();
        let entry =
            |i: usize, j: usize, k: usize| plane[plane_index(i.min(89), j.min(89), k % PHI_D_RES)];
        let mut rng = rand_pcg::Pcg64::seed_from_u64(12);
        let cases: Vec<_> = (0..3000).map(|_| random_case(&mut rng)).collect();
        for interpolation in [
            Interpolation::Trilinear,
            Interpolation::Nearest,
            Interpolation::Floor,
        ] {
            let table = nickel.clone().with_interpolation(interpolation);
            let (mut exact, mut flips, mut compared) = (0, 0, 0);
            for (wo, half, columns) in &cases {
                let mut got = [0.0f32; 8];
                table.luminance_half_ring(*wo, *half, columns, &mut got);
                for (&(cos_p, sin_p), &got) in columns.iter().zip(&got) {
                    let h = Vec3::new(half.0 * cos_p, half.0 * sin_p, half.1);
                    let wi = reflect(*wo, h);
                    let want = table.luminance(*wo, wi);
                    assert!(got.is_finite() && got >= 0.0);
                    if wi.z < 1e-6 {
                        continue; // on the horizon either answer is right
                    }
                    compared += 1;
                    let hd = HalfDiff::from_directions(wi.normalize(), *wo).unwrap();
                    let u = [
                        theta_h_index(hd.theta_h),
                        (hd.theta_d / std::f32::consts::FRAC_PI_2 * 90.0).min(89.0),
                        (hd.phi_d % std::f32::consts::PI) / std::f32::consts::PI * 180.0,
                    ];
                    let bounds = index_error_bounds(hd.theta_h, hd.theta_d);
                    let diff = (got - want).abs();
                    if diff <= 1e-5 * want {
                        exact += 1;
                        continue;
                    }
                    if interpolation == Interpolation::Trilinear {
                        // The largest step between neighbouring entries
                        // along each axis, over every cell either path can
                        // be in.
                        let span = |a: usize| {
                            let lo = (u[a] - bounds[a]).max(0.0) as usize;
                            lo..=((u[a] + bounds[a]) as usize + 1).min(lo + 4)
                        };
                        let mut steps = [0.0f32; 3];
                        for i in span(0) {
                            for j in span(1) {
                                for k in span(2) {
                                    let here = entry(i, j, k);
                                    let next = [
                                        entry(i + 1, j, k),
                                        entry(i, j + 1, k),
                                        entry(i, j, k + 1),
                                    ];
                                    for (s, n) in steps.iter_mut().zip(next) {
                                        *s = s.max((n - here).abs());
                                    }
                                }
                            }
                        }
                        let tolerance = 1e-5 * want
                            + steps.iter().zip(&bounds).map(|(s, b)| s * b).sum::<f32>();
                        assert!(
                            diff <= tolerance,
                            "{got} vs {want} (tolerance {tolerance}) at {wo} {h}"
                        );
                        continue;
                    }
                    let boundary = if interpolation == Interpolation::Nearest {
                        0.5
                    } else {
                        0.0
                    };
                    let near = u.iter().zip(&bounds).any(|(&u, &b)| {
                        let f = (u - boundary).rem_euclid(1.0);
                        f.min(1.0 - f) <= b
                    });
                    assert!(
                        near,
                        "{interpolation:?}: {got} vs {want}, indices {u:?}, bounds {bounds:?}"
                    );
                    flips += 1;
                }
            }
            println!(
                "{interpolation:?}: {compared} compared, {exact} within 1e-5, \
                 {flips} boundary flips"
            );
            // Most columns are far from the pole, θ_d = π/2 and cell
            // boundaries (a third of the cases here are near the pole, a
            // quarter grazing).
            assert!(compared > 10_000 && exact * 10 > 9 * compared);
        }
    }

    /// Inputs outside the fast path give what the default ring gives (one
    /// `eval` per column), and nothing NaN, infinite or negative.
    #[test]
    fn ring_bad_inputs() {
        let table = MerlTable::tabulate(&analytic::nickel());
        let reference = EvalOnly(&table);
        let wo = spherical_direction(0.7, 0.3);
        let unit = (0.4f32.sin(), 0.4f32.cos());
        let columns = [
            (1.0, 0.0),
            (0.0, 1.0),
            (2.0, 0.0),
            (f32::NAN, 0.0),
            (0.6, 0.8),
            (-1.0, 0.0),
        ];
        let cases = [
            (wo, unit),
            (Vec3::new(f32::NAN, 0.0, 1.0), unit),
            (Vec3::ZERO, unit),
            (Vec3::new(0.3, 0.0, -0.9), unit),
            (Vec3::new(0.0, 0.0, 1.0), unit),
            (wo * 3.0, unit),
            (wo, (-0.3, 0.95)),
            (wo, (0.6, 0.9)),
            (wo, (1.0, 0.0)),
            (wo, (f32::NAN, 1.0)),
            (wo, (0.0, 1.0)),
        ];
        for (wo, half) in cases {
            let mut got = [7.0f32; 6];
            let mut want = [7.0f32; 6];
            table.luminance_half_ring(wo, half, &columns, &mut got);
            reference.luminance_half_ring(wo, half, &columns, &mut want);
            for (g, w) in got.iter().zip(&want) {
                assert!(g.is_finite() && *g >= 0.0, "{wo} {half:?}: {got:?}");
                assert!(
                    (g - w).abs() <= 1e-4 * w,
                    "{wo} {half:?}: {got:?} vs {want:?}"
                );
            }
        }
        // A short output gets only its own length.
        let mut short = [7.0f32; 2];
        table.luminance_half_ring(wo, unit, &columns, &mut short);
        assert!(short.iter().all(|v| *v != 7.0));
        table.luminance_half_ring(wo, unit, &[], &mut short);
    }
}
