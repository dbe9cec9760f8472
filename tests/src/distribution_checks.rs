//! The battery for [`Distribution1D`] and [`Distribution2D`]: the battery
//! supplies the tables (ordinary and extreme), builds each with the
//! constructor under test, and checks the outcome stated for the table.

use crate::chi2::{chi_square, sidak};
use crate::quadrature::{integrate_1d, integrate_2d};
use crate::reference::{piecewise_constant_integral_1d, piecewise_constant_integral_2d};
use crate::report::{Check, ChiSquareLine, Report};
use crate::sampler_checks::{close, guarded};
use acdf_core::{
    clamp_unit, Distribution1D, Distribution2D, Error, Result, Vec2, ONE_MINUS_EPSILON,
};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

/// Parameters of the distribution battery.
#[derive(Debug, Clone)]
pub struct DistributionConfig {
    /// Draws per table for the chi-square test.
    pub samples: usize,
    pub seed: u64,
    /// Histogram cells over [0, 1) for 1D tables: a prime, so that no
    /// interior cell edge lines up with a table edge, and at least twice the
    /// largest table the battery supplies (300 cells).
    pub cells_1d: usize,
    /// Histogram cells (x, y) for 2D tables, primes and at least twice the
    /// largest table dimension (16).
    pub cells_2d: (usize, usize),
    /// Family-wise significance, Sidak-corrected over the tables tested.
    pub significance: f64,
    /// Allowed quadrature error per cell, in expected counts.
    pub quadrature_tolerance: f64,
    /// What `integral()` must return for a table: the mean of the cell
    /// values for piecewise-constant semantics (the default).
    pub integral_1d: fn(&[f32]) -> f64,
    /// The same for (table, nx, ny).
    pub integral_2d: fn(&[f32], usize, usize) -> f64,
}

impl Default for DistributionConfig {
    fn default() -> Self {
        DistributionConfig {
            samples: 1_000_000,
            seed: 0xd157_acdf,
            cells_1d: 1009,
            cells_2d: (101, 103),
            significance: 0.01,
            quadrature_tolerance: 0.001,
            integral_1d: piecewise_constant_integral_1d,
            integral_2d: piecewise_constant_integral_2d,
        }
    }
}

impl DistributionConfig {
    /// For distributions whose table values are vertex values of a
    /// piecewise-linear (1D) or bilinear (2D) interpolant.
    pub fn piecewise_linear() -> Self {
        DistributionConfig {
            integral_1d: crate::reference::piecewise_linear_integral_1d,
            integral_2d: crate::reference::bilinear_integral_2d,
            ..DistributionConfig::default()
        }
    }
}

/// The error a constructor must return for a bad table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExpectedError {
    /// `Error::EmptyTable`.
    Empty,
    /// `Error::SizeMismatch` with these counts.
    SizeMismatch { expected: usize, got: usize },
    /// `Error::NonFinite` at this index.
    NonFinite { index: usize },
    /// `Error::Negative` at this index.
    Negative { index: usize },
    /// Any error (the dimensions themselves overflow).
    Any,
}

impl ExpectedError {
    fn matches(&self, e: &Error) -> bool {
        match (*self, e) {
            (ExpectedError::Empty, Error::EmptyTable { .. }) => true,
            (
                ExpectedError::SizeMismatch { expected, got },
                Error::SizeMismatch {
                    expected: e,
                    got: g,
                    ..
                },
            ) => expected == *e && got == *g,
            (ExpectedError::NonFinite { index }, Error::NonFinite { index: i, .. }) => index == *i,
            (ExpectedError::Negative { index }, Error::Negative { index: i, .. }) => index == *i,
            (ExpectedError::Any, _) => true,
            _ => false,
        }
    }
}

/// What a table must give.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expect {
    /// Builds and passes every check.
    Accept,
    /// All zero: builds, samples the uniform density (pdf 1 in [0, 1)) and
    /// reports `integral() == 0`.
    UniformFallback,
    /// The constructor returns this error.
    Reject(ExpectedError),
}

/// A 1D table supplied by the battery.
#[derive(Debug, Clone)]
pub struct Table1D {
    pub name: &'static str,
    pub values: Vec<f32>,
    pub expect: Expect,
}

