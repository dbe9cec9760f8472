//! The `tensor_file` container (version 1.x, little-endian) that stores RGL
//! `.bsdf` materials: a magic string, a version, a list of named,
//! typed, n-dimensional fields, each pointing at its data by absolute offset.
//!
//! Parsing never trusts a count or a size from the header: every descriptor is
//! read byte by byte against the remaining input, every shape product and byte
//! length is computed with overflow checks and compared with the file length,
//! and only then is memory allocated for a field's data.

use super::RglError;
use std::path::{Path, PathBuf};

/// The 12 bytes every tensor file starts with.
pub const TENSOR_MAGIC: &[u8; 12] = b"tensor_file\0";

/// The element type of a field, with its on-disk code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dtype {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F16,
    F32,
    F64,
}

impl Dtype {
    /// The dtype for an on-disk code (1 = u8 ... 11 = f64).
    pub fn from_code(code: u8) -> Option<Dtype> {
        use Dtype::*;
        Some(match code {
            1 => U8,
            2 => I8,
            3 => U16,
            4 => I16,
            5 => U32,
            6 => I32,
            7 => U64,
            8 => I64,
            9 => F16,
            10 => F32,
            11 => F64,
            _ => return None,
        })
    }

    /// The on-disk code of this dtype.
    pub fn code(self) -> u8 {
        self as u8 + 1
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        use Dtype::*;
        match self {
            U8 | I8 => 1,
            U16 | I16 | F16 => 2,
            U32 | I32 | F32 => 4,
            U64 | I64 | F64 => 8,
        }
    }

    /// Whether the elements are floating point.
    pub fn is_float(self) -> bool {
        matches!(self, Dtype::F16 | Dtype::F32 | Dtype::F64)
    }
}

/// One named field: its type, its shape (C order) and a copy of its bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct TensorField {
    pub name: String,
    pub dtype: Dtype,
    pub shape: Vec<usize>,
    /// The absolute file offset the data was read from.
    pub offset: u64,
    bytes: Vec<u8>,
}

impl TensorField {
    /// The number of elements, the product of the shape.
    pub fn len(&self) -> usize {
        self.bytes.len() / self.dtype.size()
    }

    /// Whether the field holds no element.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// The raw little-endian bytes of the data.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Every element converted to `f64` (exact for all dtypes but the 64-bit
    /// integers above 2^53).
    pub fn to_f64(&self) -> Vec<f64> {
        let size = self.dtype.size();
        self.bytes
            .chunks_exact(size)
            .map(|c| element_to_f64(self.dtype, c))
            .collect()
    }

    /// Every element converted to `f32` (rounded to nearest).
    pub fn to_f32(&self) -> Vec<f32> {
        if self.dtype == Dtype::F32 {
            return self
                .bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
        }
        self.to_f64().into_iter().map(|v| v as f32).collect()
    }
}

fn element_to_f64(dtype: Dtype, c: &[u8]) -> f64 {
    let mut b = [0u8; 8];
    b[..c.len()].copy_from_slice(c);
    match dtype {
        Dtype::U8 => b[0] as f64,
        Dtype::I8 => b[0] as i8 as f64,
        Dtype::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
        Dtype::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
        Dtype::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        Dtype::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        Dtype::U64 => u64::from_le_bytes(b) as f64,
        Dtype::I64 => i64::from_le_bytes(b) as f64,
        Dtype::F16 => f16_to_f64(u16::from_le_bytes([b[0], b[1]])),
        Dtype::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        Dtype::F64 => f64::from_le_bytes(b),
    }
}

/// IEEE 754 binary16 to f64: sign · 2^(e-15) · (1 + m/1024), subnormals
/// 2^-14 · m/1024, and e = 31 for infinities and NaN.
fn f16_to_f64(h: u16) -> f64 {
    let exponent = ((h >> 10) & 0x1f) as i32;
    let mantissa = (h & 0x3ff) as f64;
    let magnitude = match exponent {
        0 => mantissa * 2f64.powi(-24),
        31 if mantissa == 0.0 => f64::INFINITY,
        31 => f64::NAN,
        e => (1.0 + mantissa / 1024.0) * 2f64.powi(e - 15),
    };
    if h & 0x8000 != 0 {
        -magnitude
    } else {
        magnitude
    }
}

