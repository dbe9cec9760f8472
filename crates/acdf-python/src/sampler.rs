//! `acdf.Sampler`: any sampler of the registry, built for a material or
//! loaded from a sampler file, sampling and evaluating over NumPy arrays.

use std::path::PathBuf;
use std::sync::Arc;

use acdf::registry::{load_sampler, make_sampler_spec, save_sampler, AnySampler};
use acdf::{SamplerOps, SamplerOptions, SamplerSpec};
use acdf_core::{BxdfSample, BxdfSampler, Vec2, Vec3};
use acdf_tabulated::Resolution;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyString, PyTuple};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use acdf::spec::SamplerAt;
use acdf_experiments::target::{build_for_target, check_target, TargetOutcome};

use crate::arrays::{common_len, direction_pair, read, Rows, CHUNK, PARALLEL_MIN};
use crate::errors::{raise, require_file, IntoPyResult};
use crate::experiments::json_value;
use crate::interrupt::{cancellable, in_slices, SLICE};
use crate::material::Material;

/// An importance sampler of incident directions for one material.
///
/// `Sampler(material, name, ...)` builds the sampler `name` for `material`:
/// any name of `acdf.SAMPLER_NAMES` (`cosine`, `uniform`, `adaptive:chi2`,
/// ..., `rgl` for `.bsdf` materials), the names `acdf sample --sampler`
/// accepts. `Sampler.load(path, material)` reads one saved by `save` or by
/// `acdf build`.
#[pyclass(module = "acdf", name = "Sampler", frozen)]
pub struct Sampler {
    sampler: Arc<AnySampler>,
    name: String,
    material: Py<Material>,
    /// The target-efficiency search that chose the tolerance, if any.
    search: Option<TargetOutcome>,
}

/// Options from the keyword arguments, checked as the command line checks
/// them.
fn options(
    py: Python<'_>,
    resolution: Option<&Bound<'_, PyAny>>,
    tolerance: Option<f64>,
    cosine_mix: f32,
) -> PyResult<SamplerOptions> {
    check_tolerance(py, tolerance)?;
    Ok(SamplerOptions {
        resolution: match resolution {
            None => Resolution::ISOTROPIC,
            Some(r) => parse_resolution(r)?,
        },
        tolerance,
        cosine_mix,
    })
}

/// A tolerance must be a non-negative number (`acdf.InvalidArgumentError`).
pub fn check_tolerance(py: Python<'_>, tolerance: Option<f64>) -> PyResult<()> {
    match tolerance {
        Some(t) if t.is_nan() || t < 0.0 => Err(raise(
            py,
            "InvalidArgumentError",
            format!("invalid tolerance `{t}`: must be a non-negative number"),
        )),
        _ => Ok(()),
    }
}

/// The reference of a target efficiency: `NAME` or `NAME@RES`, by default
/// `uniform@32x16x256x32` as for `acdf build --target-efficiency`.
pub fn parse_reference(py: Python<'_>, reference: Option<&str>) -> PyResult<SamplerAt> {
    match reference {
        Some(r) => r.parse::<SamplerAt>().py_err(py),
        None => Ok(SamplerAt::PAPER_UNIFORM),
    }
}

/// `"32x1x256x32"`, `"paper"`, or a tuple of four counts (θ_o, φ_o, θ_h, φ_h).
pub fn parse_resolution(r: &Bound<'_, PyAny>) -> PyResult<Resolution> {
    let py = r.py();
    let invalid = |value: String, reason: String| {
        raise(
            py,
            "InvalidArgumentError",
            format!("invalid resolution `{value}`: {reason}"),
        )
    };
    if let Ok(s) = r.cast::<PyString>() {
        let s = s.to_str()?;
        if s == "paper" {
            return Ok(Resolution::PAPER);
        }
        return s
            .parse::<Resolution>()
            .map_err(|e| invalid(s.to_string(), e.to_string()));
    }
    let counts: Vec<usize> = r.extract().map_err(|_| {
        invalid(
            r.to_string(),
            "expected \"TxPxTxP\", \"paper\" or four counts".into(),
        )
    })?;
    match counts[..] {
        [a, b, c, d] => {
            Resolution::new(a, b, c, d).map_err(|e| invalid(r.to_string(), e.to_string()))
        }
        _ => Err(invalid(r.to_string(), "expected four counts".into())),
    }
}