/// A row-major 2D table supplied by the battery, `nx` values per row.
#[derive(Debug, Clone)]
pub struct Table2D {
    pub name: &'static str,
    pub values: Vec<f32>,
    pub nx: usize,
    pub ny: usize,
    pub expect: Expect,
}

fn random_table(seed: u64, n: usize, zero_fraction: f32) -> Vec<f32> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let v: f32 = rng.random();
            if v < zero_fraction {
                0.0
            } else {
                v * v * 4.0
            }
        })
        .collect()
}

/// The 1D tables of the battery, each with its expected outcome.
pub fn tables_1d() -> Vec<Table1D> {
    use Expect::*;
    use ExpectedError::*;
    let mut spike = vec![0.0; 64];
    spike[37] = 1.0;
    vec![
        Table1D {
            name: "random-64",
            values: random_table(1, 64, 0.1),
            expect: Accept,
        },
        Table1D {
            name: "random-300",
            values: random_table(2, 300, 0.0),
            expect: Accept,
        },
        Table1D {
            name: "single",
            values: vec![3.5],
            expect: Accept,
        },
        Table1D {
            name: "seven-with-zeros",
            values: vec![0.0, 1.0, 5.0, 0.0, 2.0, 0.5, 0.0],
            expect: Accept,
        },
        Table1D {
            name: "one-cell",
            values: spike,
            expect: Accept,
        },
        Table1D {
            name: "span-1e-30..1e30",
            values: (0..61).map(|k| 10f64.powi(k - 30) as f32).collect(),
            expect: Accept,
        },
        Table1D {
            name: "huge",
            values: vec![f32::MAX, 1.0, f32::MAX / 4.0, 0.0],
            expect: Accept,
        },
        Table1D {
            name: "subnormal",
            values: vec![1e-45, 0.0, 3e-45, 1e-40],
            expect: Accept,
        },
        Table1D {
            name: "negative-zero",
            values: vec![-0.0, 1.0, 2.0],
            expect: Accept,
        },
        Table1D {
            name: "all-zero",
            values: vec![0.0; 16],
            expect: UniformFallback,
        },
        Table1D {
            name: "empty",
            values: vec![],
            expect: Reject(Empty),
        },
        Table1D {
            name: "nan",
            values: vec![1.0, f32::NAN, 2.0],
            expect: Reject(NonFinite { index: 1 }),
        },
        Table1D {
            name: "infinity",
            values: vec![1.0, 2.0, f32::INFINITY],
            expect: Reject(NonFinite { index: 2 }),
        },
        Table1D {
            name: "negative-infinity",
            values: vec![f32::NEG_INFINITY],
            expect: Reject(NonFinite { index: 0 }),
        },
        Table1D {
            name: "negative",
            values: vec![1.0, -1e-30],
            expect: Reject(Negative { index: 1 }),
        },
        Table1D {
            name: "negative-first",
            values: vec![-5.0, 1.0],
            expect: Reject(Negative { index: 0 }),
        },
    ]
}

