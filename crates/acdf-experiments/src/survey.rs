//! The survey: every sampler on every MERL material of the Neural-BRDF
//! file, against the 32x16x256x32 table of Lawrence et al. (the uniform
//! sampler at that resolution).
//!
//! For each material (`nbrdf:NAME`, baked into a MERL table) the survey
//! builds the reference, the uniform sampler at the default resolution,
//! every simplifier of the adaptive plug-in at its default tolerance,
//! `adaptive:chi2` at the tolerance that keeps a target fraction of the
//! reference's efficiency ([`search_tolerance`]), `outgoing:chi2` at its
//! default tolerance, and cosine sampling; it
//! measures each by the noise-free measures of
//! [`efficiency`](crate::efficiency) (no Monte Carlo draws), times their
//! own work in turns, and records storage, compression against the
//! reference, relative efficiency, firefly measure and build time. The
//! reference's 16 φ_o slices are tabulated by turning the tables of its
//! first φ_o cell ([`Tabulation::by_rotation`], equal to tabulating each
//! to float rounding), and every sampler at the default resolution is
//! built from one shared tabulation ([`make_sampler_tabulated`]). The
//! summary gives, per sampler, the median, the 10th percentile and the
//! worst material of the relative efficiency, and the compression among
//! the materials where the sampler keeps the target. The target row
//! reports the timing that decided its search (its own and the
//! reference's, in turns), so that it meets the target exactly when the
//! search found a tolerance that does.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use acdf_core::BxdfSampler;
use serde::Serialize;

use crate::efficiency::{efficiency_of, measure_with, EfficiencyConfig, Integrands};
use crate::plot::{figure_bytes, Figure, Marker, Panel, Series, Style};
use crate::target::{relative, search_tolerance, Reference, TargetOutcome};
use acdf::env::Environment;
use acdf::error::Result;
use acdf::material::Material;
use acdf::registry::{make_sampler_tabulated, AnySampler, SamplerOps, SamplerOptions, Tabulation};
use acdf::spec::{SamplerAt, SamplerSpec, SimplifierName};

/// What the survey measures with.
#[derive(Debug, Clone)]
pub struct SurveyConfig {
    /// The reference of compression and relative efficiency.
    pub reference: SamplerAt,
    /// Resolution of the samplers other than the reference.
    pub options: SamplerOptions,
    /// The fraction of the reference's efficiency `adaptive:chi2` is tuned
    /// to keep.
    pub target: f64,
    /// The noise-free measures and the timing.
    pub efficiency: EfficiencyConfig,
}

/// One (material, sampler) row.
#[derive(Debug, Clone, Serialize)]
pub struct SurveyRow {
    pub material: String,
    /// `uniform@32x16x256x32` (the reference), `uniform`, `adaptive:NAME`,
    /// `adaptive:chi2@target`, `cosine`.
    pub sampler: String,
    /// θ_o×φ_o×θ_h×φ_h, with mean kept vertices for adaptive samplers.
    pub resolution: String,
    pub tolerance: Option<f64>,
    pub storage_bytes: usize,
    /// Reference storage over this sampler's; `null` without tables.
    pub compression: Option<f64>,
    /// By quadrature.
    pub relative_variance: f64,
    pub firefly: f64,
    /// t_s, the sampler's own work per draw.
    pub seconds_per_sampler: f64,
    pub efficiency: Option<f64>,
    /// Efficiency over the reference's.
    pub relative_efficiency: Option<f64>,
    /// r(reference) / r: the variance's part of `relative_efficiency`.
    pub variance_ratio: Option<f64>,
    /// t_s(reference) / t_s: the time's part.
    pub time_ratio: Option<f64>,
    /// The share of Y(f) cos θ_i the sampler cannot draw, largest over the
    /// outgoing directions, on the quadrature grid.
    pub missed_share: f64,
    pub build_seconds: f64,
    /// For the target row: whether some tolerance met the target.
    pub target_reached: Option<bool>,
    /// For the target row: the search, every tolerance it tried.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub search: Option<TargetOutcome>,
}

/// The label of the row of `adaptive:chi2` at the target.
pub const TARGET_LABEL: &str = "adaptive:chi2@target";

