//! The storage/accuracy trade of the adaptive sampler: every simplifier over
//! a range of tolerances (and, for isotropic materials, the outgoing
//! sampler with the same simplifiers, its tolerances scaled as its default
//! is), with every other sampler the registry knows
//! (uniform, cosine, lobes, and `rgl` for RGL materials) as reference points, each
//! with its storage, time and the noise-free relative variance, firefly
//! measure and efficiency of [`efficiency`](crate::efficiency), relative to
//! a reference sampler.

use std::io::Write;
use std::path::Path;

use acdf_core::BxdfSampler;
use serde::Serialize;

use crate::efficiency::{measure_with, Efficiency, EfficiencyConfig, Integrands};
use crate::plot::{figure_bytes, Figure, Marker, Panel, Series, Style};
use crate::target::{relative, search_tolerance, Reference, TargetOutcome};
use acdf::env::Environment;
use acdf::error::Result;
use acdf::material::Material;
use acdf::registry::{
    make_sampler_tabulated, plain_samplers, AnySampler, SamplerOps, SamplerOptions, Tabulation,
};
use acdf::spec::{SamplerAt, SamplerSpec, SimplifierName};

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

/// The tolerances a sweep tries for `simplifier`: `fixed` when given, else
/// [`TOLERANCE_FACTORS`] times the simplifier's default.
pub fn sweep_tolerances(fixed: Option<&[f64]>, simplifier: SimplifierName) -> Vec<f64> {
    match fixed {
        Some(t) => t.to_vec(),
        None => {
            let d = default_tolerance(simplifier);
            TOLERANCE_FACTORS.iter().map(|f| f * d).collect()
        }
    }
}

/// The default tolerance of a simplifier, as its plug-in defines it.
pub fn default_tolerance(simplifier: SimplifierName) -> f64 {
    (simplifier.entry().make)().default_tolerance()
}

/// The default tolerance of a sampler with a simplifier: the simplifier's
/// for `adaptive:`, scaled by
/// [`TOLERANCE_SCALE`](acdf_outgoing::TOLERANCE_SCALE) for
/// `outgoing:`; `None` for a sampler without one.
pub fn spec_default_tolerance(spec: SamplerSpec) -> Option<f64> {
    let base = default_tolerance(spec.simplifier()?);
    Some(if spec.family().name == acdf::registry::OUTGOING {
        base * acdf_outgoing::TOLERANCE_SCALE
    } else {
        base
    })
}

/// `outgoing:SIMPLIFIER`.
fn outgoing(simplifier: SimplifierName) -> SamplerSpec {
    format!("{}:{simplifier}", acdf::registry::OUTGOING)
        .parse()
        .expect("the outgoing family takes every simplifier")
}

/// One measured point: one sampler at one tolerance.
#[derive(Debug, Clone, Serialize)]
pub struct SweepPoint {
    pub material: String,
    /// `adaptive:dp`, …, or `uniform`, `cosine`, `rgl`.
    pub sampler: String,
    /// The simplifier's tolerance (`null` for the others).
    pub tolerance: Option<f64>,
    /// The tabulation θ_o×φ_o×θ_h×φ_h (`-` without tables).
    pub resolution: String,
    /// Whether this point is the reference of `relative_efficiency`.
    pub is_reference: bool,
    /// Whether a `--target-efficiency` search chose this point.
    pub target_chosen: bool,
    pub storage_bytes: usize,
    /// Mean kept vertices of the θ_h marginals and of the φ_h conditionals.
    pub mean_marginal_vertices: Option<f64>,
    pub mean_conditional_vertices: Option<f64>,
    pub ns_per_draw: f64,
    pub ns_per_pdf: f64,
    /// t_s = t_sample + v t_pdf, the sampler's own work.
    pub ns_per_sampler: f64,
    /// One BRDF evaluation (not part of t_s).
    pub ns_per_eval: f64,
    /// By quadrature.
    pub relative_variance: f64,
    pub firefly: f64,
    /// The Monte Carlo cross-check and its relative standard error (from
    /// the estimator's fourth moment by quadrature).
    pub mc_relative_variance: Option<f64>,
    pub mc_relative_variance_rel_se: Option<f64>,
    /// 1 / (r t_s).
    pub efficiency: Option<f64>,
    pub relative_efficiency: Option<f64>,
}

/// A sampler of the sweep with all its tables built, before it is timed.
struct Built {
    spec: SamplerSpec,
    tolerance: Option<f64>,
    sampler: AnySampler,
    is_reference: bool,
    target_chosen: bool,
}

/// `spec` at `options` on `material`, all tables built (from `tables`
/// where they fit).
fn build(
    spec: SamplerSpec,
    material: &Material,
    options: &SamplerOptions,
    tables: &Tabulation,
) -> Result<Built> {
    let sampler = make_sampler_tabulated(spec, material, options, tables)?;
    Ok(Built {
        spec,
        tolerance: spec.simplifier().and(options.tolerance),
        sampler,
        is_reference: false,
        target_chosen: false,
    })
}

