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
//! | name      | algorithm                    | tolerance bounds                |
//! |-----------|------------------------------|---------------------------------|
//! | `dp`      | Douglas-Peucker              | vertical error                  |
//! | `dp-perp` | Douglas-Peucker (classic)    | perpendicular distance          |
//! | `vw`      | Visvalingam-Whyatt           | vertical error                  |
//! | `vw-area` | Visvalingam-Whyatt (classic) | effective area of each removal  |
//! | `rw`      | Reumann-Witkam, one pass     | vertical error                  |
//! | `optimal` | fewest vertices (DAG search) | vertical error                  |
//! | `chi2`    | fewest vertices (DAG search) | chi-square divergence (variance) |

use acdf_core::{Error, Result};
use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::sync::Arc;

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

/// The names accepted by [`simplifier_by_name`], main ones first.
pub const SIMPLIFIER_NAMES: [&str; 7] = ["dp", "vw", "rw", "optimal", "chi2", "dp-perp", "vw-area"];

/// The simplifier called `name` (see [`SIMPLIFIER_NAMES`]).
pub fn simplifier_by_name(name: &str) -> Result<Arc<dyn Simplifier>> {
    Ok(match name {
        "dp" => Arc::new(DouglasPeucker::vertical()),
        "dp-perp" => Arc::new(DouglasPeucker::perpendicular()),
        "vw" => Arc::new(VisvalingamWhyatt::vertical()),
        "vw-area" => Arc::new(VisvalingamWhyatt::area()),
        "rw" => Arc::new(ReumannWitkam),
        "optimal" => Arc::new(OptimalVertical),
        "chi2" => Arc::new(ChiSquareOptimal),
        _ => {
            return Err(Error::InvalidParameter {
                name: "simplifier",
                reason: format!("unknown simplifier `{name}`; known: {SIMPLIFIER_NAMES:?}"),
            })
        }
    })
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

// ---------------------------------------------------------------------------
// Douglas-Peucker
// ---------------------------------------------------------------------------

/// Douglas-Peucker: split a chord at its farthest point until every point is
/// within the tolerance of its chord. The recursion runs on an explicit stack,
/// so the depth of the split tree costs no call stack.
///
/// The distance is either vertical (`dp`, the default: it bounds the vertical
/// error by the tolerance) or perpendicular (`dp-perp`, the classic form the
/// seed used: it bounds the perpendicular distance; the vertical error of a
/// steep segment can then be far larger than the tolerance).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DouglasPeucker {
    pub metric: ErrorBound,
}

impl DouglasPeucker {
    /// Douglas-Peucker on vertical distance.
    pub fn vertical() -> Self {
        Self {
            metric: ErrorBound::Vertical,
        }
    }

    /// Classic Douglas-Peucker on perpendicular distance.
    pub fn perpendicular() -> Self {
        Self {
            metric: ErrorBound::Perpendicular,
        }
    }

    fn distance(&self, x: &[f64], p: &[f64], i: usize, j: usize, k: usize) -> f64 {
        match self.metric {
            ErrorBound::Perpendicular => perpendicular_distance(x, p, i, j, k),
            _ => chord_vertical_distance(x, p, i, j, k),
        }
    }

    /// The farthest point strictly between i and j and its distance.
    fn farthest(&self, x: &[f64], p: &[f64], i: usize, j: usize) -> (usize, f64) {
        let mut best = (i, -1.0);
        for k in i + 1..j {
            let d = self.distance(x, p, i, j, k);
            if d > best.1 {
                best = (k, d);
            }
        }
        best
    }
}

