//! Adaptive Simpson quadrature in f64, used to turn a pdf into the expected
//! count of every histogram cell.
//!
//! Each interval is integrated with Simpson's rule and again with Simpson's
//! rule on its two halves; when the two estimates agree to the tolerance the
//! finer one (with its Richardson correction) is kept, otherwise both halves
//! are refined. Simpson's nodes include the interval's ends, so a support
//! boundary that only clips the corner of a cell is still seen. A cell over
//! which the pdf is smooth costs 5 evaluations per dimension; only cells
//! crossed by a discontinuity (a table edge, the rim of a lobe) are refined.
//! In two dimensions the rule is nested (an adaptive integral over `x`
//! inside an adaptive integral over `y`), so a jump along any curve becomes a
//! point jump of the inner integrand and a kink of the outer one, both of
//! which the 1D refinement resolves cheaply.

/// Refinement stops after this many halvings of an interval (2^-20 of a
/// histogram cell is far below anything a million samples can resolve).
const MAX_DEPTH: u32 = 20;

/// An integral and an estimate of its error: the sum over accepted
/// intervals of |fine - coarse| / 15.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub error: f64,
}

impl std::ops::Add for Estimate {
    type Output = Estimate;
    fn add(self, o: Estimate) -> Estimate {
        Estimate {
            value: self.value + o.value,
            error: self.error + o.error,
        }
    }
}

/// Refine Simpson's estimate `whole` of the integral over [a, b], given f at
/// a, m = (a + b)/2 and b.
fn refine(
    f: &mut impl FnMut(f64) -> f64,
    (a, fa): (f64, f64),
    (m, fm): (f64, f64),
    (b, fb): (f64, f64),
    whole: f64,
    tolerance: f64,
    depth: u32,
) -> Estimate {
    let (lm, rm) = (0.5 * (a + m), 0.5 * (m + b));
    let (flm, frm) = (f(lm), f(rm));
    let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
    let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
    let fine = left + right;
    let difference = fine - whole;
    // The same absolute tolerance is passed to both halves: halving it would
    // never converge at a jump, whose error only halves per level.
    if difference.abs() <= 15.0 * tolerance || depth == 0 || !difference.is_finite() {
        // Richardson's correction, except where it would turn a
        // non-negative integral negative (an unresolved jump).
        let corrected = fine + difference / 15.0;
        let value = if corrected < 0.0 && fine >= 0.0 && whole >= 0.0 {
            fine
        } else {
            corrected
        };
        return Estimate {
            value,
            error: difference.abs() / 15.0,
        };
    }
    refine(f, (a, fa), (lm, flm), (m, fm), left, tolerance, depth - 1)
        + refine(f, (m, fm), (rm, frm), (b, fb), right, tolerance, depth - 1)
}

/// The integral of f over [a, b] to an absolute `tolerance` per accepted
/// interval.
pub fn integrate_1d(mut f: impl FnMut(f64) -> f64, a: f64, b: f64, tolerance: f64) -> Estimate {
    let m = 0.5 * (a + b);
    let (fa, fm, fb) = (f(a), f(m), f(b));
    let whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
    refine(
        &mut f,
        (a, fa),
        (m, fm),
        (b, fb),
        whole,
        tolerance,
        MAX_DEPTH,
    )
}

/// The integral of f(x, y) over [x0, x1] × [y0, y1], nested: the inner
/// integrals get a tenth of the tolerance (scaled by the outer width), the
/// outer one the rest.
pub fn integrate_2d(
    f: impl FnMut(f64, f64) -> f64,
    x: (f64, f64),
    y: (f64, f64),
    tolerance: f64,
) -> Estimate {
    integrate_2d_split(f, x, y, tolerance, (1, 1))
}

/// As [`integrate_2d`], but each dimension is first cut into `splits` equal
/// pieces, each integrated adaptively. A pdf with a periodic structure finer
/// than the cell (a sampler's own table) can alias with Simpson's five
/// nodes, which then agree with each other and are accepted with a biased
/// value; more starting nodes push that down to structures finer than the
/// pieces.
pub fn integrate_2d_split(
    mut f: impl FnMut(f64, f64) -> f64,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    tolerance: f64,
    (sx, sy): (usize, usize),
) -> Estimate {
    let (sx, sy) = (sx.max(1), sy.max(1));
    let inner_tolerance = 0.1 * tolerance / (y1 - y0).abs().max(f64::MIN_POSITIVE);
    let mut inner_error = 0.0;
    let mut total = Estimate::default();
    let piece = |a: f64, b: f64, k: usize, n: usize| a + (b - a) * k as f64 / n as f64;
    for j in 0..sy {
        let (ya, yb) = (piece(y0, y1, j, sy), piece(y0, y1, j + 1, sy));
        let outer = integrate_1d(
            |y| {
                let mut inner = Estimate::default();
                for i in 0..sx {
                    let (xa, xb) = (piece(x0, x1, i, sx), piece(x0, x1, i + 1, sx));
                    inner = inner + integrate_1d(|x| f(x, y), xa, xb, inner_tolerance);
                }
                inner_error += inner.error * (yb - ya).abs() / 5.0;
                inner.value
            },
            ya,
            yb,
            0.9 * tolerance,
        );
        total = total + outer;
    }
    Estimate {
        value: total.value,
        error: total.error + inner_error,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrates_a_polynomial_exactly_and_a_step_closely() {
        let e = integrate_1d(|x| x.powi(5) - 2.0 * x * x, 0.0, 2.0, 1e-12);
        assert!((e.value - (64.0 / 6.0 - 16.0 / 3.0)).abs() < 1e-12);
        let step = integrate_1d(|x| if x < 0.3 { 1.0 } else { 5.0 }, 0.0, 1.0, 1e-9);
        assert!((step.value - (0.3 + 3.5)).abs() < 1e-6, "{step:?}");
    }

    /// The unit disc's quarter has area π/4: a curved discontinuity. As in
    /// the battery, the domain is cut into cells first; a single 3-point
    /// rule over the whole square could miss a thin sliver of the disc.
    #[test]
    fn integrates_a_disc_over_cells() {
        let cells = 20;
        let mut total = 0.0;
        for i in 0..cells {
            for j in 0..cells {
                let c = |k: usize| (k as f64 / cells as f64, (k + 1) as f64 / cells as f64);
                total += integrate_2d(
                    |x, y| if x * x + y * y < 1.0 { 1.0 } else { 0.0 },
                    c(i),
                    c(j),
                    1e-9,
                )
                .value;
            }
        }
        assert!(
            (total - std::f64::consts::FRAC_PI_4).abs() < 1e-6,
            "{total}"
        );
    }
}