/// What [`run_sweep`] measures.
pub struct SweepPlan<'a> {
    /// The simplifiers whose tolerances are swept.
    pub simplifiers: &'a [SimplifierName],
    /// The tolerances of each simplifier.
    pub tolerances: &'a dyn Fn(SimplifierName) -> Result<Vec<f64>>,
    /// The reference of the relative efficiency (measured as a point of
    /// its own when it is not the uniform sampler at `options`).
    pub reference: SamplerAt,
    /// Resolution and cosine mixing of every sampler.
    pub options: SamplerOptions,
    /// With a target efficiency, each simplifier's tolerance is also
    /// searched for ([`search_tolerance`]) and the chosen sampler added.
    pub target: Option<f64>,
}

/// Run the sweep: the reference, every plain sampler of the registry
/// usable with `material` ([`plain_samplers`]), then every simplifier at
/// every tolerance, and with a target each simplifier's chosen tolerance.
/// `progress` is called once per built sampler with its label, then with
/// "quadrature" and "timing" (and with each tolerance a target search
/// tries). Every sampler is built before any is timed, and their timed
/// repeats are taken in turns, so that the points of the curves are timed
/// under the same conditions (all the tables are held at once: at the
/// default 32x1x256x32 about 0.2 to 1 MiB a sampler).
pub fn run_sweep(
    material: &Material,
    env: &dyn Environment,
    plan: &SweepPlan,
    config: &EfficiencyConfig,
    mut progress: impl FnMut(&str),
) -> Result<(Vec<SweepPoint>, Vec<TargetOutcome>)> {
    let base = &plan.options;
    let reference_options = SamplerOptions {
        resolution: plan.reference.resolution.unwrap_or(base.resolution),
        ..*base
    };
    // Uniform first: the reference of the curves when none is named.
    let mut plain = plain_samplers(material);
    plain.sort_by_key(|&s| s != SamplerSpec::UNIFORM);
    let among_plain = reference_options == *base && plain.contains(&plan.reference.sampler);
    let tables = Tabulation::new(material, base.resolution);
    let mut built = Vec::new();
    if !among_plain {
        progress(&format!("reference {}", plan.reference));
        let mut b = build(
            plan.reference.sampler,
            material,
            &reference_options,
            &tables,
        )?;
        b.is_reference = true;
        built.push(b);
    }
    for spec in plain {
        progress(&spec.to_string());
        let mut b = build(spec, material, base, &tables)?;
        b.is_reference = among_plain && spec == plan.reference.sampler;
        built.push(b);
    }
    let reference_at = built.iter().position(|b| b.is_reference).unwrap_or(0);
    for &simplifier in plan.simplifiers {
        for tolerance in (plan.tolerances)(simplifier)? {
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
                &tables,
            )?);
        }
    }
    // The outgoing sampler's front, for isotropic materials: each swept
    // simplifier at its tolerances scaled as the outgoing default is.
    if material.brdf.is_isotropic() {
        for &simplifier in plan.simplifiers {
            let spec = outgoing(simplifier);
            for tolerance in (plan.tolerances)(simplifier)? {
                let tolerance = tolerance * acdf_outgoing::TOLERANCE_SCALE;
                progress(&format!("{spec} tolerance {tolerance:.3e}"));
                let options = SamplerOptions {
                    tolerance: Some(tolerance),
                    ..*base
                };
                built.push(build(spec, material, &options, &tables)?);
            }
        }
    }
    progress("quadrature");
    let integrands = Integrands::new(material.brdf.as_ref(), env, config);
    let mut outcomes = Vec::new();
    if let Some(target) = plan.target {
        let reference = &built[reference_at].sampler;
        let relative_variance = integrands.noise_free(reference).relative_variance;
        let mut chosen = Vec::new();
        for &simplifier in plan.simplifiers {
            let (outcome, sampler) = search_tolerance(
                material,
                SamplerSpec::adaptive(simplifier),
                base,
                &Reference {
                    sampler: reference,
                    relative_variance,
                },
                &integrands,
                &tables,
                config,
                target,
                |t| progress(&format!("target: adaptive:{simplifier} tolerance {t:.3e}")),
            )?;
            chosen.push(Built {
                spec: SamplerSpec::adaptive(simplifier),
                tolerance: Some(outcome.chosen.tolerance),
                sampler,
                is_reference: false,
                target_chosen: true,
            });
            outcomes.push(outcome);
        }
        built.extend(chosen);
    }
    progress("timing");
    let samplers: Vec<&dyn BxdfSampler> = built
        .iter()
        .map(|b| &b.sampler as &dyn BxdfSampler)
        .collect();
    let efficiencies = measure_with(&integrands, material.brdf.as_ref(), &samplers, env, config);
    let reference_efficiency = efficiencies[reference_at].efficiency;
    let label = material.label();
    let points = built
        .iter()
        .zip(&efficiencies)
        .map(|(b, e)| point(&label, b, e, reference_efficiency))
        .collect();
    Ok((points, outcomes))
}

