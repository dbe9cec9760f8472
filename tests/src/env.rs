//! The battery for environment samplers: directions over the whole sphere
//! drawn for a lat-long map and a shading normal (or none).
//!
//! Per (map, normal), with N draws:
//! - **validity**: every sample has a unit, finite direction and a finite
//!   pdf > 0 equal to `pdf(normal, dir)` to 1e-4 relative;
//! - **chi-square**: the draws binned over `z_cells` × `phi_cells` cells of
//!   equal solid angle (equal steps of cos θ and φ) plus one bin for
//!   `None`, against N ∫_cell pdf. The samplers' densities are constant over
//!   each texel (their documented contract), and both texels and cells are
//!   rectangles in (cos θ, φ), so the expected counts are exact sums of the
//!   texels' densities times their overlap with each cell: no quadrature
//!   error. Cells under 5 expected are pooled, a draw in a cell expecting 0
//!   fails outright, α = 0.01 with Sidak over every case of the call;
//! - **integral**: ∫ pdf over the sphere (exact, the same sums) is at most
//!   1 + 1e-4 and within three standard errors (plus 1e-4) of the fraction
//!   of successful draws;
//! - **target**: the density follows the function its table is built for
//!   ([`EnvTarget`]): the chi-square divergence Σ f²/p − 1 over the texels
//!   (f, p the texels' probabilities under the target and the sampler) is at
//!   most `max_divergence`, and the target's mass on texels of density 0 is
//!   at most `max_missed` (the support: light the sampler never draws). A
//!   sampler consistent with its own pdf but built from the wrong table (a
//!   missing sin θ) is caught here;
//! - **extremes**: `u` at and beyond the edges of [0, 1) gives the sample
//!   of `clamp_unit(u)` bit for bit, valid; `pdf` at the poles, on both
//!   sides of the φ seam, and for NaN, infinite and zero directions is
//!   finite and not negative (0 for the last three), equal on the two signs
//!   of zero of the seam; the batch forms equal the single calls; normals
//!   at the poles, NaN and zero normals (which act as none) give valid,
//!   consistent samples.
//!
//! Panics anywhere are caught and reported as [`Check::Panic`].

// `!(x <= bound)` is how this module says "above the bound, or NaN": the
// negated comparison is the point, since NaN must fail.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;

use acdf_core::{clamp_unit, usable_normal, SphereSample, SphereSampler, Vec2, Vec3};
use acdf_lights::EnvMap;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::chi2::{chi_square, sidak};
use crate::report::{Check, ChiSquareLine, Report};
use crate::sampler_checks::EXTREME_U;

/// The function a sampler's table follows, per texel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnvTarget {
    /// Y(L) per solid angle.
    Luminance,
    /// max(0, Y − Ȳ) per solid angle (uniform where that is 0 everywhere).
    Compensated,
    /// Y(L) max(0, n·ω) for the normal, Y(L) without one.
    Oriented,
}

/// How the environment battery measures.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvConfig {
    /// Draws per (map, normal).
    pub samples: usize,
    pub seed: u64,
    /// Cells in cos θ and in φ of the chi-square histogram.
    pub z_cells: usize,
    pub phi_cells: usize,
    /// Family-wise significance of the chi-square tests of one call.
    pub significance: f64,
    /// What the sampler's density should follow.
    pub target: EnvTarget,
    /// The largest chi-square divergence of the target from the density.
    pub max_divergence: f64,
    /// The largest share of the target on texels of density 0; `None` to
    /// skip the check.
    pub max_missed: Option<f64>,
}

impl Default for EnvConfig {
    /// 200,000 draws, 50 × 100 cells, α = 0.01, the luminance target with
    /// divergence 1e-3 and no missed light.
    fn default() -> Self {
        EnvConfig {
            samples: 200_000,
            seed: 0x05ee_de4f,
            z_cells: 50,
            phi_cells: 100,
            significance: 0.01,
            target: EnvTarget::Luminance,
            max_divergence: 1e-3,
            max_missed: Some(1e-7),
        }
    }
}

