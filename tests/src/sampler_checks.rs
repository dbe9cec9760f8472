//! The battery for [`BxdfSampler`]s: chi-square goodness of fit over
//! equal-area cells of the sphere, consistency of `sample` with `pdf`, the
//! integral of the pdf against the fraction of successful draws, finite
//! weights, and extreme outgoing directions, uniform numbers and BRDFs.

use crate::chi2::{chi_square, sidak, ChiSquareOutcome};
use crate::quadrature::integrate_2d_split;
use crate::report::{Check, ChiSquareLine, Report};
use acdf_core::geometry::{phi, spherical_direction};
use acdf_core::{
    clamp_unit, missed_share, Brdf, BxdfSample, BxdfSampler, MissedShare, Result, Vec2, Vec3,
    ONE_MINUS_EPSILON,
};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use std::f64::consts::TAU;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;

/// Parameters of the sampler battery. `Default` gives the documented
/// battery: 10^6 draws per wo, 100 × 200 cells, α = 0.01.
#[derive(Debug, Clone)]
pub struct SamplerConfig {
    /// Draws per (BRDF, wo) for the chi-square test, `None` included.
    pub samples: usize,
    /// Seed of the Pcg64 streams (one stream per wo, derived from it).
    pub seed: u64,
    /// Cells in cos θ over [-1, 1]; even, so that the horizon is a cell edge.
    pub cos_theta_cells: usize,
    /// Cells in φ over [0, 2π).
    pub phi_cells: usize,
    /// Family-wise significance; each test gets the Sidak-corrected share
    /// over all chi-square tests of one battery call.
    pub significance: f64,
    /// θ of the outgoing directions tested, in degrees.
    pub wo_theta_degrees: Vec<f32>,
    /// φ of the outgoing directions, in radians (non-zero on purpose, so an
    /// anisotropic sampler that ignores φ_o is caught).
    pub wo_phi: f32,
    /// Allowed quadrature error per cell, in expected counts.
    pub quadrature_tolerance: f64,
    /// Each cell is cut into (φ, cos θ) pieces before adaptive quadrature,
    /// so that a pdf with structure finer than the cell (a tabulated
    /// sampler's own grid) does not alias with Simpson's nodes.
    pub quadrature_splits: (usize, usize),
    /// Draws per wo for the extreme directions and extreme BRDFs.
    pub extreme_samples: usize,
    /// Draws per wo on which the weight f cos θ_i / pdf is checked.
    pub weight_samples: usize,
    /// Draws per wo of the grazing agreement check ([`GRAZING_THETA_DEGREES`]
    /// at two azimuths).
    pub grazing_samples: usize,
    /// The largest share of f cos θ_i that may lie where the pdf is 0 (see
    /// [`missed_share`]), at each configured wo, when a BRDF is given;
    /// `None` for a sampler that does not stand for its BRDF (the
    /// battery's own reference samplers, paired with a BRDF only for the
    /// weight check).
    pub max_missed_share: Option<f64>,
    /// The (cos θ_i, φ_i) cells of the quadrature of [`missed_share`].
    pub support_cells: (usize, usize),
}

impl Default for SamplerConfig {
    fn default() -> Self {
        SamplerConfig {
            samples: 1_000_000,
            seed: 0x5eed_acdf,
            cos_theta_cells: 100,
            phi_cells: 200,
            significance: 0.01,
            wo_theta_degrees: vec![0.0, 30.0, 60.0, 85.0, 89.5],
            wo_phi: 1.0,
            quadrature_tolerance: 0.001,
            quadrature_splits: (1, 4),
            extreme_samples: 20_000,
            weight_samples: 16_384,
            grazing_samples: 2_000,
            max_missed_share: Some(1e-7),
            support_cells: (128, 256),
        }
    }
}

/// cos θ at which the quadrature evaluates the pdf for a node on the
/// horizon.
const HORIZON_NODE: f64 = 1.0 / (1u64 << 24) as f64;

/// Uniform numbers at and beyond the edges of [0, 1), plus dyadic cell
/// boundaries of power-of-two tables.
pub const EXTREME_U: [f32; 16] = [
    0.0,
    ONE_MINUS_EPSILON,
    0.5,
    0.25,
    0.75,
    1.0 / 64.0,
    63.0 / 64.0,
    1.0 / 3.0,
    1e-30,
    -0.0,
    1.0,
    -1.0,
    2.0,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
];

/// θ_o of the agreement check, in degrees: from the pole to a thousandth
/// of a degree above the horizon, where wo + wi nearly cancels for the
/// draws near the horizon on the other side and the half vector of a
/// naive formulation keeps few digits.
pub const GRAZING_THETA_DEGREES: [f32; 8] = [0.0, 45.0, 80.0, 85.0, 89.0, 89.9, 89.99, 89.999];

