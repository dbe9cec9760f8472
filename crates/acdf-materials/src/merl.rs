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

use std::io::Write;
use std::path::Path;

use acdf_core::{Brdf, HalfDiff, Rgb, Vec3};
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

fn io_error(path: &Path, source: std::io::Error) -> MaterialError {
    MaterialError::Io {
        path: path.to_owned(),
        source,
    }
}

fn name_from_path(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "merl".to_owned())
}

/// Check the header and the length of a MERL file's bytes; `origin` names
/// the file in errors.
fn check_layout(bytes: &[u8], origin: &Path) -> Result<(), MaterialError> {
    let path = || origin.to_owned();
    if bytes.is_empty() {
        return Err(MaterialError::EmptyFile { path: path() });
    }
    if bytes.len() < 12 {
        return Err(MaterialError::ShortHeader {
            path: path(),
            len: bytes.len(),
        });
    }
    let mut dims = [0i32; 3];
    for (d, chunk) in dims.iter_mut().zip(bytes[..12].chunks_exact(4)) {
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
    let got = bytes.len() as u64;
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

impl MerlTable {
    /// Read a MERL `.binary` file; the table is named after the file stem.
    ///
    /// Reads the whole file at once and converts it in one pass, so a 35 MB
    /// file loads in a small fraction of a second.
    pub fn read(path: impl AsRef<Path>) -> Result<MerlTable, MaterialError> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| io_error(path, e))?;
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

    /// Write the table as a MERL `.binary` file (see [`MerlTable::write_to`]).
    pub fn write(&self, path: impl AsRef<Path>) -> Result<(), MaterialError> {
        let path = path.as_ref();
        let file = std::fs::File::create(path).map_err(|e| io_error(path, e))?;
        self.write_to(std::io::BufWriter::new(file))
            .map_err(|e| io_error(path, e))
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
        let u_h = (theta_h.clamp(0.0, half_pi) / half_pi).sqrt() * THETA_H_RES as f32;
        let u_d = theta_d.clamp(0.0, half_pi) / half_pi * THETA_D_RES as f32;
        // Fold φ_d into [0, π) before scaling, where the subtraction is exact
        // to an ulp of π rather than of 360.
        let phi_d = acdf_core::geometry::wrap_angle(phi_d);
        let pi = std::f32::consts::PI;
        let phi_d = if phi_d >= pi { phi_d - pi } else { phi_d };
        let u_p = phi_d / pi * PHI_D_RES as f32;
        let u_h = u_h.min((THETA_H_RES - 1) as f32);
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
        assert!(matches!(missing, E::Io { .. }));
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
