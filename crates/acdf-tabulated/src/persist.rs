//! The sampler file format: built tabulated samplers kept on disk and loaded
//! without rebuilding.
//!
//! Building a sampler evaluates the BRDF on the whole 4D grid and simplifies
//! thousands of curves; a renderer wants to pay that once. This module is the
//! one place the file format is defined.
//!
//! # Layout (all integers and floats little-endian)
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `ACDFSMP\0` |
//! | 8 | 4 | format version (u32), currently [`FORMAT_VERSION`] |
//! | 12 | 8 | body length B (u64) |
//! | 20 | B | body |
//! | 20 + B | 4 | CRC-32 (IEEE) of bytes 0 .. 20 + B |
//!
//! The file is exactly 24 + B bytes long. The body is a sequence of fields:
//! - `string`: u32 byte length, then UTF-8 bytes;
//! - `f32 array`: u32 element count, then the elements;
//! - scalars as themselves (u8, u32, f32, f64).
//!
//! The body of a tabulated sampler, in order: the family (`string`:
//! `uniform` or `adaptive`), the sampler name (`string`, e.g.
//! `uniform` or `adaptive:dp`), the builder's parameters (written by the
//! builder, see [`Persist`]), the material name (`string`), whether it is
//! isotropic (u8, 0 or 1), the material's fingerprint (u64,
//! [`Brdf::fingerprint`]: a loaded sampler is used only with a material of
//! the same content), the resolution (4 × u32: θ_o, φ_o, θ_h, φ_h; one
//! φ_o cell means φ_h is relative to φ_o), the cosine mixing fraction (f32),
//! the slice count (u32, equal to θ_o × φ_o), then every slice's distribution
//! (written by [`Persist::encode`]), θ_o-major. All slices are built before saving, so a loaded
//! sampler never needs its BRDF.
//!
//! # Checks on load
//! Reading a file takes its 20-byte header first and compares the length
//! it announces with the file's (and with the memory limit) before the rest
//! is read. Then: magic, version (a newer version and version 1, which
//! recorded no fingerprint, are their own errors), exact length, checksum,
//! then every field: each length is checked against the bytes that remain
//! *before* anything is allocated, and each decoded table is validated as a
//! constructor would validate it. Any byte string gives a [`PersistError`],
//! never a panic.

use crate::{Resolution, SliceBuilder, SliceDistribution, TabulatedBrdfSampler};
use acdf_core::{Brdf, Rgb, Vec3};
use acdf_io::fsio::{write_atomic, FsError};
use std::path::Path;
use std::sync::Arc;

/// Magic bytes at the start of every sampler file.
pub const MAGIC: [u8; 8] = *b"ACDFSMP\0";

/// The format version this build writes and reads (2: with the material's
/// fingerprint; version 1 files are refused with a request to rebuild).
pub const FORMAT_VERSION: u32 = 2;

/// Bytes of the envelope around the body: magic, version, body length and
/// checksum.
pub const ENVELOPE_BYTES: usize = 8 + 4 + 8 + 4;