/// Draw `n` rows: the columns wi (n×3), pdf and valid, a failed draw
/// being (0, 0, 0), 0, false as `acdf sample` prints it. Each chunk of rows
/// is drawn by one `sample_batch` (a single wo) or `sample_each` call, in
/// slices between which Ctrl-C is handled ([`SLICE`]), the chunks of a
/// large slice on rayon's pool.
fn draw(
    py: Python<'_>,
    sampler: &AnySampler,
    wo: &Rows<Vec3>,
    u: &Rows<Vec2>,
    n: usize,
) -> PyResult<(Vec<f32>, Vec<f32>, Vec<bool>)> {
    let mut wi = vec![0.0f32; 3 * n];
    let mut pdf = vec![0.0f32; n];
    let mut valid = vec![false; n];
    let work = |start: usize, wi: &mut [f32], pdf: &mut [f32], valid: &mut [bool]| {
        let len = pdf.len();
        let mut out: Vec<Option<BxdfSample>> = vec![None; len];
        let us = u.chunk(start, len);
        match wo {
            Rows::One(w) => sampler.sample_batch(*w, &us, &mut out),
            Rows::Many(_) => sampler.sample_each(&wo.chunk(start, len), &us, &mut out),
        }
        for (k, d) in out.iter().enumerate() {
            if let Some(s) = d {
                wi[3 * k..3 * k + 3].copy_from_slice(&s.wi.to_array());
                pdf[k] = s.pdf;
                valid[k] = true;
            }
        }
    };
    let slices = wi
        .chunks_mut(3 * SLICE)
        .zip(pdf.chunks_mut(SLICE))
        .zip(valid.chunks_mut(SLICE));
    for (s, ((wi, pdf), valid)) in slices.enumerate() {
        let base = s * SLICE;
        let work = &work;
        py.detach(move || {
            if pdf.len() < PARALLEL_MIN {
                work(base, wi, pdf, valid);
            } else {
                wi.par_chunks_mut(3 * CHUNK)
                    .zip(pdf.par_chunks_mut(CHUNK))
                    .zip(valid.par_chunks_mut(CHUNK))
                    .enumerate()
                    .for_each(|(c, ((wi, pdf), valid))| work(base + c * CHUNK, wi, pdf, valid));
            }
        });
        py.check_signals()?;
    }
    Ok((wi, pdf, valid))
}

