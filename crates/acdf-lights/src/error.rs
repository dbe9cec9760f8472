//! The error type of `acdf-lights`: everything that can be wrong with an
//! environment map file or table.

use std::path::PathBuf;

/// What can be wrong with an environment map. Every variant prints as one
/// line naming its cause.
#[derive(Debug, thiserror::Error)]
pub enum EnvError {
    /// The file could not be opened or read, or is larger than an image of
    /// the size its header declares can be (`acdf_io::fsio::Input`).
    #[error("{0}")]
    File(#[from] acdf_io::fsio::FsError),

    /// The file is not an image the decoder reads (unknown format, or a
    /// truncated or corrupt `.hdr`/`.exr`).
    #[error("{}: cannot decode the image: {message}", path.display())]
    Decode { path: PathBuf, message: String },

    /// The image has no texels.
    #[error("environment map has no texels ({width}x{height})")]
    Empty { width: usize, height: usize },

    /// The image is not a latitude-longitude map: its width is not twice
    /// its height (a 1x1 image, a constant environment, is accepted).
    #[error(
        "environment map is {width}x{height}: a latitude-longitude map is twice as wide as it is high"
    )]
    NotLatLong { width: usize, height: usize },

    /// The texel array's length does not match the dimensions.
    #[error("environment map of {width}x{height} needs {expected} texels, got {got}")]
    SizeMismatch {
        width: usize,
        height: usize,
        expected: usize,
        got: usize,
    },

    /// A texel channel is NaN or infinite: the map has no finite energy to
    /// sample. `count` is the number of such channel values in the map.
    #[error(
        "environment map texel (column {column}, row {row}) has a non-finite value {value} ({count} non-finite values in the map)"
    )]
    NonFinite {
        column: usize,
        row: usize,
        value: f32,
        count: usize,
    },

    /// A texel channel is negative: radiance cannot be. `count` is the
    /// number of negative channel values in the map.
    #[error(
        "environment map texel (column {column}, row {row}) has a negative value {value} ({count} negative values in the map)"
    )]
    Negative {
        column: usize,
        row: usize,
        value: f32,
        count: usize,
    },

    /// A table or distribution built from the map rejected its input.
    #[error("{0}")]
    Core(#[from] acdf_core::Error),
}

/// `Result` with [`EnvError`].
pub type Result<T> = std::result::Result<T, EnvError>;
