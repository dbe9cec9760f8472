//! Reumann-Witkam (`rw`).

use super::{sanitize, trivial, usable_len, ErrorBound, Simplifier};

/// The default tolerance of `rw`, whose strip is half the tolerance wide and
/// which therefore keeps more points than the others at the same tolerance.
pub const DEFAULT_RW_TOLERANCE: f64 = 5e-4;

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