/// Agreement of `sample` and `pdf` from the pole to the horizon: at each of
/// [`GRAZING_THETA_DEGREES`], with φ_o at the configured azimuth and at 0
/// (an edge of every φ_o grid of the tabulated samplers), every valid draw's
/// density must equal `pdf(wo, wi)` of its own wi to 1e-4 relative, and
/// the draw must be valid (unit, above the horizon, finite).
fn check_grazing_agreement(
    report: &mut Report,
    subject: &str,
    sampler: &dyn BxdfSampler,
    brdf: Option<&dyn Brdf>,
    config: &SamplerConfig,
) {
    let mut rng = Pcg64::seed_from_u64(config.seed ^ 0x9a2_1e6);
    for theta in GRAZING_THETA_DEGREES {
        for phi in [config.wo_phi, 0.0] {
            let wo = outgoing(theta, phi);
            let case = format!("{subject} {}(grazing θ_o = {theta}°)", describe(brdf, wo));
            guarded(report, &case, |r| {
                for _ in 0..config.grazing_samples {
                    let u = Vec2::new(rng.random(), rng.random());
                    if let Some(s) = sampler.sample(wo, u) {
                        check_sample(r, &case, &s, sampler.pdf(wo, s.wi));
                    }
                }
            });
        }
    }
}

/// The outgoing direction at (θ, φ), with θ = 0 exactly the pole.
fn outgoing(theta_degrees: f32, phi: f32) -> Vec3 {
    if theta_degrees == 0.0 {
        Vec3::Z
    } else {
        spherical_direction((theta_degrees as f64).to_radians() as f32, phi)
    }
}

fn describe(brdf: Option<&dyn Brdf>, wo: Vec3) -> String {
    let theta = (wo.x.hypot(wo.y) as f64).atan2(wo.z as f64).to_degrees();
    format!(
        "brdf={} wo=(θ {:.4}°, φ {:.2}) ",
        brdf.map_or("-", |b| b.name()),
        theta,
        phi(wo)
    )
}

/// Run `f`, turning a panic into a [`Check::Panic`] failure.
pub(crate) fn guarded(report: &mut Report, case: &str, f: impl FnOnce(&mut Report)) {
    let mut inner = Report::new("");
    let result = catch_unwind(AssertUnwindSafe(|| f(&mut inner)));
    report.merge(inner);
    if let Err(payload) = result {
        let msg = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        report.fail(Check::Panic, case, format!("panicked: {msg}"));
    }
}

/// The checks every returned sample passes: finite unit wi strictly above
/// the horizon, a finite pdf > 0 equal to `pdf(wo, wi)` to 1e-4 relative.
fn check_sample(report: &mut Report, case: &str, s: &BxdfSample, pdf_again: f32) {
    let valid = s.wi.is_finite()
        && s.wi.z > 0.0
        && (s.wi.length() - 1.0).abs() <= 1e-3
        && s.pdf.is_finite()
        && s.pdf > 0.0;
    if !valid {
        report.fail(
            Check::SampleInvalid,
            case,
            format!("sample wi = {}, pdf = {}", s.wi, s.pdf),
        );
        return;
    }
    if !pdf_again.is_finite() || pdf_again < 0.0 {
        report.fail(
            Check::PdfInvalid,
            case,
            format!("pdf(wo, {}) = {pdf_again}", s.wi),
        );
    } else if (s.pdf - pdf_again).abs() > 1e-4 * s.pdf.max(pdf_again) {
        report.fail(
            Check::PdfMismatch,
            case,
            format!(
                "sample returned pdf {} but pdf(wo, {}) = {pdf_again}",
                s.pdf, s.wi
            ),
        );
    }
}

/// f cos θ_i / pdf, evaluated in f32 as a renderer would, must be finite.
fn check_weight(report: &mut Report, case: &str, brdf: &dyn Brdf, wo: Vec3, s: &BxdfSample) {
    if s.pdf > 0.0 {
        let w = brdf.eval(wo, s.wi) * s.wi.z / s.pdf;
        if !w.is_finite() {
            report.fail(
                Check::Weight,
                case,
                format!("f cos / pdf = {w} at wi = {}, pdf = {}", s.wi, s.pdf),
            );
        }
    }
}

