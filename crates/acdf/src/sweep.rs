//! The speed/accuracy trade of the adaptive sampler: for each simplifier,
//! over a range of tolerances, the storage, the kept vertices, the time per
//! draw and per pdf, and the variance and efficiency of
//! [`efficiency`](crate::efficiency), with the uniform and cosine samplers
//! as the two reference points.

use std::io::Write;
use std::path::Path;

use acdf_core::BxdfSampler;
use serde::Serialize;

use crate::efficiency::{measure_efficiencies, Efficiency, EfficiencyConfig};
use crate::env::Environment;
use crate::error::{Error, Result};
use crate::material::Material;
use crate::plot::{Figure, Panel, Series};
use crate::registry::{make_sampler_spec, AnySampler, SamplerOps, SamplerOptions};
use crate::spec::{SamplerSpec, SimplifierName};

/// The default tolerances of a sweep: the simplifier's default tolerance
/// times 1/16, 1/8, …, 8.
pub const TOLERANCE_FACTORS: [f64; 8] = [
    1.0 / 16.0,
    1.0 / 8.0,
    1.0 / 4.0,
    1.0 / 2.0,
    1.0,
    2.0,
    4.0,
    8.0,
];

/// The default tolerance of a simplifier, as its plug-in defines it.
pub fn default_tolerance(simplifier: SimplifierName) -> f64 {
    (simplifier.entry().make)().default_tolerance()
}

/// One measured point: one sampler at one tolerance.
#[derive(Debug, Clone, Serialize)]
pub struct SweepPoint {
    pub material: String,
    /// `adaptive:dp`, …, or `uniform` / `cosine` for the references.
    pub sampler: String,
    /// The simplifier's tolerance (`null` for the references).
    pub tolerance: Option<f64>,
    pub storage_bytes: usize,
    /// Mean kept vertices of the θ_h marginals and of the φ_h conditionals.
    pub mean_marginal_vertices: Option<f64>,
    pub mean_conditional_vertices: Option<f64>,
    pub ns_per_draw: f64,
    pub ns_per_pdf: f64,
    pub ns_per_sample: f64,
    pub variance: f64,
    pub variance_rel_se: f64,
    pub efficiency: Option<f64>,
    pub relative_efficiency: Option<f64>,
}

fn point(
    material: &str,
    sampler: &str,
    tolerance: Option<f64>,
    storage_bytes: usize,
    vertices: Option<(f64, f64)>,
    e: &Efficiency,
) -> SweepPoint {
    SweepPoint {
        material: material.to_string(),
        sampler: sampler.to_string(),
        tolerance,
        storage_bytes,
        mean_marginal_vertices: vertices.map(|v| v.0),
        mean_conditional_vertices: vertices.map(|v| v.1),
        ns_per_draw: e.timing.seconds_per_draw * 1e9,
        ns_per_pdf: e.timing.seconds_per_pdf * 1e9,
        ns_per_sample: e.seconds_per_sample * 1e9,
        variance: e.variance,
        variance_rel_se: e.variance_rel_se,
        efficiency: e.efficiency.is_finite().then_some(e.efficiency),
        relative_efficiency: None,
    }
}

/// A sampler of the sweep with all its tables built, before it is timed.
struct Built {
    spec: SamplerSpec,
    tolerance: Option<f64>,
    sampler: AnySampler,
}

/// `spec` at `options` on `material`, all tables built.
fn build(spec: SamplerSpec, material: &Material, options: &SamplerOptions) -> Result<Built> {
    let sampler = make_sampler_spec(spec, material, options)?;
    sampler.build_all()?;
    Ok(Built {
        spec,
        tolerance: spec.simplifier().and(options.tolerance),
        sampler,
    })
}

