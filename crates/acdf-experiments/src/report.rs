//! The results table: for one material, every sampler's storage, the
//! compression against a reference sampler (the uniform tabulation by
//! default), its noise-free relative variance and firefly measure, the
//! Monte Carlo estimate of the same variance beside it, the time of its own
//! work and its efficiency (see [`efficiency`](crate::efficiency)),
//! absolute and relative to the reference, and the share of the reflected
//! light it can never draw
//! ([`missed_share`](crate::efficiency::missed_share)). With a target
//! efficiency, each adaptive sampler's tolerance is searched for first
//! ([`target`](crate::target)).

use std::time::Instant;

use acdf_core::BxdfSampler;
use serde::Serialize;

use crate::efficiency::{
    measure_with, missed_shares, Efficiency, EfficiencyConfig, Integrands, MISSED_SHARE_GRID,
    MISSED_SHARE_THETA_O,
};
use crate::target::{relative, search_tolerance, Reference, TargetOutcome};
use acdf::env::Environment;
use acdf::error::Result;
use acdf::material::Material;
use acdf::registry::{make_sampler_tabulated, AnySampler, SamplerOps, SamplerOptions, Tabulation};
use acdf::spec::{SamplerAt, SamplerSpec};

/// One (material, sampler) line of the report.
#[derive(Debug, Clone, Serialize)]
pub struct ReportRow {
    /// The material's short name.
    pub material: String,
    /// The sampler's command-line name.
    pub sampler: String,
    /// θ_o×φ_o×θ_h×φ_h for the uniform sampler, θ_o×φ_o× mean kept marginal
    /// × mean kept conditional vertices for adaptive ones.
    pub resolution: String,
    /// The simplifier's tolerance, for adaptive samplers.
    pub tolerance: Option<f64>,
    /// Whether this row is the reference of the relative columns.
    pub is_reference: bool,
    /// The reference, `NAME@RESOLUTION`.
    pub reference: String,
    /// Heap bytes of the sampler's tables, all slices built.
    pub storage_bytes: usize,
    /// storage(reference) / storage(sampler); `null` for a sampler without
    /// tables or a reference without them.
    pub compression_ratio: Option<f64>,
    /// Seconds to build every table (in parallel).
    pub build_seconds: f64,
    /// The relative variance r of the one-sample estimator, by quadrature.
    pub relative_variance: f64,
    /// r at each outgoing direction.
    pub relative_variance_by_direction: Vec<f64>,
    /// The largest weight f cos θ_i / p over the quadrature grid over the
    /// mean weight.
    pub firefly: f64,
    /// The Monte Carlo estimate of r and its relative standard error at
    /// this number of draws, from the estimator's fourth moment by
    /// quadrature (`null` without draws).
    pub mc_relative_variance: Option<f64>,
    pub mc_relative_variance_rel_se: Option<f64>,
    /// The same error as the draws estimate it themselves: it misses what
    /// draws rarer than one in n contribute.
    pub mc_sample_rel_se: Option<f64>,
    /// The Monte Carlo estimate of the mean reflected luminance (a
    /// consistency check: unbiased samplers agree within a few
    /// `estimate_se`).
    pub estimate: Option<f64>,
    pub estimate_se: Option<f64>,
    /// Draws behind the Monte Carlo figures.
    pub samples: usize,
    /// t_s = t_sample + v t_pdf, the sampler's own work per draw.
    pub seconds_per_sampler: f64,
    pub seconds_per_draw: f64,
    pub seconds_per_pdf: f64,
    /// One BRDF evaluation, not part of t_s.
    pub seconds_per_eval: f64,
    /// The fraction v of draws that succeed.
    pub valid_fraction: f64,
    /// 1 / (r t_s); `null` if r is 0.
    pub efficiency: Option<f64>,
    /// efficiency / efficiency(reference).
    pub relative_efficiency: Option<f64>,
    /// The missed share ∫_{p=0} Y(f) cos θ_i dω / ∫ Y(f) cos θ_i dω at each
    /// outgoing angle of `missed_share_theta_o` (φ_o =
    /// [`MISSED_SHARE_PHI_O`](crate::efficiency::MISSED_SHARE_PHI_O)), by the midpoint rule on
    /// [`MISSED_SHARE_GRID`]: the bias of the sampler used alone.
    pub missed_share: Vec<f64>,
    /// θ_o in degrees of each entry of `missed_share`.
    pub missed_share_theta_o: Vec<f32>,
    /// The largest entry of `missed_share`.
    pub missed_share_max: f64,
    /// The tolerance search that chose this sampler, with a target.
    pub target: Option<TargetOutcome>,
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// What [`report_material`] compares and how.
#[derive(Debug, Clone)]
pub struct ReportPlan<'a> {
    /// The samplers of the rows.
    pub samplers: &'a [SamplerSpec],
    /// The reference of the relative columns; added as a row of its own
    /// when it is not one of `samplers` at the same resolution.
    pub reference: SamplerAt,
    /// Resolution, tolerance and cosine mixing of the samplers.
    pub options: SamplerOptions,
    /// A target efficiency relative to the reference: every adaptive
    /// sampler's tolerance is searched for first.
    pub target: Option<f64>,
}