/// The maps of the battery, small so that it runs in seconds: a structured
/// 64 × 32 sky (a gradient, a bright spot across the φ seam, a dim ground),
/// and the extremes: one bright texel on black, a constant map, a black
/// map (whose samplers draw uniform directions), a map with zero rows (the
/// first four, two in the middle and the last), 1 × 1 and 2 × 1.
pub fn env_test_maps() -> Vec<(&'static str, Arc<EnvMap>)> {
    use acdf_core::Rgb;
    let map = |w, h, f: &dyn Fn(usize, usize) -> Rgb| {
        Arc::new(EnvMap::from_fn(w, h, f).expect("a valid test map"))
    };
    vec![
        (
            "sky64x32",
            map(64, 32, &|k, j| {
                if j < 16 && !(2..=61).contains(&k) && (5..8).contains(&j) {
                    Rgb::new(400.0, 380.0, 300.0)
                } else if j < 16 {
                    Rgb::new(0.3, 0.5, 1.0) * (1.0 + 0.05 * j as f32 + 0.01 * k as f32)
                } else {
                    Rgb::splat(0.1)
                }
            }),
        ),
        (
            "one-texel",
            map(32, 16, &|k, j| {
                if (k, j) == (20, 6) {
                    Rgb::splat(1000.0)
                } else {
                    Rgb::ZERO
                }
            }),
        ),
        ("constant", map(32, 16, &|_, _| Rgb::splat(0.7))),
        ("black", map(32, 16, &|_, _| Rgb::ZERO)),
        (
            "zero-rows",
            map(32, 16, &|k, j| {
                if j < 4 || j == 8 || j == 9 || j == 15 {
                    Rgb::ZERO
                } else {
                    Rgb::splat(1.0 + (k % 7) as f32)
                }
            }),
        ),
        ("1x1", map(1, 1, &|_, _| Rgb::splat(2.0))),
        ("2x1", map(2, 1, &|k, _| Rgb::splat(1.0 + 3.0 * k as f32))),
    ]
}

/// Normals that every orientation-aware sampler meets: none, the poles, a
/// generic one, one on the φ seam, one just above the horizon.
pub fn env_test_normals() -> Vec<Option<Vec3>> {
    vec![
        None,
        Some(Vec3::Z),
        Some(-Vec3::Z),
        Some(Vec3::new(0.3, -0.5, 0.6).normalize()),
        Some(Vec3::new(1.0, -0.0, 0.2).normalize()),
        Some(Vec3::new(-0.2, 0.9, -0.05).normalize()),
    ]
}

/// Per texel, row-major: the target's mass (∫ over the texel of the
/// function, up to a constant), for `normal`.
pub fn target_masses(map: &EnvMap, target: EnvTarget, normal: Option<Vec3>) -> Vec<f64> {
    let grid = map.grid();
    let (w, h) = grid.size();
    let lum = map.luminance();
    let omega = |j: usize| grid.texel_solid_angle(j);
    match (target, usable_normal(normal)) {
        (EnvTarget::Luminance, _) | (EnvTarget::Oriented, None) => {
            (0..w * h).map(|i| lum[i] as f64 * omega(i / w)).collect()
        }
        (EnvTarget::Compensated, _) => {
            let mean = map.luminance_integral() / (4.0 * std::f64::consts::PI);
            let m: Vec<f64> = (0..w * h)
                .map(|i| (lum[i] as f64 - mean).max(0.0) * omega(i / w))
                .collect();
            if m.iter().all(|&v| v <= 0.0) {
                (0..w * h).map(|i| omega(i / w)).collect()
            } else {
                m
            }
        }
        (EnvTarget::Oriented, Some(n)) => {
            const S: usize = 4;
            (0..w * h)
                .map(|i| {
                    let (k, j) = (i % w, i / w);
                    let mut c = 0.0;
                    for a in 0..S {
                        for b in 0..S {
                            let f =
                                Vec2::new((a as f32 + 0.5) / S as f32, (b as f32 + 0.5) / S as f32);
                            c += (n.dot(grid.direction_in_texel(k, j, f)) as f64).max(0.0);
                        }
                    }
                    lum[i] as f64 * omega(j) * c / (S * S) as f64
                })
                .collect()
        }
    }
}

