//! Few vertices under a chi-square (variance) budget (`chi2`).

use rayon::prelude::*;

use super::{sanitize, trivial, usable_len, ErrorBound, Simplifier};

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
        let cost = CostMatrix::direct(n, |i, j| chi_square_cost(x, p, &s, i, j) / mass);
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
        let cost = CostMatrix::cached(n_y + 1, |i, j| {
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
        if weights.len() != curves.len() {
            return None;
        }
        // One closure expression, so one type for every curve's costs.
        let matrices: Vec<Option<CostMatrix<_>>> = curves
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
                let (x, p) = (x.as_slice(), p.as_slice());
                Some(CostMatrix::direct(n, move |i, j| {
                    chi_square_cost(x, p, &s, i, j) * scale
                }))
            })
            .collect();
        // The curves' paths on the threads, their costs summed in order.
        let solve = |lambda: Option<f64>| {
            let solved: Vec<(Vec<usize>, f64)> = curves
                .par_iter()
                .zip(&matrices)
                .map(|((x, p), m)| {
                    let n = usable_len(x, p);
                    match (m, lambda) {
                        (Some(m), Some(l)) => m.path(l),
                        (Some(m), None) => (vec![0, n - 1], m.get(0, n - 1)),
                        (None, _) if n <= 2 => ((0..n).collect(), 0.0),
                        (None, _) => (vec![0, n - 1], 0.0),
                    }
                })
                .collect();
            let total = solved.iter().map(|s| s.1).sum::<f64>();
            (solved.into_iter().map(|s| s.0).collect::<Vec<_>>(), total)
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

/// Curves up to this many points get their segment costs cached when a
/// cost is expensive to evaluate.
const MAX_CACHED: usize = 4096;

/// The cost c(i, j) of the segments i < j of a curve of n points (single
/// cells cost 0), either evaluated when asked (a cost of O(1) from running
/// sums: cheaper than reading an n × n matrix, which the shortest path
/// reads down its columns, and without its n² memory) or cached in a
/// matrix for short curves (an expensive cost, such as the merge of whole
/// rows).
struct CostMatrix<F: Fn(usize, usize) -> f64> {
    n: usize,
    cost: F,
    cache: Option<Vec<f64>>,
}

impl<F: Fn(usize, usize) -> f64> CostMatrix<F> {
    /// Costs evaluated when asked.
    fn direct(n: usize, cost: F) -> Self {
        Self {
            n,
            cost,
            cache: None,
        }
    }

    /// Costs cached for curves up to [`MAX_CACHED`] points.
    fn cached(n: usize, cost: F) -> Self {
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
    /// go to the lower cost. For each end point j, the candidates' values
    /// are computed in one pass over the start points (which the compiler
    /// can vectorise: no branch on the data), then the best is picked in
    /// order.
    fn path(&self, lambda: f64) -> (Vec<usize>, f64) {
        let n = self.n;
        // One segment has the value 1 + lambda c(0, n - 1) and every other
        // path at least 2: below 2 the single segment is the answer the
        // search would find (a low-mass curve at most lambdas).
        if n >= 2 && n - 1 <= MAX_SPAN {
            let c = self.get(0, n - 1);
            if 1.0 + lambda * c < 2.0 {
                return (vec![0, n - 1], c);
            }
        }
        let mut value = vec![f64::INFINITY; n];
        let mut total = vec![0.0f64; n];
        let mut from = vec![0usize; n];
        value[0] = 0.0;
        let mut cand_value = vec![0.0f64; MAX_SPAN];
        let mut cand_total = vec![0.0f64; MAX_SPAN];
        for j in 1..n {
            let lo = j.saturating_sub(MAX_SPAN);
            let len = j - lo;
            let (cv, ct) = (&mut cand_value[..len], &mut cand_total[..len]);
            for (k, (v, t)) in cv.iter_mut().zip(ct.iter_mut()).enumerate() {
                let i = lo + k;
                let c = self.get(i, j);
                *v = value[i] + 1.0 + lambda * c;
                *t = total[i] + c;
            }
            let (mut bv, mut bt, mut bi) = (f64::INFINITY, 0.0f64, 0usize);
            for (k, (&v, &t)) in cv.iter().zip(ct.iter()).enumerate() {
                if v < bv || (v == bv && t < bt) {
                    (bv, bt, bi) = (v, t, lo + k);
                }
            }
            (value[j], total[j], from[j]) = (bv, bt, bi);
        }
        let mut path = vec![n - 1];
        let mut k = n - 1;
        while k > 0 {
            k = from[k];
            path.push(k);
        }
        path.reverse();
        (path, total[n - 1])
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
