//! From the facade's typed errors to the Python exceptions of
//! `acdf.errors`. The classes are defined in Python (`python/acdf/errors.py`)
//! because several derive from two bases (e.g. `NotFoundError` from
//! `acdf.Error` and the built-in `FileNotFoundError`), which a class made by
//! PyO3 cannot.

use std::path::Path;

use acdf::lights::EnvError;
use acdf::Error;
use acdf_tabulated::persist::PersistError;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyType;

/// The errno of a missing file, as `FileNotFoundError` carries it.
const ENOENT: i32 = 2;

/// The class `name` of `acdf.errors`.
fn class<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyType>> {
    Ok(py
        .import("acdf.errors")?
        .getattr(name)?
        .cast_into::<PyType>()?)
}

/// An exception of class `name` with the one-line message `message`.
pub fn raise(py: Python<'_>, name: &str, message: impl Into<String>) -> PyErr {
    let message = message.into();
    match class(py, name) {
        Ok(cls) => PyErr::from_type(cls, message),
        // The package's Python half is missing (the native module imported
        // on its own): still an exception, never a crash.
        Err(_) => PyRuntimeError::new_err(message),
    }
}

/// `acdf.NotFoundError` (a `FileNotFoundError`) for `path`, with errno and
/// filename set as the built-in sets them.
pub fn not_found(py: Python<'_>, path: &Path, message: impl Into<String>) -> PyErr {
    let message = message.into();
    match class(py, "NotFoundError") {
        Ok(cls) => PyErr::from_type(cls, (ENOENT, message, path.display().to_string())),
        Err(_) => PyRuntimeError::new_err(message),
    }
}

/// Raise `NotFoundError` if `path` does not exist; `what` names the file in
/// the message.
pub fn require_file(py: Python<'_>, path: &Path, what: &str) -> PyResult<()> {
    if path.exists() {
        Ok(())
    } else {
        Err(not_found(py, path, format!("{what} does not exist")))
    }
}

/// Whether an I/O error says the file is not there.
fn missing(e: &std::io::Error) -> bool {
    e.kind() == std::io::ErrorKind::NotFound
}

/// The Python exception for a facade error: its class from the variant, its
/// message the error's own line.
pub fn to_py(py: Python<'_>, e: Error) -> PyErr {
    let message = e.to_string();
    let name = match &e {
        Error::UnknownMaterial { .. } | Error::UnknownSampler { .. } => "UnknownNameError",
        Error::Material { .. } => "MaterialError",
        Error::Incompatible { .. } | Error::NotSaveable { .. } | Error::NeedsEnvironment { .. } => {
            "IncompatibleError"
        }
        Error::InvalidArgument { .. } | Error::Input { .. } | Error::Core(_) => {
            "InvalidArgumentError"
        }
        Error::Io { path, source } if missing(source) => return not_found(py, path, message),
        Error::SamplerFile {
            path,
            source: PersistError::File(acdf_io::fsio::FsError::Read { source, .. }),
        } if missing(source) => return not_found(py, path, message),
        Error::UnknownSamplerKind { .. } | Error::SamplerFile { .. } => "SamplerFileError",
        Error::TargetNotReached { .. } => "TargetNotReachedError",
        Error::Env(EnvError::File(acdf_io::fsio::FsError::Read { path, source }))
            if missing(source) =>
        {
            return not_found(py, path, message)
        }
        Error::Env(EnvError::File(acdf_io::fsio::FsError::Read { .. })) => "IoError",
        Error::Env(EnvError::Core(_)) => "InvalidArgumentError",
        Error::Env(_) => "EnvMapError",
        Error::Io { .. } | Error::Stream(_) => "IoError",
        _ => "Error",
    };
    raise(py, name, message)
}

/// `Result` of the facade, mapped to Python's.
pub trait IntoPyResult<T> {
    /// The value, or the exception [`to_py`] makes of the error.
    fn py_err(self, py: Python<'_>) -> PyResult<T>;
}

impl<T> IntoPyResult<T> for acdf::Result<T> {
    fn py_err(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| to_py(py, e))
    }
}

impl<T> IntoPyResult<T> for acdf_core::Result<T> {
    fn py_err(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| to_py(py, Error::Core(e)))
    }
}
