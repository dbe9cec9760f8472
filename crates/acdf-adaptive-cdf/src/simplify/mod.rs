//! Polyline simplifiers for tabulated CDF curves.
//!
//! A tabulated CDF is the polyline through the points (x_k, P_k), k = 0..n-1,
//! with x increasing and P non-decreasing from 0 to 1. A [`Simplifier`]
//! returns the indices of the points to keep; the simplified CDF is the
//! polyline through the kept points only. Every simplifier keeps the first
//! and the last point, and the kept indices are strictly increasing.
//!
//! What matters for sampling is the **vertical** error
//! max_k |P_k - Q(x_k)|, where Q is the simplified CDF: it is the largest
//! amount of probability mass that the simplified distribution moves across
//! any tabulated point. Each simplifier states which error its tolerance
//! bounds ([`ErrorBound`]); [`vertical_error`] measures the vertical one for
//! any result.
//!
//! [`SIMPLIFIERS`] is the one list of them, each with a line saying what
//! its tolerance bounds: [`simplifier_by_name`],
//! [`SIMPLIFIER_NAMES`], the `acdf` command's `adaptive:NAME` samplers, its
//! help texts and error messages, and the default set of `acdf report` all
//! derive from it. Adding a simplifier is one type implementing
//! [`Simplifier`] (a file in this module), one entry in [`SIMPLIFIERS`], and
//! one line in the conformance battery (`tests/tests/adaptive.rs`); see
//! CONTRIBUTING.md.

use acdf_core::{Error, Result};
use std::sync::Arc;

mod chi_square;
mod douglas_peucker;
mod opheim;
mod optimal;
mod reumann_witkam;
mod visvalingam_whyatt;

pub use chi_square::{chi_square_error, ChiSquareOptimal, DEFAULT_CHI_SQUARE_TOLERANCE};
pub use douglas_peucker::DouglasPeucker;
pub use opheim::Opheim;
pub use optimal::OptimalVertical;
pub use reumann_witkam::{ReumannWitkam, DEFAULT_RW_TOLERANCE};
pub use visvalingam_whyatt::{VisvalingamWhyatt, DEFAULT_AREA_TOLERANCE};

/// The error measure a simplifier's tolerance bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorBound {
    /// max_k |P_k - Q(x_k)| over every tabulated point k.
    Vertical,
    /// The largest Euclidean distance from a tabulated point to the line
    /// through the two kept vertices around it.
    Perpendicular,
    /// Visvalingam-Whyatt's effective area: no removed point formed, at the
    /// moment of its removal, a triangle with its two neighbours of area
    /// larger than the tolerance. This bounds no distance.
    EffectiveArea,
    /// The chi-square divergence of the tabulated density from the simplified
    /// one, sum over tabulated cells of (f_k - q_k)^2 / q_k dx_k, where f_k
    /// and q_k are the two piecewise-constant densities (slopes of the two
    /// CDFs), relative to the total mass. It is exactly the relative variance
    /// an importance sampler of f gains by drawing from q instead of f.
    ChiSquare,
}

/// Chooses which points of a tabulated curve to keep.
///
/// `x` and `p` are the coordinates of the points (only the first
/// `min(x.len(), p.len())` are used); `x` must be strictly increasing. The
/// result is the strictly increasing list of kept indices, starting with 0 and
/// ending with the last index (empty for an empty input). A tolerance that is
/// negative or NaN acts as 0; an infinite one keeps only the two ends.
///
/// # Examples
///
/// Simplify the CDF of a small table with a spike, at a vertical tolerance
/// of 0.01:
///
/// ```
/// use acdf_adaptive_cdf::simplify::{simplifier_by_name, vertical_error};
///
/// // The tabulated CDF of the cell values 1, 1, 1, 1, 8, 1, 1, 1 over [0, 1]:
/// // the points (k / 8, P_k).
/// let values = [1.0, 1.0, 1.0, 1.0, 8.0, 1.0, 1.0, 1.0];
/// let total: f64 = values.iter().sum();
/// let x: Vec<f64> = (0..=8).map(|k| k as f64 / 8.0).collect();
/// let mut p = vec![0.0];
/// for v in values {
///     p.push(p[p.len() - 1] + v / total);
/// }
///
/// let dp = simplifier_by_name("dp").unwrap();
/// let kept = dp.simplify(&x, &p, 0.01);
/// // The two ends are kept, and the indices increase.
/// assert_eq!((kept[0], kept[kept.len() - 1]), (0, 8));
/// assert!(kept.windows(2).all(|w| w[0] < w[1]));
/// // `dp` bounds the vertical error, which the straight runs on either side
/// // of the spike do not reach: only the spike's cell keeps its vertices.
/// assert!(vertical_error(&x, &p, &kept) <= 0.01);
/// assert_eq!(kept, vec![0, 4, 5, 8]);
/// ```
pub trait Simplifier: Send + Sync + std::fmt::Debug {
    /// The name used on the command line (`dp`, `vw`, `rw`, `optimal`, ...).
    fn name(&self) -> &'static str;