/// The sampler's probability of every texel, pdf at the texel's centre
/// times its solid angle, row-major.
fn texel_probabilities(
    sampler: &dyn SphereSampler,
    map: &EnvMap,
    normal: Option<Vec3>,
) -> Vec<f64> {
    let grid = map.grid();
    let (w, h) = grid.size();
    let mut out = Vec::with_capacity(w * h);
    let mut dirs = vec![Vec3::ZERO; w];
    let mut pdf = vec![0.0f32; w];
    for j in 0..h {
        for (k, d) in dirs.iter_mut().enumerate() {
            *d = grid.texel_direction(k, j);
        }
        sampler.pdf_batch(normal, &dirs, &mut pdf);
        out.extend(pdf.iter().map(|&p| p as f64 * grid.texel_solid_angle(j)));
    }
    out
}

/// The length of the overlap of [a0, a1] and [b0, b1].
fn overlap(a0: f64, a1: f64, b0: f64, b1: f64) -> f64 {
    (a1.min(b1) - a0.max(b0)).max(0.0)
}

/// The exact probability of every histogram cell (row-major, z cells of
/// cos θ from +1 down, φ cells from 0) under texel probabilities `prob`.
fn cell_probabilities(map: &EnvMap, prob: &[f64], nz: usize, nphi: usize) -> Vec<f64> {
    let grid = map.grid();
    let (w, h) = grid.size();
    let tau = std::f64::consts::TAU;
    let mut cells = vec![0.0f64; nz * nphi];
    let mut row = vec![0.0f64; nphi];
    for j in 0..h {
        let (t0, t1) = grid.row_thetas(j);
        let (z_hi, z_lo) = (t0.cos(), t1.cos());
        row.iter_mut().for_each(|r| *r = 0.0);
        for k in 0..w {
            let p = prob[j * w + k];
            if p == 0.0 {
                continue;
            }
            let (p0, p1) = grid.column_phis(k);
            let b0 = ((p0 / tau * nphi as f64).floor() as usize).min(nphi - 1);
            let b1 = ((p1 / tau * nphi as f64).ceil() as usize).min(nphi);
            for (b, r) in row.iter_mut().enumerate().take(b1).skip(b0) {
                let (c0, c1) = (
                    tau * b as f64 / nphi as f64,
                    tau * (b + 1) as f64 / nphi as f64,
                );
                *r += p * overlap(p0, p1, c0, c1) / (p1 - p0);
            }
        }
        let dz = z_hi - z_lo;
        for bz in 0..nz {
            let (c_hi, c_lo) = (
                1.0 - 2.0 * bz as f64 / nz as f64,
                1.0 - 2.0 * (bz + 1) as f64 / nz as f64,
            );
            let o = overlap(z_lo, z_hi, c_lo, c_hi);
            if o > 0.0 {
                let f = o / dz;
                for (c, &r) in cells[bz * nphi..(bz + 1) * nphi].iter_mut().zip(&row) {
                    *c += f * r;
                }
            }
        }
    }
    cells
}

/// The histogram cell of a direction.
fn cell_of(dir: Vec3, nz: usize, nphi: usize) -> usize {
    let d = dir.as_dvec3();
    let z = d.z.clamp(-1.0, 1.0);
    let bz = (((1.0 - z) * 0.5 * nz as f64) as usize).min(nz - 1);
    let mut phi = d.y.atan2(d.x);
    if phi < 0.0 {
        phi += std::f64::consts::TAU;
    }
    let bp = ((phi / std::f64::consts::TAU * nphi as f64) as usize).min(nphi - 1);
    bz * nphi + bp
}

/// Whether `s` is a valid sample: unit finite direction, finite pdf > 0.
fn valid(s: &SphereSample) -> bool {
    s.dir.is_finite() && (s.dir.length() - 1.0).abs() < 1e-4 && s.pdf.is_finite() && s.pdf > 0.0
}

fn describe(normal: Option<Vec3>) -> String {
    match normal {
        None => "normal=none".into(),
        Some(n) => format!("normal=({:.3},{:.3},{:.3})", n.x, n.y, n.z),
    }
}

