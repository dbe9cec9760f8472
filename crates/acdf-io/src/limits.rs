//! The memory limit: every table, image and file body acdf allocates from
//! sizes that come from its input (a resolution, an image width, a file
//! header) is first estimated in bytes and checked here, so that a hostile
//! or mistaken size is refused with an error naming the figure instead of
//! exhausting memory.
//!
//! The limit is one number per process, [`DEFAULT_MEMORY_LIMIT`] until
//! [`set_memory_limit`] changes it (the `acdf` command's `--memory-limit`
//! flag does). Estimates count what one allocation of the checked object
//! needs, not the whole process.

use std::sync::atomic::{AtomicU64, Ordering};

use acdf_core::{Error, Result};

/// The limit a process starts with: 4 GiB.
pub const DEFAULT_MEMORY_LIMIT: u64 = 4 << 30;

static LIMIT: AtomicU64 = AtomicU64::new(DEFAULT_MEMORY_LIMIT);

/// The current limit in bytes (`u64::MAX` when unlimited).
pub fn memory_limit() -> u64 {
    LIMIT.load(Ordering::Relaxed)
}

/// Set the limit for the rest of the process; `u64::MAX` lifts it.
pub fn set_memory_limit(bytes: u64) {
    LIMIT.store(bytes, Ordering::Relaxed);
}

/// `Ok` if `bytes` is within the limit, otherwise [`Error::MemoryLimit`]
/// naming `what` and both figures.
pub fn check_memory(what: &str, bytes: u64) -> Result<()> {
    let limit = memory_limit();
    if bytes <= limit {
        Ok(())
    } else {
        Err(Error::MemoryLimit {
            what: what.to_string(),
            bytes,
            limit,
        })
    }
}

/// `count` elements of `size` bytes each, saturating at `u64::MAX` (which
/// no limit admits) instead of overflowing.
pub fn bytes_of(count: u64, size: u64) -> u64 {
    count.saturating_mul(size)
}

pub use acdf_core::error::format_bytes;

/// Parse a size as the `--memory-limit` flag takes it: a number of bytes,
/// optionally fractional and followed by `K`, `M`, `G` or `T` (powers of
/// 1024; `KiB`, `MB` and the like are read the same), or `unlimited`.
pub fn parse_size(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    if t.eq_ignore_ascii_case("unlimited") {
        return Ok(u64::MAX);
    }
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let shift = match unit.trim().to_ascii_uppercase().as_str() {
        "" | "B" => 0,
        "K" | "KB" | "KIB" => 10,
        "M" | "MB" | "MIB" => 20,
        "G" | "GB" | "GIB" => 30,
        "T" | "TB" | "TIB" => 40,
        other => {
            return Err(format!(
                "unknown unit `{other}`: use K, M, G or T (powers of 1024), or `unlimited`"
            ))
        }
    };
    let value: f64 = number
        .parse()
        .map_err(|_| format!("`{number}` is not a number of bytes"))?;
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0) {
        return Err("must be at least 1 byte".into());
    }
    if bytes >= u64::MAX as f64 {
        return Ok(u64::MAX);
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_units() {
        assert_eq!(parse_size("4096").unwrap(), 4096);
        assert_eq!(parse_size("4K").unwrap(), 4096);
        assert_eq!(parse_size("1.5G").unwrap(), 3 << 29);
        assert_eq!(parse_size("2TiB").unwrap(), 2 << 40);
        assert_eq!(parse_size("16 gb").unwrap(), 16 << 30);
        assert_eq!(parse_size("unlimited").unwrap(), u64::MAX);
        for bad in ["", "G", "-1G", "0", "1Q", "nan", "1e9"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn bytes_format_for_people() {
        assert_eq!(format_bytes(512), "512 B");
        assert_eq!(format_bytes(17 << 20 | 512 << 10), "17.5 MiB");
        assert_eq!(format_bytes(u64::MAX), "16.0 EiB");
    }

    #[test]
    fn the_check_names_the_figures() {
        let e = check_memory("a test table", DEFAULT_MEMORY_LIMIT.max(memory_limit()) + 1)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("a test table") && e.contains("memory limit"),
            "{e}"
        );
        assert!(check_memory("small", 1).is_ok());
    }
}