impl Simplifier for DouglasPeucker {
    fn name(&self) -> &'static str {
        match self.metric {
            ErrorBound::Perpendicular => "dp-perp",
            _ => "dp",
        }
    }

    fn bound(&self) -> ErrorBound {
        match self.metric {
            ErrorBound::Perpendicular => ErrorBound::Perpendicular,
            _ => ErrorBound::Vertical,
        }
    }

    fn default_tolerance(&self) -> f64 {
        DEFAULT_VERTICAL_TOLERANCE
    }

    fn simplify(&self, x: &[f64], p: &[f64], tolerance: f64) -> Vec<usize> {
        let n = usable_len(x, p);
        if let Some(all) = trivial(n) {
            return all;
        }
        let tolerance = sanitize(tolerance);
        let mut keep = vec![false; n];
        keep[0] = true;
        keep[n - 1] = true;
        let mut stack = vec![(0usize, n - 1)];
        while let Some((i, j)) = stack.pop() {
            if j <= i + 1 {
                continue;
            }
            let (k, d) = self.farthest(x, p, i, j);
            if d > tolerance {
                keep[k] = true;
                stack.push((i, k));
                stack.push((k, j));
            }
        }
        (0..n).filter(|&k| keep[k]).collect()
    }

    /// Greedy refinement: start from the two ends and keep splitting the
    /// chord whose farthest point is farthest, until `budget` points are kept.
    fn simplify_to_budget(&self, x: &[f64], p: &[f64], budget: usize) -> Option<Vec<usize>> {
        let n = usable_len(x, p);
        if let Some(all) = trivial(n) {
            return Some(all);
        }
        let budget = budget.max(2);
        let mut keep = vec![false; n];
        keep[0] = true;
        keep[n - 1] = true;
        let mut kept = 2;
        let mut heap = BinaryHeap::new();
        let (k, d) = self.farthest(x, p, 0, n - 1);
        if k > 0 {
            heap.push(Candidate {
                key: d,
                k,
                i: 0,
                j: n - 1,
            });
        }
        while kept < budget {
            let Some(c) = heap.pop() else { break };
            keep[c.k] = true;
            kept += 1;
            for (i, j) in [(c.i, c.k), (c.k, c.j)] {
                if j > i + 1 {
                    let (k, d) = self.farthest(x, p, i, j);
                    heap.push(Candidate { key: d, k, i, j });
                }
            }
        }
        Some((0..n).filter(|&k| keep[k]).collect())
    }
}

/// A max-heap entry ordered by `key`.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    key: f64,
    k: usize,
    i: usize,
    j: usize,
}

impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Candidate {}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        self.key
            .total_cmp(&other.key)
            .then_with(|| other.k.cmp(&self.k))
    }
}

// ---------------------------------------------------------------------------
// Visvalingam-Whyatt
// ---------------------------------------------------------------------------

/// Visvalingam-Whyatt: repeatedly remove the point whose triangle with its two
/// current neighbours has the smallest area (its "effective area").
///
/// Three forms:
/// - `vw` ([`VisvalingamWhyatt::vertical`]): the tolerance bounds the vertical
///   error. Points are still removed in order of effective area, but a point
///   whose removal would put any tabulated point between its neighbours more
///   than the tolerance away (vertically) from the new chord stays, until a
///   neighbour's removal changes its chord.
/// - `vw-area` ([`VisvalingamWhyatt::area`]): the classic tolerance on the
///   effective area (areas in the units of x times P); bounds no distance.
/// - the budget form ([`Simplifier::simplify_to_budget`], either variant):
///   remove by effective area until `budget` points are left.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VisvalingamWhyatt {
    pub metric: ErrorBound,
}

impl VisvalingamWhyatt {
    /// Removal by effective area, with the tolerance on the vertical error.
    pub fn vertical() -> Self {
        Self {
            metric: ErrorBound::Vertical,
        }
    }

    /// Classic removal by effective area, with the tolerance on that area.
    pub fn area() -> Self {
        Self {
            metric: ErrorBound::EffectiveArea,
        }
    }
}

/// Area of the triangle (a, k, b).
#[inline]
fn triangle_area(x: &[f64], p: &[f64], a: usize, k: usize, b: usize) -> f64 {
    0.5 * ((x[k] - x[a]) * (p[b] - p[a]) - (x[b] - x[a]) * (p[k] - p[a])).abs()
}

/// A min-heap entry for Visvalingam-Whyatt, with the neighbours it was
/// computed for so that stale entries can be recognised.
#[derive(Debug, Clone, Copy)]
struct Removal {
    area: f64,
    k: usize,
    prev: usize,
    next: usize,
}