/// The draws of one case: histogram, failed draws, the first problems.
struct Draws {
    counts: Vec<u64>,
    failed: u64,
    invalid: Vec<String>,
    mismatch: Vec<String>,
}

fn draw(sampler: &dyn SphereSampler, normal: Option<Vec3>, config: &EnvConfig, seed: u64) -> Draws {
    const CHUNK: usize = 1 << 14;
    let (nz, nphi) = (config.z_cells, config.phi_cells);
    let chunks = config.samples.div_ceil(CHUNK);
    (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut rng =
                rand_pcg::Pcg64::seed_from_u64(seed ^ (c as u64).wrapping_mul(0x9E37_79B9));
            let n = CHUNK.min(config.samples - c * CHUNK);
            let mut d = Draws {
                counts: vec![0; nz * nphi],
                failed: 0,
                invalid: vec![],
                mismatch: vec![],
            };
            for _ in 0..n {
                let u = Vec2::new(rng.random(), rng.random());
                match sampler.sample(normal, u) {
                    None => d.failed += 1,
                    Some(s) if !valid(&s) => {
                        if d.invalid.len() < 3 {
                            d.invalid.push(format!("u={u} gave {s:?}"));
                        }
                    }
                    Some(s) => {
                        let p = sampler.pdf(normal, s.dir);
                        if !((p - s.pdf).abs() <= 1e-4 * s.pdf) && d.mismatch.len() < 3 {
                            d.mismatch.push(format!(
                                "u={u}: sample pdf {} but pdf() {p} at {}",
                                s.pdf, s.dir
                            ));
                        }
                        d.counts[cell_of(s.dir, nz, nphi)] += 1;
                    }
                }
            }
            d
        })
        .reduce(
            || Draws {
                counts: vec![0; nz * nphi],
                failed: 0,
                invalid: vec![],
                mismatch: vec![],
            },
            |mut a, b| {
                for (x, y) in a.counts.iter_mut().zip(&b.counts) {
                    *x += y;
                }
                a.failed += b.failed;
                a.invalid.extend(b.invalid);
                a.mismatch.extend(b.mismatch);
                a
            },
        )
}

/// The distributional checks of one (map, normal) case.
fn check_case(
    report: &mut Report,
    sampler: &dyn SphereSampler,
    map: &EnvMap,
    normal: Option<Vec3>,
    config: &EnvConfig,
    case: &str,
    threshold: f64,
) {
    let prob = texel_probabilities(sampler, map, normal);
    if let Some(bad) = prob.iter().position(|p| !(p.is_finite() && *p >= 0.0)) {
        report.fail(
            Check::PdfInvalid,
            case,
            format!("texel {bad}: probability {}", prob[bad]),
        );
        return;
    }
    let integral: f64 = prob.iter().sum();
    let seed = config.seed ^ (case.len() as u64).wrapping_mul(0x2545_F491);
    let draws = draw(sampler, normal, config, seed);
    for d in &draws.invalid {
        report.fail(Check::SampleInvalid, case, d.clone());
    }
    for d in &draws.mismatch {
        report.fail(Check::PdfMismatch, case, d.clone());
    }
    let n = config.samples as f64;
    let mut expected: Vec<f64> = cell_probabilities(map, &prob, config.z_cells, config.phi_cells)
        .into_iter()
        .map(|p| p * n)
        .collect();
    expected.push((n * (1.0 - integral)).max(0.0));
    let mut observed = draws.counts.clone();
    observed.push(draws.failed);
    let outcome = chi_square(&observed, &expected);
    if outcome.impossible > 0 {
        report.fail(
            Check::ZeroExpectedCell,
            case,
            format!(
                "{} draws in cells of density 0 (first: cell {:?})",
                outcome.impossible, outcome.first_impossible_cell
            ),
        );
    }
    let line = ChiSquareLine {
        subject: report.subject.clone(),
        case: case.to_string(),
        samples: config.samples,
        failed_draws: draws.failed as usize,
        integral,
        statistic: outcome.statistic,
        dof: outcome.dof,
        p_value: outcome.p_value,
        threshold,
    };
    if !line.passed() {
        report.fail(Check::ChiSquare, case, line.to_string());
    }
    report.chi_square.push(line);
    let success = 1.0 - draws.failed as f64 / n;
    let se = (integral.clamp(0.0, 1.0) * (1.0 - integral.clamp(0.0, 1.0)) / n).sqrt();
    if integral > 1.0 + 1e-4 || (integral - success).abs() > 3.0 * se + 1e-4 {
        report.fail(
            Check::Integral,
            case,
            format!("∫ pdf = {integral:.6}, successful draws {success:.6}"),
        );
    }
    let target = target_masses(map, config.target, normal);
    let total: f64 = target.iter().sum();
    if total > 0.0 {
        let (mut second, mut missed) = (0.0f64, 0.0f64);
        for (&t, &p) in target.iter().zip(&prob) {
            let f = t / total;
            if p > 0.0 {
                second += f * f / p;
            } else {
                missed += f;
            }
        }
        let divergence = second - (1.0 - missed) * (1.0 - missed);
        report.notes.push(format!(
            "{case}: divergence from the target {divergence:.3e}, missed {missed:.1e}"
        ));
        if !(divergence <= config.max_divergence) {
            report.fail(
                Check::Target,
                case,
                format!(
                    "divergence from the target {divergence:.4e} > {:.1e}",
                    config.max_divergence
                ),
            );
        }
        if let Some(max) = config.max_missed {
            if !(missed <= max) {
                report.fail(
                    Check::Support,
                    case,
                    format!("target mass on density 0: {missed:.3e} > {max:.0e}"),
                );
            }
        }
    }
}

