//! `acdf.EnvMap` and `acdf.EnvSampler`: environment maps and the samplers
//! of directions towards them (`acdf env-sample`, `acdf env-pdf`), over
//! NumPy arrays. Every sampler name comes from the registry
//! (`acdf::env_registry::ENV_SAMPLERS`).

use std::path::PathBuf;
use std::sync::Arc;

use acdf::env_registry::{
    make_env_sampler_spec, parse_sphere_direction_degrees, AnyEnvSampler, EnvSamplerOptions,
    EnvSamplerSpec,
};
use acdf::lights::{self, NormalGrid};
use acdf_core::{SphereSample, SphereSampler, Vec2, Vec3};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyString, PyTuple};

use crate::arrays::{common_len, read, unit, Rows};
use crate::errors::{raise, require_file, IntoPyResult};
use crate::interrupt::{cancellable, in_slices};
use crate::sampler::check_tolerance;

/// A latitude-longitude environment map: radiance over the sphere.
///
/// `EnvMap.load(path)` reads a Radiance `.hdr` or OpenEXR `.exr` map, +z
/// up, row 0 at the zenith, φ = 0 along +x at the left edge (the
/// convention of `acdf env-sample --env`).
#[pyclass(module = "acdf", name = "EnvMap", frozen)]
pub struct EnvMap {
    inner: Arc<lights::EnvMap>,
    path: PathBuf,
    repairs: (usize, usize),
}

/// A one-line reason for a map the samplers cannot use.
fn black_map(py: Python<'_>, path: &std::path::Path) -> PyErr {
    raise(
        py,
        "InvalidArgumentError",
        format!(
            "invalid environment map `{}`: every texel is 0: a black environment has no light to sample",
            path.display()
        ),
    )
}

#[pymethods]
impl EnvMap {
    /// Read the map at `path` (`.hdr` or `.exr`). A missing file raises
    /// `acdf.NotFoundError`, one that cannot be decoded or is not twice as
    /// wide as high `acdf.EnvMapError`, as do NaN, infinite or negative
    /// texels unless `repair` is true (then they are set to 0, with a
    /// warning, and `repairs` counts them); a map black everywhere raises
    /// `acdf.InvalidArgumentError` (nothing to sample).
    #[staticmethod]
    #[pyo3(signature = (path, *, repair = false))]
    fn load(py: Python<'_>, path: PathBuf, repair: bool) -> PyResult<EnvMap> {
        require_file(py, &path, "environment map")?;
        let file = path.clone();
        let (map, repairs) = py
            .detach(move || {
                if repair {
                    lights::EnvMap::open_repaired(&file)
                        .map(|(m, r)| (m, (r.non_finite, r.negative)))
                } else {
                    lights::EnvMap::open(&file).map(|m| (m, (0, 0)))
                }
            })
            .map_err(acdf::Error::from)
            .py_err(py)?;
        if map.is_black() {
            return Err(black_map(py, &path));
        }
        if repairs != (0, 0) {
            let message = format!(
                "{}: set {} non-finite and {} negative channel values to 0",
                path.display(),
                repairs.0,
                repairs.1
            );
            py.import("warnings")?.call_method1("warn", (message,))?;
        }
        Ok(EnvMap {
            inner: Arc::new(map),
            path,
            repairs,
        })
    }

    /// The file it was read from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// (width, height) in texels.
    #[getter]
    fn size(&self) -> (usize, usize) {
        self.inner.size()
    }

    /// (non-finite, negative) channel values set to 0 by `repair=True`.
    #[getter]
    fn repairs(&self) -> (usize, usize) {
        self.repairs
    }

