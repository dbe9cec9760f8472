//! `acdf.Material`: a BRDF loaded from any spec the command line accepts.

use std::path::PathBuf;

use acdf::spec::MaterialSpec;
use acdf_core::Brdf;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;

use crate::arrays::direction_pair;
use crate::errors::{raise, require_file, IntoPyResult};
use crate::interrupt::in_slices;

/// A measured or analytic BRDF.
///
/// Load one with `Material.load(spec)`, where `spec` is any material name
/// the `acdf` command accepts: `builtin:NAME` (see `acdf.BUILTIN_MATERIALS`),
/// a MERL `.binary` path, an RGL `.bsdf` path, or `nbrdf:NAME` for a MERL
/// material as a Neural-BRDF network.
#[pyclass(module = "acdf", name = "Material", frozen)]
pub struct Material {
    pub inner: acdf::Material,
}

impl Material {
    /// Load `spec`; a missing `.binary`, `.bsdf` or weight file raises
    /// `acdf.NotFoundError`.
    pub fn load_spec(
        py: Python<'_>,
        spec: &str,
        nbrdf_weights: Option<PathBuf>,
    ) -> PyResult<Material> {
        let parsed: MaterialSpec = spec.parse::<MaterialSpec>().py_err(py)?;
        match &parsed {
            MaterialSpec::Merl(path) => require_file(py, path, "MERL file")?,
            MaterialSpec::Rgl(path) => require_file(py, path, "RGL file")?,
            MaterialSpec::Nbrdf(_) => {
                if let Some(path) = &nbrdf_weights {
                    require_file(py, path, "Neural-BRDF weight file")?;
                }
            }
            MaterialSpec::Builtin(_) => {}
        }
        let weights = nbrdf_weights.clone();
        let inner = py
            .detach(move || acdf::load_material(&parsed, weights.as_deref()))
            .py_err(py)?;
        Ok(Material { inner })
    }
}

#[pymethods]
impl Material {
    /// Load the material `spec` names (`builtin:nickel`, a `.binary` or
    /// `.bsdf` path, `nbrdf:NAME`); `nbrdf_weights` is the Neural-BRDF weight
    /// file for `nbrdf:` materials (default: the shared data's). A missing
    /// file raises `acdf.NotFoundError` (a `FileNotFoundError`), an unknown
    /// name `acdf.UnknownNameError`, a malformed file `acdf.MaterialError`.
    #[staticmethod]
    #[pyo3(signature = (spec, nbrdf_weights = None))]
    fn load(
        py: Python<'_>,
        spec: &Bound<'_, PyAny>,
        nbrdf_weights: Option<PathBuf>,
    ) -> PyResult<Material> {
        // A path may come as a str or an os.PathLike.
        let text = match spec.extract::<String>() {
            Ok(s) => s,
            Err(_) => spec
                .extract::<PathBuf>()?
                .to_str()
                .ok_or_else(|| {
                    raise(
                        py,
                        "InvalidArgumentError",
                        "invalid material path: not valid UTF-8",
                    )
                })?
                .to_string(),
        };
        Material::load_spec(py, &text, nbrdf_weights)
    }

    /// The spec it was loaded from, as the command line names it.
    #[getter]
    fn spec(&self) -> String {
        self.inner.spec.to_string()
    }

    /// The BRDF's own name (the one recorded in sampler files).
    #[getter]
    fn name(&self) -> String {
        self.inner.brdf.name().to_string()
    }

    /// A short label for tables: the built-in or network name, or the file
    /// stem.
    #[getter]
    fn label(&self) -> String {
        self.inner.label()
    }

    /// Whether f_r depends on the two azimuths only through their
    /// difference (then samplers tabulate one φ_o slice).
    #[getter]
    fn is_isotropic(&self) -> bool {
        self.inner.brdf.is_isotropic()
    }

    /// f_r(wo, wi) per RGB channel in 1/sr, without the cosine factor.
    ///
    /// `wo` and `wi` are float32 or float64 arrays of shape (3,) or (N, 3)
    /// in the local shading frame (z along the normal, both pointing away
    /// from the surface); a single direction is broadcast against N. The
    /// result is float32 of shape (N, 3), or (3,) when both are single.
    /// Directions at or below the horizon (or zero, or not finite) give 0.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        wo: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (wo, wi, n) = direction_pair(wo, wi)?;
        let brdf = &self.inner.brdf;
        let (wo, wi) = py.detach(move || (wo.normalised(), wi.normalised()));
        let mut out = vec![0.0f32; 3 * n.unwrap_or(1)];
        in_slices(py, &mut out, 3, |start, chunk| {
            let len = chunk.len() / 3;
            let (wo, wi) = (wo.chunk(start, len), wi.chunk(start, len));
            for (k, o) in chunk.chunks_exact_mut(3).enumerate() {
                o.copy_from_slice(&brdf.eval(wo[k], wi[k]).to_array());
            }
        })?;
        match n {
            None => Ok(PyArray1::from_vec(py, out).into_any()),
            Some(n) => {
                let array = Array2::from_shape_vec((n, 3), out).expect("n rows of 3");
                Ok(array.into_pyarray(py).into_any())
            }
        }
    }

    fn __repr__(&self) -> String {
        format!("acdf.Material.load({:?})", self.inner.spec.to_string())
    }
}