/// A parsed tensor file: its fields in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct TensorFile {
    path: Option<PathBuf>,
    major: u8,
    minor: u8,
    fields: Vec<TensorField>,
}

/// A cursor over the header that fails instead of reading past the end.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, field: usize, what: &str) -> Result<&'a [u8], RglError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        match end {
            Some(end) => {
                let s = &self.bytes[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(RglError::Field {
                index: field,
                reason: format!(
                    "{what} at byte {} runs past the end of the file ({} bytes)",
                    self.pos,
                    self.bytes.len()
                ),
            }),
        }
    }

    fn u8(&mut self, field: usize, what: &str) -> Result<u8, RglError> {
        Ok(self.take(1, field, what)?[0])
    }

    fn u16(&mut self, field: usize, what: &str) -> Result<u16, RglError> {
        let b = self.take(2, field, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u64(&mut self, field: usize, what: &str) -> Result<u64, RglError> {
        let b = self.take(8, field, what)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
}

impl TensorFile {
    /// Read and parse the file at `path`; errors name the file.
    ///
    /// The magic string is read and checked before anything else, so that
    /// `/dev/zero` or a file of another kind is refused after 12 bytes; the
    /// rest is read up to the memory limit (a regular file larger than that
    /// is refused from its size, before it is read).
    pub fn read(path: impl AsRef<Path>) -> Result<TensorFile, RglError> {
        let path = path.as_ref();
        let mut input = acdf_io::fsio::Input::open(path)?;
        let mut bytes = input.read_up_to(TENSOR_MAGIC.len())?;
        if bytes.as_slice() != TENSOR_MAGIC {
            return Err(RglError::BadMagic.in_file(path));
        }
        let limit = acdf_io::limits::memory_limit();
        let rest = input.read_rest(
            limit / 2,
            "half the memory limit (the tables take as much again; acdf --memory-limit raises it)",
        )?;
        bytes.extend_from_slice(&rest);
        let mut file = TensorFile::from_bytes(&bytes).map_err(|e| e.in_file(path))?;
        file.path = Some(path.to_path_buf());
        Ok(file)
    }

    /// Parse a tensor file held in memory.
    pub fn from_bytes(bytes: &[u8]) -> Result<TensorFile, RglError> {
        if bytes.len() < TENSOR_MAGIC.len() || &bytes[..TENSOR_MAGIC.len()] != TENSOR_MAGIC {
            return Err(RglError::BadMagic);
        }
        let file_len = bytes.len() as u64;
        let mut r = Reader {
            bytes,
            pos: TENSOR_MAGIC.len(),
        };
        let header = |r: &mut Reader<'_>| -> Result<(u8, u8, u32), RglError> {
            let major = r.u8(0, "the version")?;
            let minor = r.u8(0, "the version")?;
            let b = r.take(4, 0, "the field count")?;
            Ok((major, minor, u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
        };
        let (major, minor, count) = header(&mut r).map_err(|_| RglError::Field {
            index: 0,
            reason: "the file ends inside the version and field count".into(),
        })?;
        if major != 1 {
            return Err(RglError::Version { major, minor });
        }
        // No capacity from `count`: each descriptor is read against the bytes
        // that are really there, so a huge count fails on the first missing one.
        let mut fields: Vec<TensorField> = Vec::new();
        for index in 0..count as usize {
            let name_len = r.u16(index, "the name length")? as usize;
            let name = std::str::from_utf8(r.take(name_len, index, "the name")?)
                .map_err(|_| RglError::Field {
                    index,
                    reason: "the name is not UTF-8".into(),
                })?
                .to_string();
            let ndim = r.u16(index, "the dimension count")? as usize;
            let code = r.u8(index, "the dtype")?;
            let offset = r.u64(index, "the data offset")?;
            let dtype = Dtype::from_code(code).ok_or_else(|| RglError::Dtype {
                field: name.clone(),
                reason: format!("unknown dtype code {code}"),
            })?;
            let mut shape = Vec::new();
            let mut count_elems: u64 = 1;
            for _ in 0..ndim {
                let n = r.u64(index, "the shape")?;
                count_elems = count_elems.checked_mul(n).ok_or_else(|| RglError::Shape {
                    field: name.clone(),
                    reason: "the product of the shape overflows".into(),
                })?;
                shape.push(usize::try_from(n).map_err(|_| RglError::Shape {
                    field: name.clone(),
                    reason: format!("dimension {n} does not fit in memory"),
                })?);
            }
            let len = count_elems
                .checked_mul(dtype.size() as u64)
                .ok_or_else(|| RglError::Shape {
                    field: name.clone(),
                    reason: "the byte size of the data overflows".into(),
                })?;
            let end = offset.checked_add(len).filter(|&e| e <= file_len);
            let Some(end) = end else {
                return Err(RglError::OutOfBounds {
                    field: name,
                    offset,
                    len,
                    file_len,
                });
            };
            if fields.iter().any(|f| f.name == name) {
                return Err(RglError::Field {
                    index,
                    reason: format!("the name `{name}` appears twice"),
                });
            }
            // Checked against the file length above, so these casts are exact.
            let data = bytes[offset as usize..end as usize].to_vec();
            fields.push(TensorField {
                name,
                dtype,
                shape,
                offset,
                bytes: data,
            });
        }
        check_layout(&fields, r.pos as u64)?;
        Ok(TensorFile {
            path: None,
            major,
            minor,
            fields,
        })
    }

    /// The file the data came from, if it was read from one.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// The format version (major, minor) from the header.
    pub fn version(&self) -> (u8, u8) {
        (self.major, self.minor)
    }

    /// All fields in file order.
    pub fn fields(&self) -> &[TensorField] {
        &self.fields
    }

    /// The field called `name`, if present.
    pub fn field(&self, name: &str) -> Option<&TensorField> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The field called `name`, or [`RglError::MissingField`].
    pub fn require(&self, name: &str) -> Result<&TensorField, RglError> {
        self.field(name)
            .ok_or_else(|| RglError::MissingField(name.to_string()))
    }
}

/// Every field's data lies after the header (which ends at `header_end`)
/// and no two fields share a byte: a block that points into the header or
/// into another field is a corrupt or crafted file.
fn check_layout(fields: &[TensorField], header_end: u64) -> Result<(), RglError> {
    let mut blocks: Vec<(u64, u64, &str)> = fields
        .iter()
        .filter(|f| !f.bytes.is_empty())
        .map(|f| (f.offset, f.offset + f.bytes.len() as u64, f.name.as_str()))
        .collect();
    if let Some(&(offset, _, name)) = blocks.iter().find(|b| b.0 < header_end) {
        return Err(RglError::Overlap {
            field: name.to_string(),
            offset,
            other: format!("the header (bytes 0 to {header_end})"),
        });
    }
    blocks.sort_unstable();
    for pair in blocks.windows(2) {
        let ((_, end, first), (offset, _, second)) = (pair[0], pair[1]);
        if offset < end {
            return Err(RglError::Overlap {
                field: second.to_string(),
                offset,
                other: format!("field `{first}` (which ends at byte {end})"),
            });
        }
    }
    Ok(())
}

/// Serialise fields into a version 1.0 tensor file, data blocks 8-byte
/// aligned after the header. Used by tests to build valid and broken files.
pub fn write_tensor_file(fields: &[(&str, Dtype, &[usize], &[u8])]) -> Vec<u8> {
    let mut header = Vec::new();
    header.extend_from_slice(TENSOR_MAGIC);
    header.extend_from_slice(&[1, 0]);
    header.extend_from_slice(&(fields.len() as u32).to_le_bytes());
    let header_len = header.len()
        + fields
            .iter()
            .map(|(n, _, s, _)| 2 + n.len() + 2 + 1 + 8 + 8 * s.len())
            .sum::<usize>();
    let mut offset = header_len.next_multiple_of(8);
    let mut data = Vec::new();
    for (name, dtype, shape, bytes) in fields {
        header.extend_from_slice(&(name.len() as u16).to_le_bytes());
        header.extend_from_slice(name.as_bytes());
        header.extend_from_slice(&(shape.len() as u16).to_le_bytes());
        header.push(dtype.code());
        header.extend_from_slice(&(offset as u64).to_le_bytes());
        for &n in shape.iter() {
            header.extend_from_slice(&(n as u64).to_le_bytes());
        }
        let padded = bytes.len().next_multiple_of(8);
        data.extend_from_slice(bytes);
        data.resize(data.len() + padded - bytes.len(), 0);
        offset += padded;
    }
    header.resize(header_len.next_multiple_of(8), 0);
    header.extend_from_slice(&data);
    header
}