/// One step of a report, for a progress display.
#[derive(Debug, Clone)]
pub enum Progress {
    /// A step of the count [`report_steps`] gives: a sampler built, the
    /// quadrature, the timing.
    Step(String),
    /// A detail within a step (a tolerance the target search tries).
    Detail(String),
}

/// The steps [`report_material`] reports as [`Progress::Step`] for
/// `samplers` samplers: each sampler, the reference when it is not among
/// them, the quadrature and the timing.
pub fn report_steps(samplers: usize) -> usize {
    samplers + 3
}

/// A built sampler of the report.
struct Entry {
    spec: SamplerSpec,
    options: SamplerOptions,
    sampler: AnySampler,
    build_seconds: f64,
    target: Option<TargetOutcome>,
}

/// `spec` at `options`, all tables built (from `tables` where they fit);
/// its build time counts the tabulation it shares, as if built alone.
fn build(
    spec: SamplerSpec,
    material: &Material,
    options: SamplerOptions,
    tables: &Tabulation,
) -> Result<Entry> {
    let start = Instant::now();
    let sampler = make_sampler_tabulated(spec, material, &options, tables)?;
    let shared = if spec.family().file_kind.is_some() && options.resolution == tables.resolution() {
        tables.seconds
    } else {
        0.0
    };
    Ok(Entry {
        spec,
        options,
        sampler,
        build_seconds: start.elapsed().as_secs_f64() + shared,
        target: None,
    })
}

/// Measure each sampler of `plan` on `material` (the default set is
/// [`report_samplers`](acdf::registry::report_samplers)), the reference
/// first if it is not one of them. The integrand is evaluated once; the
/// samplers' timed repeats run in turns
/// ([`time_samplers`](crate::efficiency::time_samplers)) so that their
/// times are compared under the same conditions.
pub fn report_material(
    material: &Material,
    plan: &ReportPlan,
    env: &dyn Environment,
    config: &EfficiencyConfig,
    mut progress: impl FnMut(Progress),
) -> Result<Vec<ReportRow>> {
    let reference_options = SamplerOptions {
        resolution: plan.reference.resolution.unwrap_or(plan.options.resolution),
        ..plan.options
    };
    let is_reference =
        |e: &Entry| e.spec == plan.reference.sampler && e.options == reference_options;
    // One tabulation for every sampler with tables at the plan's
    // resolution; none when no sampler has tables.
    let tabulated = plan.samplers.iter().any(|s| s.family().file_kind.is_some());
    let tables = if tabulated {
        Tabulation::new(material, plan.options.resolution)
    } else {
        Tabulation::empty()
    };
    let mut entries: Vec<Entry> = Vec::new();
    for &spec in plan.samplers {
        progress(Progress::Step(spec.to_string()));
        entries.push(build(spec, material, plan.options, &tables)?);
    }
    let reference_at = match entries.iter().position(is_reference) {
        Some(k) => {
            progress(Progress::Step(format!("reference {}", plan.reference)));
            k
        }
        None => {
            progress(Progress::Step(format!("reference {}", plan.reference)));
            entries.insert(
                0,
                build(plan.reference.sampler, material, reference_options, &tables)?,
            );
            0
        }
    };
    progress(Progress::Step("quadrature".into()));
    let integrands = Integrands::new(material.brdf.as_ref(), env, config);
    if let Some(target) = plan.target {
        let reference = &entries[reference_at].sampler;
        let relative_variance = integrands.noise_free(reference).relative_variance;
        let mut found = Vec::new();
        for (k, e) in entries.iter().enumerate() {
            if e.spec.simplifier().is_none() {
                continue;
            }
            if k == reference_at {
                continue;
            }
            let label = e.spec.to_string();
            let (outcome, sampler) = search_tolerance(
                material,
                e.spec,
                &e.options,
                &Reference {
                    sampler: reference,
                    relative_variance,
                },
                &integrands,
                &tables,
                config,
                target,
                |t| progress(Progress::Detail(format!("{label}: tolerance {t:.3e}"))),
            )?;
            found.push((k, outcome, sampler));
        }
        for (k, outcome, sampler) in found {
            let e = &mut entries[k];
            e.options.tolerance = Some(outcome.chosen.tolerance);
            e.build_seconds = outcome.chosen.build_seconds;
            e.sampler = sampler;
            e.target = Some(outcome);
        }
    }
    progress(Progress::Step("timing".into()));
    let samplers: Vec<&dyn BxdfSampler> = entries
        .iter()
        .map(|e| &e.sampler as &dyn BxdfSampler)
        .collect();
    let efficiencies = measure_with(&integrands, material.brdf.as_ref(), &samplers, env, config);
    let reference = &entries[reference_at];
    let reference_storage = reference.sampler.storage_bytes();
    let reference_efficiency = efficiencies[reference_at].efficiency;
    let reference_label = format!(
        "{}@{}",
        plan.reference.sampler, reference_options.resolution
    );
    let label = material.label();
    Ok(entries
        .into_iter()
        .zip(efficiencies)
        .enumerate()
        .map(|(k, (e, eff))| {
            let missed = missed_shares(material.brdf.as_ref(), &e.sampler, MISSED_SHARE_GRID);
            row(
                &label,
                e,
                &eff,
                missed,
                k == reference_at,
                &reference_label,
                reference_storage,
                reference_efficiency,
            )
        })
        .collect())
}