/// Draw `count` random u and the grid of [`EXTREME_U`] pairs for one valid
/// wo and check every result; `sample(u)` must equal `sample(clamp(u))`.
fn check_draws(
    report: &mut Report,
    case: &str,
    sampler: &dyn BxdfSampler,
    brdf: Option<&dyn Brdf>,
    wo: Vec3,
    count: usize,
    rng: &mut Pcg64,
) {
    let mut us: Vec<Vec2> = (0..count)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect();
    for &a in &EXTREME_U {
        for &b in &EXTREME_U {
            us.push(Vec2::new(a, b));
        }
    }
    for &u in &us {
        let s = sampler.sample(wo, u);
        let clamped = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
        if clamped != u || u.x.is_sign_negative() || u.y.is_sign_negative() {
            let t = sampler.sample(wo, clamped);
            if !same_sample(&s, &t) {
                report.fail(
                    Check::Extremes,
                    case,
                    format!("sample(u = {u}) = {s:?} but sample(clamp_unit(u)) = {t:?}"),
                );
            }
        }
        if let Some(s) = s {
            check_sample(report, case, &s, sampler.pdf(wo, s.wi));
            if let Some(b) = brdf {
                check_weight(report, case, b, wo, &s);
            }
        }
    }
}

/// Equal to 1e-5 relative: batch entry points may evaluate in another
/// order (SIMD, fused multiply-add) than the single ones.
pub(crate) fn close(a: f32, b: f32) -> bool {
    a == b || (a - b).abs() <= 1e-5 * a.abs().max(b.abs())
}

/// Both `None`, or both samples with wi and pdf equal to 1e-5 relative.
fn close_sample(a: &Option<BxdfSample>, b: &Option<BxdfSample>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => (a.wi - b.wi).abs().max_element() <= 1e-5 && close(a.pdf, b.pdf),
        _ => false,
    }
}

fn same_sample(a: &Option<BxdfSample>, b: &Option<BxdfSample>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            a.wi.to_array().map(f32::to_bits) == b.wi.to_array().map(f32::to_bits)
                && a.pdf.to_bits() == b.pdf.to_bits()
        }
        _ => false,
    }
}

/// pdf(wo, wi) for wi at and below the horizon must be 0, and finite and
/// non-negative for NaN and non-unit wi.
fn check_pdf_probes(
    report: &mut Report,
    case: &str,
    sampler: &dyn BxdfSampler,
    wo: Vec3,
    rng: &mut Pcg64,
) {
    for k in 0..256 {
        let z = -rng.random::<f32>();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let a = rng.random::<f32>() * std::f32::consts::TAU;
        let mut wi = Vec3::new(r * a.cos(), r * a.sin(), z);
        if k == 0 {
            wi = Vec3::new(1.0, 0.0, 0.0);
        }
        let p = sampler.pdf(wo, wi);
        if p != 0.0 {
            report.fail(
                Check::PdfInvalid,
                case,
                format!("pdf(wo, {wi}) = {p} for wi at or below the horizon"),
            );
        }
    }
    for wi in [
        Vec3::splat(f32::NAN),
        Vec3::new(0.0, 0.0, f32::INFINITY),
        Vec3::ZERO,
        Vec3::new(0.3, 0.2, 2.0),
    ] {
        let p = sampler.pdf(wo, wi);
        if !(p.is_finite() && p >= 0.0) {
            report.fail(Check::PdfInvalid, case, format!("pdf(wo, {wi}) = {p}"));
        }
    }
}

/// Extreme outgoing directions. Valid but extreme (θ = 0, 1e-6 rad,
/// 89.99°): every draw is `None` or a valid sample. At or below the horizon,
/// or not finite: every draw is `None` and every pdf 0.
fn check_extreme_wo(
    report: &mut Report,
    subject: &str,
    sampler: &dyn BxdfSampler,
    brdf: Option<&dyn Brdf>,
    config: &SamplerConfig,
) {
    let mut rng = Pcg64::seed_from_u64(config.seed ^ 0xe7_7e3e);
    let phi = config.wo_phi;
    let valid = [
        Vec3::Z,
        spherical_direction(1e-6, phi),
        spherical_direction(89.99f32.to_radians(), phi),
    ];
    for wo in valid {
        let case = format!("{subject} {}(extreme)", describe(brdf, wo));
        guarded(report, &case, |r| {
            check_draws(
                r,
                &case,
                sampler,
                brdf,
                wo,
                config.extreme_samples,
                &mut rng,
            );
            check_pdf_probes(r, &case, sampler, wo, &mut rng);
        });
    }
    let invalid = [
        Vec3::new(phi.cos(), phi.sin(), 0.0),
        Vec3::new(phi.cos(), phi.sin(), -0.0),
        spherical_direction(100f32.to_radians(), phi),
        -Vec3::Z,
        Vec3::splat(f32::NAN),
        Vec3::new(0.0, 0.0, f32::INFINITY),
    ];
    for wo in invalid {
        let case = format!("{subject} wo={wo} (invalid)");
        guarded(report, &case, |r| {
            for k in 0..256 {
                let u = if let Some(&e) = EXTREME_U.get(k) {
                    Vec2::splat(e)
                } else {
                    Vec2::new(rng.random(), rng.random())
                };
                if let Some(s) = sampler.sample(wo, u) {
                    r.fail(
                        Check::Extremes,
                        &case,
                        format!("sample returned {s:?}, expected None"),
                    );
                }
                let wi = crate::sampler_checks::outgoing(45.0, u.y * 6.0);
                let p = sampler.pdf(wo, wi);
                if p != 0.0 {
                    r.fail(
                        Check::Extremes,
                        &case,
                        format!("pdf(wo, {wi}) = {p}, expected 0"),
                    );
                }
            }
        });
    }
}