impl PartialEq for Removal {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Removal {}
impl PartialOrd for Removal {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Removal {
    // Reversed so that BinaryHeap pops the smallest area first.
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .area
            .total_cmp(&self.area)
            .then_with(|| other.k.cmp(&self.k))
    }
}

/// Stop rule of one Visvalingam-Whyatt run.
enum VwStop {
    /// Remove while the effective area is at most this.
    Area(f64),
    /// Remove while the new chord's vertical error is at most this.
    Vertical(f64),
    /// Remove until this many points are left.
    Budget(usize),
}

fn visvalingam(x: &[f64], p: &[f64], stop: VwStop) -> Vec<usize> {
    let n = usable_len(x, p);
    if let Some(all) = trivial(n) {
        return all;
    }
    let mut prev: Vec<usize> = (0..n).map(|k| k.wrapping_sub(1)).collect();
    let mut next: Vec<usize> = (1..=n).collect();
    let mut alive = vec![true; n];
    let mut left = n;
    let mut heap: BinaryHeap<Removal> = (1..n - 1)
        .map(|k| Removal {
            area: triangle_area(x, p, k - 1, k, k + 1),
            k,
            prev: k - 1,
            next: k + 1,
        })
        .collect();
    while let Some(r) = heap.pop() {
        if !alive[r.k] || prev[r.k] != r.prev || next[r.k] != r.next {
            continue; // stale: a neighbour has gone since this entry was made
        }
        match stop {
            VwStop::Area(tol) => {
                if r.area > tol {
                    break;
                }
            }
            VwStop::Budget(budget) => {
                if left <= budget.max(2) {
                    break;
                }
            }
            VwStop::Vertical(tol) => {
                if span_vertical_error(x, p, r.prev, r.next) > tol {
                    // Not removable with these neighbours; it is re-queued
                    // when a neighbour goes and its chord changes.
                    continue;
                }
            }
        }
        alive[r.k] = false;
        left -= 1;
        next[r.prev] = r.next;
        prev[r.next] = r.prev;
        for m in [r.prev, r.next] {
            if m > 0 && m < n - 1 {
                // The classic rule: an area never drops below the area of
                // the point removed before it, so the removal order stays
                // monotone in area.
                let area = triangle_area(x, p, prev[m], m, next[m]).max(r.area);
                heap.push(Removal {
                    area,
                    k: m,
                    prev: prev[m],
                    next: next[m],
                });
            }
        }
    }
    (0..n).filter(|&k| alive[k]).collect()
}

impl Simplifier for VisvalingamWhyatt {
    fn name(&self) -> &'static str {
        match self.metric {
            ErrorBound::EffectiveArea => "vw-area",
            _ => "vw",
        }
    }

    fn bound(&self) -> ErrorBound {
        match self.metric {
            ErrorBound::EffectiveArea => ErrorBound::EffectiveArea,
            _ => ErrorBound::Vertical,
        }
    }

    fn default_tolerance(&self) -> f64 {
        match self.metric {
            ErrorBound::EffectiveArea => DEFAULT_AREA_TOLERANCE,
            _ => DEFAULT_VERTICAL_TOLERANCE,
        }
    }

    fn simplify(&self, x: &[f64], p: &[f64], tolerance: f64) -> Vec<usize> {
        let tolerance = sanitize(tolerance);
        match self.metric {
            ErrorBound::EffectiveArea => visvalingam(x, p, VwStop::Area(tolerance)),
            _ => visvalingam(x, p, VwStop::Vertical(tolerance)),
        }
    }

    fn simplify_to_budget(&self, x: &[f64], p: &[f64], budget: usize) -> Option<Vec<usize>> {
        Some(visvalingam(x, p, VwStop::Budget(budget)))
    }
}

// ---------------------------------------------------------------------------
// Reumann-Witkam
// ---------------------------------------------------------------------------

/// Reumann-Witkam in one pass: from the current key point, lay a strip around
/// the line through it and the next point, walk forward while the points stay
/// inside the strip, and make the last point inside the next key point.
///
/// The strip is vertical with half-width tolerance / 2. Every point between two
/// key points is then within tolerance / 2 of the strip line, and so is the
/// second key point; the chord and the strip line start at the same key point,
/// so they differ by at most tolerance / 2 over the span, and the vertical
/// error of the chord is at most the tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ReumannWitkam;

