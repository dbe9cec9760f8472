//! What a battery run found: one line per chi-square test, and every failed
//! check with enough detail to find the bug.

use std::fmt;

/// The checks of the battery, so that a test can ask which one rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Check {
    /// The chi-square p-value fell below the (Sidak-corrected) significance.
    ChiSquare,
    /// A sample landed in a cell where the pdf integrates to zero.
    ZeroExpectedCell,
    /// The pdf returned with a sample differs from `pdf()` at that point.
    PdfMismatch,
    /// `pdf()` returned a negative, NaN or infinite value somewhere.
    PdfInvalid,
    /// A sample is not where the contract puts it (outside the domain, below
    /// the horizon, not unit length, a zero or non-finite pdf, NaN).
    SampleInvalid,
    /// ∫ pdf exceeds 1 + 1e-3, or differs from the fraction of successful
    /// draws by more than three standard errors.
    Integral,
    /// f cos θ_i / pdf is not finite where pdf > 0.
    Weight,
    /// An extreme input (wo at or below the horizon, u outside [0, 1), a
    /// CDF value) did not give its stated outcome.
    Extremes,
    /// A constructor accepted a bad table, rejected a good one, or returned a
    /// different error than stated.
    Construction,
    /// `invert` is not the inverse of `sample`, or `integral()` is wrong.
    Inverse,
    /// `sample_batch` / `pdf_batch` / `sample_each` / `pdf_each` disagree
    /// with the one-at-a-time calls.
    Batch,
    /// The pdf is 0 on more than the allowed share of f cos θ_i
    /// ([`missed_share`](acdf_core::missed_share)): light the
    /// sampler can never draw.
    Support,
    /// An environment sampler's density does not follow the function its
    /// table is built for: the chi-square divergence of that function from
    /// the density exceeds the configured bound.
    Target,
    /// The code under test panicked.
    Panic,
}

/// One chi-square test: a (subject, case) pair, e.g. (sampler, wo) or
/// (distribution, table).
#[derive(Debug, Clone, PartialEq)]
pub struct ChiSquareLine {
    /// The sampler or distribution.
    pub subject: String,
    /// The BRDF and wo, or the table.
    pub case: String,
    /// Number of draws, including those that returned `None`.
    pub samples: usize,
    /// Draws that returned `None`.
    pub failed_draws: usize,
    /// ∫ pdf over the domain by quadrature.
    pub integral: f64,
    /// The chi-square statistic, its degrees of freedom and p-value.
    pub statistic: f64,
    pub dof: usize,
    pub p_value: f64,
    /// The per-test significance after the Sidak correction.
    pub threshold: f64,
}

impl ChiSquareLine {
    /// Whether this test alone passed.
    pub fn passed(&self) -> bool {
        self.p_value >= self.threshold
    }
}

impl fmt::Display for ChiSquareLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "chi2 {:<28} {:<44} p = {:.4e} (threshold {:.2e}) chi2 = {:.1} dof = {} N = {} none = {} int = {:.6} {}",
            self.subject,
            self.case,
            self.p_value,
            self.threshold,
            self.statistic,
            self.dof,
            self.samples,
            self.failed_draws,
            self.integral,
            if self.passed() { "ok" } else { "FAIL" }
        )
    }
}

/// A failed check.
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    pub check: Check,
    /// The (subject, case) where it failed.
    pub case: String,
    pub detail: String,
}

/// Everything one battery run found. [`Report::passed`] is true when no
/// check failed; the battery macros assert it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Report {
    /// What was tested (the macro's test name).
    pub subject: String,
    /// One line per chi-square test, in the order run.
    pub chi_square: Vec<ChiSquareLine>,
    /// Outcomes that are not failures but worth seeing (a constructor that
    /// rejected an extreme BRDF, ...).
    pub notes: Vec<String>,
    pub failures: Vec<Failure>,
}

impl Report {
    /// An empty report for `subject`.
    pub fn new(subject: &str) -> Report {
        Report {
            subject: subject.to_string(),
            ..Report::default()
        }
    }

    /// No check failed.
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }

    /// Whether `check` failed at least once.
    pub fn failed(&self, check: Check) -> bool {
        self.failures.iter().any(|f| f.check == check)
    }

    /// Record a failure of `check` in `case`.
    pub fn fail(&mut self, check: Check, case: &str, detail: impl Into<String>) {
        // A broken sampler can fail the same check a million times; the first
        // few occurrences say all there is to say.
        let same = self
            .failures
            .iter()
            .filter(|f| f.check == check && f.case == case)
            .count();
        if same < 3 {
            self.failures.push(Failure {
                check,
                case: case.to_string(),
                detail: detail.into(),
            });
        }
    }

    /// Append another report's findings (its subject is dropped).
    pub fn merge(&mut self, other: Report) {
        self.chi_square.extend(other.chi_square);
        self.notes.extend(other.notes);
        self.failures.extend(other.failures);
    }

    /// Print the chi-square lines, notes and failures to stdout (visible with
    /// `cargo test -- --nocapture`).
    pub fn print(&self) {
        println!("{self}");
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "== conformance battery `{}`: {} chi-square tests, {} failures",
            self.subject,
            self.chi_square.len(),
            self.failures.len()
        )?;
        for line in &self.chi_square {
            writeln!(f, "{line}")?;
        }
        for note in &self.notes {
            writeln!(f, "note {note}")?;
        }
        for x in &self.failures {
            writeln!(f, "FAILED {:?} [{}]: {}", x.check, x.case, x.detail)?;
        }
        Ok(())
    }
}

/// Print the report and assert that the battery rejected what it checked
/// (a deliberately broken sampler or distribution) through `expected`;
/// other checks may fail too.
pub fn assert_rejected(report: &Report, expected: Check) {
    report.print();
    assert!(
        !report.passed(),
        "the battery accepted a broken sampler:\n{report}"
    );
    assert!(
        report.failed(expected),
        "rejected, but not by {expected:?}:\n{report}"
    );
}