/// The 2D tables of the battery, each with its expected outcome.
pub fn tables_2d() -> Vec<Table2D> {
    use Expect::*;
    use ExpectedError::*;
    let t = |name, values, nx, ny, expect| Table2D {
        name,
        values,
        nx,
        ny,
        expect,
    };
    let mut spike = vec![0.0; 16 * 12];
    spike[5 * 16 + 7] = 2.0;
    let mut holes = random_table(4, 8 * 6, 0.0);
    for x in 0..8 {
        holes[2 * 8 + x] = 0.0;
    }
    for y in 0..6 {
        holes[y * 8 + 3] = 0.0;
    }
    let mut nan = vec![1.0; 9];
    nan[4] = f32::NAN;
    let mut negative = vec![1.0; 9];
    negative[7] = -2.0;
    vec![
        t(
            "random-16x12",
            random_table(3, 16 * 12, 0.1),
            16,
            12,
            Accept,
        ),
        t("single-1x1", vec![0.25], 1, 1, Accept),
        t("column-1x9", random_table(5, 9, 0.0), 1, 9, Accept),
        t("row-9x1", random_table(6, 9, 0.0), 9, 1, Accept),
        t("odd-5x3", random_table(7, 15, 0.2), 5, 3, Accept),
        t("one-cell-16x12", spike, 16, 12, Accept),
        t("zero-row-and-column-8x6", holes, 8, 6, Accept),
        t(
            "span-1e-30..1e30-8x8",
            (0..64)
                .map(|k| 10f64.powf(-30.0 + 60.0 * k as f64 / 63.0) as f32)
                .collect(),
            8,
            8,
            Accept,
        ),
        t(
            "huge-3x2",
            vec![f32::MAX, 1.0, 0.0, f32::MAX / 2.0, 3.0, f32::MAX],
            3,
            2,
            Accept,
        ),
        t("all-zero-8x8", vec![0.0; 64], 8, 8, UniformFallback),
        t("empty-0x0", vec![], 0, 0, Reject(Empty)),
        t("empty-0x4", vec![], 0, 4, Reject(Empty)),
        t(
            "too-long-3x3",
            vec![1.0; 10],
            3,
            3,
            Reject(SizeMismatch {
                expected: 9,
                got: 10,
            }),
        ),
        t(
            "too-short-3x4",
            vec![1.0; 9],
            3,
            4,
            Reject(SizeMismatch {
                expected: 12,
                got: 9,
            }),
        ),
        t("nan-3x3", nan, 3, 3, Reject(NonFinite { index: 4 })),
        t(
            "negative-3x3",
            negative,
            3,
            3,
            Reject(Negative { index: 7 }),
        ),
        t(
            "overflowing-dimensions",
            vec![1.0; 4],
            usize::MAX,
            2,
            Reject(Any),
        ),
    ]
}

/// Check what a constructor did with a table against the expectation; hand
/// back the distribution when it should be tested further.
fn check_construction<D>(
    report: &mut Report,
    case: &str,
    built: Result<D>,
    expect: Expect,
) -> Option<D> {
    match (built, expect) {
        (Ok(d), Expect::Accept | Expect::UniformFallback) => Some(d),
        (Err(e), Expect::Accept | Expect::UniformFallback) => {
            report.fail(
                Check::Construction,
                case,
                format!("rejected a valid table: {e}"),
            );
            None
        }
        (Ok(_), Expect::Reject(x)) => {
            report.fail(
                Check::Construction,
                case,
                format!("accepted a bad table, expected {x:?}"),
            );
            None
        }
        (Err(e), Expect::Reject(x)) => {
            if !x.matches(&e) {
                report.fail(
                    Check::Construction,
                    case,
                    format!("returned `{e}`, expected {x:?}"),
                );
            }
            None
        }
    }
}

fn relative_difference(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(f64::MIN_POSITIVE)
}

/// The largest normalised density of a table: max / mean (1 if all zero).
fn peak_density(values: &[f32]) -> f64 {
    let mean = piecewise_constant_integral_1d(values);
    let max = values.iter().fold(0.0f64, |m, &v| m.max(v as f64));
    if mean > 0.0 {
        max / mean
    } else {
        1.0
    }
}

fn check_integral(report: &mut Report, case: &str, got: f64, expected: f64, expect: Expect) {
    let ok = if expect == Expect::UniformFallback {
        got == 0.0
    } else {
        relative_difference(got, expected) <= 1e-5
    };
    if !ok {
        report.fail(
            Check::Inverse,
            case,
            format!("integral() = {got:e}, expected {expected:e}"),
        );
    }
}

/// Chi-square and consistency for one 1D distribution built from `table`.
fn check_1d<D: Distribution1D>(
    subject: &str,
    d: &D,
    table: &Table1D,
    config: &DistributionConfig,
    stream: u64,
) -> (ChiSquareLine, Report) {
    let case = format!("{subject} table={}", table.name);
    let mut report = Report::new(subject);
    let n = config.samples.max(1);
    let m = config.cells_1d.max(2);
    let mut rng = Pcg64::seed_from_u64(
        config
            .seed
            .wrapping_add(stream.wrapping_mul(0x9e37_79b9_7f4a_7c15)),
    );
    check_integral(
        &mut report,
        &case,
        d.integral(),
        (config.integral_1d)(&table.values),
        table.expect,
    );

    let observed = histogram_1d(d, table, n, m, &mut rng, &case, &mut report);
    let (expected, integral) = expected_counts_1d(d, n, m, config, &case, &mut report);
    let outcome = chi_square(&observed, &expected);
    if outcome.impossible > 0 {
        report.fail(
            Check::ZeroExpectedCell,
            &case,
            format!(
                "{} samples where the pdf integrates to 0, first in cell {:?} of {m}",
                outcome.impossible, outcome.first_impossible_cell
            ),
        );
    }

    check_extremes_1d(d, table, &case, &mut report);
    let line = ChiSquareLine {
        subject: subject.to_string(),
        case: format!("table={} (n={})", table.name, table.values.len()),
        samples: n,
        failed_draws: 0,
        integral,
        statistic: outcome.statistic,
        dof: outcome.dof,
        p_value: outcome.p_value,
        threshold: 0.0,
    };
    (line, report)
}