/// Run the sweep: the uniform and cosine references, then every simplifier
/// at every tolerance of `tolerances(simplifier)`. `progress` is called once
/// per built sampler with its label, then with "timing". Every sampler is
/// built before any is timed, and their timed passes are taken in turns
/// ([`measure_efficiencies`]), so that the points of the curves are timed
/// under the same conditions (all the tables are held at once: at the
/// default 32x1x256x32 about 0.2 to 1 MiB a sampler). Points carry
/// efficiency relative to the uniform sampler.
pub fn run_sweep(
    material: &Material,
    env: &dyn Environment,
    base: &SamplerOptions,
    simplifiers: &[SimplifierName],
    tolerances: impl Fn(SimplifierName) -> Result<Vec<f64>>,
    config: &EfficiencyConfig,
    mut progress: impl FnMut(&str),
) -> Result<Vec<SweepPoint>> {
    let mut built = Vec::new();
    for spec in [SamplerSpec::UNIFORM, SamplerSpec::COSINE] {
        progress(&spec.to_string());
        built.push(build(spec, material, base)?);
    }
    for &simplifier in simplifiers {
        for tolerance in tolerances(simplifier)? {
            progress(&format!(
                "adaptive:{} tolerance {tolerance:.3e}",
                simplifier.short()
            ));
            let options = SamplerOptions {
                tolerance: Some(tolerance),
                ..*base
            };
            built.push(build(
                SamplerSpec::adaptive(simplifier),
                material,
                &options,
            )?);
        }
    }
    progress("timing");
    let samplers: Vec<&dyn BxdfSampler> = built
        .iter()
        .map(|b| &b.sampler as &dyn BxdfSampler)
        .collect();
    let efficiencies = measure_efficiencies(material.brdf.as_ref(), &samplers, env, config);
    let label = material.label();
    let mut points: Vec<SweepPoint> = built
        .iter()
        .zip(&efficiencies)
        .map(|(b, e)| {
            point(
                &label,
                &b.spec.to_string(),
                b.tolerance,
                b.sampler.storage_bytes(),
                b.sampler.mean_vertices(),
                e,
            )
        })
        .collect();
    let uniform = points[0].efficiency;
    for p in &mut points {
        p.relative_efficiency = match (p.efficiency, uniform) {
            (Some(e), Some(u)) if u > 0.0 => Some(e / u),
            _ => None,
        };
    }
    Ok(points)
}

/// The CSV header of [`write_csv`].
pub const CSV_HEADER: &str = "material,sampler,tolerance,storage_bytes,mean_marginal_vertices,\
mean_conditional_vertices,ns_per_draw,ns_per_pdf,ns_per_sample,variance,variance_rel_se,\
efficiency,relative_efficiency";

/// Write the points as CSV (empty fields for missing values).
pub fn write_csv(points: &[SweepPoint], out: &mut impl Write) -> std::io::Result<()> {
    let o = |x: Option<f64>| x.map(|v| format!("{v}")).unwrap_or_default();
    writeln!(out, "{CSV_HEADER}")?;
    for p in points {
        writeln!(
            out,
            "{},{},{},{},{},{},{:.2},{:.2},{:.2},{},{},{},{}",
            p.material,
            p.sampler,
            o(p.tolerance),
            p.storage_bytes,
            o(p.mean_marginal_vertices),
            o(p.mean_conditional_vertices),
            p.ns_per_draw,
            p.ns_per_pdf,
            p.ns_per_sample,
            p.variance,
            p.variance_rel_se,
            o(p.efficiency),
            o(p.relative_efficiency),
        )?;
    }
    Ok(())
}

/// Plot efficiency (left) and variance (right) against storage: one curve
/// per simplifier, the uniform sampler as a point, the cosine sampler as a
/// line. The variance panel shows the accuracy trade free of timing noise.
pub fn plot_sweep(points: &[SweepPoint], title: &str, svg: &Path, png: &Path) -> Result<()> {
    let find = |name: &str| points.iter().find(|p| p.sampler == name);
    let uniform = find("uniform").ok_or_else(|| Error::Plot {
        path: svg.to_path_buf(),
        message: "the sweep has no uniform point".into(),
    })?;
    let cosine = find("cosine");
    let panel = |y_label: &str, value: &dyn Fn(&SweepPoint) -> Option<f64>, legend: bool| {
        let mut series: Vec<Series> = Vec::new();
        for p in points.iter().filter(|p| p.sampler.starts_with("adaptive")) {
            let Some(v) = value(p) else { continue };
            let xy = (p.storage_bytes as f64, v);
            match series.iter_mut().find(|s| s.label == p.sampler) {
                Some(s) => s.points.push(xy),
                None => series.push(Series {
                    label: p.sampler.clone(),
                    points: vec![xy],
                }),
            }
        }
        Panel {
            y_label: y_label.to_string(),
            series,
            uniform: (uniform.storage_bytes as f64, value(uniform).unwrap_or(0.0)),
            cosine: cosine.and_then(value).unwrap_or(0.0),
            legend,
        }
    };
    let figure = Figure {
        title: title.to_string(),
        panels: vec![
            panel("efficiency 1/(V t) (1/s)", &|p| p.efficiency, true),
            panel("variance V", &|p| Some(p.variance), false),
        ],
    };
    crate::plot::plot_figure(&figure, svg, png)
}