/// The simplifier tuned to the target.
fn target_simplifier() -> SimplifierName {
    SimplifierName::find("chi2").unwrap_or_else(SimplifierName::default_simplifier)
}

/// `outgoing:chi2`, the outgoing sampler at its default tolerance.
fn outgoing_spec() -> SamplerSpec {
    format!("{}:{}", acdf::registry::OUTGOING, target_simplifier())
        .parse()
        .expect("the outgoing family takes the chi2 simplifier")
}

/// The sampler labels of a material's rows, in order.
pub fn survey_labels(reference: &SamplerAt) -> Vec<String> {
    let mut labels = vec![reference_label(reference), SamplerSpec::UNIFORM.to_string()];
    labels.extend(SimplifierName::all().map(|s| SamplerSpec::adaptive(s).to_string()));
    labels.push(TARGET_LABEL.to_string());
    labels.push(outgoing_spec().to_string());
    labels.push(SamplerSpec::COSINE.to_string());
    labels
}

fn reference_label(reference: &SamplerAt) -> String {
    reference.to_string()
}

struct Entry {
    label: String,
    sampler: AnySampler,
    tolerance: Option<f64>,
    build_seconds: f64,
    /// For the target row, the search.
    target: Option<TargetOutcome>,
    target_reached: Option<bool>,
}

/// `spec` at `options`, its tables from `tables` where they fit; the build
/// time counts the tabulation, as if built alone.
fn build(
    label: String,
    spec: SamplerSpec,
    material: &Material,
    options: &SamplerOptions,
    tables: &Tabulation,
) -> Result<Entry> {
    let start = Instant::now();
    let sampler = make_sampler_tabulated(spec, material, options, tables)?;
    // The uniform and adaptive samplers are built from the shared
    // tabulation; the outgoing one tabulates its own.
    let shared =
        if spec.family().file_kind.is_some() && spec.family().name != acdf::registry::OUTGOING {
            tables.seconds
        } else {
            0.0
        };
    Ok(Entry {
        label,
        tolerance: crate::sweep::spec_default_tolerance(spec)
            .map(|d| options.tolerance.unwrap_or(d)),
        sampler,
        build_seconds: start.elapsed().as_secs_f64() + shared,
        target: None,
        target_reached: None,
    })
}