    /// Which error the tolerance bounds.
    fn bound(&self) -> ErrorBound;

    /// The tolerance used when none is given, chosen by measurement (see the
    /// crate documentation).
    fn default_tolerance(&self) -> f64;

    /// The kept indices such that the error named by [`bound`](Self::bound)
    /// stays at or below `tolerance`.
    fn simplify(&self, x: &[f64], p: &[f64], tolerance: f64) -> Vec<usize>;

    /// At most `max(budget, 2)` kept indices, chosen by the simplifier's own
    /// ranking; `None` when the simplifier has no budget form.
    fn simplify_to_budget(&self, _x: &[f64], _p: &[f64], _budget: usize) -> Option<Vec<usize>> {
        None
    }

    /// The kept row boundaries (0 = first, `n_y` = last) of the marginal of a
    /// 2D table (row-major, `n_y` rows of `n_x` non-negative values whose sum
    /// is positive), for a simplifier whose criterion looks at the whole table
    /// rather than at the marginal CDF alone. `None` (the default): the 2D
    /// distribution simplifies the marginal CDF with [`simplify`](Self::simplify).
    fn simplify_rows(
        &self,
        _values: &[f32],
        _n_x: usize,
        _n_y: usize,
        _tolerance: f64,
    ) -> Option<Vec<usize>> {
        None
    }

    /// The kept indices of several curves at once, for a simplifier that can
    /// share one error budget among them: `curves[j]` are the points (x, p)
    /// of curve j, `weights[j]` its share of the whole (the marginal mass of
    /// a conditional), and the weighted sum of the errors is at most
    /// `tolerance`. `None` (the default): each curve is simplified alone with
    /// [`simplify`](Self::simplify).
    fn simplify_many(
        &self,
        _curves: &[(Vec<f64>, Vec<f64>)],
        _weights: &[f64],
        _tolerance: f64,
    ) -> Option<Vec<Vec<usize>>> {
        None
    }
}

/// One simplifier as the rest of the workspace knows it.
#[derive(Debug, Clone, Copy)]
pub struct SimplifierEntry {
    /// The name on the command line (`acdf ... --sampler adaptive:NAME`) and
    /// in sampler files; [`Simplifier::name`] of what `make` returns.
    pub name: &'static str,
    /// One line for help texts: the algorithm and what its tolerance bounds.
    pub description: &'static str,
    /// Whether `acdf report` compares it by default; the others are reached
    /// with `--sampler adaptive:NAME`.
    pub in_report: bool,
    /// The simplifier; its tolerance when none is given is
    /// [`Simplifier::default_tolerance`].
    pub make: fn() -> Arc<dyn Simplifier>,
}

/// Every simplifier, in the order of reports and help texts (the first is
/// the default of `adaptive`).
pub const SIMPLIFIERS: &[SimplifierEntry] = &[
    SimplifierEntry {
        name: "dp",
        description: "Douglas-Peucker, bounds the vertical error of the CDF",
        in_report: true,
        make: || Arc::new(DouglasPeucker::vertical()),
    },
    SimplifierEntry {
        name: "vw",
        description: "Visvalingam-Whyatt, bounds the vertical error",
        in_report: true,
        make: || Arc::new(VisvalingamWhyatt::vertical()),
    },
    SimplifierEntry {
        name: "rw",
        description: "Reumann-Witkam, bounds the vertical error",
        in_report: true,
        make: || Arc::new(ReumannWitkam),
    },
    SimplifierEntry {
        name: "optimal",
        description: "fewest vertices within the vertical error",
        in_report: true,
        make: || Arc::new(OptimalVertical),
    },
    SimplifierEntry {
        name: "chi2",
        description: "few vertices within a chi-square budget, the variance added",
        in_report: true,
        make: || Arc::new(ChiSquareOptimal),
    },
    SimplifierEntry {
        name: "dp-perp",
        description: "classic Douglas-Peucker, bounds the perpendicular distance",
        in_report: false,
        make: || Arc::new(DouglasPeucker::perpendicular()),
    },
    SimplifierEntry {
        name: "vw-area",
        description: "classic Visvalingam-Whyatt, bounds the effective area",
        in_report: false,
        make: || Arc::new(VisvalingamWhyatt::area()),
    },
    SimplifierEntry {
        name: "opheim",
        description: "Opheim, bounds the vertical error",
        in_report: false,
        make: || Arc::new(Opheim::default()),
    },
];

