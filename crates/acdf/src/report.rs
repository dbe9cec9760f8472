//! The results table: for one material, every sampler's storage, the
//! compression against the uniform tabulation, and its estimator efficiency
//! (see [`efficiency`](crate::efficiency)), absolute and relative to the
//! uniform sampler, and the share of the reflected light it can never draw
//! ([`missed_share`](crate::efficiency::missed_share)).

use std::time::Instant;

use acdf_core::BxdfSampler;
use serde::Serialize;

use crate::efficiency::{
    measure_efficiencies, missed_shares, Efficiency, EfficiencyConfig, HemisphereGrid,
    MISSED_SHARE_THETA_O,
};
use crate::env::Environment;
use crate::error::Result;
use crate::material::Material;
use crate::registry::{make_sampler_spec, SamplerOps, SamplerOptions};
use crate::spec::SamplerSpec;

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
    /// Heap bytes of the sampler's tables, all slices built.
    pub storage_bytes: usize,
    /// storage(uniform) / storage(sampler); `null` for a sampler without
    /// tables.
    pub compression_ratio: Option<f64>,
    /// Seconds to build every table (in parallel).
    pub build_seconds: f64,
    /// The estimate of the mean reflected luminance (a consistency check:
    /// unbiased samplers agree within a few `estimate_se`).
    pub estimate: f64,
    pub estimate_se: f64,
    /// V, the per-direction variance of the one-sample estimator, averaged.
    pub variance: f64,
    /// Relative standard error of `variance`.
    pub variance_rel_se: f64,
    /// Draws behind `variance`.
    pub samples: usize,
    /// t = t_sample + v (t_eval + t_pdf).
    pub seconds_per_sample: f64,
    pub seconds_per_draw: f64,
    pub seconds_per_pdf: f64,
    pub seconds_per_eval: f64,
    /// 1 / (V t); `null` if V is 0.
    pub efficiency: Option<f64>,
    /// efficiency / efficiency(uniform).
    pub relative_efficiency: Option<f64>,
    /// The missed share ∫_{p=0} Y(f) cos θ_i dω / ∫ Y(f) cos θ_i dω at each
    /// outgoing angle of `missed_share_theta_o` (φ_o =
    /// [`MISSED_SHARE_PHI_O`](crate::efficiency::MISSED_SHARE_PHI_O)), by the midpoint rule on
    /// [`HemisphereGrid::REPORT`]: the bias of the sampler used alone.
    pub missed_share: Vec<f64>,
    /// θ_o in degrees of each entry of `missed_share`.
    pub missed_share_theta_o: Vec<f32>,
    /// The largest entry of `missed_share`.
    pub missed_share_max: f64,
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// A measured sampler, before it is compared with the uniform one.
struct Measured {
    spec: SamplerSpec,
    name: String,
    resolution: String,
    storage_bytes: usize,
    build_seconds: f64,
    efficiency: Efficiency,
    missed: Vec<f64>,
}

