//! Unit tests and property tests of the simplifiers and the distributions.

use crate::curve::{cdf_points, prefix_sums};
use crate::simplify::*;
use crate::{AdaptiveCdf1D, AdaptiveCdf2D};
use acdf_core::{Distribution1D, Distribution2D, Error, Vec2, ONE_MINUS_EPSILON};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// Slack for comparing float errors against a tolerance: the error is
/// recomputed with a formula that rounds differently from the simplifier's.
const SLACK: f64 = 1e-12;

fn all_simplifiers() -> Vec<std::sync::Arc<dyn Simplifier>> {
    SIMPLIFIER_NAMES
        .iter()
        .map(|n| simplifier_by_name(n).unwrap())
        .collect()
}

fn vertical_simplifiers() -> Vec<std::sync::Arc<dyn Simplifier>> {
    all_simplifiers()
        .into_iter()
        .filter(|s| s.bound() == ErrorBound::Vertical)
        .collect()
}

fn points(values: &[f32]) -> Option<(Vec<f64>, Vec<f64>)> {
    cdf_points(&prefix_sums(values.iter().map(|&v| v as f64)))
}

/// Tables with zeros, plateaus, spikes and a huge dynamic range.
fn table(max_len: usize) -> impl Strategy<Value = Vec<f32>> {
    prop::collection::vec(
        prop_oneof![
            3 => Just(0.0f32),
            4 => 0.0f32..1.0,
            2 => (-30i32..30).prop_map(|e| 10f32.powi(e)),
            1 => Just(1e30f32),
        ],
        1..max_len,
    )
}

fn check_kept(kept: &[usize], n: usize) {
    assert_eq!(kept.first(), Some(&0));
    assert_eq!(kept.last(), Some(&(n - 1)));
    assert!(kept.windows(2).all(|w| w[0] < w[1]), "{kept:?}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn every_simplifier_keeps_its_bound(values in table(300), tol in 1e-5f64..0.3) {
        let Some((x, p)) = points(&values) else { return Ok(()); };
        let n = x.len();
        for s in all_simplifiers() {
            let kept = s.simplify(&x, &p, tol);
            check_kept(&kept, n);
            let vertical = vertical_error(&x, &p, &kept);
            match s.bound() {
                ErrorBound::Vertical => prop_assert!(
                    vertical <= tol + SLACK,
                    "{}: vertical error {vertical} > {tol}", s.name()
                ),
                ErrorBound::Perpendicular => {
                    let e = perpendicular_error(&x, &p, &kept);
                    prop_assert!(e <= tol + SLACK, "{}: perpendicular {e} > {tol}", s.name());
                }
                ErrorBound::ChiSquare => {
                    let e = chi_square_error(&x, &p, &kept);
                    prop_assert!(e <= tol * (1.0 + 1e-9) + SLACK, "{}: chi2 {e} > {tol}", s.name());
                }
                ErrorBound::EffectiveArea => {}
            }
        }
    }

    #[test]
    fn optimal_never_keeps_more_than_any_vertical_simplifier(
        values in table(300),
        tol in 1e-5f64..0.3,
    ) {
        let Some((x, p)) = points(&values) else { return Ok(()); };
        let best = OptimalVertical.simplify(&x, &p, tol).len();
        for s in vertical_simplifiers() {
            let other = s.simplify(&x, &p, tol).len();
            prop_assert!(best <= other, "optimal {best} > {} {other}", s.name());
        }
    }

    #[test]
    fn budget_forms_respect_the_budget(values in table(200), budget in 0usize..40) {
        let Some((x, p)) = points(&values) else { return Ok(()); };
        for s in [&VisvalingamWhyatt::vertical() as &dyn Simplifier, &DouglasPeucker::vertical()] {
            let kept = s.simplify_to_budget(&x, &p, budget).unwrap();
            check_kept(&kept, x.len());
            prop_assert!(kept.len() <= budget.max(2));
            prop_assert!(kept.len() == budget.max(2).min(x.len()));
        }
    }

    #[test]
    fn sample_pdf_invert_agree_1d(values in table(300), u in 0.0f32..1.0, pick in 0usize..7, tol in 0.0f64..0.1) {
        let s = simplifier_by_name(SIMPLIFIER_NAMES[pick]).unwrap();
        let d = AdaptiveCdf1D::from_values(&values, &*s, tol).unwrap();
        let sample = d.sample(u);
        prop_assert!((0.0..1.0).contains(&sample.x));
        prop_assert!(sample.pdf > 0.0 && sample.pdf.is_finite());
        prop_assert_eq!(sample.pdf.to_bits(), d.pdf(sample.x).to_bits());
        let back = d.invert(sample.x);
        // x is rounded to f32: the round trip may move by the density times
        // half an ulp of x, plus rounding of u.
        let allowed = 3e-7 + sample.pdf * 6e-8;
        prop_assert!((back - u).abs() <= allowed, "u {u} -> x {} -> {back}", sample.x);
    }

    #[test]
    fn built_cdf_stays_within_tolerance_of_the_table(values in table(300), tol in 1e-4f64..0.1) {
        let Some((x, p)) = points(&values) else { return Ok(()); };
        for s in vertical_simplifiers() {
            let d = AdaptiveCdf1D::from_values(&values, &*s, tol).unwrap();
            for (xk, pk) in x.iter().zip(&p) {
                let q = d.invert(*xk as f32) as f64;
                // f32 storage of x and of the CDF adds a few 1e-7.
                prop_assert!((q - pk).abs() <= tol + 1e-6, "{}: at {xk} {q} vs {pk}", s.name());
            }
        }
    }

    #[test]
    fn sample_pdf_invert_agree_2d(
        values in table(200),
        nx in 1usize..12,
        u in (0.0f32..1.0, 0.0f32..1.0),
        pick in 0usize..7,
        tol in 0.0f64..0.1,
    ) {
        let ny = values.len() / nx;
        prop_assume!(ny >= 1);
        let values = &values[..nx * ny];
        let s = simplifier_by_name(SIMPLIFIER_NAMES[pick]).unwrap();
        let d = AdaptiveCdf2D::from_values(values, nx, ny, &*s, tol).unwrap();
        let u = Vec2::new(u.0, u.1);
        let sample = d.sample(u);
        prop_assert!((0.0..1.0).contains(&sample.p.x) && (0.0..1.0).contains(&sample.p.y));
        prop_assert!(sample.pdf > 0.0 && sample.pdf.is_finite());
        prop_assert_eq!(sample.pdf.to_bits(), d.pdf(sample.p).to_bits());
        let back = d.invert(sample.p);
        prop_assert!((back.y - u.y).abs() <= 3e-7 + d.marginal_pdf(sample.p.y) * 6e-8);
        prop_assert!((back.x - u.x).abs() <= 3e-7 + sample.pdf / d.marginal_pdf(sample.p.y) * 6e-8);
    }
}