/// The support check: at each configured wo,
/// [`missed_share`](acdf_core::missed_share) must not
/// exceed `config.max_missed_share`.
fn check_support(
    report: &mut Report,
    subject: &str,
    sampler: &dyn BxdfSampler,
    brdf: &dyn Brdf,
    config: &SamplerConfig,
) {
    let Some(bound) = config.max_missed_share else {
        return;
    };
    for &t in &config.wo_theta_degrees {
        let wo = outgoing(t, config.wo_phi);
        let case = format!("{subject} {}(support)", describe(Some(brdf), wo));
        guarded(report, &case, |r| {
            let (n_cos, n_phi) = config.support_cells;
            let MissedShare { share, worst } = missed_share(brdf, sampler, wo, n_cos, n_phi);
            if share > bound {
                r.fail(
                    Check::Support,
                    &case,
                    format!(
                        "pdf is 0 on {share:.3e} of f cos θ_i (bound {bound:.0e}; \
                         {} x {} cells in cos θ_i x φ_i), most at wi = {}",
                        config.support_cells.0,
                        config.support_cells.1,
                        worst.unwrap_or(Vec3::ZERO)
                    ),
                );
            }
        });
    }
}

/// The measure of one goodness-of-fit run, before the Sidak threshold is known.
struct Fit {
    line: ChiSquareLine,
    report: Report,
}

/// One chi-square case: a sampler at one wo, its histogram grid and its
/// sample count.
struct FitCase<'a> {
    /// The sampler and BRDF, described for messages.
    case: String,
    sampler: &'a dyn BxdfSampler,
    brdf: Option<&'a dyn Brdf>,
    wo: Vec3,
    /// Cells over cos θ in [-1, 1] and over φ; one more bin counts `None`.
    nt: usize,
    np: usize,
    /// Draws.
    n: usize,
    config: &'a SamplerConfig,
}

impl FitCase<'_> {
    /// The index of the `None` bin, after the nt × np cells.
    fn none_bin(&self) -> usize {
        self.nt * self.np
    }
}

/// Draw `config.samples` directions for one wo, histogram them over
/// (cos θ, φ) cells and compare with N ∫_cell pdf d(cos θ) dφ; then compare
/// ∫ pdf with the fraction of draws that succeeded.
fn goodness_of_fit(
    subject: &str,
    sampler: &dyn BxdfSampler,
    brdf: Option<&dyn Brdf>,
    wo: Vec3,
    stream: u64,
    config: &SamplerConfig,
) -> Fit {
    let fit = FitCase {
        case: format!("{subject} {}", describe(brdf, wo)),
        sampler,
        brdf,
        wo,
        nt: config.cos_theta_cells.max(2),
        np: config.phi_cells.max(1),
        n: config.samples.max(1),
        config,
    };
    let mut report = Report::new(subject);
    let mut rng = Pcg64::seed_from_u64(
        config
            .seed
            .wrapping_add(stream.wrapping_mul(0x9e37_79b9_7f4a_7c15)),
    );
    let (observed, failed) = draw_histogram(&fit, &mut report, &mut rng);
    let (expected, integral) = expected_counts(&fit, &mut report);
    let outcome = chi_square(&observed, &expected);
    report_impossible_cells(&fit, &outcome, &mut report);
    check_integral_of_pdf(&fit, failed, integral, &mut rng, &mut report);
    Fit {
        line: ChiSquareLine {
            subject: subject.to_string(),
            case: describe(brdf, wo),
            samples: fit.n,
            failed_draws: failed,
            integral,
            statistic: outcome.statistic,
            dof: outcome.dof,
            p_value: outcome.p_value,
            threshold: 0.0,
        },
        report,
    }
}

