//! What `acdf env-report` measures: for an environment map and each
//! environment sampler, the storage of its tables, the variance of the
//! irradiance estimator over a fixed set of normals, the time per sample,
//! and the efficiency relative to the uniform sampler.
//!
//! # The measure
//!
//! For a normal n, the irradiance is E(n) = ∫ Y(L(ω)) max(0, n·ω) dω (Y the
//! luminance of the nearest texel, the function the samplers follow), and
//! the one-sample estimator F = Y(L(ω)) max(0, n·ω) / p(ω) with ω drawn by
//! the sampler for n (a failed draw gives F = 0). Its variance is
//! V(n) = ∫_{p>0} Y² max(0, n·ω)² / p dω − (E(n) − M(n))², where M(n) is the
//! part of E(n) on directions of density 0 (the bias of a sampler that
//! does not cover the map, such as the compensated ones).
//!
//! Every sampler of acdf has a density that is constant over each texel, as
//! is the nearest-texel radiance, so the integrals are sums over texels of
//! Y, Y²/p and the texel's moments ∫ max(0, n·ω) dω and ∫ max(0, n·ω)² dω.
//! Those are exact in closed form for the texels entirely above or below
//! the horizon of n, and by an 8 × 8 midpoint rule (equal solid angle) for
//! the few that the horizon cuts: the variance is without sampling noise.
//! A Monte Carlo estimate with the sampler's own draws is reported beside
//! it as a check.
//!
//! The relative variance V(n) / E(n)² is averaged over the normals
//! ([`standard_normals`], those with E > 0), so that every orientation
//! counts alike whatever its brightness. The time t is that of one
//! `sample` call plus the radiance lookup of the drawn direction, the
//! normal changing on every call as in a renderer, one thread, the fastest
//! of the passes; efficiency is 1 / (mean relative variance × t).

use std::hint::black_box;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use acdf_core::{SphereSampler, Vec2, Vec3};
use acdf_lights::EnvMap;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

use crate::report::{human_bytes, markdown};
use acdf::env_registry::{make_env_sampler_spec, EnvSamplerOptions, EnvSamplerSpec};
use acdf::error::Result;

/// `count` normals spread evenly over the sphere: the spherical Fibonacci
/// set z_i = 1 − (2i + 1)/count, φ_i = i · golden angle (none at a pole).
pub fn fibonacci_normals(count: usize) -> Vec<Vec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - (2 * i + 1) as f64 / count as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32)
        })
        .collect()
}

/// The fixed normals of every environment report: 32 of the Fibonacci
/// set, plus the two poles.
pub fn standard_normals() -> Vec<Vec3> {
    let mut normals = fibonacci_normals(32);
    normals.extend([Vec3::Z, -Vec3::Z]);
    normals
}

/// The closed-form moments of every row band and column wedge of a map's
/// grid, in f64: for row j (θ from θ0 to θ1, with the measure sin θ dθ)
/// ∫ sin θ, ∫ sin²θ, ∫ cos θ sin θ, ∫ sin³θ, ∫ cos²θ sin θ, ∫ sin²θ cos θ;
/// for column k (φ from φ0 to φ1) Δφ, ∫ cos, ∫ sin, ∫ cos², ∫ sin², ∫ sin cos.
struct Moments {
    rows: Vec<[f64; 6]>,
    columns: Vec<[f64; 6]>,
    /// Per row: (sin, cos) of the centre in cos θ and the angular radius.
    row_centre: Vec<(f64, f64, f64)>,
    /// Per column: (cos, sin) of the centre.
    column_centre: Vec<(f64, f64)>,
}