    /// The radiance (RGB) the map gives direction `dirs`: float32 (N, 3) for
    /// dirs of shape (N, 3), (3,) for one direction. Directions are in the
    /// map's frame and need not be unit; a zero or non-finite one gives 0.
    /// The texel's value, or with `bilinear` the bilinear interpolation of
    /// the four nearest texel centres.
    #[pyo3(signature = (dirs, *, bilinear = false))]
    fn radiance<'py>(
        &self,
        py: Python<'py>,
        dirs: &Bound<'py, PyAny>,
        bilinear: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let dirs = read::<Vec3>(dirs, "dirs")?;
        let n = dirs.len();
        let dirs = py.detach(move || dirs.normalised());
        let map = &self.inner;
        let mut out = vec![0.0f32; 3 * n.unwrap_or(1)];
        in_slices(py, &mut out, 3, |start, chunk| {
            let d = dirs.chunk(start, chunk.len() / 3);
            for (o, &d) in chunk.chunks_exact_mut(3).zip(d.iter()) {
                if d != Vec3::ZERO {
                    let l = if bilinear {
                        map.radiance_bilinear(d)
                    } else {
                        map.radiance(d)
                    };
                    o.copy_from_slice(&l.to_array());
                }
            }
        })?;
        match n {
            None => Ok(PyArray1::from_vec(py, out).into_any()),
            Some(n) => Ok(Array2::from_shape_vec((n, 3), out)
                .expect("n rows of 3")
                .into_pyarray(py)
                .into_any()),
        }
    }

    fn __repr__(&self) -> String {
        let (w, h) = self.inner.size();
        format!(
            "acdf.EnvMap.load({:?}) ({w}x{h})",
            self.path.display().to_string()
        )
    }
}

/// An importance sampler of directions towards an environment map.
///
/// `EnvSampler(envmap, name, ...)` builds the sampler `name`, any of
/// `acdf.ENV_SAMPLER_NAMES` (the names `acdf env-sample --sampler`
/// accepts), for `envmap`.
#[pyclass(module = "acdf", name = "EnvSampler", frozen)]
pub struct EnvSampler {
    sampler: Arc<AnyEnvSampler>,
    name: String,
    envmap: Py<EnvMap>,
}

/// `"8x16"` or `(8, 16)`: rows × columns of the oriented sampler's cells
/// of normals.
fn parse_normal_cells(cells: &Bound<'_, PyAny>) -> PyResult<NormalGrid> {
    let py = cells.py();
    let invalid = || {
        raise(
            py,
            "InvalidArgumentError",
            format!(
                "invalid normal cells `{cells}`: expected ROWSxCOLUMNS, e.g. \"8x16\", or two counts, \
                 at least 1x1 and at most 65536 cells"
            ),
        )
    };
    let (rows, columns): (usize, usize) = match cells.cast::<PyString>() {
        Ok(s) => {
            let s = s.to_str()?;
            let (r, c) = s.split_once('x').ok_or_else(invalid)?;
            (
                r.trim().parse().map_err(|_| invalid())?,
                c.trim().parse().map_err(|_| invalid())?,
            )
        }
        Err(_) => cells.extract().map_err(|_| invalid())?,
    };
    NormalGrid::new(rows, columns).map_err(|_| invalid())
}

/// A direction of the batch made unit; `None` for a zero or non-finite one
/// (its density is 0).
fn usable(v: Vec3) -> Option<Vec3> {
    let v = unit(v);
    (v != Vec3::ZERO).then_some(v)
}

/// Draw `n` rows towards the map, in slices between which Ctrl-C is
/// handled; `None` for a failed draw.
fn draw(
    py: Python<'_>,
    sampler: &AnyEnvSampler,
    normal: &Option<Rows<Vec3>>,
    u: &Rows<Vec2>,
    n: usize,
) -> PyResult<Vec<Option<SphereSample>>> {
    let mut out: Vec<Option<SphereSample>> = vec![None; n];
    in_slices(py, &mut out, 1, |start, chunk| {
        let us = u.chunk(start, chunk.len());
        match normal {
            None => sampler.sample_batch(None, &us, chunk),
            Some(Rows::One(v)) => sampler.sample_batch(Some(*v), &us, chunk),
            Some(many) => {
                let normals = many.chunk(start, chunk.len());
                for ((o, &v), &u) in chunk.iter_mut().zip(normals.iter()).zip(us.iter()) {
                    *o = sampler.sample(Some(v), u);
                }
            }
        }
    })?;
    Ok(out)
}