#[pymethods]
impl Sampler {
    /// Build the sampler `name` for `material`.
    ///
    /// `name` is any of `acdf.SAMPLER_NAMES`. `resolution` is the tabulation
    /// θ_o×φ_o×θ_h×φ_h as `"32x1x256x32"` (the default), `"paper"`
    /// (32x16x256x32) or a tuple of four counts; an anisotropic material
    /// gets 16 φ_o slices where one is asked for. `tolerance` is the
    /// simplifier's (default: its own), `cosine_mix` the probability of
    /// drawing from a cosine lobe instead of the tables.
    ///
    /// `target_efficiency` (a positive number) replaces the tolerance by a
    /// quality target, for an adaptive sampler: the tolerance is searched
    /// for, from `tolerance` or the simplifier's default, as `acdf build
    /// --target-efficiency` does, and the sampler of least storage whose
    /// efficiency is at least that fraction of `reference`'s is built
    /// (`reference`: `NAME` or `NAME@RES`, default
    /// `uniform@32x16x256x32`). `target_search` then holds what the search
    /// tried; a target no tolerance reaches raises
    /// `acdf.TargetNotReachedError`.
    ///
    /// Every table is built now, in parallel and with the interpreter
    /// released, unless `lazy` is true (then each is built on first use).
    /// Ctrl-C interrupts the build.
    #[new]
    #[pyo3(signature = (material, name, *, resolution = None, tolerance = None, cosine_mix = 0.0, target_efficiency = None, reference = None, lazy = false))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        material: Py<Material>,
        name: &str,
        resolution: Option<&Bound<'_, PyAny>>,
        tolerance: Option<f64>,
        cosine_mix: f32,
        target_efficiency: Option<f64>,
        reference: Option<&str>,
        lazy: bool,
    ) -> PyResult<Sampler> {
        let options = options(py, resolution, tolerance, cosine_mix)?;
        let spec: SamplerSpec = name.parse::<SamplerSpec>().py_err(py)?;
        let m = material.get().inner.clone();
        let (sampler, search) = match target_efficiency {
            None => {
                if reference.is_some() {
                    return Err(raise(
                        py,
                        "InvalidArgumentError",
                        "invalid reference: `reference` is the reference of `target_efficiency`, \
                         which is not given",
                    ));
                }
                let built = cancellable(py, move |_| {
                    let sampler = make_sampler_spec(spec, &m, &options)?;
                    if !lazy {
                        sampler.build_all()?;
                    }
                    Ok::<_, acdf::Error>(sampler)
                })?;
                (built.py_err(py)?, None)
            }
            Some(target) => {
                check_target(target).py_err(py)?;
                let reference = parse_reference(py, reference)?;
                let found = cancellable(py, move |checkpoint| {
                    let (outcome, sampler) =
                        build_for_target(&m, spec, &options, reference, target, |_| {
                            checkpoint.check()
                        })?;
                    outcome.require_reached(&reference.to_string())?;
                    Ok::<_, acdf::Error>((sampler, outcome))
                })?;
                let (sampler, outcome) = found.py_err(py)?;
                (sampler, Some(outcome))
            }
        };
        Ok(Sampler {
            name: spec.to_string(),
            sampler: Arc::new(sampler),
            material,
            search,
        })
    }

    /// What the target-efficiency search found (`target_efficiency=`): a
    /// dict with the keys `sampler`, `target`, `reached`, `chosen` (the
    /// candidate built: `tolerance`, `storage_bytes`,
    /// `relative_variance`, `relative_efficiency`, ...) and `tried` (every
    /// candidate, in order); None for a sampler built without a target.
    #[getter]
    fn target_search<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.search.as_ref().map(|s| json_value(py, s)).transpose()
    }

    /// Read a sampler file written by `Sampler.save` or `acdf build`; it
    /// must have been built for `material` (else `acdf.IncompatibleError`).
    /// A missing file raises `acdf.NotFoundError`, a damaged one
    /// `acdf.SamplerFileError`.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf, material: Py<Material>) -> PyResult<Sampler> {
        require_file(py, &path, "sampler file")?;
        let file = path.clone();
        let sampler = py.detach(move || load_sampler(&file)).py_err(py)?;
        let m = &material.get().inner;
        if let Some(recorded) = sampler.material_name() {
            if recorded != m.brdf.name() {
                return Err(raise(
                    py,
                    "IncompatibleError",
                    format!(
                        "sampler `{}` cannot be used with material `{}`: the file was built for material `{recorded}`",
                        path.display(),
                        m.spec
                    ),
                ));
            }
        }
        Ok(Sampler {
            name: sampler.name().to_string(),
            sampler: Arc::new(sampler),
            material,
            search: None,
        })
    }

    /// Build every table (if not yet) and write the sampler file to `path`,
    /// replacing it atomically; samplers without tables (`cosine`, `rgl`)
    /// raise `acdf.IncompatibleError`.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let sampler = self.sampler.clone();
        py.detach(move || save_sampler(&sampler, &path)).py_err(py)
    }

    /// The sampler's name, e.g. `adaptive:chi2`.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// The material it samples.
    #[getter]
    fn material(&self, py: Python<'_>) -> Py<Material> {
        self.material.clone_ref(py)
    }

    /// Bytes held by the tables built so far (all of them unless built
    /// with `lazy=True`).
    #[getter]
    fn storage_bytes(&self) -> usize {
        self.sampler.storage_bytes()
    }

    /// The tables' size: θ_o×φ_o×θ_h×φ_h for `uniform`, θ_o×φ_o× the mean
    /// kept vertices for adaptive samplers, `-` without tables.
    #[getter]
    fn resolution(&self) -> String {
        self.sampler.resolution_label()
    }

    /// (mean kept marginal vertices, mean kept conditional vertices) of an
    /// adaptive sampler, else None.
    #[getter]
    fn mean_vertices(&self) -> Option<(f64, f64)> {
        self.sampler.mean_vertices()
    }

    /// Draw incident directions: returns `(wi, pdf, valid)`.
    ///
    /// `wo` has shape (3,) or (N, 3), `u` (uniform numbers in [0, 1)) shape
    /// (2,) or (N, 2), float32 or float64; a single row is broadcast. `wi`
    /// is float32 (N, 3), `pdf` float32 (N,) per unit solid angle, `valid`
    /// bool (N,); a failed draw (wo at or below the horizon, or a draw that
    /// lands there) has wi = 0, pdf = 0, valid = False. With both arguments
    /// single the result is `(wi (3,), pdf float, valid bool)`. The same
    /// `u` gives the same draws as `acdf sample` (see `acdf.uniform_2d`).
    fn sample<'py>(
        &self,
        py: Python<'py>,
        wo: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let (wo, u) = (read::<Vec3>(wo, "wo")?, read::<Vec2>(u, "u")?);
        let n = common_len(py, &[("wo", wo.len()), ("u", u.len())])?;
        let wo = py.detach(move || wo.normalised());
        let (wi, pdf, valid) = draw(py, &self.sampler, &wo, &u, n.unwrap_or(1))?;
        match n {
            None => (PyArray1::from_vec(py, wi), pdf[0], valid[0]).into_pyobject(py),
            Some(n) => {
                let wi = Array2::from_shape_vec((n, 3), wi).expect("n rows of 3");
                (
                    wi.into_pyarray(py),
                    PyArray1::from_vec(py, pdf),
                    PyArray1::from_vec(py, valid),
                )
                    .into_pyobject(py)
            }
        }
    }

    /// The density per unit solid angle with which `sample` draws `wi`
    /// given `wo`.
    ///
    /// `wo` and `wi` have shape (3,) or (N, 3), float32 or float64; a single
    /// row is broadcast. Returns float32 (N,), or a float when both are
    /// single; 0 where either direction is at or below the horizon.
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        wo: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (wo, wi, n) = direction_pair(wo, wi)?;
        let sampler = &self.sampler;
        let (wo, wi) = py.detach(move || (wo.normalised(), wi.normalised()));
        let mut out = vec![0.0f32; n.unwrap_or(1)];
        in_slices(py, &mut out, 1, |start, chunk| {
            let wis = wi.chunk(start, chunk.len());
            match &wo {
                Rows::One(w) => sampler.pdf_batch(*w, &wis, chunk),
                Rows::Many(_) => sampler.pdf_each(&wo.chunk(start, chunk.len()), &wis, chunk),
            }
        })?;
        match n {
            None => Ok(out[0].into_pyobject(py)?.into_any()),
            Some(_) => Ok(PyArray1::from_vec(py, out).into_any()),
        }
    }

    fn __repr__(&self) -> String {
        format!(
            "acdf.Sampler({:?} for {}, {}, {} bytes)",
            self.name,
            self.material.get().inner.spec,
            self.sampler.resolution_label(),
            self.sampler.storage_bytes()
        )
    }
}