#[test]
fn optimal_matches_brute_force_on_small_curves() {
    let mut rng = Pcg64::seed_from_u64(7);
    for _ in 0..300 {
        let n = rng.random_range(1..10usize);
        let values: Vec<f32> = (0..n)
            .map(|_| {
                if rng.random_bool(0.3) {
                    0.0
                } else {
                    rng.random::<f32>()
                }
            })
            .collect();
        let Some((x, p)) = points(&values) else {
            continue;
        };
        let tol = rng.random_range(0.0..0.2);
        let m = x.len();
        // Every subset of the interior points, ends always kept.
        let mut best = usize::MAX;
        for mask in 0u32..(1 << (m - 2)) {
            let mut kept = vec![0];
            kept.extend((1..m - 1).filter(|k| mask & (1 << (k - 1)) != 0));
            kept.push(m - 1);
            if vertical_error(&x, &p, &kept) <= tol {
                best = best.min(kept.len());
            }
        }
        let got = OptimalVertical.simplify(&x, &p, tol);
        assert!(vertical_error(&x, &p, &got) <= tol + SLACK);
        assert_eq!(got.len(), best, "values {values:?} tol {tol}");
    }
}

#[test]
fn douglas_peucker_survives_very_long_curves() {
    // A staircase of 200 000 steps splits at nearly every point: a recursive
    // implementation would go very deep; the explicit stack does not care.
    let values: Vec<f32> = (0..200_000).map(|k| (k % 2) as f32).collect();
    let (x, p) = points(&values).unwrap();
    let kept = DouglasPeucker::vertical().simplify(&x, &p, 0.0);
    assert!(kept.len() > 100_000);
    assert!(vertical_error(&x, &p, &kept) <= SLACK);
}