impl Moments {
    fn new(map: &EnvMap) -> Moments {
        let grid = map.grid();
        let (w, h) = grid.size();
        let rows = (0..h)
            .map(|j| {
                let (t0, t1) = grid.row_thetas(j);
                let f = |t: f64| {
                    let (s, c) = t.sin_cos();
                    [
                        -c,
                        0.5 * t - 0.25 * (2.0 * t).sin(),
                        0.5 * s * s,
                        -c + c * c * c / 3.0,
                        -c * c * c / 3.0,
                        s * s * s / 3.0,
                    ]
                };
                let (a, b) = (f(t0), f(t1));
                std::array::from_fn(|i| b[i] - a[i])
            })
            .collect();
        let columns = (0..w)
            .map(|k| {
                let (p0, p1) = grid.column_phis(k);
                let f = |p: f64| {
                    let (s, c) = p.sin_cos();
                    [
                        p,
                        s,
                        -c,
                        0.5 * p + 0.25 * (2.0 * p).sin(),
                        0.5 * p - 0.25 * (2.0 * p).sin(),
                        0.5 * s * s,
                    ]
                };
                let (a, b) = (f(p0), f(p1));
                std::array::from_fn(|i| b[i] - a[i])
            })
            .collect();
        let row_centre = (0..h)
            .map(|j| {
                let (t0, t1) = grid.row_thetas(j);
                let c = 0.5 * (t0.cos() + t1.cos());
                ((1.0 - c * c).max(0.0).sqrt(), c, grid.texel_radius(j))
            })
            .collect();
        let column_centre = (0..w)
            .map(|k| {
                let (p0, p1) = grid.column_phis(k);
                let p = 0.5 * (p0 + p1);
                (p.cos(), p.sin())
            })
            .collect();
        Moments {
            rows,
            columns,
            row_centre,
            column_centre,
        }
    }

    /// (∫ max(0, n·ω) dω, ∫ max(0, n·ω)² dω) over texel (k, j).
    fn texel(&self, map: &EnvMap, n: [f64; 3], k: usize, j: usize) -> (f64, f64) {
        let (st, ct, r) = self.row_centre[j];
        let (cp, sp) = self.column_centre[k];
        let c = (n[0] * st * cp + n[1] * st * sp + n[2] * ct).clamp(-1.0, 1.0);
        let alpha = c.acos();
        if alpha + r <= 0.5 * std::f64::consts::PI {
            let [_, a1, b1, a2, b2, c2] = self.rows[j];
            let [p0, pc, ps, pcc, pss, pcs] = self.columns[k];
            let m1 = [a1 * pc, a1 * ps, b1 * p0];
            let i1 = n[0] * m1[0] + n[1] * m1[1] + n[2] * m1[2];
            let i2 = n[0] * n[0] * a2 * pcc
                + n[1] * n[1] * a2 * pss
                + n[2] * n[2] * b2 * p0
                + 2.0 * n[0] * n[1] * a2 * pcs
                + 2.0 * n[0] * n[2] * c2 * pc
                + 2.0 * n[1] * n[2] * c2 * ps;
            (i1.max(0.0), i2.max(0.0))
        } else if alpha - r >= 0.5 * std::f64::consts::PI {
            (0.0, 0.0)
        } else {
            const S: usize = 8;
            let grid = map.grid();
            let omega = grid.texel_solid_angle(j) / (S * S) as f64;
            let nv = Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32);
            let (mut i1, mut i2) = (0.0, 0.0);
            for a in 0..S {
                for b in 0..S {
                    let f = Vec2::new((a as f32 + 0.5) / S as f32, (b as f32 + 0.5) / S as f32);
                    let d = grid.direction_in_texel(k, j, f);
                    let c = (nv.dot(d) as f64).max(0.0);
                    i1 += c * omega;
                    i2 += c * c * omega;
                }
            }
            (i1, i2)
        }
    }
}

/// The irradiance estimator's moments for one normal, by quadrature.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IrradianceQuadrature {
    /// E(n) = ∫ Y(L) max(0, n·ω) dω.
    pub irradiance: f64,
    /// ∫_{p>0} Y² max(0, n·ω)² / p dω.
    pub second_moment: f64,
    /// ∫_{p=0} Y max(0, n·ω) dω: what the sampler cannot draw.
    pub missed: f64,
}

impl IrradianceQuadrature {
    /// The variance of the one-sample estimator.
    pub fn variance(&self) -> f64 {
        let mean = self.irradiance - self.missed;
        (self.second_moment - mean * mean).max(0.0)
    }

    /// V / E², `None` when E = 0.
    pub fn relative_variance(&self) -> Option<f64> {
        (self.irradiance > 0.0).then(|| self.variance() / (self.irradiance * self.irradiance))
    }

    /// M / E, 0 when E = 0.
    pub fn missed_share(&self) -> f64 {
        if self.irradiance > 0.0 {
            self.missed / self.irradiance
        } else {
            0.0
        }
    }
}

/// The texel-centre directions of a map, row-major.
fn texel_directions(map: &EnvMap) -> Vec<Vec3> {
    let grid = map.grid();
    let (w, h) = grid.size();
    (0..h)
        .flat_map(|j| (0..w).map(move |k| grid.texel_direction(k, j)))
        .collect()
}