/// Survey one material: the rows of [`survey_labels`], in that order.
/// The target search starts at `start_tolerance` (the previous material's
/// answer saves steps; `None` starts at the simplifier's default).
/// `progress` is called with what is being done.
pub fn survey_material(
    material: &Material,
    env: &dyn Environment,
    config: &SurveyConfig,
    start_tolerance: Option<f64>,
    mut progress: impl FnMut(&str),
) -> Result<Vec<SurveyRow>> {
    let reference_options = SamplerOptions {
        resolution: config
            .reference
            .resolution
            .unwrap_or(config.options.resolution),
        ..config.options
    };
    let mut entries = Vec::new();
    progress("reference");
    let reference_tables = Tabulation::by_rotation(material, reference_options.resolution);
    entries.push(build(
        reference_label(&config.reference),
        config.reference.sampler,
        material,
        &reference_options,
        &reference_tables,
    )?);
    drop(reference_tables);
    progress("tabulation");
    let tables = Tabulation::new(material, config.options.resolution);
    progress("uniform");
    entries.push(build(
        SamplerSpec::UNIFORM.to_string(),
        SamplerSpec::UNIFORM,
        material,
        &config.options,
        &tables,
    )?);
    for simplifier in SimplifierName::all() {
        let spec = SamplerSpec::adaptive(simplifier);
        progress(&spec.to_string());
        entries.push(build(
            spec.to_string(),
            spec,
            material,
            &config.options,
            &tables,
        )?);
    }
    progress("quadrature");
    let integrands = Integrands::new(material.brdf.as_ref(), env, &config.efficiency);
    let reference_rv = integrands.noise_free(&entries[0].sampler).relative_variance;
    let (outcome, sampler) = search_tolerance(
        material,
        SamplerSpec::adaptive(target_simplifier()),
        &SamplerOptions {
            tolerance: start_tolerance,
            ..config.options
        },
        &Reference {
            sampler: &entries[0].sampler,
            relative_variance: reference_rv,
        },
        &integrands,
        &tables,
        &config.efficiency,
        config.target,
        |t| progress(&format!("{TARGET_LABEL}: tolerance {t:.2e}")),
    )?;
    entries.push(Entry {
        label: TARGET_LABEL.to_string(),
        sampler,
        tolerance: Some(outcome.chosen.tolerance),
        build_seconds: outcome.chosen.build_seconds,
        target_reached: Some(outcome.reached),
        target: Some(outcome),
    });
    let outgoing = outgoing_spec();
    progress(&outgoing.to_string());
    entries.push(build(
        outgoing.to_string(),
        outgoing,
        material,
        &config.options,
        &tables,
    )?);
    progress("cosine");
    entries.push(build(
        SamplerSpec::COSINE.to_string(),
        SamplerSpec::COSINE,
        material,
        &config.options,
        &tables,
    )?);
    progress("timing");
    let samplers: Vec<&dyn BxdfSampler> = entries
        .iter()
        .map(|e| &e.sampler as &dyn BxdfSampler)
        .collect();
    let measured = measure_with(
        &integrands,
        material.brdf.as_ref(),
        &samplers,
        env,
        &config.efficiency,
    );
    let reference = &measured[0];
    let reference_storage = entries[0].sampler.storage_bytes();
    let label = material.label();
    let finite = |x: f64| x.is_finite().then_some(x);
    Ok(entries
        .iter()
        .zip(&measured)
        .map(|(e, m)| {
            let storage_bytes = e.sampler.storage_bytes();
            let rv = m.noise_free.relative_variance;
            // The target row keeps the timing that decided the search
            // (paired with the reference's), so that it meets the target
            // exactly when the search says it does.
            let (t, t_ref) = match &e.target {
                Some(o) => (o.chosen.sampler_seconds, o.chosen.reference_seconds),
                None => (
                    m.timing.sampler_seconds(),
                    reference.timing.sampler_seconds(),
                ),
            };
            let eff = efficiency_of(rv, t);
            let eff_ref = efficiency_of(reference.noise_free.relative_variance, t_ref);
            SurveyRow {
                material: label.clone(),
                sampler: e.label.clone(),
                resolution: e.sampler.resolution_label(),
                tolerance: e.tolerance,
                storage_bytes,
                compression: (storage_bytes > 0)
                    .then(|| reference_storage as f64 / storage_bytes as f64),
                relative_variance: rv,
                firefly: m.noise_free.firefly,
                seconds_per_sampler: t,
                efficiency: finite(eff),
                relative_efficiency: finite(relative(eff, eff_ref)),
                variance_ratio: (rv > 0.0)
                    .then(|| reference.noise_free.relative_variance / rv)
                    .and_then(finite),
                time_ratio: (t > 0.0).then(|| t_ref / t).and_then(finite),
                missed_share: m.noise_free.missed_share,
                build_seconds: e.build_seconds,
                target_reached: e.target_reached,
                search: e.target.clone(),
            }
        })
        .collect())
}

/// The q-quantile (0 ≤ q ≤ 1) of `values` by linear interpolation between
/// order statistics; `None` for none.
pub fn quantile(values: &[f64], q: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    Some(v[lo] + (v[hi] - v[lo]) * (pos - lo as f64))
}

/// One sampler's line of the summary.
#[derive(Debug, Clone, Serialize)]
pub struct SummaryRow {
    pub sampler: String,
    /// Materials with a relative efficiency.
    pub materials: usize,
    pub median_relative_efficiency: Option<f64>,
    pub p10_relative_efficiency: Option<f64>,
    /// The material of the lowest relative efficiency, and that value.
    pub worst_material: Option<String>,
    pub worst_relative_efficiency: Option<f64>,
    pub median_firefly: Option<f64>,
    /// Materials where the relative efficiency is at least the target.
    pub meeting_target: usize,
    /// Among those: the median and the least compression.
    pub median_compression_meeting: Option<f64>,
    pub worst_compression_meeting: Option<f64>,
    /// The materials below the target, lowest relative efficiency first.
    pub below_target: Vec<String>,
}