#[test]
fn collinear_points_collapse_to_the_two_ends() {
    let values = vec![0.25f32; 256];
    let (x, p) = points(&values).unwrap();
    for s in vertical_simplifiers() {
        assert_eq!(s.simplify(&x, &p, 1e-9), vec![0, 256], "{}", s.name());
    }
}

#[test]
fn tiny_inputs_keep_every_point() {
    for s in all_simplifiers() {
        assert_eq!(s.simplify(&[], &[], 0.1), Vec::<usize>::new());
        assert_eq!(s.simplify(&[0.0], &[0.0], 0.1), vec![0]);
        assert_eq!(s.simplify(&[0.0, 1.0], &[0.0, 1.0], 0.1), vec![0, 1]);
        // NaN and negative tolerances act as 0: nothing non-collinear goes.
        let (x, p) = points(&[1.0, 0.0, 1.0]).unwrap();
        assert_eq!(s.simplify(&x, &p, f64::NAN).len(), 4, "{}", s.name());
        assert_eq!(s.simplify(&x, &p, -1.0).len(), 4, "{}", s.name());
        assert_eq!(
            s.simplify(&x, &p, f64::INFINITY),
            vec![0, 3],
            "{}",
            s.name()
        );
    }
}

#[test]
fn names_round_trip_and_unknown_names_fail() {
    for name in SIMPLIFIER_NAMES {
        assert_eq!(simplifier_by_name(name).unwrap().name(), name);
    }
    assert!(matches!(
        simplifier_by_name("nope"),
        Err(Error::InvalidParameter { .. })
    ));
}

#[test]
fn bad_tables_and_tolerances_are_rejected() {
    let s = OptimalVertical;
    assert!(matches!(
        AdaptiveCdf1D::from_values(&[], &s, 0.1),
        Err(Error::EmptyTable { .. })
    ));
    assert!(matches!(
        AdaptiveCdf1D::from_values(&[1.0, f32::NAN], &s, 0.1),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        AdaptiveCdf1D::from_values(&[1.0, -1.0], &s, 0.1),
        Err(Error::Negative { .. })
    ));
    assert!(matches!(
        AdaptiveCdf1D::from_values(&[1.0], &s, f64::NAN),
        Err(Error::InvalidParameter { .. })
    ));
    assert!(matches!(
        AdaptiveCdf1D::from_values(&[1.0], &s, -0.5),
        Err(Error::InvalidParameter { .. })
    ));
    assert!(matches!(
        AdaptiveCdf1D::from_values_with_budget(&[1.0, 2.0, 3.0], &ReumannWitkam, 2),
        Err(Error::InvalidParameter { .. })
    ));
    assert!(matches!(
        AdaptiveCdf2D::from_values(&[1.0; 6], 4, 2, &s, 0.1),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        AdaptiveCdf2D::from_values(&[], 0, 2, &s, 0.1),
        Err(Error::EmptyTable { .. })
    ));
    assert!(matches!(
        AdaptiveCdf2D::from_values(&[1.0, f32::INFINITY], 2, 1, &s, 0.1),
        Err(Error::NonFinite { .. })
    ));
}

#[test]
fn all_zero_tables_fall_back_to_uniform() {
    for s in all_simplifiers() {
        let d = AdaptiveCdf1D::from_values(&[0.0; 17], &*s, 0.01).unwrap();
        assert_eq!(d.integral(), 0.0);
        assert_eq!(d.vertex_count(), 2);
        assert_eq!(d.pdf(0.3), 1.0);
        let smp = d.sample(0.3);
        assert_eq!((smp.x, smp.pdf), (0.3, 1.0));
        assert_eq!(d.invert(0.7), 0.7);

        let d2 = AdaptiveCdf2D::from_values(&[0.0; 12], 3, 4, &*s, 0.01).unwrap();
        assert_eq!(d2.integral(), 0.0);
        let smp = d2.sample(Vec2::new(0.2, 0.9));
        assert_eq!(smp.pdf, 1.0);
        assert!((smp.p - Vec2::new(0.2, 0.9)).length() < 1e-6);
        assert_eq!(d2.pdf(Vec2::new(0.5, 0.5)), 1.0);
    }
}