/// Draw n samples in batches and count them in m equal cells of [0, 1),
/// checking every sample, the first batch against `sample`, and that
/// `invert` undoes the first 4096 draws.
fn histogram_1d<D: Distribution1D>(
    d: &D,
    table: &Table1D,
    n: usize,
    m: usize,
    rng: &mut Pcg64,
    case: &str,
    report: &mut Report,
) -> Vec<u64> {
    let mut observed = vec![0u64; m];
    let chunk = 4096;
    let mut us = vec![0f32; chunk];
    let mut out = vec![acdf_core::Sample1D::default(); chunk];
    let mut drawn = 0;
    while drawn < n {
        let c = chunk.min(n - drawn);
        for u in &mut us[..c] {
            *u = rng.random();
        }
        d.sample_batch(&us[..c], &mut out[..c]);
        for k in 0..c {
            let s = out[k];
            let single = (drawn == 0 && k < 64).then(|| d.sample(us[k]));
            if let Some(single) = single.filter(|t| !(close(t.x, s.x) && close(t.pdf, s.pdf))) {
                report.fail(
                    Check::Batch,
                    case,
                    format!("sample_batch gave {s:?}, sample gave {single:?}"),
                );
            }
            check_sample_1d(report, case, d, s);
            if drawn < 4096 {
                let back = d.invert(s.x) as f64;
                let allowed = 1e-5 + 2e-7 * peak_density(&table.values);
                if (back - us[k] as f64).abs() > allowed || !back.is_finite() {
                    report.fail(
                        Check::Inverse,
                        case,
                        format!("invert(sample({}).x = {}) = {back}", us[k], s.x),
                    );
                }
            }
            if (0.0..1.0).contains(&s.x) {
                observed[((s.x as f64 * m as f64) as usize).min(m - 1)] += 1;
            }
        }
        drawn += c;
    }
    observed
}

/// Expected counts n ∫_cell pdf over m equal cells by adaptive quadrature,
/// with ∫ pdf; a pdf that is invalid anywhere or does not integrate to 1
/// is a failure.
fn expected_counts_1d<D: Distribution1D>(
    d: &D,
    n: usize,
    m: usize,
    config: &DistributionConfig,
    case: &str,
    report: &mut Report,
) -> (Vec<f64>, f64) {
    let tolerance = config.quadrature_tolerance / n as f64;
    let mut invalid = None;
    let mut expected = vec![0.0; m];
    let mut integral = 0.0;
    let mut error = 0.0;
    for (k, e) in expected.iter_mut().enumerate() {
        let q = integrate_1d(
            |x| {
                // The domain is [0, 1): Simpson's end node at 1 takes the limit
                // from below.
                let p = d.pdf((x as f32).min(ONE_MINUS_EPSILON));
                if p.is_finite() && p >= 0.0 {
                    p as f64
                } else {
                    invalid.get_or_insert((x, p));
                    0.0
                }
            },
            k as f64 / m as f64,
            (k + 1) as f64 / m as f64,
            tolerance,
        );
        *e = q.value * n as f64;
        integral += q.value;
        error += q.error;
    }
    if let Some((x, p)) = invalid {
        report.fail(Check::PdfInvalid, case, format!("pdf({x}) = {p}"));
    }
    if (integral - 1.0).abs() > 1e-4 + error {
        report.fail(
            Check::Integral,
            case,
            format!("∫ pdf = {integral:.6}, expected 1"),
        );
    }
    (expected, integral)
}

