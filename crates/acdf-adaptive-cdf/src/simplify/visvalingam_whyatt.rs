//! Visvalingam-Whyatt (`vw`, `vw-area`).

use super::{
    sanitize, span_vertical_error, trivial, usable_len, ErrorBound, Simplifier,
    DEFAULT_VERTICAL_TOLERANCE,
};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// The default effective-area tolerance of `vw-area`.
pub const DEFAULT_AREA_TOLERANCE: f64 = 5e-7;

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