/// The summary of `rows` per sampler, in the order of `labels`.
pub fn summarize(rows: &[SurveyRow], labels: &[String], target: f64) -> Vec<SummaryRow> {
    labels
        .iter()
        .map(|label| {
            let mine: Vec<&SurveyRow> = rows.iter().filter(|r| &r.sampler == label).collect();
            let rel: Vec<f64> = mine.iter().filter_map(|r| r.relative_efficiency).collect();
            let worst = mine
                .iter()
                .filter_map(|r| r.relative_efficiency.map(|e| (e, r)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let meeting: Vec<&&SurveyRow> = mine
                .iter()
                .filter(|r| r.relative_efficiency.is_some_and(|e| e >= target))
                .collect();
            let compression: Vec<f64> = meeting.iter().filter_map(|r| r.compression).collect();
            let mut below: Vec<(f64, String)> = mine
                .iter()
                .filter_map(|r| {
                    r.relative_efficiency
                        .filter(|&e| e < target)
                        .map(|e| (e, r.material.clone()))
                })
                .collect();
            below.sort_by(|a, b| a.0.total_cmp(&b.0));
            let fireflies: Vec<f64> = mine.iter().map(|r| r.firefly).collect();
            SummaryRow {
                sampler: label.clone(),
                materials: rel.len(),
                median_relative_efficiency: quantile(&rel, 0.5),
                p10_relative_efficiency: quantile(&rel, 0.1),
                worst_material: worst.map(|w| w.1.material.clone()),
                worst_relative_efficiency: worst.map(|w| w.0),
                median_firefly: quantile(&fireflies, 0.5),
                meeting_target: meeting.len(),
                median_compression_meeting: quantile(&compression, 0.5),
                worst_compression_meeting: compression.iter().copied().reduce(f64::min),
                below_target: below.into_iter().map(|(_, m)| m).collect(),
            }
        })
        .collect()
}

/// The summary as a Markdown table.
pub fn format_summary(summary: &[SummaryRow], target: f64) -> String {
    let o = |x: Option<f64>, digits: usize| {
        x.map_or_else(|| "-".to_string(), |v| format!("{v:.digits$}"))
    };
    let mut out = format!(
        "| sampler | median rel. eff. | 10th percentile | worst material | materials ≥ {target} | \
         compression where ≥ {target}: median | least | median firefly |\n\
         |:--|--:|--:|:--|--:|--:|--:|--:|\n"
    );
    for s in summary {
        let worst = match (&s.worst_material, s.worst_relative_efficiency) {
            (Some(m), Some(e)) => format!("{m} ({e:.3})"),
            _ => "-".into(),
        };
        out.push_str(&format!(
            "| {} | {} | {} | {worst} | {}/{} | {} | {} | {} |\n",
            s.sampler,
            o(s.median_relative_efficiency, 3),
            o(s.p10_relative_efficiency, 3),
            s.meeting_target,
            s.materials,
            o(s.median_compression_meeting, 1),
            o(s.worst_compression_meeting, 1),
            o(s.median_firefly, 0),
        ));
    }
    out
}

/// The CSV header of [`write_csv`].
pub const CSV_HEADER: &str = "material,sampler,resolution,tolerance,storage_bytes,compression,\
relative_variance,firefly,ns_per_sampler,efficiency,relative_efficiency,variance_ratio,\
time_ratio,missed_share,build_seconds,target_reached";

/// Write the rows as CSV (empty fields for missing values).
pub fn write_csv(rows: &[SurveyRow], out: &mut impl Write) -> std::io::Result<()> {
    let o = |x: Option<f64>| x.map(|v| format!("{v}")).unwrap_or_default();
    writeln!(out, "{CSV_HEADER}")?;
    for r in rows {
        writeln!(
            out,
            "{},{},{},{},{},{},{},{},{:.2},{},{},{},{},{},{:.4},{}",
            r.material,
            r.sampler,
            r.resolution,
            o(r.tolerance),
            r.storage_bytes,
            o(r.compression),
            r.relative_variance,
            r.firefly,
            r.seconds_per_sampler * 1e9,
            o(r.efficiency),
            o(r.relative_efficiency),
            o(r.variance_ratio),
            o(r.time_ratio),
            r.missed_share,
            r.build_seconds,
            r.target_reached.map_or(String::new(), |b| b.to_string()),
        )?;
    }
    Ok(())
}

/// The survey's scatter plot: compression against the reference (x)
/// against relative efficiency (y), one point per material and sampler
/// with tables; samplers without tables are printed as the median of
/// their relative efficiency. Returns the SVG text and the PNG bytes.
pub fn plot_survey(
    rows: &[SurveyRow],
    labels: &[String],
    title: &str,
    name: &Path,
) -> Result<(String, Vec<u8>)> {
    let mut series = Vec::new();
    let mut notes = Vec::new();
    let mut markers = Vec::new();
    for (k, label) in labels.iter().enumerate() {
        let mine: Vec<&SurveyRow> = rows.iter().filter(|r| &r.sampler == label).collect();
        if k == 0 {
            markers.push(Marker {
                label: format!("{label} (reference)"),
                point: (1.0, 1.0),
            });
            continue;
        }
        let points: Vec<(f64, f64)> = mine
            .iter()
            .filter_map(|r| Some((r.compression?, r.relative_efficiency?)))
            .collect();
        if points.is_empty() {
            let rel: Vec<f64> = mine.iter().filter_map(|r| r.relative_efficiency).collect();
            if let Some(m) = quantile(&rel, 0.5) {
                notes.push(format!("{label} (no tables): median rel. eff. {m:.2e}"));
            }
            continue;
        }
        series.push(Series {
            label: label.clone(),
            points,
            style: Style::Points,
        });
    }
    let figure = Figure {
        title: title.to_string(),
        panels: vec![Panel {
            x_label: "compression against the reference (storage ratio)".into(),
            y_label: "efficiency relative to the reference".into(),
            series,
            markers,
            notes,
            legend: true,
        }],
    };
    figure_bytes(&figure, name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_interpolate() {
        let v = [5.0, 1.0, 3.0, 2.0, 4.0];
        assert_eq!(quantile(&v, 0.5), Some(3.0));
        assert_eq!(quantile(&v, 0.0), Some(1.0));
        assert_eq!(quantile(&v, 1.0), Some(5.0));
        assert!((quantile(&v, 0.1).unwrap() - 1.4).abs() < 1e-12);
        assert_eq!(quantile(&[], 0.5), None);
        assert_eq!(quantile(&[f64::NAN, 2.0], 0.5), Some(2.0));
    }

    fn row(material: &str, sampler: &str, rel: f64, compression: f64) -> SurveyRow {
        SurveyRow {
            material: material.into(),
            sampler: sampler.into(),
            resolution: "-".into(),
            tolerance: None,
            storage_bytes: 1,
            compression: Some(compression),
            relative_variance: 1.0,
            firefly: 2.0,
            seconds_per_sampler: 1e-7,
            efficiency: Some(rel),
            relative_efficiency: Some(rel),
            variance_ratio: Some(rel),
            time_ratio: Some(1.0),
            missed_share: 0.0,
            build_seconds: 0.1,
            target_reached: None,
            search: None,
        }
    }

    /// The summary counts the materials that meet the target and takes the
    /// compression among those only; the worst material is the least
    /// efficient.
    #[test]
    fn summary_of_a_small_survey() {
        let rows = [
            row("a", "s", 1.2, 10.0),
            row("b", "s", 0.9, 50.0),
            row("c", "s", 0.96, 20.0),
            row("a", "t", 0.5, 2.0),
        ];
        let labels = ["s".to_string(), "t".to_string()];
        let summary = summarize(&rows, &labels, 0.95);
        let s = &summary[0];
        assert_eq!(s.materials, 3);
        assert_eq!(s.meeting_target, 2);
        assert_eq!(s.worst_material.as_deref(), Some("b"));
        assert_eq!(s.median_compression_meeting, Some(15.0));
        assert_eq!(s.worst_compression_meeting, Some(10.0));
        assert_eq!(s.below_target, ["b"]);
        assert_eq!(summary[1].below_target, ["a"]);
        let table = format_summary(&summary, 0.95);
        assert_eq!(table.lines().count(), 4);
        assert!(
            table.contains("| s | 0.960 |") && table.contains("b (0.900)"),
            "{table}"
        );
    }
}