/// Extreme u: the edges of [0, 1), values beyond, and the CDF at every
/// table cell edge (k/n) and vertex (k/(n-1)); `pdf` outside [0, 1) and at
/// every cell edge.
fn check_extremes_1d<D: Distribution1D>(d: &D, table: &Table1D, case: &str, report: &mut Report) {
    let len = table.values.len();
    let mut extreme: Vec<f32> = vec![
        0.0,
        ONE_MINUS_EPSILON,
        1.0,
        -1.0,
        2.0,
        f32::NAN,
        f32::INFINITY,
        -0.0,
    ];
    for k in 0..=len {
        extreme.push(d.invert(k as f32 / len as f32));
        if len > 1 {
            extreme.push(d.invert(k as f32 / (len - 1) as f32));
        }
    }
    for &u in &extreme {
        let s = d.sample(u);
        check_sample_1d(report, case, d, s);
        let c = d.sample(clamp_unit(u));
        if s.x.to_bits() != c.x.to_bits() || s.pdf.to_bits() != c.pdf.to_bits() {
            report.fail(
                Check::Extremes,
                case,
                format!("sample({u}) = {s:?} but sample(clamp_unit(u)) = {c:?}"),
            );
        }
    }
    for x in [
        -1e-7,
        -0.0,
        1.0,
        1.5,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
    ] {
        let p = d.pdf(x);
        if !(p.is_finite() && p >= 0.0) || (p != 0.0 && !(0.0..1.0).contains(&x)) {
            report.fail(
                Check::Extremes,
                case,
                format!("pdf({x}) = {p}, expected 0 outside [0, 1)"),
            );
        }
    }
    for k in 0..=len {
        let x = (k as f32 / len as f32).min(ONE_MINUS_EPSILON);
        let p = d.pdf(x);
        if table.expect == Expect::UniformFallback && p != 1.0 {
            report.fail(
                Check::Extremes,
                case,
                format!("all-zero table: pdf({x}) = {p}, expected the uniform 1"),
            );
        }
        if !(p.is_finite() && p >= 0.0) {
            report.fail(
                Check::PdfInvalid,
                case,
                format!("pdf({x}) = {p} at a cell edge"),
            );
        }
    }
}

fn check_sample_1d<D: Distribution1D>(
    report: &mut Report,
    case: &str,
    d: &D,
    s: acdf_core::Sample1D,
) {
    if !((0.0..1.0).contains(&s.x) && s.pdf.is_finite() && s.pdf > 0.0) {
        report.fail(
            Check::SampleInvalid,
            case,
            format!("sample {s:?}: x must be in [0, 1) with a finite pdf > 0"),
        );
        return;
    }
    let p = d.pdf(s.x);
    if (p - s.pdf).abs() > 1e-4 * p.max(s.pdf) {
        report.fail(
            Check::PdfMismatch,
            case,
            format!("sample returned pdf {} but pdf({}) = {p}", s.pdf, s.x),
        );
    }
}

fn check_sample_2d<D: Distribution2D>(
    report: &mut Report,
    case: &str,
    d: &D,
    s: acdf_core::Sample2D,
) {
    let inside = (0.0..1.0).contains(&s.p.x) && (0.0..1.0).contains(&s.p.y);
    if !(inside && s.pdf.is_finite() && s.pdf > 0.0) {
        report.fail(
            Check::SampleInvalid,
            case,
            format!("sample {s:?}: p must be in [0, 1)^2 with a finite pdf > 0"),
        );
        return;
    }
    let p = d.pdf(s.p);
    if (p - s.pdf).abs() > 1e-4 * p.max(s.pdf) {
        report.fail(
            Check::PdfMismatch,
            case,
            format!("sample returned pdf {} but pdf({}) = {p}", s.pdf, s.p),
        );
    }
}