fn point(material: &str, b: &Built, e: &Efficiency, reference_efficiency: f64) -> SweepPoint {
    let vertices = b.sampler.mean_vertices();
    let mc = e.monte_carlo.as_ref();
    let finite = |x: f64| x.is_finite().then_some(x);
    SweepPoint {
        material: material.to_string(),
        sampler: b.spec.to_string(),
        tolerance: b.tolerance,
        resolution: b.sampler.resolution_label(),
        is_reference: b.is_reference,
        target_chosen: b.target_chosen,
        storage_bytes: b.sampler.storage_bytes(),
        mean_marginal_vertices: vertices.map(|v| v.0),
        mean_conditional_vertices: vertices.map(|v| v.1),
        ns_per_draw: e.timing.seconds_per_draw * 1e9,
        ns_per_pdf: e.timing.seconds_per_pdf * 1e9,
        ns_per_sampler: e.timing.sampler_seconds() * 1e9,
        ns_per_eval: e.timing.seconds_per_eval * 1e9,
        relative_variance: e.noise_free.relative_variance,
        firefly: e.noise_free.firefly,
        mc_relative_variance: mc.map(|m| m.relative_variance),
        mc_relative_variance_rel_se: mc.map(|m| m.relative_variance_rel_se),
        efficiency: finite(e.efficiency),
        relative_efficiency: finite(relative(e.efficiency, reference_efficiency)),
    }
}

/// The CSV header of [`write_csv`].
pub const CSV_HEADER: &str = "material,sampler,tolerance,resolution,is_reference,target_chosen,\
storage_bytes,mean_marginal_vertices,mean_conditional_vertices,ns_per_draw,ns_per_pdf,\
ns_per_sampler,ns_per_eval,relative_variance,firefly,mc_relative_variance,\
mc_relative_variance_rel_se,efficiency,relative_efficiency";

/// Write the points as CSV (empty fields for missing values).
pub fn write_csv(points: &[SweepPoint], out: &mut impl Write) -> std::io::Result<()> {
    let o = |x: Option<f64>| x.map(|v| format!("{v}")).unwrap_or_default();
    writeln!(out, "{CSV_HEADER}")?;
    for p in points {
        writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{:.2},{:.2},{:.2},{:.2},{},{},{},{},{},{}",
            p.material,
            p.sampler,
            o(p.tolerance),
            p.resolution,
            p.is_reference,
            p.target_chosen,
            p.storage_bytes,
            o(p.mean_marginal_vertices),
            o(p.mean_conditional_vertices),
            p.ns_per_draw,
            p.ns_per_pdf,
            p.ns_per_sampler,
            p.ns_per_eval,
            p.relative_variance,
            p.firefly,
            o(p.mc_relative_variance),
            o(p.mc_relative_variance_rel_se),
            o(p.efficiency),
            o(p.relative_efficiency),
        )?;
    }
    Ok(())
}

/// The sweep's figure: relative efficiency (left) and relative variance
/// (right) against storage, one curve per simplifier, the other tabulated
/// samplers and the points a target search chose as marked points; a
/// sampler without tables (cosine) has no storage to place it at, and is
/// printed as a figure in the panel instead, so that the axes fit the
/// tabulated samplers. Returns the SVG text and the PNG bytes.
pub fn plot_sweep(points: &[SweepPoint], title: &str, name: &Path) -> Result<(String, Vec<u8>)> {
    let panel = |y_label: &str, value: &dyn Fn(&SweepPoint) -> Option<f64>, legend: bool| {
        let mut series: Vec<Series> = Vec::new();
        let mut markers = Vec::new();
        let mut notes = Vec::new();
        for p in points {
            let Some(v) = value(p) else { continue };
            let xy = (p.storage_bytes as f64, v);
            if p.storage_bytes == 0 {
                notes.push(format!("{} (no tables): {v:.2e}", p.sampler));
            } else if p.target_chosen {
                markers.push(Marker {
                    label: format!("{} at the target", p.sampler),
                    point: xy,
                });
            } else if p.tolerance.is_none() {
                let reference = if p.is_reference { ", reference" } else { "" };
                markers.push(Marker {
                    label: format!("{} {}{reference}", p.sampler, p.resolution),
                    point: xy,
                });
            } else {
                match series.iter_mut().find(|s| s.label == p.sampler) {
                    Some(s) => s.points.push(xy),
                    None => series.push(Series {
                        label: p.sampler.clone(),
                        points: vec![xy],
                        style: Style::Line,
                    }),
                }
            }
        }
        Panel {
            x_label: "storage (bytes)".into(),
            y_label: y_label.to_string(),
            series,
            markers,
            notes,
            legend,
        }
    };
    let figure = Figure {
        title: title.to_string(),
        panels: vec![
            panel(
                "efficiency relative to the reference",
                &|p| p.relative_efficiency,
                true,
            ),
            panel(
                "relative variance (quadrature)",
                &|p| Some(p.relative_variance),
                false,
            ),
        ],
    };
    figure_bytes(&figure, name)
}
