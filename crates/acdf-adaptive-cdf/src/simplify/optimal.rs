//! The fewest vertices within a vertical tolerance (`optimal`).

use super::{sanitize, trivial, usable_len, ErrorBound, Simplifier, DEFAULT_VERTICAL_TOLERANCE};

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