/// Draw the case's samples in batches and count them per (cos θ, φ) cell,
/// failed draws in the `None` bin; on the way, check every sample
/// ([`check_sample`]), the first weights ([`check_weight`]), and that the
/// batch entry points agree with the single ones on the first batch.
/// Returns the counts and the number of failed draws.
fn draw_histogram(fit: &FitCase<'_>, report: &mut Report, rng: &mut Pcg64) -> (Vec<u64>, usize) {
    let (sampler, wo, case) = (fit.sampler, fit.wo, &fit.case);
    let mut observed = vec![0u64; fit.none_bin() + 1];
    let mut failed = 0usize;
    let chunk = 4096;
    let mut us = vec![Vec2::ZERO; chunk];
    let mut out = vec![None; chunk];
    let mut wis = vec![Vec3::ZERO; chunk];
    let mut pdfs = vec![0f32; chunk];
    let mut drawn = 0;
    let mut weighed = 0;
    while drawn < fit.n {
        let m = chunk.min(fit.n - drawn);
        for u in &mut us[..m] {
            *u = Vec2::new(rng.random(), rng.random());
        }
        sampler.sample_batch(wo, &us[..m], &mut out[..m]);
        for k in 0..m {
            wis[k] = out[k].map_or(Vec3::Z, |s| s.wi);
        }
        sampler.pdf_batch(wo, &wis[..m], &mut pdfs[..m]);
        if drawn == 0 {
            check_batch_against_single(fit, &us[..m], &out[..m], &wis[..m], &pdfs[..m], report);
        }
        for k in 0..m {
            let Some(s) = out[k] else {
                failed += 1;
                observed[fit.none_bin()] += 1;
                continue;
            };
            check_sample(report, case, &s, pdfs[k]);
            if weighed < fit.config.weight_samples {
                if let Some(b) = fit.brdf {
                    check_weight(report, case, b, wo, &s);
                }
                weighed += 1;
            }
            if !s.wi.is_finite() {
                continue;
            }
            let z = (s.wi.z as f64).clamp(-1.0, 1.0);
            let row = (((z + 1.0) * 0.5 * fit.nt as f64) as usize).min(fit.nt - 1);
            let col = ((phi(s.wi) as f64 / TAU * fit.np as f64) as usize).min(fit.np - 1);
            observed[row * fit.np + col] += 1;
        }
        drawn += m;
    }
    (observed, failed)
}

/// The batch entry points must agree with the single ones: the first 64
/// draws of a batch (`u`, their samples `out`, the directions `wis` whose
/// batch densities are `pdfs`) against `sample` and `pdf`, then the
/// one-wo-per-pair forms ([`check_each`]).
fn check_batch_against_single(
    fit: &FitCase<'_>,
    u: &[Vec2],
    out: &[Option<BxdfSample>],
    wis: &[Vec3],
    pdfs: &[f32],
    report: &mut Report,
) {
    let (sampler, wo, case) = (fit.sampler, fit.wo, &fit.case);
    let m = u.len().min(64);
    for k in 0..m {
        let single = sampler.sample(wo, u[k]);
        if !close_sample(&single, &out[k]) {
            report.fail(
                Check::Batch,
                case,
                format!("sample_batch gave {:?}, sample gave {single:?}", out[k]),
            );
        }
        let p = sampler.pdf(wo, wis[k]);
        if !close(p, pdfs[k]) {
            report.fail(
                Check::Batch,
                case,
                format!("pdf_batch gave {}, pdf gave {p}", pdfs[k]),
            );
        }
    }
    check_each(report, case, sampler, wo, &u[..m]);
}

/// Expected counts N ∫_cell pdf per (cos θ, φ) cell by adaptive quadrature,
/// and in the `None` bin N (1 - ∫ pdf); returns them with ∫ pdf. By
/// contract pdf = 0 below the horizon (probed separately), so only cells
/// with cos θ > 0 are integrated. A pdf that is negative or not finite
/// anywhere is a failure.
fn expected_counts(fit: &FitCase<'_>, report: &mut Report) -> (Vec<f64>, f64) {
    let (nt, np, n) = (fit.nt, fit.np, fit.n);
    let tolerance = fit.config.quadrature_tolerance / n as f64;
    let mut invalid_pdf: Option<(Vec3, f32)> = None;
    let mut expected = vec![0.0f64; fit.none_bin() + 1];
    let mut integral = 0.0;
    for row in 0..nt {
        let z0 = -1.0 + 2.0 * row as f64 / nt as f64;
        let z1 = -1.0 + 2.0 * (row + 1) as f64 / nt as f64;
        if z1 <= 0.0 {
            continue;
        }
        let z0 = z0.max(0.0);
        for col in 0..np {
            let p0 = TAU * col as f64 / np as f64;
            let p1 = TAU * (col + 1) as f64 / np as f64;
            let e = integrate_2d_split(
                |ph, z| {
                    // The horizon itself has pdf 0 by contract; Simpson's
                    // end node there takes the limit from above instead,
                    // so that a density that is positive up to the horizon
                    // does not look like a jump.
                    let z = z.max(HORIZON_NODE);
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let wi = Vec3::new((r * ph.cos()) as f32, (r * ph.sin()) as f32, z as f32);
                    let p = fit.sampler.pdf(fit.wo, wi);
                    if p.is_finite() && p >= 0.0 {
                        p as f64
                    } else {
                        invalid_pdf.get_or_insert((wi, p));
                        0.0
                    }
                },
                (p0, p1),
                (z0, z1),
                tolerance,
                fit.config.quadrature_splits,
            );
            expected[row * np + col] = e.value * n as f64;
            integral += e.value;
        }
    }
    if let Some((wi, p)) = invalid_pdf {
        report.fail(Check::PdfInvalid, &fit.case, format!("pdf(wo, {wi}) = {p}"));
    }
    expected[fit.none_bin()] = n as f64 * (1.0 - integral).max(0.0);
    (expected, integral)
}