#[test]
fn a_single_spike_is_always_hit_with_the_right_density() {
    let mut values = vec![0.0f32; 64];
    values[37] = 5.0;
    for s in all_simplifiers() {
        let d = AdaptiveCdf1D::from_values(&values, &*s, s.default_tolerance()).unwrap();
        assert!((d.integral() - 5.0 / 64.0).abs() < 1e-12);
        for k in 0..=1000 {
            let smp = d.sample(k as f32 / 1000.0);
            assert!(
                (37.0 / 64.0..38.0 / 64.0).contains(&smp.x),
                "{}: {}",
                s.name(),
                smp.x
            );
            assert_eq!(smp.pdf, 64.0);
        }
        assert_eq!(d.pdf(0.1), 0.0);
    }
    // The same spike in 2D, at column 5 of row 3 of an 8 x 6 table.
    let mut values = vec![0.0f32; 48];
    values[3 * 8 + 5] = 2.0;
    for s in all_simplifiers() {
        let d = AdaptiveCdf2D::from_values(&values, 8, 6, &*s, s.default_tolerance()).unwrap();
        let smp = d.sample(Vec2::new(0.61, 0.13));
        assert!((5.0 / 8.0..6.0 / 8.0).contains(&smp.p.x), "{}", s.name());
        assert!((3.0 / 6.0..4.0 / 6.0).contains(&smp.p.y), "{}", s.name());
        assert!((smp.pdf - 48.0).abs() < 1e-3);
        assert_eq!(d.pdf(Vec2::new(0.1, 0.1)), 0.0);
    }
}

#[test]
fn huge_dynamic_range_and_extreme_uniforms_stay_finite() {
    let values: Vec<f32> = (0..61).map(|k| 10f32.powi(k - 30)).collect();
    let extremes = [
        0.0,
        f32::MIN_POSITIVE,
        0.5,
        ONE_MINUS_EPSILON,
        1.0,
        2.0,
        -1.0,
        f32::NAN,
        f32::INFINITY,
    ];
    for s in all_simplifiers() {
        let d = AdaptiveCdf1D::from_values(&values, &*s, 0.01).unwrap();
        assert!(d.integral().is_finite() && d.integral() > 0.0);
        for u in extremes {
            let smp = d.sample(u);
            assert!((0.0..1.0).contains(&smp.x), "{} u={u}", s.name());
            assert!(smp.pdf > 0.0 && smp.pdf.is_finite());
            assert_eq!(smp.pdf, d.pdf(smp.x));
            let back = d.invert(u);
            assert!((0.0..=1.0).contains(&back));
        }
        // u next to 1 lands in the last cell, where almost all the mass is.
        assert!(d.sample(ONE_MINUS_EPSILON).x >= 60.0 / 61.0);
        assert_eq!(d.invert(1.0), 1.0);
        assert_eq!(d.invert(f32::NAN), 0.0);
        assert_eq!(d.pdf(1.0), 0.0);
        assert_eq!(d.pdf(f32::NAN), 0.0);
        assert_eq!(d.pdf(-0.1), 0.0);

        let d2 = AdaptiveCdf2D::from_values(&values[..60], 6, 10, &*s, 0.01).unwrap();
        for ux in extremes {
            for uy in extremes {
                let smp = d2.sample(Vec2::new(ux, uy));
                assert!(smp.p.is_finite() && smp.pdf > 0.0 && smp.pdf.is_finite());
                assert_eq!(smp.pdf, d2.pdf(smp.p));
                assert!(d2.invert(Vec2::new(ux, uy)).is_finite());
            }
        }
    }
}

#[test]
fn zero_tolerance_reproduces_the_tabulated_density() {
    let mut rng = Pcg64::seed_from_u64(11);
    let (nx, ny) = (7, 9);
    let values: Vec<f32> = (0..nx * ny)
        .map(|_| {
            if rng.random_bool(0.2) {
                0.0
            } else {
                rng.random::<f32>()
            }
        })
        .collect();
    let mean = values.iter().map(|&v| v as f64).sum::<f64>() / (nx * ny) as f64;
    for name in ["dp", "vw", "rw", "optimal"] {
        let s = simplifier_by_name(name).unwrap();
        let d = AdaptiveCdf2D::from_values(&values, nx, ny, &*s, 0.0).unwrap();
        for iy in 0..ny {
            for ix in 0..nx {
                let p = Vec2::new((ix as f32 + 0.5) / nx as f32, (iy as f32 + 0.5) / ny as f32);
                let expected = values[iy * nx + ix] as f64 / mean;
                let got = d.pdf(p) as f64;
                assert!(
                    (got - expected).abs() <= 1e-4 * (1.0 + expected),
                    "{name} ({ix},{iy}): {got} vs {expected}"
                );
            }
        }
    }
}

