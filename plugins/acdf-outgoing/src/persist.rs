//! The outgoing sampler in the sampler file format of
//! [`acdf_tabulated::persist`] (envelope, checksum and version checks are
//! that module's).
//!
//! The body, in order: the kind `outgoing` (`string`), the layout version
//! of this body (u32, [`OUTGOING_VERSION`]; the anisotropic sampler's
//! layout, [`ANISOTROPIC_VERSION`](super::anisotropic::persist::ANISOTROPIC_VERSION),
//! is read by [`super::anisotropic::persist`]), the sampler name (`string`,
//! e.g. `outgoing:chi2`), the simplifier name (`string`), its tolerance
//! (f64), the θ_o budget (f64), the fine slice count (u32), the material
//! name (`string`), whether it is isotropic (u8, 1), its fingerprint (u64),
//! the half-vector cells θ_h and φ_h (2 × u32), the cosine mixing fraction
//! (f32), the breakpoints u_o (`f32 array`), then the slices' shared grid
//! and per breakpoint its slice's CDF values without the end vertices of
//! any curve ([`CompactSlices`]), each an array of a u32 count and the
//! values: the inner marginal positions (u16), per marginal segment the
//! count of its conditional's inner vertices (u8, 255 for none), the inner
//! conditional positions (u8), then per slice its inner marginal then
//! conditional CDF values (u16).
//!
//! `write_slice` and `read_slice` hold the anisotropic sampler's
//! slices, each with vertices of its own: the marginal positions, the
//! marginal CDF values, the offsets, the conditional positions and the
//! conditional CDF values.

use super::{CompactSlices, OutgoingBuilder, OutgoingSampler, PackedCdf2D, SharedSlices};
use acdf_adaptive_cdf::simplify::simplifier_by_name;
use acdf_core::BxdfSampler;
use acdf_io::fsio::write_atomic;
use acdf_tabulated::persist::{
    open, read_file, seal, ByteReader, ByteWriter, PersistError, StoredMaterial,
};
use acdf_tabulated::Resolution;
use std::path::Path;
use std::sync::Arc;

/// The kind recorded in the file.
pub const KIND: &str = "outgoing";

/// The layout version of the body this build writes and reads: 6, whose
/// slices share one grid, blend linearly in cos θ_o and store no curve's
/// end vertices. The earlier isotropic layouts are refused with the
/// reason, and the sampler is built again: 1 blended linearly in u_o, 3
/// kept each slice's own vertices, 5 stored the end vertices (2, 4 and 7 are
/// the anisotropic layouts).
pub const OUTGOING_VERSION: u32 = 6;

pub(crate) fn write_u16s(w: &mut ByteWriter, values: &[u16]) {
    w.length(values.len());
    for &v in values {
        let [a, b] = v.to_le_bytes();
        w.u8(a);
        w.u8(b);
    }
}

pub(crate) fn write_u8s(w: &mut ByteWriter, values: &[u8]) {
    w.length(values.len());
    for &v in values {
        w.u8(v);
    }
}

pub(crate) fn read_u8s(
    r: &mut ByteReader<'_>,
    field: &'static str,
) -> Result<Vec<u8>, PersistError> {
    let n = r.count(field, 1)?;
    (0..n).map(|_| r.u8(field)).collect()
}

pub(crate) fn read_u16s(
    r: &mut ByteReader<'_>,
    field: &'static str,
) -> Result<Vec<u16>, PersistError> {
    let n = r.count(field, 2)?;
    (0..n)
        .map(|_| Ok(u16::from_le_bytes([r.u8(field)?, r.u8(field)?])))
        .collect()
}

pub(crate) fn invalid(field: &'static str, reason: String) -> PersistError {
    PersistError::Invalid { field, reason }
}

/// Write one slice's five arrays, in the order the module documentation gives.
pub(crate) fn write_slice(w: &mut ByteWriter, s: &PackedCdf2D) {
    write_u16s(w, s.marginal_pos());
    write_u16s(w, s.marginal_cdf());
    write_u16s(w, s.offsets());
    write_u8s(w, s.conditional_pos());
    write_u16s(w, s.conditional_cdf());
}

/// Read one slice written by [`write_slice`] and check it against the
/// half-vector grid (`n_phi_h` × `n_theta_h` cells).
pub(crate) fn read_slice(
    r: &mut ByteReader<'_>,
    n_phi_h: usize,
    n_theta_h: usize,
) -> Result<PackedCdf2D, PersistError> {
    let marginal_pos = read_u16s(r, "marginal positions")?;
    let marginal_cdf = read_u16s(r, "marginal CDF")?;
    let offsets = read_u16s(r, "offsets")?;
    let conditional_pos = read_u8s(r, "conditional positions")?;
    let conditional_cdf = read_u16s(r, "conditional CDF")?;
    let slice = PackedCdf2D::from_arrays(
        &marginal_pos,
        &marginal_cdf,
        &offsets,
        conditional_pos,
        &conditional_cdf,
    );
    slice
        .validate(n_phi_h, n_theta_h)
        .map_err(|reason| invalid("slice", reason))?;
    Ok(slice)
}