/// A sample in a cell where the pdf integrates to 0 is a failure whatever
/// the chi-square statistic says.
fn report_impossible_cells(fit: &FitCase<'_>, outcome: &ChiSquareOutcome, report: &mut Report) {
    if outcome.impossible == 0 {
        return;
    }
    let cell = outcome.first_impossible_cell.unwrap_or(0);
    let what = if cell == fit.none_bin() {
        "the `None` bin".to_string()
    } else {
        format!(
            "cell (cos θ row {}, φ column {})",
            cell / fit.np,
            cell % fit.np
        )
    };
    report.fail(
        Check::ZeroExpectedCell,
        &fit.case,
        format!(
            "{} samples where the pdf integrates to 0, first in {what}",
            outcome.impossible
        ),
    );
}

/// ∫ pdf ≤ 1 and ∫ pdf ≈ fraction of successful draws.
///
/// Two independent estimates of the integral have opposite blind spots:
/// the stratified Monte Carlo one is unbiased, but an isolated spike that
/// no point hits (the mirror peak of a sharp lobe at grazing wo) leaves it
/// low with an overconfident standard error; the adaptive quadrature
/// (`integral`) resolves such a spike but can miss structure aligned with
/// its nodes. A correct pdf agrees with the successful fraction under at
/// least one of them; a wrong one (a scale, a missing Jacobian, a shifted
/// table) moves both, so the check fails only when neither agrees. The
/// same holds for the bound ∫ pdf ≤ 1: a spike narrower than the strata
/// that one point more or less hits (a sun texel of a 1k map under the
/// product sampler) makes the Monte Carlo estimate heavy-tailed and its
/// standard error an underestimate in the other direction, so an excess
/// fails only when the quadrature sees it too (a note otherwise).
fn check_integral_of_pdf(
    fit: &FitCase<'_>,
    failed: usize,
    integral: f64,
    rng: &mut Pcg64,
    report: &mut Report,
) {
    let (n, case) = (fit.n, &fit.case);
    let success = 1.0 - failed as f64 / n as f64;
    let se_success = (success * (1.0 - success)).max(1.0 / n as f64).sqrt() / (n as f64).sqrt();
    let (mc, se_mc) = stratified_integral(fit.sampler, fit.wo, n, rng);
    let se = (se_success * se_success + se_mc * se_mc).sqrt();
    if mc > 1.0 + 1e-3 + 3.0 * se_mc {
        if integral > 1.0 + 1e-3 + QUADRATURE_SLACK {
            report.fail(
                Check::Integral,
                case,
                format!("∫ pdf = {mc:.6} ± {se_mc:.1e} (quadrature {integral:.6}) > 1 + 1e-3"),
            );
        } else {
            report.notes.push(format!(
                "{case}: Monte Carlo ∫ pdf = {mc:.6} ± {se_mc:.1e} > 1 + 1e-3, \
                 quadrature {integral:.6}: only the Monte Carlo estimate exceeds 1"
            ));
        }
    }
    let mc_agrees = (mc - success).abs() <= 3.0 * se;
    let quadrature_agrees = (integral - success).abs() <= 3.0 * se_success + QUADRATURE_SLACK;
    if mc_agrees != quadrature_agrees {
        report.notes.push(format!(
            "{case}: quadrature ∫ pdf = {integral:.6}, Monte Carlo {mc:.6} ± {se_mc:.1e}, \
             successful draws {success:.6}: only the {} agrees",
            if mc_agrees {
                "Monte Carlo estimate"
            } else {
                "quadrature"
            }
        ));
    }
    if !mc_agrees && !quadrature_agrees {
        report.fail(
            Check::Integral,
            case,
            format!(
                "∫ pdf = {mc:.6} ± {se_mc:.1e} (quadrature {integral:.6}) but {success:.6} of the draws \
                 succeeded (allowed difference 3 σ = {:.2e})",
                3.0 * se
            ),
        );
    }
}

/// How far the quadrature's ∫ pdf may sit from the fraction of successful
/// draws beyond their 3 standard errors: the quadrature's own error bound.
const QUADRATURE_SLACK: f64 = 1e-3;