impl Simplifier for ReumannWitkam {
    fn name(&self) -> &'static str {
        "rw"
    }

    fn bound(&self) -> ErrorBound {
        ErrorBound::Vertical
    }

    fn default_tolerance(&self) -> f64 {
        DEFAULT_RW_TOLERANCE
    }

    fn simplify(&self, x: &[f64], p: &[f64], tolerance: f64) -> Vec<usize> {
        let n = usable_len(x, p);
        if let Some(all) = trivial(n) {
            return all;
        }
        let half = 0.5 * sanitize(tolerance);
        let mut kept = vec![0usize];
        let mut key = 0usize;
        while key < n - 1 {
            let slope = (p[key + 1] - p[key]) / (x[key + 1] - x[key]);
            let mut j = key + 1;
            while j + 1 < n {
                let line = p[key] + slope * (x[j + 1] - x[key]);
                if (p[j + 1] - line).abs() > half {
                    break;
                }
                j += 1;
            }
            kept.push(j);
            key = j;
        }
        kept
    }
}

// ---------------------------------------------------------------------------
// Optimal (fewest vertices under a vertical tolerance)
// ---------------------------------------------------------------------------

/// The fewest kept points such that the vertical error is at most the
/// tolerance at every tabulated point (kept points are a subset of the
/// tabulated ones).
///
/// The chord i -> j is valid when, for every k between, its slope s satisfies
/// (p_k - tol - p_i) / (x_k - x_i) <= s <= (p_k + tol - p_i) / (x_k - x_i).
/// Sweeping j forward from i keeps the running intersection [lo, hi] of these
/// intervals, so each validity test costs O(1); once lo > hi no later j can be
/// valid. The fewest-vertex path from 0 to n-1 over valid chords is a shortest
/// path in a DAG whose nodes come in increasing order, solved by one forward
/// pass: O(n^2) time, O(n) memory. Among the paths with the fewest vertices it
/// returns the one whose chords start as late as possible (the last predecessor
/// found), which is deterministic.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct OptimalVertical;

impl Simplifier for OptimalVertical {
    fn name(&self) -> &'static str {
        "optimal"
    }

    fn bound(&self) -> ErrorBound {
        ErrorBound::Vertical
    }

    fn default_tolerance(&self) -> f64 {
        DEFAULT_VERTICAL_TOLERANCE
    }

    fn simplify(&self, x: &[f64], p: &[f64], tolerance: f64) -> Vec<usize> {
        let n = usable_len(x, p);
        if let Some(all) = trivial(n) {
            return all;
        }
        let tol = sanitize(tolerance);
        let mut hops = vec![usize::MAX; n];
        let mut from = vec![0usize; n];
        hops[0] = 0;
        for i in 0..n - 1 {
            if hops[i] == usize::MAX {
                continue; // unreachable cannot happen (i -> i+1 is valid), kept for safety
            }
            let h = hops[i] + 1;
            let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
            for j in i + 1..n {
                let dx = x[j] - x[i];
                let s = (p[j] - p[i]) / dx;
                if s < lo || s > hi {
                    // The chord misses some point between; later chords may
                    // still fit, unless the interval is already empty.
                } else if h <= hops[j] {
                    hops[j] = h;
                    from[j] = i;
                }
                lo = lo.max((p[j] - tol - p[i]) / dx);
                hi = hi.min((p[j] + tol - p[i]) / dx);
                if lo > hi {
                    break;
                }
            }
        }
        let mut path = vec![n - 1];
        let mut k = n - 1;
        while k > 0 {
            k = from[k];
            path.push(k);
        }
        path.reverse();
        path
    }
}

/// The default tolerance of the vertical-error simplifiers (in units of
/// probability), chosen by measurement: see the crate documentation.
pub const DEFAULT_VERTICAL_TOLERANCE: f64 = 1e-4;

/// The default tolerance of `rw`, whose strip is half the tolerance wide and
/// which therefore keeps more points than the others at the same tolerance.
pub const DEFAULT_RW_TOLERANCE: f64 = 5e-4;

/// The default effective-area tolerance of `vw-area`.
pub const DEFAULT_AREA_TOLERANCE: f64 = 5e-7;

// ---------------------------------------------------------------------------
// Fewest vertices under a chi-square (variance) budget
// ---------------------------------------------------------------------------