/// Everything that can be wrong with a sampler file.
#[derive(Debug, thiserror::Error)]
pub enum PersistError {
    /// Writing or reading the file failed, was refused or hit a bound
    /// ([`acdf_io::fsio`]).
    #[error("{0}")]
    File(#[from] FsError),
    /// The first 8 bytes are not [`MAGIC`]: not a sampler file.
    #[error("not an acdf sampler file (bad magic bytes)")]
    BadMagic,
    /// Written by a newer acdf.
    #[error("sampler file format version {found} is newer than this build reads ({supported})")]
    FutureVersion { found: u32, supported: u32 },
    /// A version number this build never wrote (0).
    #[error("sampler file format version {0} is not valid")]
    BadVersion(u32),
    /// Written by an older acdf, in a format that records no fingerprint of
    /// the material.
    #[error("sampler file format version {found} records no fingerprint of its material and is no longer read; rebuild the file with `acdf build` (format {supported})")]
    OldVersion { found: u32, supported: u32 },
    /// The file is shorter than its header says.
    #[error("truncated: the header announces {expected} bytes, the file has {found}")]
    Truncated { expected: u64, found: u64 },
    /// The file is longer than its header says.
    #[error("{extra} unexpected bytes after the end of the sampler data")]
    TrailingBytes { extra: u64 },
    /// The checksum does not match: the file was corrupted.
    #[error("checksum mismatch (stored {stored:#010x}, computed {computed:#010x}): the file is corrupted")]
    Checksum { stored: u32, computed: u32 },
    /// A field runs past the end of the body.
    #[error("field `{field}` needs {needed} bytes but only {remaining} remain")]
    FieldOverrun {
        field: &'static str,
        needed: u64,
        remaining: u64,
    },
    /// A field has a value that no valid writer produces.
    #[error("field `{field}` is invalid: {reason}")]
    Invalid { field: &'static str, reason: String },
    /// The file holds a different kind of sampler than the one asked for.
    #[error(
        "the file holds a sampler of kind {found:?}, but it was read as a {expected:?} sampler"
    )]
    WrongKind { found: String, expected: String },
    /// A size beyond the memory limit, or a stored value its constructor
    /// refuses.
    #[error("{0}")]
    Limit(acdf_core::Error),
    /// A decoded table fails the checks its constructor makes.
    #[error("stored table is invalid: {0}")]
    Table(#[from] acdf_core::Error),
}

/// Appends fields to a body.
#[derive(Debug, Default)]
pub struct ByteWriter {
    bytes: Vec<u8>,
}

impl ByteWriter {
    pub fn new() -> Self {
        Self::default()
    }
    pub fn u8(&mut self, v: u8) {
        self.bytes.push(v);
    }
    pub fn u32(&mut self, v: u32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f32(&mut self, v: f32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f64(&mut self, v: f64) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    /// A length as u32; tables in acdf never approach 2^32 elements.
    pub fn length(&mut self, n: usize) {
        self.u32(u32::try_from(n).expect("table longer than 2^32 elements"));
    }
    pub fn string(&mut self, s: &str) {
        self.length(s.len());
        self.bytes.extend_from_slice(s.as_bytes());
    }
    pub fn f32_array(&mut self, values: &[f32]) {
        self.length(values.len());
        self.bytes.reserve(values.len() * 4);
        for v in values {
            self.bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    pub fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }
}

/// Reads fields from a body, checking every length against what remains.
#[derive(Debug)]
pub struct ByteReader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> ByteReader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    pub fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn take(&mut self, field: &'static str, n: usize) -> Result<&'a [u8], PersistError> {
        if n > self.remaining() {
            return Err(PersistError::FieldOverrun {
                field,
                needed: n as u64,
                remaining: self.remaining() as u64,
            });
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    pub fn u8(&mut self, field: &'static str) -> Result<u8, PersistError> {
        Ok(self.take(field, 1)?[0])
    }
    pub fn u32(&mut self, field: &'static str) -> Result<u32, PersistError> {
        let b = self.take(field, 4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    pub fn f32(&mut self, field: &'static str) -> Result<f32, PersistError> {
        let b = self.take(field, 4)?;
        Ok(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    pub fn f64(&mut self, field: &'static str) -> Result<f64, PersistError> {
        let b = self.take(field, 8)?;
        Ok(f64::from_le_bytes(b.try_into().expect("8 bytes")))
    }
    pub fn u64(&mut self, field: &'static str) -> Result<u64, PersistError> {
        let b = self.take(field, 8)?;
        Ok(u64::from_le_bytes(b.try_into().expect("8 bytes")))
    }
    /// A u32 count of elements of `elem_bytes` each, checked against the bytes
    /// that remain so that a corrupt count never drives an allocation.
    pub fn count(&mut self, field: &'static str, elem_bytes: usize) -> Result<usize, PersistError> {
        let n = self.u32(field)? as usize;
        let needed = n as u64 * elem_bytes as u64;
        if needed > self.remaining() as u64 {
            return Err(PersistError::FieldOverrun {
                field,
                needed,
                remaining: self.remaining() as u64,
            });
        }
        Ok(n)
    }
    pub fn string(&mut self, field: &'static str) -> Result<String, PersistError> {
        let n = self.count(field, 1)?;
        let b = self.take(field, n)?;
        String::from_utf8(b.to_vec()).map_err(|_| PersistError::Invalid {
            field,
            reason: "not UTF-8".into(),
        })
    }
    /// Reads the kind string and checks that it is `expected`.
    pub fn kind(&mut self, expected: &str) -> Result<(), PersistError> {
        let found = self.string("kind")?;
        if found != expected {
            return Err(PersistError::WrongKind {
                found,
                expected: expected.to_string(),
            });
        }
        Ok(())
    }
    pub fn f32_array(&mut self, field: &'static str) -> Result<Vec<f32>, PersistError> {
        let n = self.count(field, 4)?;
        let b = self.take(field, n * 4)?;
        Ok(b.chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect())
    }
    /// Succeeds only if every byte was consumed.
    pub fn finish(self) -> Result<(), PersistError> {
        match self.remaining() {
            0 => Ok(()),
            extra => Err(PersistError::TrailingBytes {
                extra: extra as u64,
            }),
        }
    }
}

/// A value that can be written to and read back from a sampler file.
///
/// `decode(encode(x))` must give a value that samples bit-identically to `x`,
/// and `decode` must validate everything it reads.
pub trait Persist: Sized {
    fn encode(&self, w: &mut ByteWriter);
    fn decode(r: &mut ByteReader<'_>) -> Result<Self, PersistError>;
}

/// Wrap a body in the envelope: magic, version, length, body, checksum.
pub fn seal(body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len() + ENVELOPE_BYTES);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&(body.len() as u64).to_le_bytes());
    out.extend_from_slice(body);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Bytes of the header: magic, version and body length.
const HEADER_BYTES: usize = 8 + 4 + 8;

/// Check the header (the first [`HEADER_BYTES`] bytes of a file, or all of
/// a shorter one) and return the file length it announces.
fn check_header(bytes: &[u8]) -> Result<u64, PersistError> {
    if bytes.len() < 8 || bytes[..8] != MAGIC {
        return Err(PersistError::BadMagic);
    }
    if bytes.len() < HEADER_BYTES {
        return Err(PersistError::Truncated {
            expected: ENVELOPE_BYTES as u64,
            found: bytes.len() as u64,
        });
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if version > FORMAT_VERSION {
        return Err(PersistError::FutureVersion {
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    if version == 0 {
        return Err(PersistError::BadVersion(version));
    }
    if version < FORMAT_VERSION {
        return Err(PersistError::OldVersion {
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    let body_len = u64::from_le_bytes(bytes[12..20].try_into().expect("8 bytes"));
    Ok(body_len.saturating_add(ENVELOPE_BYTES as u64))
}

/// Check the envelope of `bytes` and return the body.
pub fn open(bytes: &[u8]) -> Result<&[u8], PersistError> {
    let header = HEADER_BYTES;
    let expected = check_header(&bytes[..bytes.len().min(HEADER_BYTES)])?;
    let body_len = expected - ENVELOPE_BYTES as u64;
    let found = bytes.len() as u64;
    if found < expected {
        return Err(PersistError::Truncated { expected, found });
    }
    if found > expected {
        return Err(PersistError::TrailingBytes {
            extra: found - expected,
        });
    }
    let end = header + body_len as usize;
    let stored = u32::from_le_bytes(bytes[end..end + 4].try_into().expect("4 bytes"));
    let computed = crc32fast::hash(&bytes[..end]);
    if stored != computed {
        return Err(PersistError::Checksum { stored, computed });
    }
    Ok(&bytes[header..end])
}

/// Read a whole sampler file: its header first, whose announced length is
/// compared with the file's size and with the memory limit before the rest
/// is read (a pipe or device is read no further than that length).
pub fn read_file(path: &Path) -> Result<Vec<u8>, PersistError> {
    let mut input = acdf_io::fsio::Input::open(path)?;
    let mut bytes = input.read_up_to(HEADER_BYTES)?;
    let expected = check_header(&bytes)?;
    if let Some(found) = input.len() {
        if found < expected {
            return Err(PersistError::Truncated { expected, found });
        }
        if found > expected {
            return Err(PersistError::TrailingBytes {
                extra: found - expected,
            });
        }
    }
    acdf_io::limits::check_memory(
        &format!("reading sampler file {}", path.display()),
        expected.saturating_mul(2),
    )
    .map_err(PersistError::Limit)?;
    let rest = input.read_rest(expected - bytes.len() as u64, "the length its header gives")?;
    bytes.extend_from_slice(&rest);
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn envelope_round_trip_and_corruption() {
        let mut w = ByteWriter::new();
        w.string("uniform");
        w.f32_array(&[1.0, 2.0, 3.0]);
        let file = seal(&w.into_bytes());
        let body = open(&file).unwrap();
        let mut r = ByteReader::new(body);
        assert_eq!(r.string("name").unwrap(), "uniform");
        assert_eq!(r.f32_array("a").unwrap(), vec![1.0, 2.0, 3.0]);
        r.finish().unwrap();

        // Every single-bit flip is caught, whichever error names it.
        for byte in 0..file.len() {
            for bit in 0..8 {
                let mut bad = file.clone();
                bad[byte] ^= 1 << bit;
                assert!(open(&bad).is_err(), "flip at {byte}:{bit} accepted");
            }
        }
        // Every truncation is caught.
        for len in 0..file.len() {
            assert!(open(&file[..len]).is_err());
        }
        let mut future = file.clone();
        future[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
        assert!(matches!(
            open(&future),
            Err(PersistError::FutureVersion { .. })
        ));
        let mut old = file.clone();
        old[8..12].copy_from_slice(&1u32.to_le_bytes());
        let err = open(&old).unwrap_err();
        assert!(
            matches!(err, PersistError::OldVersion { found: 1, .. }),
            "{err}"
        );
        assert!(err.to_string().contains("rebuild"), "{err}");
    }

    #[test]
    fn absurd_counts_are_rejected_before_allocation() {
        let mut w = ByteWriter::new();
        w.u32(u32::MAX);
        let body = w.into_bytes();
        let mut r = ByteReader::new(&body);
        assert!(matches!(
            r.f32_array("values"),
            Err(PersistError::FieldOverrun { .. })
        ));
    }
}

/// A builder whose samplers can be saved: its parameters are [`Persist`], and
/// `KIND` names the family (`uniform`, `adaptive`) in the file.
pub trait PersistBuilder: SliceBuilder + Persist {
    const KIND: &'static str;
}

/// The material of a sampler read from a file: its name, isotropy and
/// fingerprint, as recorded when it was saved. Every slice of such a
/// sampler is built, so the BRDF itself is never evaluated; `eval` returns
/// zero.
#[derive(Debug, Clone)]
pub struct StoredMaterial {
    pub name: String,
    pub isotropic: bool,
    /// [`Brdf::fingerprint`] of the material the sampler was built from.
    pub fingerprint: u64,
}

impl Brdf for StoredMaterial {
    fn name(&self) -> &str {
        &self.name
    }
    fn eval(&self, _: Vec3, _: Vec3) -> Rgb {
        Rgb::ZERO
    }
    fn is_isotropic(&self) -> bool {
        self.isotropic
    }
    fn fingerprint(&self) -> u64 {
        self.fingerprint
    }
}

/// The family (`uniform`, `adaptive`, ...) of the sampler in a file, after
/// checking its envelope; lets a caller pick the type to load it as.
pub fn peek_kind(bytes: &[u8]) -> Result<String, PersistError> {
    ByteReader::new(open(bytes)?).string("kind")
}

impl<B> TabulatedBrdfSampler<B>
where
    B: PersistBuilder,
    B::Dist: Persist,
{
    /// The sampler as a file image (see the module documentation); builds
    /// every slice first.
    pub fn to_bytes(&self) -> Result<Vec<u8>, PersistError> {
        self.build_all()?;
        let mut w = ByteWriter::new();
        w.string(B::KIND);
        w.string(&self.builder().name());
        self.builder().encode(&mut w);
        w.string(self.brdf().name());
        w.u8(self.brdf().is_isotropic() as u8);
        w.u64(self.brdf().fingerprint());
        let r = self.resolution();
        for n in [r.theta_o, r.phi_o, r.theta_h, r.phi_h] {
            w.length(n);
        }
        w.f32(self.cosine_mix());
        let slices: Vec<&B::Dist> = self.built_slices().collect();
        w.length(slices.len());
        for slice in slices {
            slice.encode(&mut w);
        }
        Ok(seal(&w.into_bytes()))
    }

    /// Save to `path` atomically ([`acdf_io::fsio::write_atomic`]).
    pub fn save(&self, path: &Path) -> Result<(), PersistError> {
        let bytes = self.to_bytes()?;
        Ok(write_atomic(path, |w| w.write_all(&bytes))?)
    }

    /// Read a sampler from a file image, checking everything (see the module
    /// documentation).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, PersistError> {
        let mut r = ByteReader::new(open(bytes)?);
        r.kind(B::KIND)?;
        let name = r.string("sampler name")?;
        let builder = B::decode(&mut r)?;
        if builder.name() != name {
            return Err(PersistError::Invalid {
                field: "sampler name",
                reason: format!(
                    "`{name}` does not match its parameters (`{}`)",
                    builder.name()
                ),
            });
        }
        let material = r.string("material")?;
        let isotropic = match r.u8("isotropic")? {
            0 => false,
            1 => true,
            other => {
                return Err(PersistError::Invalid {
                    field: "isotropic",
                    reason: format!("{other} is not 0 or 1"),
                })
            }
        };
        let fingerprint = r.u64("fingerprint")?;
        let mut counts = [0usize; 4];
        for c in &mut counts {
            *c = r.u32("resolution")? as usize;
        }
        let resolution = Resolution::new(counts[0], counts[1], counts[2], counts[3])?;
        let cosine_mix = r.f32("cosine mix")?;
        // Each slice takes at least one byte, so the count is checked against
        // the bytes left before the vector is allocated.
        let count = r.count("slices", 1)?;
        if count != resolution.slices() {
            return Err(PersistError::Invalid {
                field: "slices",
                reason: format!("{count} slices for resolution {resolution}"),
            });
        }
        let mut slices = Vec::with_capacity(count);
        for _ in 0..count {
            slices.push(B::Dist::decode(&mut r)?);
        }
        r.finish()?;
        // The resolution's θ_h and φ_h are not implied by the slice count:
        // each slice's own table must fit them.
        if let Some(k) = slices
            .iter()
            .position(|d| !d.fits_grid(resolution.phi_h, resolution.theta_h))
        {
            return Err(PersistError::Invalid {
                field: "resolution",
                reason: format!(
                    "θ_h × φ_h = {} × {} does not fit the table of slice {k}",
                    resolution.theta_h, resolution.phi_h
                ),
            });
        }
        let brdf = Arc::new(StoredMaterial {
            name: material,
            isotropic,
            fingerprint,
        });
        let limit_or_table = |e| match e {
            e @ acdf_core::Error::MemoryLimit { .. } => PersistError::Limit(e),
            e => PersistError::Table(e),
        };
        Self::from_built_slices(brdf, resolution, builder, slices)
            .and_then(|s| s.with_cosine_mix(cosine_mix))
            .map_err(limit_or_table)
    }

    /// Load a sampler saved with [`save`](Self::save).
    pub fn load(path: &Path) -> Result<Self, PersistError> {
        Self::from_bytes(&read_file(path)?)
    }
}
