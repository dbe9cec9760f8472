//! The error type of `acdf-core`, shared by the distributions and samplers
//! that validate their input at construction.

/// Everything that can be wrong with the input to a distribution or sampler.
///
/// Construction validates; sampling never fails with an error (it returns a
/// documented result instead), so these only come out of constructors and
/// parsers of parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A table with no entries (or a zero dimension).
    #[error("{what}: the table is empty")]
    EmptyTable { what: &'static str },

    /// The table's length does not match the dimensions it was given with.
    #[error("{what}: expected {expected} values, got {got}")]
    SizeMismatch {
        what: &'static str,
        expected: usize,
        got: usize,
    },

    /// NaN or an infinity in a table.
    #[error("{what}: value {value:?} at index {index} is not finite")]
    NonFinite {
        what: &'static str,
        index: usize,
        value: f64,
    },

    /// A negative value in a table that must be a non-negative density.
    #[error("{what}: value {value:?} at index {index} is negative")]
    Negative {
        what: &'static str,
        index: usize,
        value: f64,
    },

    /// A parameter out of its domain (a resolution of zero, a tolerance that
    /// is negative or NaN, a mixing fraction outside [0, 1], ...).
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter { name: &'static str, reason: String },

    /// An allocation whose estimated size exceeds the memory limit
    /// (checked by `acdf_io::limits::check_memory`).
    #[error(
        "{what} would take about {} ({bytes} bytes), more than the memory limit of {} (acdf --memory-limit raises it)",
        format_bytes(*bytes),
        format_bytes(*limit)
    )]
    MemoryLimit {
        what: String,
        bytes: u64,
        limit: u64,
    },

    /// A material that is zero everywhere asked to be importance sampled:
    /// there is nothing to sample in proportion to.
    #[error("material `{material}` is zero everywhere (every value of its table is 0 or unmeasured): there is nothing to importance-sample")]
    ZeroMaterial { material: String },
}

/// `Result` with the crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

/// A byte count for people: `512 B`, `17.5 MiB`, `2.0 TiB`.
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 6] = ["KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    if bytes < 1024 {
        return format!("{bytes} B");
    }
    let mut value = bytes as f64 / 1024.0;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    format!("{value:.1} {}", UNITS[unit])
}
