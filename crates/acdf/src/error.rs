//! The one error type of the `acdf` facade and command. Every variant prints
//! as a single line, so the command can report any failure as one line on
//! stderr.

use std::path::PathBuf;

/// Everything that can go wrong while naming, loading, measuring or writing.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// `--material` named nothing acdf knows.
    #[error("unknown material `{spec}`: {reason}")]
    UnknownMaterial { spec: String, reason: String },

    /// A material was named correctly but could not be loaded.
    #[error("material `{spec}`: {message}")]
    Material { spec: String, message: String },

    /// `--sampler` named nothing acdf knows; `known` lists every name
    /// ([`sampler_names`](crate::registry::sampler_names)).
    #[error("unknown sampler `{name}`: expected one of {known}")]
    UnknownSampler { name: String, known: String },

    /// A sampler file records a kind of sampler that no family of the
    /// registry reads; `known` lists the kinds that are read.
    #[error("sampler file {}: unknown sampler kind {kind:?}; the known kinds are {known}", path.display())]
    UnknownSamplerKind {
        path: PathBuf,
        kind: String,
        known: String,
    },

    /// The sampler cannot be used with this material (e.g. `rgl` needs a
    /// `.bsdf` file).
    #[error("sampler `{sampler}` cannot be used with material `{material}`: {reason}")]
    Incompatible {
        sampler: String,
        material: String,
        reason: String,
    },

    /// A sampler of BRDF × environment (`product`) asked for without the
    /// environment map and shading normal it is formed for, or by a
    /// command that has neither.
    #[error("sampler `{sampler}` samples BRDF × environment at one shading point: it needs --envmap FILE and --normal THETA_DEG,PHI_DEG (`acdf sample` and `acdf pdf`), {context}")]
    NeedsEnvironment { sampler: String, context: String },

    /// A sampler without tables asked to be saved to a file.
    #[error("sampler `{sampler}` has no tables to save: only tabulated samplers ({kinds}) are saved to files")]
    NotSaveable { sampler: String, kinds: String },

    /// A saved sampler offered for a material other than the one it was
    /// built from (compared by content, [`acdf_core::Brdf::fingerprint`]).
    #[error("sampler file {} was built for material `{recorded}` (fingerprint {recorded_fingerprint:016x}), but `{material}` has other content (fingerprint {fingerprint:016x}); build a sampler for it with `acdf build`", path.display())]
    SamplerMaterialMismatch {
        path: PathBuf,
        recorded: String,
        recorded_fingerprint: u64,
        material: String,
        fingerprint: u64,
    },

    /// An option that a saved sampler fixes, given with `--sampler-file`.
    #[error("{option} cannot be used with --sampler-file: the saved sampler {} fixes it; rebuild the file with `acdf build {option} ...` to change it", path.display())]
    FixedBySamplerFile { option: &'static str, path: PathBuf },

    /// A command-line value that parses but is out of its domain, or does
    /// not parse.
    #[error("invalid {what} `{value}`: {reason}")]
    InvalidArgument {
        what: &'static str,
        value: String,
        reason: String,
    },

    /// A malformed line of standard input.
    #[error("stdin line {line}: {reason}")]
    Input { line: usize, reason: String },

    /// No tolerance of the search reaches the target efficiency; `best`
    /// says what the best candidate reached.
    #[error("no tolerance of {sampler} reaches {target} x the efficiency of {reference}: {best}")]
    TargetNotReached {
        sampler: String,
        target: f64,
        reference: String,
        best: String,
    },

    /// Reading or writing a file.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },

    /// Writing a file failed or was refused, or reading one hit a bound
    /// ([`acdf_io::fsio`]); the message names the file.
    #[error("{0}")]
    File(#[from] acdf_io::fsio::FsError),

    /// Writing standard output failed (a closed pipe, a full disk).
    #[error("cannot write to standard output: {0}")]
    Stream(#[from] std::io::Error),

    /// Decoding or encoding an image.
    #[error("image {}: {message}", path.display())]
    Image { path: PathBuf, message: String },

    /// Drawing a plot.
    #[error("plot {}: {message}", path.display())]
    Plot { path: PathBuf, message: String },

    /// A sampler file could not be written or read.
    #[error("sampler file {}: {source}", path.display())]
    SamplerFile {
        path: PathBuf,
        source: acdf_tabulated::persist::PersistError,
    },

    /// A sampler or distribution rejected its parameters.
    #[error("{0}")]
    Core(#[from] acdf_core::Error),

    /// An environment map could not be read or is not a usable map.
    #[error("{0}")]
    Env(#[from] acdf_lights::EnvError),

    /// Serialising results.
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
}

impl Error {
    /// Wrap an I/O error with the path it happened on.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Error {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// `message` on one line: control characters (newlines, escapes, ...),
/// which a file name or an argument can carry into a message, are written
/// as escapes (`\n`, `\u{1b}`), so that every error is one line (on the
/// command's stderr, or from the C interface's `acdf_last_error`) and no
/// byte of the user's reaches a terminal as a control sequence.
pub fn one_line(message: &str) -> String {
    message
        .chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// `Result` with the facade's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
