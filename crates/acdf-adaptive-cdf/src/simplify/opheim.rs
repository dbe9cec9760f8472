//! Opheim (`opheim`).

use super::{sanitize, trivial, usable_len, ErrorBound, Simplifier};

/// Opheim in one pass: from the current key point, aim a ray at the first
/// following point farther than `min_distance` from it, walk forward while
/// the points stay inside a strip around the ray and within `max_distance` of
/// the key point, and make the last point inside the next key point.
///
/// Where Reumann-Witkam ([`ReumannWitkam`](super::ReumannWitkam)) aims its
/// strip at the very next point, Opheim aims it further along the curve, so
/// that one short step of the tabulation does not set the direction of a
/// long segment; the maximum distance caps how far a segment reaches.
///
/// **What the tolerance bounds: the vertical error.** The strip is vertical
/// with half-width tolerance / 2, and every point after the key point up to
/// the next key point is checked against it (the points closer than
/// `min_distance` too: when the point right after the key point lies outside
/// the strip, it is the next key point). The ray and the chord between the two key points
/// start at the same key point and differ by at most tolerance / 2 at the
/// chord's end, hence everywhere between, so every tabulated point lies
/// within the tolerance of the chord, vertically (and so also
/// perpendicularly, the perpendicular distance to a line being at most the
/// vertical one). The point right after a key point is always accepted, so
/// the kept indices increase strictly and end with the last point.
///
/// Distances are Euclidean in the (x, P) plane of the curve (both in [0, 1]
/// for a normalised CDF). The default `max_distance` is infinite, so that a
/// straight run collapses to its two ends whatever its length; with a finite
/// one, a tolerance of +infinity still keeps only the two ends, as
/// [`Simplifier`] requires.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Opheim {
    /// The ray through a key point aims at the first following point farther
    /// than this from it (the next point if none is nearer).
    pub min_distance: f64,
    /// No segment reaches farther than this from its key point.
    pub max_distance: f64,
}

impl Opheim {
    /// The default aiming distance: four cells of a 256-cell curve, half a
    /// cell of a 32-cell one.
    pub const DEFAULT_MIN_DISTANCE: f64 = 1.0 / 64.0;

    /// The default tolerance, that of `rw`, whose strip is the same.
    pub const DEFAULT_TOLERANCE: f64 = super::DEFAULT_RW_TOLERANCE;

    /// Opheim with the given aiming and maximum distances (negative or NaN
    /// act as 0 for the first, as +infinity for the second).
    pub fn new(min_distance: f64, max_distance: f64) -> Self {
        Self {
            min_distance,
            max_distance,
        }
    }

    /// The slope of the ray from `key`: through the first point farther than
    /// `min_distance` from it, or through the last point if none is.
    fn aim(&self, x: &[f64], p: &[f64], key: usize, n: usize) -> f64 {
        let far = (key + 1..n)
            .find(|&k| (x[k] - x[key]).hypot(p[k] - p[key]) > self.min_distance)
            .unwrap_or(n - 1);
        (p[far] - p[key]) / (x[far] - x[key])
    }
}

impl Default for Opheim {
    /// [`Opheim::DEFAULT_MIN_DISTANCE`] and no maximum distance.
    fn default() -> Self {
        Self::new(Self::DEFAULT_MIN_DISTANCE, f64::INFINITY)
    }
}

impl Simplifier for Opheim {
    fn name(&self) -> &'static str {
        "opheim"
    }

    fn bound(&self) -> ErrorBound {
        ErrorBound::Vertical
    }

    fn default_tolerance(&self) -> f64 {
        Self::DEFAULT_TOLERANCE
    }

    fn simplify(&self, x: &[f64], p: &[f64], tolerance: f64) -> Vec<usize> {
        let n = usable_len(x, p);
        if let Some(all) = trivial(n) {
            return all;
        }
        let tolerance = sanitize(tolerance);
        if tolerance == f64::INFINITY {
            return vec![0, n - 1];
        }
        let half = 0.5 * tolerance;
        // A NaN maximum fails every `<=` below: treat it as no maximum.
        let max_distance = if self.max_distance.is_nan() {
            f64::INFINITY
        } else {
            self.max_distance
        };
        let mut kept = vec![0usize];
        let mut key = 0usize;
        while key < n - 1 {
            let slope = self.aim(x, p, key, n);
            let off_ray = |k: usize| (p[k] - p[key] - slope * (x[k] - x[key])).abs() > half;
            let too_far = |k: usize| (x[k] - x[key]).hypot(p[k] - p[key]) > max_distance;
            // The next point is always a valid next key; the walk goes on
            // past it only if it lies inside the strip itself.
            let mut j = key + 1;
            if !off_ray(j) {
                while j + 1 < n && !off_ray(j + 1) && !too_far(j + 1) {
                    j += 1;
                }
            }
            kept.push(j);
            key = j;
        }
        kept
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simplify::vertical_error;

    /// A CDF with a steep first step and a long straight run after it.
    fn curve() -> (Vec<f64>, Vec<f64>) {
        let x: Vec<f64> = (0..=20).map(|k| k as f64 / 20.0).collect();
        let p = x
            .iter()
            .map(|&t| 0.5 * t + 0.5 * t.min(0.05) / 0.05)
            .collect();
        (x, p)
    }

    #[test]
    fn straight_runs_collapse_and_the_bound_holds() {
        let (x, p) = curve();
        let kept = Opheim::default().simplify(&x, &p, 1e-6);
        assert_eq!(kept, vec![0, 1, 20]);
        assert!(vertical_error(&x, &p, &kept) <= 1e-6);
    }

    #[test]
    fn the_maximum_distance_caps_segments() {
        let (x, p) = curve();
        let capped = Opheim::new(Opheim::DEFAULT_MIN_DISTANCE, 0.3);
        let kept = capped.simplify(&x, &p, 1e-6);
        assert!(kept.len() > 3, "{kept:?}");
        for w in kept.windows(2) {
            let (dx, dp) = (x[w[1]] - x[w[0]], p[w[1]] - p[w[0]]);
            assert!(w[1] == w[0] + 1 || dx.hypot(dp) <= 0.3, "{kept:?}");
        }
        assert_eq!(capped.simplify(&x, &p, f64::INFINITY), vec![0, 20]);
    }
}