/// ∫ pdf(wo, wi) dω over the upper hemisphere by stratified Monte Carlo in
/// (cos θ, φ): k × 2k strata, two jittered points in each (about `budget`
/// evaluations). Returns the estimate and its standard error, from the
/// spread of the two points of every stratum: Var = Σ A² (f1 - f2)² / 4.
fn stratified_integral(
    sampler: &dyn BxdfSampler,
    wo: Vec3,
    budget: usize,
    rng: &mut Pcg64,
) -> (f64, f64) {
    let kz = ((budget as f64 / 4.0).sqrt() as usize).max(8);
    let kp = 2 * kz;
    let area = (1.0 / kz as f64) * (TAU / kp as f64);
    let mut wis = vec![Vec3::ZERO; 2 * kp];
    let mut pdfs = vec![0f32; 2 * kp];
    let (mut total, mut variance) = (0.0, 0.0);
    for i in 0..kz {
        for (k, wi) in wis.iter_mut().enumerate() {
            let z = ((i as f64 + rng.random::<f64>()) / kz as f64).max(HORIZON_NODE);
            let ph = ((k / 2) as f64 + rng.random::<f64>()) / kp as f64 * TAU;
            let r = (1.0 - z * z).max(0.0).sqrt();
            *wi = Vec3::new((r * ph.cos()) as f32, (r * ph.sin()) as f32, z as f32);
        }
        sampler.pdf_batch(wo, &wis, &mut pdfs);
        for pair in pdfs.chunks_exact(2) {
            let clean = |p: f32| {
                if p.is_finite() && p > 0.0 {
                    p as f64
                } else {
                    0.0
                }
            };
            let (a, b) = (clean(pair[0]), clean(pair[1]));
            total += area * 0.5 * (a + b);
            variance += area * area * (a - b) * (a - b) / 4.0;
        }
    }
    (total, variance.sqrt())
}

/// Chi-square tests at every configured wo (in parallel), then the extreme
/// wo and u checks. `tests_total` is the number of chi-square tests in the
/// whole battery call, for the Sidak correction.
fn check_one(
    report: &mut Report,
    subject: &str,
    sampler: &dyn BxdfSampler,
    brdf: Option<&dyn Brdf>,
    config: &SamplerConfig,
    tests_total: usize,
    stream_offset: u64,
) {
    let threshold = sidak(config.significance, tests_total);
    let fits: Vec<(usize, std::thread::Result<Fit>)> = config
        .wo_theta_degrees
        .par_iter()
        .enumerate()
        .map(|(k, &t)| {
            let wo = outgoing(t, config.wo_phi);
            let fit = catch_unwind(AssertUnwindSafe(|| {
                goodness_of_fit(subject, sampler, brdf, wo, stream_offset + k as u64, config)
            }));
            (k, fit)
        })
        .collect();
    for (k, fit) in fits {
        match fit {
            Ok(mut fit) => {
                fit.line.threshold = threshold;
                if !fit.line.passed() {
                    report.fail(
                        Check::ChiSquare,
                        &format!("{subject} {}", fit.line.case),
                        format!(
                            "p = {:.3e} < {:.3e} (chi2 = {:.1}, dof = {})",
                            fit.line.p_value, threshold, fit.line.statistic, fit.line.dof
                        ),
                    );
                }
                report.chi_square.push(fit.line);
                report.merge(fit.report);
            }
            Err(_) => report.fail(
                Check::Panic,
                &format!("{subject} wo θ = {}°", config.wo_theta_degrees[k]),
                "panicked during the chi-square test",
            ),
        }
    }
    let mut rng = Pcg64::seed_from_u64(config.seed ^ 0x9b0b);
    for &t in &config.wo_theta_degrees {
        let wo = outgoing(t, config.wo_phi);
        let case = format!("{subject} {}(u grid)", describe(brdf, wo));
        guarded(report, &case, |r| {
            check_draws(r, &case, sampler, brdf, wo, 0, &mut rng);
            check_pdf_probes(r, &case, sampler, wo, &mut rng);
        });
    }
    if let Some(brdf) = brdf {
        check_support(report, subject, sampler, brdf, config);
    }
    check_extreme_wo(report, subject, sampler, brdf, config);
    check_grazing_agreement(report, subject, sampler, brdf, config);
}

/// Run the whole battery on one sampler: chi-square and consistency at each
/// configured wo, extreme wo and u. `brdf`, when given, is the BRDF the
/// sampler stands for; the weight f cos θ_i / pdf is checked with it.
pub fn check_sampler(
    subject: &str,
    sampler: &dyn BxdfSampler,
    brdf: Option<&dyn Brdf>,
    config: &SamplerConfig,
) -> Report {
    let mut report = Report::new(subject);
    check_one(
        &mut report,
        subject,
        sampler,
        brdf,
        config,
        config.wo_theta_degrees.len(),
        0,
    );
    report
}

