//! Douglas-Peucker (`dp`, `dp-perp`).

use super::{
    chord_vertical_distance, perpendicular_distance, sanitize, trivial, usable_len, ErrorBound,
    Simplifier, DEFAULT_VERTICAL_TOLERANCE,
};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

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