/// The optional normal argument: None, (3,) or (N, 3).
fn read_normal(normal: &Bound<'_, PyAny>) -> PyResult<Option<Rows<Vec3>>> {
    if normal.is_none() {
        Ok(None)
    } else {
        Ok(Some(read::<Vec3>(normal, "normal")?))
    }
}

#[pymethods]
impl EnvSampler {
    /// Build the sampler `name` (one of `acdf.ENV_SAMPLER_NAMES`) for
    /// `envmap`.
    ///
    /// `tolerance` is the simplifier's, for the adaptive and oriented
    /// samplers (default: the simplifier's own; 0.005 for chi2).
    /// `normal_cells` (`"16x32"` or `(16, 32)`, the default) and
    /// `defensive` (the probability of drawing from the plain luminance
    /// table, in [0, 1], default 0) are the oriented sampler's; its
    /// tables are built on first use, per region of normals. The others are
    /// built now, with the interpreter released; Ctrl-C interrupts the
    /// build.
    #[new]
    #[pyo3(signature = (envmap, name, *, tolerance = None, normal_cells = None, defensive = None))]
    fn new(
        py: Python<'_>,
        envmap: Py<EnvMap>,
        name: &str,
        tolerance: Option<f64>,
        normal_cells: Option<&Bound<'_, PyAny>>,
        defensive: Option<f32>,
    ) -> PyResult<EnvSampler> {
        check_tolerance(py, tolerance)?;
        let defaults = EnvSamplerOptions::default();
        let defensive = defensive.unwrap_or(defaults.defensive);
        if !(0.0..=1.0).contains(&defensive) {
            return Err(raise(
                py,
                "InvalidArgumentError",
                format!("invalid defensive share `{defensive}`: must be in [0, 1]"),
            ));
        }
        let options = EnvSamplerOptions {
            tolerance,
            normal_cells: match normal_cells {
                Some(c) => parse_normal_cells(c)?,
                None => defaults.normal_cells,
            },
            defensive,
        };
        let spec: EnvSamplerSpec = name.parse::<EnvSamplerSpec>().py_err(py)?;
        let map = envmap.get().inner.clone();
        let sampler =
            cancellable(py, move |_| make_env_sampler_spec(spec, &map, &options))?.py_err(py)?;
        Ok(EnvSampler {
            sampler: Arc::new(sampler),
            name: spec.to_string(),
            envmap,
        })
    }

    /// The sampler's name, e.g. `adaptive:chi2`.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// The map it samples.
    #[getter]
    fn envmap(&self, py: Python<'_>) -> Py<EnvMap> {
        self.envmap.clone_ref(py)
    }

    /// Bytes held by the tables built so far (for `oriented`, the cells of
    /// normals drawn from so far).
    #[getter]
    fn storage_bytes(&self) -> usize {
        self.sampler.storage_bytes()
    }

    /// For `oriented`, (cells of normals built so far, all cells); None
    /// for the samplers built whole.
    #[getter]
    fn cells_built(&self) -> Option<(usize, usize)> {
        self.sampler.built_nodes()
    }

    /// The tables, as `acdf env-report` labels them: the texel grid, the
    /// kept vertices (marginal × mean conditional), or the cells of normals.
    #[getter]
    fn tables(&self) -> String {
        self.sampler.table_label()
    }

    /// Whether it draws the compensated density (`*-comp`: for multiple
    /// importance sampling, biased alone).
    #[getter]
    fn is_compensated(&self) -> bool {
        self.sampler.is_compensated()
    }