/// The extreme inputs of one (map, normal) case.
fn check_extremes(
    report: &mut Report,
    sampler: &dyn SphereSampler,
    normal: Option<Vec3>,
    case: &str,
) {
    for &ux in &EXTREME_U {
        for &uy in &EXTREME_U {
            let u = Vec2::new(ux, uy);
            let a = sampler.sample(normal, u);
            let b = sampler.sample(normal, Vec2::new(clamp_unit(ux), clamp_unit(uy)));
            let same = match (a, b) {
                (Some(a), Some(b)) => {
                    a.dir.to_array().map(f32::to_bits) == b.dir.to_array().map(f32::to_bits)
                        && a.pdf.to_bits() == b.pdf.to_bits()
                }
                (None, None) => true,
                _ => false,
            };
            if !same {
                report.fail(
                    Check::Extremes,
                    case,
                    format!("u={u}: {a:?} but clamped {b:?}"),
                );
            }
            if let Some(s) = a {
                if !valid(&s) {
                    report.fail(Check::SampleInvalid, case, format!("u={u}: {s:?}"));
                }
            }
        }
    }
    let seam = [
        Vec3::Z,
        -Vec3::Z,
        Vec3::new(0.0, 0.0, 1e-30),
        Vec3::new(1e-7, -0.0, 1.0),
        Vec3::new(1.0, 0.0, 0.3),
        Vec3::new(1.0, -0.0, 0.3),
        Vec3::new(1.0, -1e-7, 0.3),
        Vec3::new(1.0, 1e-7, -0.3),
        Vec3::new(1.0, 0.0, 0.0),
    ];
    for d in seam {
        let p = sampler.pdf(normal, d);
        if !(p.is_finite() && p >= 0.0) {
            report.fail(Check::PdfInvalid, case, format!("pdf({d}) = {p}"));
        }
    }
    let (a, b) = (
        sampler.pdf(normal, Vec3::new(1.0, 0.0, 0.3)),
        sampler.pdf(normal, Vec3::new(1.0, -0.0, 0.3)),
    );
    if a.to_bits() != b.to_bits() {
        report.fail(
            Check::Extremes,
            case,
            format!("pdf on the seam differs with the sign of y = 0: {a} and {b}"),
        );
    }
    for d in [
        Vec3::NAN,
        Vec3::ZERO,
        Vec3::new(f32::INFINITY, 0.0, 1.0),
        Vec3::new(0.0, f32::NEG_INFINITY, 0.0),
    ] {
        let p = sampler.pdf(normal, d);
        if p != 0.0 {
            report.fail(Check::Extremes, case, format!("pdf({d}) = {p}, expected 0"));
        }
    }
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let u: Vec<Vec2> = (0..150)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect();
    let mut batch = vec![None; u.len()];
    sampler.sample_batch(normal, &u, &mut batch);
    let single: Vec<Option<SphereSample>> = u.iter().map(|&u| sampler.sample(normal, u)).collect();
    if batch != single {
        report.fail(Check::Batch, case, "sample_batch differs from sample");
    }
    let dirs: Vec<Vec3> = single.iter().flatten().map(|s| s.dir).chain(seam).collect();
    let mut pdfs = vec![0.0f32; dirs.len()];
    sampler.pdf_batch(normal, &dirs, &mut pdfs);
    for (&d, &p) in dirs.iter().zip(&pdfs) {
        if p.to_bits() != sampler.pdf(normal, d).to_bits() {
            report.fail(
                Check::Batch,
                case,
                format!("pdf_batch({d}) = {p}, pdf {}", sampler.pdf(normal, d)),
            );
        }
    }
}