/// The irradiance estimator's moments of `sampler` for `normal` on `map`
/// (see the module documentation), summed in f64 over the texels.
pub fn irradiance_quadrature(
    map: &EnvMap,
    sampler: &dyn SphereSampler,
    normal: Vec3,
) -> IrradianceQuadrature {
    let moments = Moments::new(map);
    let centres = texel_directions(map);
    quadrature_with(map, &moments, &centres, sampler, normal)
}

fn quadrature_with(
    map: &EnvMap,
    moments: &Moments,
    centres: &[Vec3],
    sampler: &dyn SphereSampler,
    normal: Vec3,
) -> IrradianceQuadrature {
    let grid = map.grid();
    let (w, h) = grid.size();
    let n = normal.normalize();
    let nd = [n.x as f64, n.y as f64, n.z as f64];
    let lum = map.luminance();
    let mut pdf = vec![0.0f32; w];
    let (mut e, mut s2, mut missed) = (0.0f64, 0.0f64, 0.0f64);
    for j in 0..h {
        sampler.pdf_batch(Some(n), &centres[j * w..(j + 1) * w], &mut pdf);
        for (k, &p) in pdf.iter().enumerate() {
            let y = lum[j * w + k] as f64;
            if y <= 0.0 {
                continue;
            }
            let (i1, i2) = moments.texel(map, nd, k, j);
            if i1 <= 0.0 {
                continue;
            }
            e += y * i1;
            if p > 0.0 && p.is_finite() {
                s2 += y * y * i2 / p as f64;
            } else {
                missed += y * i1;
            }
        }
    }
    IrradianceQuadrature {
        irradiance: e,
        second_moment: s2,
        missed,
    }
}

/// The mean and variance of `n` draws of the irradiance estimator of
/// `sampler` for `normal` (uniform numbers from PCG64 seeded with `seed`).
pub fn irradiance_monte_carlo(
    map: &EnvMap,
    sampler: &dyn SphereSampler,
    normal: Vec3,
    n: usize,
    seed: u64,
) -> (f64, f64) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let normal = normal.normalize();
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for _ in 0..n {
        let u = Vec2::new(rng.random(), rng.random());
        let f = estimate(map, sampler, normal, u);
        sum += f;
        sum2 += f * f;
    }
    let count = n.max(1) as f64;
    let mean = sum / count;
    let var = (sum2 / count - mean * mean).max(0.0) * count / (count - 1.0).max(1.0);
    (mean, var)
}

/// One draw of the irradiance estimator.
#[inline(always)]
fn estimate(map: &EnvMap, sampler: &dyn SphereSampler, normal: Vec3, u: Vec2) -> f64 {
    match sampler.sample(Some(normal), u) {
        Some(s) => {
            let y = acdf_core::luminance(map.radiance(s.dir)) as f64;
            y * (normal.dot(s.dir).max(0.0) as f64) / s.pdf as f64
        }
        None => 0.0,
    }
}

/// Seconds per `sample` call plus radiance lookup, one thread, cycling
/// through `normals` call by call; the fastest of `passes` passes of
/// `draws` calls.
pub fn time_per_sample(
    map: &EnvMap,
    sampler: &dyn SphereSampler,
    normals: &[Vec3],
    draws: usize,
    passes: usize,
    seed: u64,
) -> f64 {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let u: Vec<Vec2> = (0..draws.max(1))
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect();
    let normals: Vec<Vec3> = normals.iter().map(|n| n.normalize()).collect();
    let mut best = f64::INFINITY;
    for _ in 0..passes.max(1) {
        let start = Instant::now();
        let mut acc = 0.0f64;
        for (i, &u) in u.iter().enumerate() {
            let n = normals[i % normals.len()];
            acc += estimate(map, sampler, black_box(n), black_box(u));
        }
        black_box(acc);
        best = best.min(start.elapsed().as_secs_f64() / u.len() as f64);
    }
    best
}

/// How `env-report` measures.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvReportConfig {
    /// The normals of the irradiance estimator.
    pub normals: Vec<Vec3>,
    /// Monte Carlo draws per normal for the check beside the quadrature.
    pub mc_samples: usize,
    /// Draws per timed pass (the normal changing every call).
    pub timing_samples: usize,
    /// Timed passes, the fastest kept.
    pub timing_passes: usize,
    /// Seed of the uniform numbers.
    pub seed: u64,
}

