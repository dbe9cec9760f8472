//! Pearson's chi-square statistic over histogram cells with pooling of the
//! sparse ones, and the Sidak correction.

use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Cells whose expected count is below this are pooled: the chi-square
/// approximation of Pearson's statistic needs about five expected per bin.
pub const MIN_EXPECTED: f64 = 5.0;

/// The outcome of one goodness-of-fit test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChiSquareOutcome {
    pub statistic: f64,
    pub dof: usize,
    pub p_value: f64,
    /// Observed samples in cells whose expected count is exactly zero: each
    /// one is impossible under the pdf.
    pub impossible: u64,
    /// Index of the first such cell.
    pub first_impossible_cell: Option<usize>,
}

/// Σ (O - E)² / E over bins, with the cells of E < [`MIN_EXPECTED`] sorted
/// by E and pooled in order until each pool reaches it (a last pool that
/// stays short joins the previous bin). dof = bins - 1 because the expected
/// counts sum to the observed total.
pub fn chi_square(observed: &[u64], expected: &[f64]) -> ChiSquareOutcome {
    let mut impossible = 0;
    let mut first_impossible_cell = None;
    let mut bins: Vec<(f64, f64)> = Vec::new();
    let mut sparse: Vec<(f64, f64)> = Vec::new();
    for (k, (&o, &e)) in observed.iter().zip(expected).enumerate() {
        let e = if e.is_finite() { e.max(0.0) } else { 0.0 };
        if e == 0.0 {
            if o > 0 {
                impossible += o;
                first_impossible_cell.get_or_insert(k);
            }
        } else if e < MIN_EXPECTED {
            sparse.push((o as f64, e));
        } else {
            bins.push((o as f64, e));
        }
    }
    sparse.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut pool = (0.0, 0.0);
    for (o, e) in sparse {
        pool.0 += o;
        pool.1 += e;
        if pool.1 >= MIN_EXPECTED {
            bins.push(pool);
            pool = (0.0, 0.0);
        }
    }
    if pool.1 > 0.0 {
        match bins.last_mut() {
            Some(last) => {
                last.0 += pool.0;
                last.1 += pool.1;
            }
            None => bins.push(pool),
        }
    }
    let statistic: f64 = bins.iter().map(|&(o, e)| (o - e) * (o - e) / e).sum();
    let dof = bins.len().saturating_sub(1);
    let p_value = if dof == 0 {
        1.0
    } else {
        ChiSquared::new(dof as f64)
            .map(|d| d.sf(statistic))
            .unwrap_or(0.0)
    };
    ChiSquareOutcome {
        statistic,
        dof,
        p_value: if p_value.is_nan() { 0.0 } else { p_value },
        impossible,
        first_impossible_cell,
    }
}

/// The per-test significance that keeps the family-wise error rate at
/// `alpha` over `tests` independent tests: 1 - (1 - alpha)^(1/tests).
pub fn sidak(alpha: f64, tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / tests.max(1) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pooling_keeps_totals_and_flags_impossible_cells() {
        let o = [10, 0, 1, 2, 3, 100];
        let e = [10.0, 0.0, 1.0, 2.0, 2.0, 100.0];
        let r = chi_square(&o, &e);
        assert_eq!(r.dof, 2);
        assert_eq!(r.impossible, 0);
        let r = chi_square(&[1, 5], &[0.0, 6.0]);
        assert_eq!((r.impossible, r.first_impossible_cell), (1, Some(0)));
        assert!((sidak(0.01, 1) - 0.01).abs() < 1e-15);
        assert!(sidak(0.01, 5) < 0.01 / 4.9);
    }
}
