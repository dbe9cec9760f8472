//! The lobes sampler's file: the envelope of `acdf_tabulated::persist`
//! (magic, version, length, checksum) around a body of, in order: the kind
//! (`string`, [`KIND`]), the layout version (u32, [`LOBES_VERSION`]), the
//! material's name (`string`), whether it is isotropic (u8, 0 or 1), its
//! fingerprint (u64), the lobe count n (u32), the cosine lobe's weight (f32)
//! and n pairs (weight, α) (f32). Loading checks every field and validates
//! the parameters as [`Lobes::new`] does: a NaN, a count out of range or
//! weights that do not sum to 1 are typed errors, never a sampler.

use crate::{Lobes, LobesSampler, MAX_LOBES};
use acdf_io::fsio::write_atomic;
use acdf_tabulated::persist::{
    open, read_file, seal, ByteReader, ByteWriter, PersistError, StoredMaterial,
};
use std::path::Path;

/// The kind recorded in the file, and the family's name.
pub const KIND: &str = "lobes";

/// The layout version of the body this build writes and reads.
pub const LOBES_VERSION: u32 = 1;

fn invalid(field: &'static str, reason: String) -> PersistError {
    PersistError::Invalid { field, reason }
}

impl LobesSampler {
    /// The sampler as a file image (module documentation).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = ByteWriter::new();
        w.string(KIND);
        w.u32(LOBES_VERSION);
        let m = self.material();
        w.string(&m.name);
        w.u8(m.isotropic as u8);
        w.u64(m.fingerprint);
        let lobes = self.lobes();
        w.length(lobes.count());
        w.f32(lobes.diffuse());
        for (weight, alpha) in lobes.lobes() {
            w.f32(weight);
            w.f32(alpha);
        }
        seal(&w.into_bytes())
    }

    /// Save to `path` atomically ([`acdf_io::fsio::write_atomic`]).
    pub fn save(&self, path: &Path) -> Result<(), PersistError> {
        let bytes = self.to_bytes();
        Ok(write_atomic(path, |w| w.write_all(&bytes))?)
    }

    /// Read a sampler from a file image, checking every field.
    pub fn from_bytes(bytes: &[u8]) -> Result<LobesSampler, PersistError> {
        let mut r = ByteReader::new(open(bytes)?);
        r.kind(KIND)?;
        let version = r.u32("lobes version")?;
        if version != LOBES_VERSION {
            return Err(invalid(
                "lobes version",
                format!("{version} is not the layout this build reads ({LOBES_VERSION})"),
            ));
        }
        let name = r.string("material")?;
        let isotropic = match r.u8("isotropic")? {
            0 => false,
            1 => true,
            other => return Err(invalid("isotropic", format!("{other} is not 0 or 1"))),
        };
        let fingerprint = r.u64("fingerprint")?;
        let count = r.count("lobe count", 8)?;
        if count > MAX_LOBES {
            return Err(invalid(
                "lobe count",
                format!("{count} is not 0 to {MAX_LOBES}"),
            ));
        }
        let diffuse = r.f32("diffuse weight")?;
        let mut lobes = Vec::with_capacity(count);
        for _ in 0..count {
            lobes.push((r.f32("lobe weight")?, r.f32("lobe roughness")?));
        }
        r.finish()?;
        let lobes = Lobes::new(diffuse, &lobes)?;
        Ok(LobesSampler::from_lobes(
            lobes,
            StoredMaterial {
                name,
                isotropic,
                fingerprint,
            },
        ))
    }

    /// Load a sampler saved with [`save`](Self::save).
    pub fn load(path: &Path) -> Result<LobesSampler, PersistError> {
        Self::from_bytes(&read_file(path)?)
    }
}