/// Cell densities f_k = (p_{k+1} - p_k) / (x_{k+1} - x_k) in running sums:
/// returns S with S_k = sum_{l<k} f_l^2 (x_{l+1} - x_l).
fn squared_density_prefix(x: &[f64], p: &[f64], n: usize) -> Vec<f64> {
    let mut s = Vec::with_capacity(n);
    let mut acc = 0.0f64;
    s.push(0.0);
    for k in 0..n - 1 {
        let dp = p[k + 1] - p[k];
        let dx = x[k + 1] - x[k];
        if dx > 0.0 {
            acc += dp * dp / dx;
        }
        s.push(acc);
    }
    s
}

/// The chi-square cost of replacing the cells between points i and j by one
/// segment of constant density M / W (M = p_j - p_i, W = x_j - x_i):
/// sum_k f_k^2 dx_k W / M - M, which is >= 0 by Cauchy-Schwarz; 0 for M = 0.
#[inline]
fn chi_square_cost(x: &[f64], p: &[f64], s: &[f64], i: usize, j: usize) -> f64 {
    let m = p[j] - p[i];
    if m <= 0.0 {
        return 0.0;
    }
    ((s[j] - s[i]) * (x[j] - x[i]) / m - m).max(0.0)
}

/// The chi-square divergence of the tabulated density from the simplified
/// one, sum_k (f_k - q_k)^2 / q_k dx_k (see [`ErrorBound::ChiSquare`]),
/// relative to the total mass p_last - p_0. Cells where q = 0 have f = 0 as
/// well (a kept segment carries exactly the mass of its cells) and add 0.
pub fn chi_square_error(x: &[f64], p: &[f64], kept: &[usize]) -> f64 {
    let n = usable_len(x, p);
    if n < 2 {
        return 0.0;
    }
    let s = squared_density_prefix(x, p, n);
    let total = p[n - 1] - p[0];
    if total <= 0.0 {
        return 0.0;
    }
    kept.windows(2)
        .map(|w| chi_square_cost(x, p, &s, w[0], w[1]))
        .sum::<f64>()
        / total
}

/// Few kept points such that the chi-square divergence of the tabulated
/// density from the simplified one is at most the tolerance.
///
/// This bounds what matters for importance sampling: drawing from the
/// simplified density q instead of the tabulated f multiplies the second
/// moment of f / q by 1 + chi^2. The divergence is a sum of per-segment costs
/// c(i, j) = W S / M - M (W width, M mass, S the sum of f^2 dx over the
/// segment's cells, each O(1) from running sums). The kept points minimise
/// (number of segments) + lambda (divergence) by a shortest path over the DAG
/// of all segments (O(n^2); segments longer than 1024 points are not
/// considered), and lambda is bisected (geometrically) to the
/// smallest value whose path meets the tolerance. This Lagrangian relaxation
/// finds the fewest segments for every divergence on the lower convex hull of
/// the (segments, divergence) trade-off, and a path at most a little longer
/// otherwise; the divergence bound always holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ChiSquareOptimal;