/// Measure each sampler of `samplers` on `material` (the default set is
/// [`report_samplers`](crate::registry::report_samplers)). `progress` is
/// called with each sampler's name before it is built, and with "timing"
/// before the samplers' timed passes, which run in turns
/// ([`measure_efficiencies`]) so that their times are compared under the
/// same conditions.
pub fn report_material(
    material: &Material,
    samplers: &[SamplerSpec],
    env: &dyn Environment,
    options: &SamplerOptions,
    config: &EfficiencyConfig,
    mut progress: impl FnMut(&str),
) -> Result<Vec<ReportRow>> {
    let mut built = Vec::new();
    for &spec in samplers {
        progress(&spec.to_string());
        let sampler = make_sampler_spec(spec, material, options)?;
        let start = Instant::now();
        sampler.build_all()?;
        built.push((spec, sampler, start.elapsed().as_secs_f64()));
    }
    progress("timing");
    let samplers: Vec<&dyn BxdfSampler> = built
        .iter()
        .map(|(_, sampler, _)| sampler as &dyn BxdfSampler)
        .collect();
    let efficiencies = measure_efficiencies(material.brdf.as_ref(), &samplers, env, config);
    let measured: Vec<Measured> = built
        .iter()
        .zip(efficiencies)
        .map(|((spec, sampler, build_seconds), efficiency)| Measured {
            spec: *spec,
            name: spec.to_string(),
            resolution: sampler.resolution_label(),
            storage_bytes: sampler.storage_bytes(),
            build_seconds: *build_seconds,
            efficiency,
            missed: missed_shares(material.brdf.as_ref(), sampler, HemisphereGrid::REPORT),
        })
        .collect();
    let uniform = measured.iter().find(|m| m.spec == SamplerSpec::UNIFORM);
    let uniform_storage = uniform.map(|m| m.storage_bytes as f64);
    let uniform_eff = uniform.map(|m| m.efficiency.efficiency);
    let label = material.label();
    Ok(measured
        .iter()
        .map(|m| {
            let e = &m.efficiency;
            ReportRow {
                material: label.clone(),
                sampler: m.name.clone(),
                resolution: m.resolution.clone(),
                storage_bytes: m.storage_bytes,
                compression_ratio: match (uniform_storage, m.storage_bytes) {
                    (Some(u), s) if s > 0 => Some(u / s as f64),
                    _ => None,
                },
                build_seconds: m.build_seconds,
                estimate: e.estimate,
                estimate_se: e.estimate_se,
                variance: e.variance,
                variance_rel_se: e.variance_rel_se,
                samples: e.samples,
                seconds_per_sample: e.seconds_per_sample,
                seconds_per_draw: e.timing.seconds_per_draw,
                seconds_per_pdf: e.timing.seconds_per_pdf,
                seconds_per_eval: e.timing.seconds_per_eval,
                efficiency: finite(e.efficiency),
                relative_efficiency: uniform_eff.and_then(|u| finite(e.efficiency / u)),
                missed_share: m.missed.clone(),
                missed_share_theta_o: MISSED_SHARE_THETA_O.to_vec(),
                missed_share_max: m.missed.iter().copied().fold(0.0, f64::max),
            }
        })
        .collect())
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
/// table (φ_o = 1 rad; the grid of [`HemisphereGrid::REPORT`]).
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

/// The rows as a Markdown table.
pub fn format_table(rows: &[ReportRow]) -> String {
    let header = [
        "material",
        "sampler",
        "resolution",
        "storage",
        "compression",
        "estimate",
        "variance (±rel)",
        "ns/sample",
        "efficiency (1/s)",
        "rel. eff.",
        "missed (max)",
    ];
    let body: Vec<[String; 11]> = rows
        .iter()
        .map(|r| {
            [
                r.material.clone(),
                r.sampler.clone(),
                r.resolution.clone(),
                human_bytes(r.storage_bytes),
                opt(r.compression_ratio, |c| format!("{c:.1}x")),
                format!("{:.4}", r.estimate),
                format!("{:.4e} (±{:.0}%)", r.variance, 100.0 * r.variance_rel_se),
                format!("{:.0}", r.seconds_per_sample * 1e9),
                opt(r.efficiency, |e| format!("{e:.3e}")),
                opt(r.relative_efficiency, |e| format!("{e:.2}")),
                share(r.missed_share_max),
            ]
        })
        .collect();
    let header: Vec<String> = header.iter().map(|h| h.to_string()).collect();
    let body: Vec<Vec<String>> = body.into_iter().map(Vec::from).collect();
    markdown(&header, &body, 3)
}

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
            storage_bytes: 0,
            compression_ratio: None,
            build_seconds: 0.0,
            estimate: 1.0,
            estimate_se: 0.0,
            variance: 2.0,
            variance_rel_se: 0.01,
            samples: 10,
            seconds_per_sample: 1e-8,
            seconds_per_draw: 1e-8,
            seconds_per_pdf: 0.0,
            seconds_per_eval: 0.0,
            efficiency: Some(5e7),
            relative_efficiency: None,
            missed_share: vec![0.0, 2.5e-3],
            missed_share_theta_o: vec![0.0, 85.0],
            missed_share_max: 2.5e-3,
        };
        let t = format_table(&[row.clone(), row.clone()]);
        assert_eq!(t.lines().count(), 4);
        assert!(t.contains("cosine") && t.contains("5.000e7") && t.contains("2.50e-3"));
        assert_eq!(format_missed_table(&[row]).lines().count(), 3);
        assert_eq!(human_bytes(2048), "2.0 KiB");
    }
}