impl Default for EnvReportConfig {
    /// [`standard_normals`], 2^14 Monte Carlo draws per normal, 9 timed
    /// passes of 2^16 draws, seed 2005.
    fn default() -> Self {
        EnvReportConfig {
            normals: standard_normals(),
            mc_samples: 1 << 14,
            timing_samples: 1 << 16,
            timing_passes: 9,
            seed: 2005,
        }
    }
}

/// One line of the environment report: a sampler on a map.
#[derive(Debug, Clone, Serialize)]
pub struct EnvReportRow {
    pub map: String,
    pub path: PathBuf,
    pub sampler: String,
    /// The tables: texel grid, kept vertices, or normal cells built.
    pub tables: String,
    /// Heap bytes of the tables (for `oriented`, of what the report's
    /// normals built).
    pub storage_bytes: usize,
    /// Uniform's storage divided by this sampler's.
    pub compression: Option<f64>,
    /// For `oriented`: nodes (normal cells and poles) built, of all.
    pub built_nodes: Option<(usize, usize)>,
    /// Seconds to build the tables the report used.
    pub build_seconds: f64,
    /// Mean over the normals of V(n) / E(n)², by quadrature.
    pub relative_variance: f64,
    /// The same from the Monte Carlo draws.
    pub mc_relative_variance: f64,
    /// The largest share of E(n) the sampler cannot draw, over the normals.
    pub missed_share: f64,
    pub ns_per_sample: f64,
    /// 1 / (relative variance × seconds per sample).
    pub efficiency: f64,
    /// Efficiency divided by the uniform sampler's on the same map.
    pub relative_efficiency: Option<f64>,
    /// The uniform sampler's relative variance divided by this one's: the
    /// relative efficiency without the timing, free of sampling noise and
    /// of the machine's load.
    pub variance_ratio: Option<f64>,
    /// Per normal: (normal, E, V/E² by quadrature, V/E² by Monte Carlo,
    /// missed share).
    pub per_normal: Vec<NormalLine>,
}

/// One normal's figures in a report row.
#[derive(Debug, Clone, Serialize)]
pub struct NormalLine {
    pub normal: [f32; 3],
    pub irradiance: f64,
    pub relative_variance: Option<f64>,
    pub mc_relative_variance: Option<f64>,
    pub mc_mean: f64,
    pub missed_share: f64,
}

/// One sampler of a report: its label in the table, its name and options.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportedSampler {
    pub label: String,
    pub spec: EnvSamplerSpec,
    pub options: EnvSamplerOptions,
}

impl ReportedSampler {
    /// The sampler `spec` with `options`, labelled by its name.
    pub fn new(spec: EnvSamplerSpec, options: EnvSamplerOptions) -> Self {
        ReportedSampler {
            label: spec.to_string(),
            spec,
            options,
        }
    }
}

