//! `acdf.report` and `acdf.sweep`: the command's results table and tolerance
//! sweep as lists of dicts, one per row, with the keys of their JSON output
//! (`acdf report --json`, `acdf sweep`'s `sweep.json`).

use acdf::env::Sky;
use acdf::registry::report_samplers;
use acdf::spec::SamplerAt;
use acdf::spec::DEFAULT_REPORT_MATERIALS;
use acdf::{SamplerOptions, SamplerSpec, SimplifierName};
use acdf_experiments::report::{report_material, ReportPlan};
use acdf_experiments::sweep::{run_sweep, sweep_tolerances, SweepPlan};
use acdf_experiments::EfficiencyConfig;
use pyo3::prelude::*;

use acdf_experiments::target::check_target;

use crate::errors::{raise, IntoPyResult};
use crate::interrupt::cancellable;
use crate::material::Material;
use crate::sampler::{check_tolerance, parse_reference, parse_resolution};

/// Rows serialised as the command's JSON, then read by Python's `json`
/// module: a list of dicts whose keys keep the order of the JSON output.
fn rows<'py, T: serde::Serialize>(py: Python<'py>, rows: &[T]) -> PyResult<Bound<'py, PyAny>> {
    json_value(py, rows)
}

/// A value serialised as JSON, then read by Python's `json` module (dicts,
/// lists, numbers, strings, None).
pub fn json_value<'py, T: serde::Serialize + ?Sized>(
    py: Python<'py>,
    value: &T,
) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| raise(py, "Error", e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A material argument: an `acdf.Material` or a spec string.
fn material_of(py: Python<'_>, m: &Bound<'_, PyAny>) -> PyResult<acdf::Material> {
    if let Ok(material) = m.cast::<Material>() {
        return Ok(material.get().inner.clone());
    }
    let spec: String = m.extract().map_err(|_| {
        raise(
            py,
            "InvalidArgumentError",
            format!("invalid material `{m}`: expected an acdf.Material or a spec string"),
        )
    })?;
    Ok(Material::load_spec(py, &spec, None)?.inner)
}

/// The measurement settings: the library's defaults (those of `acdf
/// report`) where an argument is None.
fn config(
    py: Python<'_>,
    samples: Option<usize>,
    timing_samples: Option<usize>,
    timing_repeats: Option<usize>,
    seed: Option<u64>,
) -> PyResult<EfficiencyConfig> {
    let d = EfficiencyConfig::default();
    let config = EfficiencyConfig {
        samples_per_direction: samples.unwrap_or(d.samples_per_direction),
        timing_samples_per_direction: timing_samples.unwrap_or(d.timing_samples_per_direction),
        timing_repeats: timing_repeats.unwrap_or(d.timing_repeats),
        seed: seed.unwrap_or(d.seed),
        ..d
    };
    if config.samples_per_direction < 2
        || config.timing_samples_per_direction < 1
        || config.timing_repeats < 1
    {
        return Err(raise(
            py,
            "InvalidArgumentError",
            "invalid sample count: need at least 2 draws for a variance, 1 to time and 1 timed pass",
        ));
    }
    Ok(config)
}

fn table_options(
    resolution: Option<&Bound<'_, PyAny>>,
    tolerance: Option<f64>,
    cosine_mix: f32,
) -> PyResult<SamplerOptions> {
    Ok(SamplerOptions {
        resolution: match resolution {
            Some(r) => parse_resolution(r)?,
            None => SamplerOptions::default().resolution,
        },
        tolerance,
        cosine_mix,
    })
}

/// The target efficiency, checked, and the reference: `reference` parsed,
/// or the command's default (`uniform` at the plan's resolution;
/// `uniform@32x16x256x32` with a target).
fn target_and_reference(
    py: Python<'_>,
    target: Option<f64>,
    reference: Option<&str>,
) -> PyResult<(Option<f64>, SamplerAt)> {
    let target = target.map(check_target).transpose().py_err(py)?;
    let reference = match (reference, target) {
        (None, None) => SamplerAt::plain(SamplerSpec::UNIFORM),
        (r, _) => parse_reference(py, r)?,
    };
    Ok((target, reference))
}

/// The results table of `acdf report`, as a list of dicts (one per
/// material and sampler, with the keys of `acdf report --json`).
///
/// `materials` are `acdf.Material` objects or spec strings (default: the
/// three built-in stand-ins of `acdf report`); `samplers` are names of
/// `acdf.SAMPLER_NAMES` (default: the report's set for each material). The
/// measurement settings default to the command's (12 outgoing directions ×
/// 2^17 draws, seed 2005, the fastest of 45 timed repeats of 512 draws
/// per direction). `reference` is the reference of the relative columns, `NAME` or `NAME@RES` (default:
/// `uniform` at `resolution`); with `target_efficiency` each adaptive
/// sampler's tolerance is searched for first, as `acdf report
/// --target-efficiency` does (the reference then defaults to
/// `uniform@32x16x256x32`). Runs with the interpreter released; Ctrl-C
/// interrupts it; the time columns depend on the machine's load.
#[pyfunction]
#[pyo3(signature = (materials = None, samplers = None, *, resolution = None, tolerance = None, cosine_mix = 0.0, samples = None, timing_samples = None, timing_repeats = None, seed = None, target_efficiency = None, reference = None))]
#[allow(clippy::too_many_arguments)]
pub fn report<'py>(
    py: Python<'py>,
    materials: Option<Vec<Bound<'py, PyAny>>>,
    samplers: Option<Vec<String>>,
    resolution: Option<&Bound<'py, PyAny>>,
    tolerance: Option<f64>,
    cosine_mix: f32,
    samples: Option<usize>,
    timing_samples: Option<usize>,
    timing_repeats: Option<usize>,
    seed: Option<u64>,
    target_efficiency: Option<f64>,
    reference: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    check_tolerance(py, tolerance)?;
    let options = table_options(resolution, tolerance, cosine_mix)?;
    let (target, reference) = target_and_reference(py, target_efficiency, reference)?;
    let config = config(py, samples, timing_samples, timing_repeats, seed)?;
    let loaded: Vec<acdf::Material> = match materials {
        Some(list) => list
            .iter()
            .map(|m| material_of(py, m))
            .collect::<PyResult<_>>()?,
        None => DEFAULT_REPORT_MATERIALS
            .iter()
            .map(|n| Ok(Material::load_spec(py, &format!("builtin:{n}"), None)?.inner))
            .collect::<PyResult<_>>()?,
    };
    let chosen: Option<Vec<SamplerSpec>> = samplers
        .map(|names| {
            names
                .iter()
                .map(|s| s.parse::<SamplerSpec>())
                .collect::<acdf::Result<_>>()
        })
        .transpose()
        .py_err(py)?;
    let measured = cancellable(py, move |checkpoint| {
        let env = Sky::dome();
        let mut out = Vec::new();
        for m in &loaded {
            checkpoint.check();
            let specs = chosen.clone().unwrap_or_else(|| report_samplers(m));
            let plan = ReportPlan {
                samplers: &specs,
                reference,
                options,
                target,
            };
            out.extend(report_material(m, &plan, &env, &config, |_| {
                checkpoint.check()
            })?);
        }
        Ok::<_, acdf::Error>(out)
    })?
    .py_err(py)?;
    rows(py, &measured)
}