/// Run the battery on the sampler `build` makes for each of `maps`, for
/// each of `normals`; the extreme normals (the poles, NaN, zero) get the
/// extreme-input checks too.
pub fn check_env_family<S: SphereSampler>(
    subject: &str,
    build: impl Fn(&Arc<EnvMap>) -> acdf_core::Result<S>,
    maps: &[(&str, Arc<EnvMap>)],
    normals: &[Option<Vec3>],
    config: &EnvConfig,
) -> Report {
    let mut report = Report::new(subject);
    let threshold = sidak(config.significance, (maps.len() * normals.len()).max(1));
    for (name, map) in maps {
        let built = catch_unwind(AssertUnwindSafe(|| build(map)));
        let sampler = match built {
            Ok(Ok(s)) => s,
            Ok(Err(e)) => {
                report.fail(
                    Check::Construction,
                    name,
                    format!("rejected a valid map: {e}"),
                );
                continue;
            }
            Err(_) => {
                report.fail(Check::Panic, name, "the constructor panicked");
                continue;
            }
        };
        for &normal in normals {
            let case = format!("map={name} {}", describe(normal));
            let run = catch_unwind(AssertUnwindSafe(|| {
                let mut r = Report::new(subject);
                check_case(&mut r, &sampler, map, normal, config, &case, threshold);
                check_extremes(&mut r, &sampler, normal, &case);
                r
            }));
            match run {
                Ok(r) => report.merge(r),
                Err(_) => report.fail(Check::Panic, &case, "the sampler panicked"),
            }
        }
        for normal in [
            Some(Vec3::Z),
            Some(-Vec3::Z),
            Some(Vec3::NAN),
            Some(Vec3::ZERO),
        ] {
            let case = format!("map={name} extreme {}", describe(normal));
            let run = catch_unwind(AssertUnwindSafe(|| {
                let mut r = Report::new(subject);
                check_extremes(&mut r, &sampler, normal, &case);
                r
            }));
            match run {
                Ok(r) => report.merge(r),
                Err(_) => report.fail(Check::Panic, &case, "the sampler panicked"),
            }
        }
    }
    report
}

/// [`check_env_family`] for one built sampler on one map.
pub fn check_env_sampler(
    subject: &str,
    sampler: &dyn SphereSampler,
    map: &Arc<EnvMap>,
    normals: &[Option<Vec3>],
    config: &EnvConfig,
) -> Report {
    check_env_family(
        subject,
        |_| Ok(sampler),
        &[("map", map.clone())],
        normals,
        config,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_probabilities_of_a_uniform_density_are_equal() {
        let map = EnvMap::from_fn(16, 8, |_, _| acdf_core::Rgb::ONE).unwrap();
        let g = map.grid();
        let prob: Vec<f64> = (0..128)
            .map(|i| g.texel_solid_angle(i / 16) / (4.0 * std::f64::consts::PI))
            .collect();
        let cells = cell_probabilities(&map, &prob, 10, 20);
        for c in cells {
            assert!((c - 1.0 / 200.0).abs() < 1e-12, "{c}");
        }
    }
}