/// Run the battery on a sampler family: `build` makes a sampler from a BRDF.
/// Each of `brdfs` must build and pass everything [`check_sampler`] checks
/// (Sidak over all (BRDF, wo) tests). Then each of
/// [`extreme_brdfs`](crate::brdfs::extreme_brdfs) is fed to `build`: an
/// error is accepted (and noted); a sampler must then pass the extreme wo,
/// u and weight checks, and draw without NaN at every configured wo.
pub fn check_sampler_family<S, F>(
    subject: &str,
    build: F,
    brdfs: &[Arc<dyn Brdf>],
    config: &SamplerConfig,
) -> Report
where
    S: BxdfSampler,
    F: Fn(Arc<dyn Brdf>) -> Result<S>,
{
    let mut report = Report::new(subject);
    let tests_total = brdfs.len() * config.wo_theta_degrees.len();
    for (k, brdf) in brdfs.iter().enumerate() {
        let case = format!("{subject} build(brdf={})", brdf.name());
        let mut built = None;
        guarded(&mut report, &case, |r| match build(brdf.clone()) {
            Ok(s) => built = Some(s),
            Err(e) => r.fail(
                Check::Construction,
                &case,
                format!("rejected an ordinary BRDF: {e}"),
            ),
        });
        if let Some(sampler) = built {
            let stream = (k * config.wo_theta_degrees.len()) as u64;
            check_one(
                &mut report,
                subject,
                &sampler,
                Some(&**brdf),
                config,
                tests_total,
                stream,
            );
        }
    }
    for brdf in crate::brdfs::extreme_brdfs() {
        let case = format!("{subject} build(brdf={})", brdf.name());
        let mut built = None;
        guarded(&mut report, &case, |r| match build(brdf.clone()) {
            Ok(s) => built = Some(s),
            Err(e) => r
                .notes
                .push(format!("{case}: rejected with `{e}` (accepted outcome)")),
        });
        if let Some(sampler) = built {
            report
                .notes
                .push(format!("{case}: built; checked for NaN and consistency"));
            let mut rng = Pcg64::seed_from_u64(config.seed ^ 0xb7d);
            for &t in &config.wo_theta_degrees {
                let wo = outgoing(t, config.wo_phi);
                let case = format!("{subject} {}", describe(Some(&*brdf), wo));
                guarded(&mut report, &case, |r| {
                    check_draws(
                        r,
                        &case,
                        &sampler,
                        Some(&*brdf),
                        wo,
                        config.extreme_samples,
                        &mut rng,
                    );
                    check_pdf_probes(r, &case, &sampler, wo, &mut rng);
                });
            }
            check_extreme_wo(&mut report, subject, &sampler, Some(&*brdf), config);
        }
    }
    report
}

/// The outgoing direction of lane k in [`check_each`]: `wo` itself, `wo`
/// turned about the normal, or (every fourth lane) `wo` mirrored below the
/// horizon, which every entry point must refuse.
fn lane_outgoing(wo: Vec3, k: usize) -> Vec3 {
    match k % 4 {
        0 => wo,
        1 => Vec3::new(wo.x, wo.y, -wo.z),
        _ => {
            let (s, c) = (k as f32 * 0.7).sin_cos();
            Vec3::new(c * wo.x - s * wo.y, s * wo.x + c * wo.y, wo.z)
        }
    }
}

/// `sample_each` and `pdf_each`, with a different outgoing direction in
/// every lane, agree with `sample` and `pdf` pair by pair.
fn check_each(report: &mut Report, case: &str, sampler: &dyn BxdfSampler, wo: Vec3, us: &[Vec2]) {
    let wos: Vec<Vec3> = (0..us.len()).map(|k| lane_outgoing(wo, k)).collect();
    let mut each = vec![None; us.len()];
    sampler.sample_each(&wos, us, &mut each);
    let wis: Vec<Vec3> = each.iter().map(|s| s.map_or(Vec3::Z, |s| s.wi)).collect();
    let mut pdfs = vec![0f32; us.len()];
    sampler.pdf_each(&wos, &wis, &mut pdfs);
    for k in 0..us.len() {
        let single = sampler.sample(wos[k], us[k]);
        if !close_sample(&single, &each[k]) {
            report.fail(
                Check::Batch,
                case,
                format!(
                    "sample_each gave {:?} for wo {}, sample gave {single:?}",
                    each[k], wos[k]
                ),
            );
        }
        let p = sampler.pdf(wos[k], wis[k]);
        if !close(p, pdfs[k]) {
            report.fail(
                Check::Batch,
                case,
                format!("pdf_each gave {} for wo {}, pdf gave {p}", pdfs[k], wos[k]),
            );
        }
    }
}
