//! `acdf-python` is the native half of the Python package `acdf`: the
//! extension module `acdf._acdf`, which gives NumPy users the materials and
//! samplers the command line names, the environment maps and their
//! samplers, the results table and the tolerance sweep. Everything is named through the facade crate (`acdf`), so a
//! sampler family added to a registry (`acdf::registry::SAMPLERS`,
//! `acdf::env_registry::ENV_SAMPLERS`) or a simplifier added to the
//! adaptive plug-in is available from Python with no edit here. The pure-Python half (`python/acdf`: the exception classes,
//! the Mitsuba 3 plug-in, the type stubs) wraps this module.
//!
//! Batches run with the interpreter released (`Python::detach`) and, above
//! `PARALLEL_MIN` (8192) rows, on rayon's pool; Ctrl-C interrupts every
//! long call (module `interrupt`). Every failure is a Python
//! exception of the `acdf.Error` hierarchy (module `errors`) carrying the typed
//! error's message.
//!
//! maturin builds it (`pip install .` at the repository root, which reads
//! `pyproject.toml`); it sets `PYO3_BUILD_EXTENSION_MODULE`, so a plain
//! `cargo build` of the workspace links against libpython as a normal
//! library and `cargo test --workspace` is unaffected. The crate has no Rust
//! tests: the pytest suite in `tests/` runs against the installed package.

mod arrays;
mod env;
mod errors;
mod experiments;
mod interrupt;
mod material;
mod sampler;

use pyo3::prelude::*;

/// The native module; `acdf/__init__.py` re-exports what users see.
#[pymodule]
fn _acdf(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<material::Material>()?;
    m.add_class::<sampler::Sampler>()?;
    m.add_class::<env::EnvMap>()?;
    m.add_class::<env::EnvSampler>()?;
    m.add_function(wrap_pyfunction!(env::sphere_direction, m)?)?;
    m.add_function(wrap_pyfunction!(sampler::uniform_2d, m)?)?;
    m.add_function(wrap_pyfunction!(sampler::direction, m)?)?;
    m.add_function(wrap_pyfunction!(experiments::report, m)?)?;
    m.add_function(wrap_pyfunction!(experiments::sweep, m)?)?;
    m.add(
        "SAMPLER_NAMES",
        pyo3::types::PyTuple::new(m.py(), acdf::registry::sampler_names())?,
    )?;
    m.add(
        "ENV_SAMPLER_NAMES",
        pyo3::types::PyTuple::new(m.py(), acdf::env_registry::env_sampler_names())?,
    )?;
    m.add(
        "SIMPLIFIER_NAMES",
        pyo3::types::PyTuple::new(
            m.py(),
            acdf::SimplifierName::all()
                .map(|s| s.short())
                .collect::<Vec<_>>(),
        )?,
    )?;
    m.add(
        "BUILTIN_MATERIALS",
        pyo3::types::PyTuple::new(m.py(), acdf::spec::BUILTIN_MATERIALS)?,
    )?;
    m.add("PARALLEL_MIN", arrays::PARALLEL_MIN)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