#[allow(clippy::too_many_arguments)]
fn row(
    material: &str,
    e: Entry,
    eff: &Efficiency,
    missed: Vec<f64>,
    is_reference: bool,
    reference: &str,
    reference_storage: usize,
    reference_efficiency: f64,
) -> ReportRow {
    let mc = eff.monte_carlo.as_ref();
    let storage_bytes = e.sampler.storage_bytes();
    ReportRow {
        material: material.to_string(),
        sampler: e.spec.to_string(),
        resolution: e.sampler.resolution_label(),
        tolerance: e.spec.simplifier().map(|s| {
            e.options
                .tolerance
                .unwrap_or_else(|| crate::sweep::default_tolerance(s))
        }),
        is_reference,
        reference: reference.to_string(),
        storage_bytes,
        compression_ratio: (storage_bytes > 0 && reference_storage > 0)
            .then(|| reference_storage as f64 / storage_bytes as f64),
        build_seconds: e.build_seconds,
        relative_variance: eff.noise_free.relative_variance,
        relative_variance_by_direction: eff.noise_free.relative_variance_by_direction.clone(),
        firefly: eff.noise_free.firefly,
        mc_relative_variance: mc.map(|m| m.relative_variance),
        mc_relative_variance_rel_se: mc.map(|m| m.relative_variance_rel_se),
        mc_sample_rel_se: mc.map(|m| m.sample_rel_se),
        estimate: mc.map(|m| m.estimate),
        estimate_se: mc.map(|m| m.estimate_se),
        samples: mc.map_or(0, |m| m.samples),
        seconds_per_sampler: eff.timing.sampler_seconds(),
        seconds_per_draw: eff.timing.seconds_per_draw,
        seconds_per_pdf: eff.timing.seconds_per_pdf,
        seconds_per_eval: eff.timing.seconds_per_eval,
        valid_fraction: eff.timing.valid_fraction,
        efficiency: finite(eff.efficiency),
        relative_efficiency: finite(relative(eff.efficiency, reference_efficiency)),
        missed_share_theta_o: MISSED_SHARE_THETA_O.to_vec(),
        missed_share_max: missed.iter().copied().fold(0.0, f64::max),
        missed_share: missed,
        target: e.target,
    }
}

/// Bytes in a human unit (KiB, MiB).
pub fn human_bytes(bytes: usize) -> String {
    let b = bytes as f64;
    if b >= 1024.0 * 1024.0 {
        format!("{:.2} MiB", b / (1024.0 * 1024.0))
    } else if b >= 1024.0 {
        format!("{:.1} KiB", b / 1024.0)
    } else {
        format!("{bytes} B")
    }
}

/// A missed share: `0` when exactly zero, else three significant digits.
fn share(x: f64) -> String {
    if x == 0.0 {
        "0".to_string()
    } else {
        format!("{x:.2e}")
    }
}

/// The missed share of every row at each outgoing angle, as a Markdown
/// table (φ_o = 1 rad; the grid of [`MISSED_SHARE_GRID`]).
pub fn format_missed_table(rows: &[ReportRow]) -> String {
    let angles: Vec<String> = MISSED_SHARE_THETA_O
        .iter()
        .map(|t| format!("θ_o {t}°"))
        .collect();
    let mut header = vec!["material".to_string(), "sampler".to_string()];
    header.extend(angles);
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let mut cells = vec![r.material.clone(), r.sampler.clone()];
            cells.extend(r.missed_share.iter().map(|&x| share(x)));
            cells
        })
        .collect();
    markdown(&header, &body, 2)
}

fn opt(x: Option<f64>, f: impl Fn(f64) -> String) -> String {
    x.map(f).unwrap_or_else(|| "-".to_string())
}