/// Build each sampler for `map` and measure it (see the module
/// documentation). The timed passes go round the samplers in turns, so
/// that a change in the machine's load reaches them alike. The relative
/// columns divide by the `uniform` row when there is one; they stay empty
/// for the compensated samplers, which are biased alone.
pub fn report_map(
    label: &str,
    path: PathBuf,
    map: Arc<EnvMap>,
    samplers: &[ReportedSampler],
    config: &EnvReportConfig,
    mut progress: impl FnMut(&str),
) -> Result<Vec<EnvReportRow>> {
    let moments = Moments::new(&map);
    let centres = texel_directions(&map);
    let mut rows = Vec::new();
    let mut built = Vec::new();
    for reported in samplers {
        progress(&format!("{label}: {}", reported.label));
        let start = Instant::now();
        let sampler = make_env_sampler_spec(reported.spec, &map, &reported.options)?;
        // Build what the normals need before anything is timed.
        for &n in &config.normals {
            sampler.pdf(Some(n.normalize()), Vec3::Z);
        }
        let build_seconds = start.elapsed().as_secs_f64();
        let per_normal: Vec<NormalLine> = config
            .normals
            .par_iter()
            .enumerate()
            .map(|(i, &n)| {
                let q = quadrature_with(&map, &moments, &centres, &sampler, n);
                let (mc_mean, mc_var) = irradiance_monte_carlo(
                    &map,
                    &sampler,
                    n,
                    config.mc_samples,
                    config.seed.wrapping_add(i as u64),
                );
                let e2 = q.irradiance * q.irradiance;
                NormalLine {
                    normal: n.normalize().to_array(),
                    irradiance: q.irradiance,
                    relative_variance: q.relative_variance(),
                    mc_relative_variance: (e2 > 0.0).then(|| mc_var / e2),
                    mc_mean,
                    missed_share: q.missed_share(),
                }
            })
            .collect();
        let mean = |f: &dyn Fn(&NormalLine) -> Option<f64>| {
            let v: Vec<f64> = per_normal.iter().filter_map(f).collect();
            v.iter().sum::<f64>() / v.len().max(1) as f64
        };
        let relative_variance = mean(&|l| l.relative_variance);
        rows.push(EnvReportRow {
            map: label.to_string(),
            path: path.clone(),
            sampler: reported.label.clone(),
            tables: sampler.table_label(),
            storage_bytes: sampler.storage_bytes(),
            compression: None,
            built_nodes: sampler.built_nodes(),
            build_seconds,
            relative_variance,
            mc_relative_variance: mean(&|l| l.mc_relative_variance),
            missed_share: per_normal
                .iter()
                .map(|l| l.missed_share)
                .fold(0.0, f64::max),
            ns_per_sample: f64::INFINITY,
            efficiency: 0.0,
            relative_efficiency: None,
            variance_ratio: None,
            per_normal,
        });
        built.push(sampler);
    }
    progress(&format!("{label}: timing"));
    for pass in 0..config.timing_passes.max(1) {
        for (row, sampler) in rows.iter_mut().zip(&built) {
            let seconds = time_per_sample(
                &map,
                sampler,
                &config.normals,
                config.timing_samples,
                1,
                config.seed.wrapping_add(pass as u64),
            );
            row.ns_per_sample = row.ns_per_sample.min(seconds * 1e9);
        }
    }
    for row in &mut rows {
        row.efficiency = 1e9 / (row.relative_variance * row.ns_per_sample);
    }
    let uniform = EnvSamplerSpec::UNIFORM.to_string();
    if let Some(u) = rows.iter().find(|r| r.sampler == uniform).cloned() {
        for (r, s) in rows.iter_mut().zip(&built) {
            r.compression =
                (r.storage_bytes > 0).then(|| u.storage_bytes as f64 / r.storage_bytes as f64);
            if !s.is_compensated() {
                r.relative_efficiency = Some(r.efficiency / u.efficiency).filter(|e| e.is_finite());
                r.variance_ratio =
                    Some(u.relative_variance / r.relative_variance).filter(|e| e.is_finite());
            }
        }
    }
    Ok(rows)
}

/// The rows as a Markdown table.
pub fn format_env_table(rows: &[EnvReportRow]) -> String {
    let header: Vec<String> = [
        "map",
        "sampler",
        "tables",
        "storage",
        "compression",
        "rel. variance",
        "(Monte Carlo)",
        "missed (max)",
        "ns/sample",
        "efficiency (1/s)",
        "rel. eff.",
        "variance ratio",
    ]
    .map(String::from)
    .to_vec();
    let opt = |x: Option<f64>, f: &dyn Fn(f64) -> String| x.map(f).unwrap_or_else(|| "-".into());
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.map.clone(),
                r.sampler.clone(),
                r.tables.clone(),
                human_bytes(r.storage_bytes),
                opt(r.compression, &|c| format!("{c:.1}x")),
                format!("{:.4e}", r.relative_variance),
                format!("{:.4e}", r.mc_relative_variance),
                if r.missed_share == 0.0 {
                    "0".into()
                } else {
                    format!("{:.2e}", r.missed_share)
                },
                format!("{:.0}", r.ns_per_sample),
                format!("{:.3e}", r.efficiency),
                opt(r.relative_efficiency, &|e| format!("{e:.2}")),
                opt(r.variance_ratio, &|e| format!("{e:.3}")),
            ]
        })
        .collect();
    markdown(&header, &body, 3)
}