/// The tolerance sweep of `acdf sweep`, as a list of dicts (the uniform and
/// cosine references, then each simplifier at each tolerance, with the
/// keys of `sweep.json`).
///
/// `material` is an `acdf.Material` or a spec string; `simplifiers` names
/// of `acdf.SIMPLIFIER_NAMES` (default: those `acdf report` compares);
/// `tolerances` the tolerances of every simplifier (default: each
/// simplifier's own default × 1/16, 1/8, ..., 8). Measurement settings as
/// for `report`; `target_efficiency` adds, for each simplifier, the point
/// its tolerance search chooses (`acdf sweep --target-efficiency`), and
/// `reference` is as for `report`. Ctrl-C interrupts it.
#[pyfunction]
#[pyo3(signature = (material, simplifiers = None, tolerances = None, *, resolution = None, samples = None, timing_samples = None, timing_repeats = None, seed = None, target_efficiency = None, reference = None))]
#[allow(clippy::too_many_arguments)]
pub fn sweep<'py>(
    py: Python<'py>,
    material: &Bound<'py, PyAny>,
    simplifiers: Option<Vec<String>>,
    tolerances: Option<Vec<f64>>,
    resolution: Option<&Bound<'py, PyAny>>,
    samples: Option<usize>,
    timing_samples: Option<usize>,
    timing_repeats: Option<usize>,
    seed: Option<u64>,
    target_efficiency: Option<f64>,
    reference: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    let options = table_options(resolution, None, 0.0)?;
    let (target, reference) = target_and_reference(py, target_efficiency, reference)?;
    let config = config(py, samples, timing_samples, timing_repeats, seed)?;
    let m = material_of(py, material)?;
    let simplifiers: Vec<SimplifierName> = match simplifiers {
        None => SimplifierName::in_report().collect(),
        Some(names) => names
            .iter()
            .map(|n| {
                SimplifierName::find(n).ok_or_else(|| {
                    raise(
                        py,
                        "UnknownNameError",
                        format!(
                            "unknown simplifier `{n}`: expected one of {}",
                            SimplifierName::list()
                        ),
                    )
                })
            })
            .collect::<PyResult<_>>()?,
    };
    for &t in tolerances.iter().flatten() {
        check_tolerance(py, Some(t))?;
    }
    let points = cancellable(py, move |checkpoint| {
        let tolerances = |s: SimplifierName| Ok(sweep_tolerances(tolerances.as_deref(), s));
        let plan = SweepPlan {
            simplifiers: &simplifiers,
            tolerances: &tolerances,
            reference,
            options,
            target,
        };
        run_sweep(&m, &Sky::dome(), &plan, &config, |_| checkpoint.check())
            .map(|(points, _)| points)
    })?
    .py_err(py)?;
    rows(py, &points)
}