/// The rows as a Markdown table (the `±` of the Monte Carlo column is
/// [`MC_ERROR_FACTOR`] standard errors).
pub fn format_table(rows: &[ReportRow]) -> String {
    let header = [
        "material",
        "sampler",
        "resolution",
        "storage",
        "compression",
        "rel. variance",
        "Monte Carlo (±)",
        "firefly",
        "ns/sample",
        "ns/eval",
        "efficiency (1/s)",
        "rel. eff.",
        "missed (max)",
    ];
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.material.clone(),
                if r.is_reference {
                    format!("{} (ref.)", r.sampler)
                } else {
                    r.sampler.clone()
                },
                r.resolution.clone(),
                human_bytes(r.storage_bytes),
                opt(r.compression_ratio, |c| format!("{c:.1}x")),
                format!("{:.3e}", r.relative_variance),
                match (r.mc_relative_variance, r.mc_relative_variance_rel_se) {
                    (Some(v), Some(se)) => {
                        format!("{v:.3e} (±{:.0}%)", 100.0 * MC_ERROR_FACTOR * se)
                    }
                    _ => "-".to_string(),
                },
                format!("{:.1}", r.firefly),
                format!("{:.0}", r.seconds_per_sampler * 1e9),
                format!("{:.0}", r.seconds_per_eval * 1e9),
                opt(r.efficiency, |e| format!("{e:.3e}")),
                opt(r.relative_efficiency, |e| format!("{e:.2}")),
                share(r.missed_share_max),
            ]
        })
        .collect();
    let header: Vec<String> = header.iter().map(|h| h.to_string()).collect();
    markdown(&header, &body, 3)
}

/// The `±` of the Monte Carlo column, in standard errors of the estimate
/// (its true error at the number of draws,
/// [`NoiseFree::monte_carlo_rel_se`](crate::efficiency::NoiseFree::monte_carlo_rel_se)).
pub const MC_ERROR_FACTOR: f64 = 3.0;

/// A Markdown table: the first `text_columns` columns left-aligned, the
/// others (numbers) right-aligned, every column padded to its widest cell.
pub(crate) fn markdown(header: &[String], body: &[Vec<String>], text_columns: usize) -> String {
    let mut widths: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for row in body {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: &[String]| -> String {
        let padded: Vec<String> = cells
            .iter()
            .zip(&widths)
            .enumerate()
            .map(|(i, (c, &w))| {
                if i < text_columns {
                    format!("{c:<w$}")
                } else {
                    format!("{c:>w$}")
                }
            })
            .collect();
        format!("| {} |\n", padded.join(" | "))
    };
    let mut out = line(header);
    out.push_str(&format!(
        "|{}|\n",
        widths
            .iter()
            .enumerate()
            .map(|(i, &w)| if i < text_columns {
                format!(":{}", "-".repeat(w + 1))
            } else {
                format!("{}:", "-".repeat(w + 1))
            })
            .collect::<Vec<_>>()
            .join("|")
    ));
    for row in body {
        out.push_str(&line(row));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_has_a_line_per_row() {
        let row = ReportRow {
            material: "m".into(),
            sampler: "cosine".into(),
            resolution: "-".into(),
            tolerance: None,
            is_reference: false,
            reference: "uniform@32x1x256x32".into(),
            storage_bytes: 0,
            compression_ratio: None,
            build_seconds: 0.0,
            relative_variance: 2.0,
            relative_variance_by_direction: vec![2.0],
            firefly: 12.25,
            mc_relative_variance: Some(2.1),
            mc_relative_variance_rel_se: Some(0.01),
            mc_sample_rel_se: Some(0.01),
            estimate: Some(1.0),
            estimate_se: Some(0.0),
            samples: 10,
            seconds_per_sampler: 1e-8,
            seconds_per_draw: 1e-8,
            seconds_per_pdf: 0.0,
            seconds_per_eval: 3e-8,
            valid_fraction: 1.0,
            efficiency: Some(5e7),
            relative_efficiency: None,
            missed_share: vec![0.0, 2.5e-3],
            missed_share_theta_o: vec![0.0, 85.0],
            missed_share_max: 2.5e-3,
            target: None,
        };
        let t = format_table(&[row.clone(), row.clone()]);
        assert_eq!(t.lines().count(), 4);
        for needle in [
            "cosine",
            "5.000e7",
            "2.50e-3",
            "2.100e0 (±3%)",
            "12.2",
            " 30 |",
        ] {
            assert!(t.contains(needle), "{needle} in {t}");
        }
        assert_eq!(format_missed_table(&[row]).lines().count(), 3);
        assert_eq!(human_bytes(2048), "2.0 KiB");
    }
}