impl OutgoingSampler {
    /// The sampler as a file image (module documentation).
    pub fn to_bytes(&self) -> Vec<u8> {
        self.to_bytes_as(OUTGOING_VERSION)
    }

    /// The file image with `version` in its layout field (the tests write
    /// other layouts' numbers with it).
    pub(crate) fn to_bytes_as(&self, version: u32) -> Vec<u8> {
        let mut w = ByteWriter::new();
        w.string(KIND);
        w.u32(version);
        w.string(self.name());
        let b = &self.builder;
        w.string(b.simplifier.name());
        w.f64(b.tolerance);
        w.f64(b.budget);
        w.length(b.fine);
        w.string(self.brdf.name());
        w.u8(self.brdf.is_isotropic() as u8);
        w.u64(self.brdf.fingerprint());
        w.length(self.n_theta_h);
        w.length(self.n_phi_h);
        w.f32(self.cosine_fraction);
        w.f32_array(&self.breakpoints);
        let c = self.slices.compact();
        write_u16s(&mut w, &c.marginal_inner);
        write_u8s(&mut w, &c.counts);
        write_u8s(&mut w, &c.conditional_inner);
        for values in &c.slice_inner {
            write_u16s(&mut w, values);
        }
        seal(&w.into_bytes())
    }

    /// Save to `path` atomically ([`acdf_io::fsio::write_atomic`]).
    pub fn save(&self, path: &Path) -> Result<(), PersistError> {
        let bytes = self.to_bytes();
        Ok(write_atomic(path, |w| w.write_all(&bytes))?)
    }

    /// Read a sampler from a file image, checking every field.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, PersistError> {
        let mut r = ByteReader::new(open(bytes)?);
        r.kind(KIND)?;
        let version = r.u32("outgoing version")?;
        if version != OUTGOING_VERSION {
            let why = match version {
                1 => " (layout 1 blends its slices linearly in u_o: build the sampler again)",
                3 => " (layout 3 keeps each slice's own vertices: build the sampler again)",
                5 => " (layout 5 stores every curve's end vertices: build the sampler again)",
                _ => "",
            };
            return Err(invalid(
                "outgoing version",
                format!("{version} is not the layout this build reads ({OUTGOING_VERSION}){why}"),
            ));
        }
        let name = r.string("sampler name")?;
        let simplifier = simplifier_by_name(&r.string("simplifier")?)?;
        let tolerance = r.f64("tolerance")?;
        let budget = r.f64("budget")?;
        let fine = r.u32("fine slices")? as usize;
        let builder = OutgoingBuilder {
            simplifier,
            max_bytes: None,
            tolerance,
            budget,
            fine,
        };
        builder.validate().map_err(PersistError::Table)?;
        if builder.name() != name {
            return Err(invalid(
                "sampler name",
                format!(
                    "`{name}` does not match its parameters (`{}`)",
                    builder.name()
                ),
            ));
        }
        let material = r.string("material")?;
        if r.u8("isotropic")? != 1 {
            return Err(invalid(
                "isotropic",
                "an outgoing sampler is isotropic".into(),
            ));
        }
        let fingerprint = r.u64("fingerprint")?;
        let n_theta_h = r.u32("theta_h cells")? as usize;
        let n_phi_h = r.u32("phi_h cells")? as usize;
        Resolution::new(1, 1, n_theta_h, n_phi_h).map_err(PersistError::Table)?;
        let cosine_mix = r.f32("cosine mix")?;
        let breakpoints = r.f32_array("breakpoints")?;
        let n = breakpoints.len();
        if n == 0
            || breakpoints[0] != 0.0
            || breakpoints[n - 1] != 1.0
            || breakpoints.windows(2).any(|w| !(w[1] > w[0]))
        {
            return Err(invalid("breakpoints", "not increasing from 0 to 1".into()));
        }
        let marginal_inner = read_u16s(&mut r, "marginal positions")?;
        let counts = read_u8s(&mut r, "conditional counts")?;
        let conditional_inner = read_u8s(&mut r, "conditional positions")?;
        let mut slice_inner = Vec::with_capacity(n.min(r.remaining()));
        for _ in 0..n {
            slice_inner.push(read_u16s(&mut r, "slice CDF")?);
        }
        r.finish()?;
        let compact = CompactSlices {
            marginal_inner,
            counts,
            conditional_inner,
            slice_inner,
        };
        let slices = SharedSlices::from_compact(&compact, n_phi_h, n_theta_h)
            .map_err(|reason| invalid("slices", reason))?;
        let brdf = Arc::new(StoredMaterial {
            name: material,
            isotropic: true,
            fingerprint,
        });
        OutgoingSampler::from_parts(brdf, builder, n_theta_h, n_phi_h, breakpoints, slices)
            .with_cosine_mix(cosine_mix)
            .map_err(PersistError::Table)
    }

    /// Load a sampler saved with [`save`](Self::save).
    pub fn load(path: &Path) -> Result<Self, PersistError> {
        Self::from_bytes(&read_file(path)?)
    }
}