#[test]
fn storage_is_counted_exactly() {
    let mut rng = Pcg64::seed_from_u64(3);
    let (nx, ny) = (32, 64);
    let values: Vec<f32> = (0..nx * ny).map(|_| rng.random::<f32>().powi(4)).collect();
    for s in all_simplifiers() {
        let d = AdaptiveCdf2D::from_values(&values, nx, ny, &*s, 0.02).unwrap();
        let marginal = d.marginal_vertex_count();
        let conditional: usize = (0..d.conditional_count())
            .map(|j| d.conditional_vertex_count(j))
            .sum();
        assert_eq!(d.conditional_count(), marginal - 1);
        // The marginal's guide: G + 1 counts of two bytes.
        let guide = if marginal >= 3 {
            2 * (crate::curve::CURVE_GUIDE_CELLS + 1)
        } else {
            0
        };
        assert_eq!(
            d.storage_bytes(),
            8 * marginal + 4 * (d.conditional_count() + 1) + 8 * conditional + guide
        );
        let d1 = AdaptiveCdf1D::from_values(&values[..nx], &*s, 0.02).unwrap();
        assert_eq!(d1.storage_bytes(), 8 * d1.vertex_count());
    }
}

/// The chi-square statistic of `counts` against `expected` (cells with an
/// expected count below 5 pooled), and its number of degrees of freedom.
fn chi_square(counts: &[f64], expected: &[f64]) -> (f64, usize) {
    let (mut stat, mut cells) = (0.0, 0usize);
    let (mut pool_c, mut pool_e) = (0.0, 0.0);
    for (&c, &e) in counts.iter().zip(expected) {
        if e < 5.0 {
            pool_c += c;
            pool_e += e;
            continue;
        }
        stat += (c - e) * (c - e) / e;
        cells += 1;
    }
    if pool_e > 0.0 {
        stat += (pool_c - pool_e) * (pool_c - pool_e) / pool_e.max(1.0);
        cells += 1;
    }
    (stat, cells.saturating_sub(1))
}

/// The chi-square quantile at 1 - 1e-3 (Wilson-Hilferty, z = 3.09).
fn chi_square_critical(dof: usize) -> f64 {
    let k = dof.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + 3.09 * a.sqrt()).powi(3)
}

#[test]
fn samples_follow_the_pdf_chi_square() {
    // Significance 1e-3 per simplifier, fixed seed.
    let mut rng = Pcg64::seed_from_u64(2024);
    let (nx, ny) = (16, 24);
    let values: Vec<f32> = (0..nx * ny)
        .map(|k| {
            let (ix, iy) = ((k % nx) as f32, (k / nx) as f32);
            (-((ix - 5.0).powi(2) + (iy - 12.0).powi(2)) / 10.0).exp() + 0.01
        })
        .collect();
    let n = 200_000;
    for s in all_simplifiers() {
        let d = AdaptiveCdf2D::from_values(&values, nx, ny, &*s, 0.02).unwrap();
        let mut counts = vec![0.0; nx * ny];
        for _ in 0..n {
            let smp = d.sample(Vec2::new(rng.random(), rng.random()));
            let ix = ((smp.p.x * nx as f32) as usize).min(nx - 1);
            let iy = ((smp.p.y * ny as f32) as usize).min(ny - 1);
            counts[iy * nx + ix] += 1.0;
        }
        // The density is constant on each table cell (vertices lie on the
        // cell grid), so a cell's probability is pdf(centre) / (nx ny).
        let expected: Vec<f64> = (0..nx * ny)
            .map(|k| {
                let p = Vec2::new(
                    ((k % nx) as f32 + 0.5) / nx as f32,
                    ((k / nx) as f32 + 0.5) / ny as f32,
                );
                d.pdf(p) as f64 / (nx * ny) as f64 * n as f64
            })
            .collect();
        let total: f64 = expected.iter().sum::<f64>() / n as f64;
        assert!(
            (total - 1.0).abs() < 1e-4,
            "{}: pdf sums to {total}",
            s.name()
        );
        let (stat, dof) = chi_square(&counts, &expected);
        assert!(
            stat < chi_square_critical(dof),
            "{}: chi2 {stat} with {dof} dof",
            s.name()
        );
    }
}