/// Chi-square and consistency for one 2D distribution built from `table`.
/// `pdf_batch` against `pdf`, exactly, at the drawn points, the same points
/// nudged by an ulp either way (onto and across cell edges), and points
/// outside the square or not numbers.
fn check_pdf_batch_2d<D: Distribution2D>(
    report: &mut Report,
    case: &str,
    d: &D,
    samples: &[acdf_core::Sample2D],
) {
    let mut points: Vec<Vec2> = Vec::new();
    for s in samples.iter().take(1024) {
        let p = s.p;
        points.extend([
            p,
            Vec2::new(p.x.next_up(), p.y),
            Vec2::new(p.x, p.y.next_down()),
        ]);
    }
    points.extend([
        Vec2::new(-0.0, 0.5),
        Vec2::new(0.5, 1.0),
        Vec2::new(1.0, 0.5),
        Vec2::new(f32::NAN, 0.5),
        Vec2::new(0.5, f32::INFINITY),
        Vec2::new(-1e-30, 0.25),
        Vec2::ZERO,
        Vec2::splat(1.0f32.next_down()),
    ]);
    let mut batch = vec![f32::NAN; points.len() + 1];
    d.pdf_batch(&points, &mut batch);
    for (k, &p) in points.iter().enumerate() {
        let single = d.pdf(p);
        if batch[k].to_bits() != single.to_bits() {
            report.fail(
                Check::Batch,
                case,
                format!("pdf_batch gave {} at {p}, pdf gave {single}", batch[k]),
            );
            return;
        }
    }
    if !batch[points.len()].is_nan() {
        report.fail(Check::Batch, case, "pdf_batch wrote past its points");
    }
}

/// Chi-square and consistency for one 2D distribution built from `table`.
fn check_2d<D: Distribution2D>(
    subject: &str,
    d: &D,
    table: &Table2D,
    config: &DistributionConfig,
    stream: u64,
) -> (ChiSquareLine, Report) {
    let case = format!("{subject} table={}", table.name);
    let mut report = Report::new(subject);
    let n = config.samples.max(1);
    let (mx, my) = (config.cells_2d.0.max(1), config.cells_2d.1.max(1));
    let mut rng = Pcg64::seed_from_u64(
        config
            .seed
            .wrapping_add(stream.wrapping_mul(0x9e37_79b9_7f4a_7c15)),
    );
    check_integral(
        &mut report,
        &case,
        d.integral(),
        (config.integral_2d)(&table.values, table.nx, table.ny),
        table.expect,
    );

    let observed = histogram_2d(d, table, n, (mx, my), &mut rng, &case, &mut report);
    let (expected, integral) = expected_counts_2d(d, n, (mx, my), config, &case, &mut report);
    let outcome = chi_square(&observed, &expected);
    if outcome.impossible > 0 {
        report.fail(
            Check::ZeroExpectedCell,
            &case,
            format!(
                "{} samples where the pdf integrates to 0, first in cell {:?}",
                outcome.impossible, outcome.first_impossible_cell
            ),
        );
    }

    check_extremes_2d(d, table, &case, &mut report);
    let line = ChiSquareLine {
        subject: subject.to_string(),
        case: format!("table={} ({}x{})", table.name, table.nx, table.ny),
        samples: n,
        failed_draws: 0,
        integral,
        statistic: outcome.statistic,
        dof: outcome.dof,
        p_value: outcome.p_value,
        threshold: 0.0,
    };
    (line, report)
}

/// Draw n samples in batches and count them in mx × my equal cells of
/// [0, 1)^2, checking every sample, `pdf_batch` and the first batch against
/// `sample`, and that `invert` undoes the first 4096 draws.
fn histogram_2d<D: Distribution2D>(
    d: &D,
    table: &Table2D,
    n: usize,
    (mx, my): (usize, usize),
    rng: &mut Pcg64,
    case: &str,
    report: &mut Report,
) -> Vec<u64> {
    let mut observed = vec![0u64; mx * my];
    let chunk = 4096;
    let mut us = vec![Vec2::ZERO; chunk];
    let mut out = vec![acdf_core::Sample2D::default(); chunk];
    let mut drawn = 0;
    let allowed_inverse = 1e-4 + 4e-7 * peak_density(&table.values);
    while drawn < n {
        let c = chunk.min(n - drawn);
        for u in &mut us[..c] {
            *u = Vec2::new(rng.random(), rng.random());
        }
        d.sample_batch(&us[..c], &mut out[..c]);
        if drawn == 0 {
            check_pdf_batch_2d(report, case, d, &out[..c]);
        }
        for k in 0..c {
            let s = out[k];
            let single = (drawn == 0 && k < 256).then(|| d.sample(us[k]));
            let differs = |t: &acdf_core::Sample2D| {
                !(close(t.p.x, s.p.x) && close(t.p.y, s.p.y) && close(t.pdf, s.pdf))
            };
            if let Some(single) = single.filter(differs) {
                report.fail(
                    Check::Batch,
                    case,
                    format!("sample_batch gave {s:?}, sample gave {single:?}"),
                );
            }
            check_sample_2d(report, case, d, s);
            if drawn < 4096 {
                let back = d.invert(s.p);
                if (back - us[k]).abs().max_element() as f64 > allowed_inverse || !back.is_finite()
                {
                    report.fail(
                        Check::Inverse,
                        case,
                        format!("invert(sample({}).p = {}) = {back}", us[k], s.p),
                    );
                }
            }
            if (0.0..1.0).contains(&s.p.x) && (0.0..1.0).contains(&s.p.y) {
                let i = ((s.p.x as f64 * mx as f64) as usize).min(mx - 1);
                let j = ((s.p.y as f64 * my as f64) as usize).min(my - 1);
                observed[j * mx + i] += 1;
            }
        }
        drawn += c;
    }
    observed
}