/// `n` pairs of uniform numbers in [0, 1), float32 of shape (n, 2): the
/// stream `acdf sample --seed SEED` draws (PCG64), so that
/// `sampler.sample(wo, acdf.uniform_2d(n, seed))` reproduces its output.
#[pyfunction]
#[pyo3(signature = (n, seed = 1))]
pub fn uniform_2d(
    py: Python<'_>,
    n: usize,
    seed: u64,
) -> PyResult<Bound<'_, numpy::PyArray2<f32>>> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut flat = vec![0.0f32; 2 * n];
    // One stream, drawn in order: in slices on this thread, Ctrl-C handled
    // between them.
    for slice in flat.chunks_mut(2 * SLICE) {
        let rng = &mut rng;
        py.detach(move || {
            for pair in slice.chunks_exact_mut(2) {
                let u = Vec2::new(rng.random(), rng.random());
                pair.copy_from_slice(&[u.x, u.y]);
            }
        });
        py.check_signals()?;
    }
    Ok(Array2::from_shape_vec((n, 2), flat)
        .expect("n rows of 2")
        .into_pyarray(py))
}

/// The unit direction at polar angle `theta_deg` (from the normal, in
/// [0, 90)) and azimuth `phi_deg`, float32 (3,): the `--wo THETA,PHI` of
/// the command line, computed the same way.
#[pyfunction]
pub fn direction(
    py: Python<'_>,
    theta_deg: f32,
    phi_deg: f32,
) -> PyResult<Bound<'_, PyArray1<f32>>> {
    let wo = acdf::spec::parse_direction_degrees(&format!("{theta_deg},{phi_deg}")).py_err(py)?;
    Ok(PyArray1::from_vec(py, wo.to_array().to_vec()))
}