/// The names of [`SIMPLIFIERS`], in its order.
pub const SIMPLIFIER_NAMES: [&str; SIMPLIFIERS.len()] = {
    let mut names = [""; SIMPLIFIERS.len()];
    let mut k = 0;
    while k < SIMPLIFIERS.len() {
        names[k] = SIMPLIFIERS[k].name;
        k += 1;
    }
    names
};

/// The entry of [`SIMPLIFIERS`] called `name`.
pub fn simplifier_entry(name: &str) -> Option<&'static SimplifierEntry> {
    SIMPLIFIERS.iter().find(|e| e.name == name)
}

/// The simplifier called `name` (one of [`SIMPLIFIER_NAMES`]); an unknown
/// name is an [`Error::InvalidParameter`] that lists the known ones.
pub fn simplifier_by_name(name: &str) -> Result<Arc<dyn Simplifier>> {
    match simplifier_entry(name) {
        Some(entry) => Ok((entry.make)()),
        None => Err(Error::InvalidParameter {
            name: "simplifier",
            reason: format!(
                "unknown simplifier `{name}`; the simplifiers are {}",
                SIMPLIFIER_NAMES.join(", ")
            ),
        }),
    }
}

/// Check a tolerance given by a user: finite or +infinity, and not negative.
pub fn validate_tolerance(tolerance: f64) -> Result<()> {
    if tolerance.is_nan() || tolerance < 0.0 {
        return Err(Error::InvalidParameter {
            name: "tolerance",
            reason: format!("must be a non-negative number, got {tolerance}"),
        });
    }
    Ok(())
}

/// The vertical error of a simplification: max_k |p_k - Q(x_k)| with Q the
/// polyline through the points at `kept` (0 when fewer than two are kept).
pub fn vertical_error(x: &[f64], p: &[f64], kept: &[usize]) -> f64 {
    let mut worst = 0.0f64;
    for w in kept.windows(2) {
        let (i, j) = (w[0], w[1]);
        for k in i + 1..j {
            worst = worst.max(chord_vertical_distance(x, p, i, j, k));
        }
    }
    worst
}

/// The largest perpendicular distance from a point to the line through the
/// kept vertices around it.
pub fn perpendicular_error(x: &[f64], p: &[f64], kept: &[usize]) -> f64 {
    let mut worst = 0.0f64;
    for w in kept.windows(2) {
        let (i, j) = (w[0], w[1]);
        for k in i + 1..j {
            worst = worst.max(perpendicular_distance(x, p, i, j, k));
        }
    }
    worst
}

fn usable_len(x: &[f64], p: &[f64]) -> usize {
    x.len().min(p.len())
}

fn sanitize(tolerance: f64) -> f64 {
    if tolerance > 0.0 {
        tolerance
    } else {
        0.0
    }
}

/// The trivial answers for fewer than three points: every point is kept.
fn trivial(n: usize) -> Option<Vec<usize>> {
    (n <= 2).then(|| (0..n).collect())
}

/// |p_k - (p_i + (x_k - x_i) (p_j - p_i) / (x_j - x_i))|.
#[inline]
fn chord_vertical_distance(x: &[f64], p: &[f64], i: usize, j: usize, k: usize) -> f64 {
    let t = (x[k] - x[i]) / (x[j] - x[i]);
    (p[k] - (p[i] + t * (p[j] - p[i]))).abs()
}

/// Distance from point k to the line through points i and j.
#[inline]
fn perpendicular_distance(x: &[f64], p: &[f64], i: usize, j: usize, k: usize) -> f64 {
    let (dx, dy) = (x[j] - x[i], p[j] - p[i]);
    let len = dx.hypot(dy);
    if len == 0.0 {
        return (x[k] - x[i]).hypot(p[k] - p[i]);
    }
    ((x[k] - x[i]) * dy - (p[k] - p[i]) * dx).abs() / len
}

/// The largest vertical error of the chord i -> j over the points between.
fn span_vertical_error(x: &[f64], p: &[f64], i: usize, j: usize) -> f64 {
    (i + 1..j)
        .map(|k| chord_vertical_distance(x, p, i, j, k))
        .fold(0.0, f64::max)
}

/// The default tolerance of the vertical-error simplifiers (in units of
/// probability), chosen by measurement: see the crate documentation.
pub const DEFAULT_VERTICAL_TOLERANCE: f64 = 1e-4;