    /// Draw directions towards the map: returns `(dirs, pdf, valid)`.
    ///
    /// `normal` is the shading normal in the map's frame, None (the
    /// default), shape (3,) or (N, 3): samplers that use it (`oriented`)
    /// draw from the part of the sphere above it, the others ignore it.
    /// `u` (uniform numbers in [0, 1)) has shape (2,) or (N, 2). float32 or
    /// float64; a single row is broadcast. `dirs` is float32 (N, 3) on the
    /// whole sphere, `pdf` float32 (N,) per unit solid angle, `valid` bool
    /// (N,); a failed draw is dirs = 0, pdf = 0, valid = False (as `acdf
    /// env-sample` prints it). A normal need not be unit; a zero or
    /// non-finite one counts as none. With a single `u` and normal the
    /// result is `(dirs (3,), pdf float, valid bool)`. The same `u` and
    /// normal give the draws of `acdf env-sample` (`acdf.uniform_2d`,
    /// `acdf.sphere_direction`).
    #[pyo3(signature = (normal, u))]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        normal: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let normal = read_normal(normal)?;
        let u = read::<Vec2>(u, "u")?;
        let normal_len = normal.as_ref().and_then(Rows::len);
        let n = common_len(py, &[("normal", normal_len), ("u", u.len())])?;
        let out = draw(py, &self.sampler, &normal, &u, n.unwrap_or(1))?;
        let rows = out.len();
        let mut dirs = vec![0.0f32; 3 * rows];
        let mut pdf = vec![0.0f32; rows];
        let mut valid = vec![false; rows];
        for (k, d) in out.iter().enumerate() {
            if let Some(s) = d {
                dirs[3 * k..3 * k + 3].copy_from_slice(&s.dir.to_array());
                pdf[k] = s.pdf;
                valid[k] = true;
            }
        }
        match n {
            None => (PyArray1::from_vec(py, dirs), pdf[0], valid[0]).into_pyobject(py),
            Some(n) => (
                Array2::from_shape_vec((n, 3), dirs)
                    .expect("n rows of 3")
                    .into_pyarray(py),
                PyArray1::from_vec(py, pdf),
                PyArray1::from_vec(py, valid),
            )
                .into_pyobject(py),
        }
    }

    /// The density per unit solid angle with which `sample` draws `dirs`
    /// for `normal` (None, (3,) or (N, 3)); `dirs` (3,) or (N, 3), float32
    /// or float64, need not be unit. Returns float32 (N,), or a float when
    /// both are single; 0 for a zero or non-finite direction. A zero or
    /// non-finite normal counts as none.
    #[pyo3(signature = (normal, dirs))]
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        normal: &Bound<'py, PyAny>,
        dirs: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let normal = read_normal(normal)?;
        let dirs = read::<Vec3>(dirs, "dirs")?;
        let normal_len = normal.as_ref().and_then(Rows::len);
        let n = common_len(py, &[("normal", normal_len), ("dirs", dirs.len())])?;
        let sampler = &self.sampler;
        let mut out = vec![0.0f32; n.unwrap_or(1)];
        in_slices(py, &mut out, 1, |start, chunk| {
            let d = dirs.chunk(start, chunk.len());
            let normals = normal.as_ref().map(|r| r.chunk(start, chunk.len()));
            for (k, o) in chunk.iter_mut().enumerate() {
                if let Some(dir) = usable(d[k]) {
                    *o = sampler.pdf(normals.as_ref().map(|v| v[k]), dir);
                }
            }
        })?;
        match n {
            None => Ok(out[0].into_pyobject(py)?.into_any()),
            Some(_) => Ok(PyArray1::from_vec(py, out).into_any()),
        }
    }

    fn __repr__(&self) -> String {
        format!(
            "acdf.EnvSampler({:?} for {}, {}, {} bytes)",
            self.name,
            self.envmap.get().path.display(),
            self.sampler.table_label(),
            self.sampler.storage_bytes()
        )
    }
}

/// The unit direction at polar angle `theta_deg` from +z (in [0, 180])
/// and azimuth `phi_deg` from +x towards +y, float32 (3,): the `--normal
/// THETA,PHI` of `acdf env-sample`, computed the same way.
#[pyfunction]
pub fn sphere_direction(
    py: Python<'_>,
    theta_deg: f64,
    phi_deg: f64,
) -> PyResult<Bound<'_, PyArray1<f32>>> {
    let d = parse_sphere_direction_degrees(&format!("{theta_deg},{phi_deg}")).py_err(py)?;
    Ok(PyArray1::from_vec(py, d.to_array().to_vec()))
}