/// The figure of a report: one panel per map, the mean relative variance
/// against storage, the uniform sampler as the marked point and one line
/// per other family (through its simplifiers or normal grids, by storage).
/// The compensated samplers are left out: alone they are biased.
pub fn env_figure(rows: &[EnvReportRow]) -> crate::plot::Figure {
    let mut maps: Vec<&str> = Vec::new();
    for r in rows {
        if !maps.contains(&r.map.as_str()) {
            maps.push(&r.map);
        }
    }
    let panels = maps
        .iter()
        .enumerate()
        .map(|(i, &m)| {
            let of_map: Vec<&EnvReportRow> = rows
                .iter()
                .filter(|r| r.map == m && !r.sampler.contains("-comp"))
                .collect();
            let uniform = of_map
                .iter()
                .find(|r| r.sampler == EnvSamplerSpec::UNIFORM.to_string())
                .map_or((0.0, 0.0), |r| {
                    (r.storage_bytes as f64, r.relative_variance)
                });
            let mut series: Vec<crate::plot::Series> = Vec::new();
            for r in of_map.iter().filter(|r| r.sampler != "uniform") {
                let family = r.sampler.split(':').next().unwrap_or("").to_string();
                let point = (r.storage_bytes as f64, r.relative_variance);
                match series.iter_mut().find(|s| s.label == family) {
                    Some(s) => s.points.push(point),
                    None => series.push(crate::plot::Series {
                        label: family,
                        points: vec![point],
                        style: crate::plot::Style::Line,
                    }),
                }
            }
            let markers = (uniform.0 > 0.0 && uniform.1 > 0.0)
                .then(|| crate::plot::Marker {
                    label: "uniform".to_string(),
                    point: uniform,
                })
                .into_iter()
                .collect();
            crate::plot::Panel {
                x_label: "storage (bytes)".to_string(),
                y_label: format!("{m}: mean V/E² of the irradiance"),
                series,
                markers,
                notes: Vec::new(),
                legend: i == 0,
            }
        })
        .collect();
    crate::plot::Figure {
        title: "Environment samplers: relative variance of the irradiance against storage"
            .to_string(),
        panels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use acdf::env_registry::make_env_sampler;
    use acdf_core::Rgb;

    /// On a constant map the uniform sampler's density is 1/4π and the
    /// irradiance π L for every normal: the quadrature must give V/E² =
    /// 4π·(2π/3)/π² − 1 = 5/3, and the Monte Carlo check must agree.
    #[test]
    fn quadrature_is_exact_on_a_constant_map() {
        let map = Arc::new(EnvMap::from_fn(64, 32, |_, _| Rgb::splat(2.0)).unwrap());
        let s = make_env_sampler("uniform", &map, &EnvSamplerOptions::default()).unwrap();
        for n in standard_normals() {
            let q = irradiance_quadrature(&map, &s, n);
            let y = acdf_core::luminance(Rgb::splat(2.0)) as f64;
            assert!(
                (q.irradiance / (std::f64::consts::PI * y) - 1.0).abs() < 1e-4,
                "{q:?}"
            );
            assert!(
                (q.relative_variance().unwrap() - 5.0 / 3.0).abs() < 1e-3,
                "{q:?}"
            );
            assert_eq!(q.missed, 0.0);
        }
        let n = Vec3::new(0.3, 0.4, 0.5).normalize();
        let q = irradiance_quadrature(&map, &s, n);
        let (mean, var) = irradiance_monte_carlo(&map, &s, n, 200_000, 1);
        assert!((mean / q.irradiance - 1.0).abs() < 0.01);
        assert!((var / q.variance() - 1.0).abs() < 0.03);
    }

    /// The oriented sampler reduces the variance of the irradiance on a map
    /// with a bright spot, and the compensated one misses part of it.
    #[test]
    fn report_rows_rank_the_samplers() {
        let map = Arc::new(
            EnvMap::from_fn(64, 32, |k, j| {
                Rgb::splat(if (20..23).contains(&k) && (8..10).contains(&j) {
                    300.0
                } else {
                    0.5 + 0.02 * j as f32
                })
            })
            .unwrap(),
        );
        let config = EnvReportConfig {
            mc_samples: 2000,
            timing_samples: 2000,
            timing_passes: 1,
            ..EnvReportConfig::default()
        };
        let samplers: Vec<ReportedSampler> = ["uniform", "uniform-comp", "oriented"]
            .iter()
            .map(|s| ReportedSampler::new(s.parse().unwrap(), EnvSamplerOptions::default()))
            .collect();
        let rows = report_map("spot", PathBuf::new(), map, &samplers, &config, |_| {}).unwrap();
        assert_eq!(rows[0].relative_efficiency, Some(1.0));
        assert!(rows[1].missed_share > 0.1, "{}", rows[1].missed_share);
        assert_eq!(rows[1].relative_efficiency, None);
        assert!(rows[2].relative_variance < 0.5 * rows[0].relative_variance);
        let (built, all) = rows[2].built_nodes.unwrap();
        assert!(built > 0 && built <= all);
        let text = format_env_table(&rows);
        assert!(text.contains("oriented:dp") && text.contains("uniform-comp"));
    }
}