#[test]
fn tiny_positive_cells_keep_a_positive_density() {
    // Cells of mass 1e-12 next to cells of mass 1 round to the same f32 CDF
    // value, and cells of 1e-30 do not even move the f64 running sum; the
    // stored CDF must still give them a positive density.
    for tiny in [1e-12f32, 1e-30] {
        let values: Vec<f32> = (0..64)
            .map(|k| if k % 3 == 0 { tiny } else { 1.0 })
            .collect();
        for s in all_simplifiers() {
            let d = AdaptiveCdf1D::from_values(&values, &*s, 0.0).unwrap();
            for k in 0..64 {
                let x = (k as f32 + 0.5) / 64.0;
                assert!(d.pdf(x) > 0.0, "{}: cell {k}", s.name());
            }
            let d2 = AdaptiveCdf2D::from_values(&values, 8, 8, &*s, 0.0).unwrap();
            for k in 0..64 {
                let p = Vec2::new(((k % 8) as f32 + 0.5) / 8.0, ((k / 8) as f32 + 0.5) / 8.0);
                assert!(d2.pdf(p) > 0.0, "{}: 2D cell {k}", s.name());
            }
        }
    }
}

#[test]
fn chi_square_rows_bound_the_divergence_of_the_whole_table() {
    // The row merge of `chi2` looks at the conditionals too: two rows of
    // equal mass but different shape are not merged at a small tolerance.
    let mut values = vec![0.0f32; 2 * 8];
    values[0] = 1.0;
    values[8 + 7] = 1.0;
    let s = ChiSquareOptimal;
    let rows = s.simplify_rows(&values, 8, 2, 0.1).unwrap();
    assert_eq!(rows, vec![0, 1, 2]);
    // The marginal alone is flat and would merge them.
    let (x, p) = points(&[1.0, 1.0]).unwrap();
    assert_eq!(s.simplify(&x, &p, 0.1), vec![0, 2]);

    // On random tables the divergence of the table from the 2D distribution
    // (rows merged and conditionals simplified) stays within about the sum
    // of the two tolerances.
    let mut rng = Pcg64::seed_from_u64(5);
    let (nx, ny) = (16, 40);
    for _ in 0..20 {
        let values: Vec<f32> = (0..nx * ny)
            .map(|_| {
                if rng.random_bool(0.2) {
                    0.0
                } else {
                    rng.random::<f32>().powi(3)
                }
            })
            .collect();
        let tol = 0.01;
        let d = AdaptiveCdf2D::from_values(&values, nx, ny, &s, tol).unwrap();
        let mean = values.iter().map(|&v| v as f64).sum::<f64>() / (nx * ny) as f64;
        let mut m2 = 0.0;
        for (k, &v) in values.iter().enumerate() {
            if v > 0.0 {
                let p = Vec2::new(
                    ((k % nx) as f32 + 0.5) / nx as f32,
                    ((k / nx) as f32 + 0.5) / ny as f32,
                );
                let t = v as f64 / mean;
                m2 += t * t / d.pdf(p) as f64;
            }
        }
        let chi2 = m2 / (nx * ny) as f64 - 1.0;
        // (1 + 3t/4)(1 + t/4) - 1, plus f32 rounding.
        assert!(chi2 <= tol + tol * tol + 1e-5, "chi2 {chi2}");
        assert!(chi2 > 0.2 * tol, "the budget should be used: chi2 {chi2}");
    }
}

#[test]
fn pinned_rows_are_segments_of_their_own() {
    let values = vec![1.0f32; 4 * 10];
    let s = OptimalVertical;
    let free = AdaptiveCdf2D::from_values(&values, 4, 10, &s, 0.01).unwrap();
    assert_eq!(free.marginal_vertex_count(), 2);
    let pinned = AdaptiveCdf2D::from_values_pinned(&values, 4, 10, &s, 0.01, 1).unwrap();
    assert_eq!(pinned.marginal_vertex_count(), 3);
    assert_eq!(pinned.marginal_pdf(0.05), 1.0);
    let all = AdaptiveCdf2D::from_values_pinned(&values, 4, 10, &s, 0.01, 99).unwrap();
    assert_eq!(all.marginal_vertex_count(), 11);
}