/// Expected counts n ∫_cell pdf over mx × my equal cells by adaptive
/// quadrature, with ∫ pdf; a pdf that is invalid anywhere or does not
/// integrate to 1 is a failure.
fn expected_counts_2d<D: Distribution2D>(
    d: &D,
    n: usize,
    (mx, my): (usize, usize),
    config: &DistributionConfig,
    case: &str,
    report: &mut Report,
) -> (Vec<f64>, f64) {
    let tolerance = config.quadrature_tolerance / n as f64;
    let mut invalid = None;
    let mut expected = vec![0.0; mx * my];
    let mut integral = 0.0;
    let mut error = 0.0;
    for j in 0..my {
        for i in 0..mx {
            let q = integrate_2d(
                |x, y| {
                    let p = d.pdf(Vec2::new(
                        (x as f32).min(ONE_MINUS_EPSILON),
                        (y as f32).min(ONE_MINUS_EPSILON),
                    ));
                    if p.is_finite() && p >= 0.0 {
                        p as f64
                    } else {
                        invalid.get_or_insert((x, y, p));
                        0.0
                    }
                },
                (i as f64 / mx as f64, (i + 1) as f64 / mx as f64),
                (j as f64 / my as f64, (j + 1) as f64 / my as f64),
                tolerance,
            );
            expected[j * mx + i] = q.value * n as f64;
            integral += q.value;
            error += q.error;
        }
    }
    if let Some((x, y, p)) = invalid {
        report.fail(Check::PdfInvalid, case, format!("pdf({x}, {y}) = {p}"));
    }
    if (integral - 1.0).abs() > 1e-4 + error {
        report.fail(
            Check::Integral,
            case,
            format!("∫ pdf = {integral:.6}, expected 1"),
        );
    }
    (expected, integral)
}

/// Extreme u: edges, values beyond, and the CDF at every table corner;
/// `pdf` outside [0, 1)^2 and, for an all-zero table, the uniform fallback.
fn check_extremes_2d<D: Distribution2D>(d: &D, table: &Table2D, case: &str, report: &mut Report) {
    let mut edges = vec![0.0, ONE_MINUS_EPSILON, 1.0, -1.0, f32::NAN, f32::INFINITY];
    let mut us_extreme = Vec::new();
    for j in 0..=table.ny {
        for i in 0..=table.nx {
            let g = Vec2::new(i as f32 / table.nx as f32, j as f32 / table.ny as f32);
            us_extreme.push(d.invert(g));
        }
    }
    edges.push(0.5);
    for &a in &edges {
        for &b in &edges {
            us_extreme.push(Vec2::new(a, b));
        }
    }
    for &u in &us_extreme {
        let s = d.sample(u);
        check_sample_2d(report, case, d, s);
        let c = d.sample(Vec2::new(clamp_unit(u.x), clamp_unit(u.y)));
        if s.p.to_array().map(f32::to_bits) != c.p.to_array().map(f32::to_bits)
            || s.pdf.to_bits() != c.pdf.to_bits()
        {
            report.fail(
                Check::Extremes,
                case,
                format!("sample({u}) = {s:?} but sample(clamp_unit(u)) = {c:?}"),
            );
        }
    }
    for p in [
        Vec2::new(-1e-7, 0.5),
        Vec2::new(0.5, 1.0),
        Vec2::new(1.0, 0.5),
        Vec2::new(f32::NAN, 0.5),
        Vec2::new(0.5, f32::INFINITY),
    ] {
        let q = d.pdf(p);
        if q != 0.0 {
            report.fail(
                Check::Extremes,
                case,
                format!("pdf({p}) = {q}, expected 0 outside [0, 1)^2"),
            );
        }
    }
    if table.expect == Expect::UniformFallback {
        for p in [
            Vec2::ZERO,
            Vec2::new(0.3, 0.7),
            Vec2::splat(ONE_MINUS_EPSILON),
        ] {
            let q = d.pdf(p);
            if q != 1.0 {
                report.fail(
                    Check::Extremes,
                    case,
                    format!("all-zero table: pdf({p}) = {q}, expected the uniform 1"),
                );
            }
        }
    }
}