impl Simplifier for ChiSquareOptimal {
    fn name(&self) -> &'static str {
        "chi2"
    }

    fn bound(&self) -> ErrorBound {
        ErrorBound::ChiSquare
    }

    fn default_tolerance(&self) -> f64 {
        DEFAULT_CHI_SQUARE_TOLERANCE
    }

    fn simplify(&self, x: &[f64], p: &[f64], tolerance: f64) -> Vec<usize> {
        let n = usable_len(x, p);
        if let Some(all) = trivial(n) {
            return all;
        }
        let s = squared_density_prefix(x, p, n);
        let mass = p[n - 1] - p[0];
        if mass.is_nan() || mass <= 0.0 {
            return vec![0, n - 1];
        }
        let cost = CostMatrix::new(n, |i, j| chi_square_cost(x, p, &s, i, j) / mass);
        cost.lagrangian(sanitize(tolerance))
    }

    /// Rows [a, b) merged into one marginal segment are drawn with the
    /// mass-weighted average of their conditionals, so the table cell (r, c)
    /// of normalised mass T_rc gets q_rc = C_c / (b - a), C_c the column sum
    /// over the segment. The chi-square cost of the merge is
    /// (b - a) sum_c (sum_r T_rc^2) / C_c - M, O(n_x) from per-column running
    /// sums, and the rows are chosen as in [`simplify`](Simplifier::simplify):
    /// the divergence of the whole table from the row-merged one (before the
    /// conditionals are simplified) is at most the tolerance.
    fn simplify_rows(
        &self,
        values: &[f32],
        n_x: usize,
        n_y: usize,
        tolerance: f64,
    ) -> Option<Vec<usize>> {
        if n_x == 0 || values.len() < n_x * n_y {
            return None;
        }
        let total: f64 = values[..n_x * n_y].iter().map(|&v| v as f64).sum();
        if total.is_nan() || total <= 0.0 || n_y <= 1 {
            return None;
        }
        // Running sums over rows, per column, of T and T^2; and of row masses.
        let mut sum = vec![0.0f64; (n_y + 1) * n_x];
        let mut sq = vec![0.0f64; (n_y + 1) * n_x];
        let mut rows = vec![0.0f64; n_y + 1];
        for r in 0..n_y {
            let mut row = 0.0;
            for c in 0..n_x {
                let t = values[r * n_x + c] as f64 / total;
                sum[(r + 1) * n_x + c] = sum[r * n_x + c] + t;
                sq[(r + 1) * n_x + c] = sq[r * n_x + c] + t * t;
                row += t;
            }
            rows[r + 1] = rows[r] + row;
        }
        let cost = CostMatrix::new(n_y + 1, |i, j| {
            let mut acc = 0.0;
            for c in 0..n_x {
                let col = sum[j * n_x + c] - sum[i * n_x + c];
                if col > 0.0 {
                    acc += (sq[j * n_x + c] - sq[i * n_x + c]) / col;
                }
            }
            ((j - i) as f64 * acc - (rows[j] - rows[i])).max(0.0)
        });
        Some(cost.lagrangian(sanitize(tolerance)))
    }

    /// The conditionals of a 2D distribution share one budget: the
    /// divergence of the whole distribution from the one with simplified
    /// conditionals is the mass-weighted sum of the conditionals'
    /// divergences, so a common lambda for all of them (bisected as in
    /// [`simplify`](Simplifier::simplify)) spends the budget where it saves
    /// the most vertices, and low-mass conditionals shrink to a few vertices.
    fn simplify_many(
        &self,
        curves: &[(Vec<f64>, Vec<f64>)],
        weights: &[f64],
        tolerance: f64,
    ) -> Option<Vec<Vec<usize>>> {
        if weights.len() != curves.len()
            || curves.iter().any(|(x, p)| usable_len(x, p) > MAX_CACHED)
        {
            return None;
        }
        type Cost<'a> = Box<dyn Fn(usize, usize) -> f64 + 'a>;
        let matrices: Vec<Option<CostMatrix<Cost<'_>>>> = curves
            .iter()
            .zip(weights)
            .map(|((x, p), &w)| {
                let n = usable_len(x, p);
                if n <= 2 {
                    return None;
                }
                let mass = p[n - 1] - p[0];
                if !(mass > 0.0 && w > 0.0 && w.is_finite()) {
                    return None;
                }
                let s = squared_density_prefix(x, p, n);
                let scale = w / mass;
                let cost: Cost<'_> = Box::new(move |i, j| chi_square_cost(x, p, &s, i, j) * scale);
                Some(CostMatrix::new(n, cost))
            })
            .collect();
        let solve = |lambda: Option<f64>| {
            let mut total = 0.0;
            let paths: Vec<Vec<usize>> = curves
                .iter()
                .zip(&matrices)
                .map(|((x, p), m)| {
                    let n = usable_len(x, p);
                    match (m, lambda) {
                        (Some(m), Some(l)) => {
                            let (path, c) = m.path(l);
                            total += c;
                            path
                        }
                        (Some(m), None) => {
                            total += m.get(0, n - 1);
                            vec![0, n - 1]
                        }
                        (None, _) if n <= 2 => (0..n).collect(),
                        (None, _) => vec![0, n - 1],
                    }
                })
                .collect();
            (paths, total)
        };
        let tol = sanitize(tolerance);
        let (ends, cost) = solve(None);
        if cost <= tol {
            return Some(ends);
        }
        let count = |paths: &[Vec<usize>]| paths.iter().map(Vec::len).sum::<usize>();
        let mut hi = 1.0 / tol.max(1e-12);
        let (mut best, mut cost) = solve(Some(hi));
        let mut grow = 0;
        while cost > tol && grow < 40 {
            hi *= 16.0;
            (best, cost) = solve(Some(hi));
            grow += 1;
        }
        if cost > tol {
            return None;
        }
        let mut lo = hi * 1e-12;
        for _ in 0..18 {
            let mid = (lo * hi).sqrt();
            let (paths, c) = solve(Some(mid));
            if c <= tol {
                hi = mid;
                if count(&paths) <= count(&best) {
                    best = paths;
                }
            } else {
                lo = mid;
            }
        }
        Some(best)
    }
}