/// What one table gave: its case name, the checks after construction (or
/// the panic they raised; `None` for a rejected table), and the
/// construction's own findings.
type TableOutcome = (
    String,
    std::thread::Result<Option<(ChiSquareLine, Report)>>,
    Report,
);

/// Collect per-table results into one report with the Sidak threshold.
fn finish(subject: &str, config: &DistributionConfig, results: Vec<TableOutcome>) -> Report {
    let mut report = Report::new(subject);
    let tests = results
        .iter()
        .filter(|r| matches!(r.1, Ok(Some(_))))
        .count();
    let threshold = sidak(config.significance, tests);
    for (case, result, construction) in results {
        report.merge(construction);
        match result {
            Ok(Some((mut line, r))) => {
                line.threshold = threshold;
                if !line.passed() {
                    report.fail(
                        Check::ChiSquare,
                        &case,
                        format!(
                            "p = {:.3e} < {threshold:.3e} (chi2 = {:.1}, dof = {})",
                            line.p_value, line.statistic, line.dof
                        ),
                    );
                }
                report.chi_square.push(line);
                report.merge(r);
            }
            Ok(None) => {}
            Err(_) => report.fail(
                Check::Panic,
                &case,
                "panicked while sampling or integrating",
            ),
        }
    }
    report
}

/// Run the battery on a 1D distribution: build it from each of
/// [`tables_1d`] with `build` and check the stated outcome; every accepted
/// table gets the chi-square test (Sidak over the tables), the consistency,
/// inverse, integral and extreme-u checks.
pub fn check_distribution_1d<D, F>(subject: &str, build: F, config: &DistributionConfig) -> Report
where
    D: Distribution1D,
    F: Fn(&[f32]) -> Result<D> + Sync,
{
    let results = tables_1d()
        .into_par_iter()
        .enumerate()
        .map(|(k, table)| {
            let case = format!("{subject} table={}", table.name);
            let mut construction = Report::new(subject);
            let mut built = None;
            guarded(&mut construction, &case, |r| {
                built = check_construction(r, &case, build(&table.values), table.expect);
            });
            let result = catch(|| built.map(|d| check_1d(subject, &d, &table, config, k as u64)));
            (case, result, construction)
        })
        .collect();
    finish(subject, config, results)
}

/// Run the battery on a 2D distribution: as [`check_distribution_1d`] with
/// [`tables_2d`] and `build(table, nx, ny)`.
pub fn check_distribution_2d<D, F>(subject: &str, build: F, config: &DistributionConfig) -> Report
where
    D: Distribution2D,
    F: Fn(&[f32], usize, usize) -> Result<D> + Sync,
{
    let results = tables_2d()
        .into_par_iter()
        .enumerate()
        .map(|(k, table)| {
            let case = format!("{subject} table={}", table.name);
            let mut construction = Report::new(subject);
            let mut built = None;
            guarded(&mut construction, &case, |r| {
                built = check_construction(
                    r,
                    &case,
                    build(&table.values, table.nx, table.ny),
                    table.expect,
                );
            });
            let result = catch(|| built.map(|d| check_2d(subject, &d, &table, config, k as u64)));
            (case, result, construction)
        })
        .collect();
    finish(subject, config, results)
}

fn catch<T>(f: impl FnOnce() -> T) -> std::thread::Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
}