/// The longest segment (in points) the chi-square simplifier considers, so
/// that very long curves cost O(n MAX_SPAN) per lambda, not O(n^2).
const MAX_SPAN: usize = 1024;

/// Curves up to this many points get their segment costs cached.
const MAX_CACHED: usize = 4096;

/// The cost c(i, j) of the segments i < j of a curve of n points (single
/// cells cost 0), cached in a matrix for short curves.
struct CostMatrix<F: Fn(usize, usize) -> f64> {
    n: usize,
    cost: F,
    cache: Option<Vec<f64>>,
}

impl<F: Fn(usize, usize) -> f64> CostMatrix<F> {
    fn new(n: usize, cost: F) -> Self {
        let cache = (n <= MAX_CACHED).then(|| {
            let mut m = vec![0.0; n * n];
            for i in 0..n {
                for j in i + 2..n.min(i + MAX_SPAN + 1) {
                    m[i * n + j] = cost(i, j);
                }
            }
            m
        });
        Self { n, cost, cache }
    }

    #[inline]
    fn get(&self, i: usize, j: usize) -> f64 {
        match &self.cache {
            Some(m) => m[i * self.n + j],
            None if j > i + 1 => (self.cost)(i, j),
            None => 0.0,
        }
    }

    /// The path minimising segments + lambda cost, and its total cost; ties
    /// go to the lower cost.
    fn path(&self, lambda: f64) -> (Vec<usize>, f64) {
        let n = self.n;
        let mut best = vec![(f64::INFINITY, 0.0f64); n];
        let mut from = vec![0usize; n];
        best[0] = (0.0, 0.0);
        for j in 1..n {
            for i in j.saturating_sub(MAX_SPAN)..j {
                let c = self.get(i, j);
                let cand = (best[i].0 + 1.0 + lambda * c, best[i].1 + c);
                if cand.0 < best[j].0 || (cand.0 == best[j].0 && cand.1 < best[j].1) {
                    best[j] = cand;
                    from[j] = i;
                }
            }
        }
        let mut path = vec![n - 1];
        let mut k = n - 1;
        while k > 0 {
            k = from[k];
            path.push(k);
        }
        path.reverse();
        (path, best[n - 1].1)
    }

    /// The fewest-segment path found whose total cost is at most `tol`.
    fn lagrangian(&self, tol: f64) -> Vec<usize> {
        let n = self.n;
        if n <= MAX_SPAN + 1 && self.get(0, n - 1) <= tol {
            return vec![0, n - 1];
        }
        // A large enough lambda always meets the tolerance: single cells
        // cost nothing. Find one, then bisect geometrically towards fewer
        // segments.
        let mut hi = 1.0 / tol.max(1e-12);
        let (mut best, mut cost) = self.path(hi);
        let mut grow = 0;
        while cost > tol && grow < 40 {
            hi *= 16.0;
            (best, cost) = self.path(hi);
            grow += 1;
        }
        if cost > tol {
            return (0..n).collect();
        }
        let mut lo = hi * 1e-12;
        for _ in 0..18 {
            let mid = (lo * hi).sqrt();
            let (path, c) = self.path(mid);
            if c <= tol {
                hi = mid;
                if path.len() <= best.len() {
                    best = path;
                }
            } else {
                lo = mid;
            }
        }
        best
    }
}

/// The default tolerance of `chi2`, chosen by measurement: see the crate
/// documentation.
pub const DEFAULT_CHI_SQUARE_TOLERANCE: f64 = 1.5e-3;
