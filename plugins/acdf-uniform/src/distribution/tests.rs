//! Tests of the piecewise-constant distributions.

use super::*;
use proptest::prelude::*;

/// The drawn cell's fraction x n - k gives `inside_cell`'s answer for
/// every x in cell k, at and within a few ulps of the thresholds m n
/// and 1 - m n and of the cell's edges.
#[test]
fn drawn_cell_fraction_matches_truncation() {
    let mut checked = 0;
    for n in [1usize, 3, 7, 32, 100, 256, 1000] {
        let nf = n as f32;
        for m in [1.0 / 65536.0, 1e-3, 0.3] {
            for k in (0..n).step_by((n / 17).max(1)) {
                let kf = k as f32;
                let bases = [kf / nf, (kf + m * nf) / nf, (kf + 1.0 - m * nf) / nf];
                for base in bases.into_iter().chain([(kf + 1.0) / nf]) {
                    let mut x = base;
                    for _ in 0..8 {
                        x = x.next_down();
                    }
                    for _ in 0..17 {
                        if (0.0..1.0).contains(&x) && cell_of(x, n, nf) == k {
                            assert_eq!(
                                inside_drawn_cell(x, k, nf, m),
                                inside_cell(x, n, m),
                                "x {x} k {k} n {n} m {m}"
                            );
                            checked += 1;
                        }
                        x = x.next_up();
                    }
                }
            }
        }
    }
    assert!(checked > 1000);
}

/// The position of a draw lands in its cell for every grid size,
/// every cell and fractions up to the largest below 1, and is the
/// position first computed whenever that one is in the cell (the
/// shortcut test x n - k in [0, 1) accepts what `cell_of` accepts).
#[test]
fn positions_stay_in_their_cells() {
    let mut nudged = 0;
    for n in [1usize, 3, 7, 32, 100, 255, 256, 1000, 4096] {
        let nf = n as f32;
        let inv = 1.0 / nf;
        for k in (0..n).step_by((n / 23).max(1)).chain([n - 1]) {
            let mut fractions = vec![0.0f32, 1e-30, 0.25, 0.5, ONE_MINUS_EPSILON];
            let mut d = ONE_MINUS_EPSILON;
            for _ in 0..40 {
                d = d.next_down();
                fractions.push(d);
            }
            for du in fractions {
                let x = position_in_cell(k, du, n, nf, inv);
                assert_eq!(cell_of(x, n, nf), k, "n {n} k {k} du {du}");
                assert!((0.0..1.0).contains(&x));
                let first = ((k as f32 + du) * inv).min(ONE_MINUS_EPSILON);
                if cell_of(first, n, nf) == k {
                    assert_eq!(x.to_bits(), first.to_bits(), "n {n} k {k} du {du}");
                } else {
                    nudged += 1;
                }
            }
        }
    }
    // Rounding carries some positions out of their cell: the slow
    // path is exercised.
    assert!(nudged > 0);
}

#[test]
fn lower_bound_matches_partition_point() {
    let cdf = [0.1f32, 0.1, 0.3, 0.5, 0.5, 0.9, 1.0];
    for n in 0..=cdf.len() {
        let s = &cdf[..n];
        for u in [0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9, 0.95, 1.0, 2.0] {
            assert_eq!(
                count_sorted(s, u),
                s.partition_point(|&c| c <= u),
                "n {n} u {u}"
            );
        }
    }
}

#[test]
fn one_d_samples_follow_the_values() {
    let d = PiecewiseConstant1D::new(&[1.0, 3.0, 0.0, 4.0]).unwrap();
    assert_eq!(d.count(), 4);
    approx::assert_relative_eq!(d.integral(), 2.0);
    assert_eq!(d.cdf(), &[0.125, 0.5, 0.5, 1.0]);
    approx::assert_relative_eq!(d.pdf(0.1), 0.5);
    approx::assert_relative_eq!(d.pdf(0.3), 1.5);
    assert_eq!(d.pdf(0.6), 0.0);
    approx::assert_relative_eq!(d.pdf(0.9), 2.0);
    assert_eq!(d.pdf(1.0), 0.0);
    assert_eq!(d.pdf(-0.1), 0.0);
    assert_eq!(d.pdf(f32::NAN), 0.0);
    let s = d.sample(0.5);
    assert!((0.75..1.0).contains(&s.x), "{s:?}");
    approx::assert_relative_eq!(s.pdf, 2.0);
    assert_eq!(d.func(), vec![0.5, 1.5, 0.0, 2.0]);
}

#[test]
fn u_next_to_one_lands_in_the_last_non_empty_cell() {
    let d = PiecewiseConstant1D::new(&[1.0, 2.0, 0.0, 0.0]).unwrap();
    for u in [ONE_MINUS_EPSILON, 1.0, f32::INFINITY] {
        let s = d.sample(u);
        assert!((0.25..0.5).contains(&s.x), "{s:?}");
        assert!(s.pdf > 0.0 && s.pdf.is_finite());
    }
    let s = d.sample(f32::NAN);
    assert_eq!(s.x, 0.0);
    // Nine cells: x = (8 + du) / 9 can round to 1 without the guard.
    let d = PiecewiseConstant1D::new(&[1.0; 9]).unwrap();
    let s = d.sample(ONE_MINUS_EPSILON);
    assert!(s.x < 1.0 && d.pdf(s.x) == s.pdf);
    let d2 = PiecewiseConstant2D::new(&[1.0, 1.0, 0.0, 2.0, 0.0, 0.0], 2, 3).unwrap();
    let s = d2.sample(Vec2::splat(ONE_MINUS_EPSILON));
    assert!(
        s.p.y >= 1.0 / 3.0 && s.p.y < 2.0 / 3.0 && s.p.x >= 0.5,
        "{s:?}"
    );
    assert!(s.pdf > 0.0 && s.pdf == d2.pdf(s.p));
}

#[test]
fn zero_tables_fall_back_to_uniform() {
    let d = PiecewiseConstant1D::new(&[0.0; 5]).unwrap();
    assert_eq!(d.integral(), 0.0);
    for x in [0.0, 0.3, 0.99] {
        approx::assert_relative_eq!(d.pdf(x), 1.0, max_relative = 1e-6);
    }
    approx::assert_relative_eq!(d.sample(0.3).x, 0.3, max_relative = 1e-6);
    let d2 = PiecewiseConstant2D::new(&[0.0; 6], 3, 2).unwrap();
    assert_eq!(d2.integral(), 0.0);
    let s = d2.sample(Vec2::new(0.4, 0.7));
    approx::assert_relative_eq!(s.pdf, 1.0, max_relative = 1e-6);
    approx::assert_relative_eq!(s.p.x, 0.4, max_relative = 1e-6);
    // A zero row in a non-zero table: uniform conditional, never drawn.
    let d3 = PiecewiseConstant2D::new(&[0.0, 0.0, 1.0, 3.0], 2, 2).unwrap();
    assert_eq!(d3.conditional(0).unwrap(), &[0.5, 1.0]);
    assert_eq!(d3.pdf(Vec2::new(0.2, 0.2)), 0.0);
    for u in [0.0, 0.1, 0.5, ONE_MINUS_EPSILON] {
        let s = d3.sample(Vec2::new(0.3, u));
        assert!(s.p.y >= 0.5 && s.pdf > 0.0);
    }
    approx::assert_relative_eq!(d3.pdf(Vec2::new(0.7, 0.7)), 3.0);
}

#[test]
fn bad_tables_give_the_right_error() {
    assert!(matches!(
        PiecewiseConstant1D::new(&[]),
        Err(Error::EmptyTable { .. })
    ));
    assert!(matches!(
        PiecewiseConstant1D::new(&[1.0, f32::NAN]),
        Err(Error::NonFinite { index: 1, .. })
    ));
    assert!(matches!(
        PiecewiseConstant1D::new(&[f32::INFINITY]),
        Err(Error::NonFinite { index: 0, .. })
    ));
    assert!(matches!(
        PiecewiseConstant1D::new(&[1.0, -1.0]),
        Err(Error::Negative { index: 1, .. })
    ));
    assert!(matches!(
        PiecewiseConstant2D::new(&[1.0; 6], 4, 2),
        Err(Error::SizeMismatch {
            expected: 8,
            got: 6,
            ..
        })
    ));
    assert!(matches!(
        PiecewiseConstant2D::new(&[], 0, 2),
        Err(Error::EmptyTable { .. })
    ));
    assert!(matches!(
        PiecewiseConstant2D::new(&[1.0, 1.0, -0.5, 1.0], 2, 2),
        Err(Error::Negative { index: 2, .. })
    ));
    assert!(matches!(
        PiecewiseConstant2D::new(&[1.0, f32::NAN], 1, 2),
        Err(Error::NonFinite { index: 1, .. })
    ));
    assert!(matches!(
        PiecewiseConstant2D::new(&[1.0], usize::MAX, 2),
        Err(Error::InvalidParameter { .. })
    ));
}

#[test]
fn huge_dynamic_range_stays_monotone_and_ends_at_one() {
    let values: Vec<f32> = (0..61).map(|k| 10f32.powi(k - 30)).collect();
    let d = PiecewiseConstant1D::new(&values).unwrap();
    assert!(d.cdf().windows(2).all(|w| w[0] <= w[1]));
    assert_eq!(*d.cdf().last().unwrap(), 1.0);
    assert!(d.integral().is_finite() && d.integral() > 0.0);
    for u in [0.0, 1e-30, 0.5, 0.9, ONE_MINUS_EPSILON] {
        let s = d.sample(u);
        assert!(s.x < 1.0 && s.pdf > 0.0 && s.pdf.is_finite(), "{u} {s:?}");
        assert_eq!(d.pdf(s.x), s.pdf);
    }
    let mut table = values.clone();
    table.extend(values.iter().rev());
    let d2 = PiecewiseConstant2D::new(&table, 61, 2).unwrap();
    assert_eq!(*d2.marginal().last().unwrap(), 1.0);
    for u in [Vec2::ZERO, Vec2::splat(0.5), Vec2::splat(ONE_MINUS_EPSILON)] {
        let s = d2.sample(u);
        assert!(s.pdf > 0.0 && s.pdf.is_finite() && s.pdf == d2.pdf(s.p));
    }
}

/// Every positive cell keeps a positive density and every zero cell none,
/// however small the cell is against the rest: cells of 1e-30 after cells
/// of 1 (lost even in the `f64` running sum), a tiny last cell (whose top
/// must stay exactly 1), and rows of such tables in the marginal.
#[test]
fn positive_cells_keep_a_positive_density_whatever_their_share() {
    let tables: [&[f32]; 4] = [
        &[1.0, 1e-30, 0.0, 1.0, 1e-30],
        &[1e-30, 1.0, 1e-20, 1e-30, 0.0, 0.0],
        &[0.0, 1e-38, 0.0, 1.0],
        &[1.0; 7],
    ];
    for values in tables {
        let n = values.len();
        let d = PiecewiseConstant1D::new(values).unwrap();
        assert_eq!(*d.cdf().last().unwrap(), 1.0);
        for (k, &v) in values.iter().enumerate() {
            let pdf = d.pdf((k as f32 + 0.5) / n as f32);
            assert_eq!(pdf > 0.0, v > 0.0, "{values:?}: cell {k} has pdf {pdf}");
        }
    }
    // Rows 1 and 3 hold 1e-30 against rows of 1: the marginal keeps them.
    let nx = 3;
    let table = [
        1.0, 1.0, 1.0, 0.0, 1e-30, 0.0, 1.0, 0.0, 1.0, 1e-30, 0.0, 1e-35,
    ];
    let d = PiecewiseConstant2D::new(&table, nx, 4).unwrap();
    for (i, &v) in table.iter().enumerate() {
        let p = Vec2::new(
            ((i % nx) as f32 + 0.5) / nx as f32,
            ((i / nx) as f32 + 0.5) / 4.0,
        );
        assert_eq!(
            d.pdf(p) > 0.0,
            v > 0.0,
            "cell {i} ({v}) has pdf {}",
            d.pdf(p)
        );
    }
}

#[test]
fn storage_counts_the_cdfs() {
    let d = PiecewiseConstant2D::new(&vec![1.0; 256 * 32], 32, 256).unwrap();
    // The CDFs plus a u16 guide of 256 + 1 entries over the marginal.
    assert_eq!(d.storage_bytes(), (256 * 32 + 256) * 4 + 257 * 2);
    assert_eq!(
        PiecewiseConstant1D::new(&[1.0; 7]).unwrap().storage_bytes(),
        28 + 8 * 2
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// The branch-free search counts exactly what a binary search does,
    /// for every length.
    #[test]
    fn search_matches_partition_point(
        mut v in prop::collection::vec(prop_oneof![Just(0.5f32), 0.0f32..1.0], 0..300),
        u in prop::collection::vec(0.0f32..1.0, 8),
    ) {
        v.sort_by(f32::total_cmp);
        let lanes: [f32; 8] = std::array::from_fn(|l| if l == 3 { 0.5 } else { u[l] });
        for &u in &lanes {
            let expected = v.partition_point(|&c| c <= u);
            prop_assert_eq!(count_sorted(&v, u), expected);
        }
    }

    /// The guided search counts exactly what a binary search does, for
    /// CDFs with long flat runs, steep steps and every u near a guide
    /// boundary.
    #[test]
    fn guided_search_matches_partition_point(values in table(300), u in prop::collection::vec(0.0f32..1.0, 16)) {
        let d = PiecewiseConstant1D::new(&values).unwrap();
        let cdf = d.cdf();
        let n = cdf.len();
        for u in u.iter().copied().chain(near_guide_boundaries(n)).chain(cdf.iter().copied()) {
            let u = clamp_unit(u);
            let expected = cdf[..n - 1].partition_point(|&c| c <= u);
            prop_assert_eq!(d.guide.guided_count(cdf, u), expected, "u {}", u);
        }
    }

    /// The 2D marginal's guide has a fixed number of cells; the row it
    /// finds is that of a binary search whether the table has fewer
    /// rows than guide cells, as many, or more (wide guide intervals),
    /// for u on and beside every guide boundary and marginal entry.
    #[test]
    fn marginal_rows_match_partition_point(values in table(900), nx in 1usize..4, u in prop::collection::vec(0.0f32..1.0, 16)) {
        let ny = values.len().div_ceil(nx);
        let mut v = values.clone();
        v.resize(nx * ny, 0.0);
        let d = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
        let marginal = d.marginal();
        let boundaries = near_guide_boundaries(MARGINAL_GUIDE_CELLS);
        for u in u.iter().copied().chain(boundaries).chain(marginal.iter().copied()) {
            let u = clamp_unit(u);
            let expected = marginal[..ny - 1].partition_point(|&c| c <= u);
            prop_assert_eq!(d.row(u), expected, "u {} ny {}", u, ny);
        }
    }

    /// The draw's own box test equals `same_cell_around` of the sample,
    /// and the sample is `sample`'s, on grids of any size (rounding
    /// carries x to a cell edge more often off powers of two), for u
    /// at and beside every CDF entry, where draws land on cell edges,
    /// and margins from a sliver to more than half a cell.
    #[test]
    fn drawn_cell_box_test_matches_same_cell_around(
        values in table(600),
        nx in 1usize..40,
        u in prop::collection::vec(0.0f32..1.0, 8),
    ) {
        let ny = values.len().div_ceil(nx);
        let mut v = values.clone();
        v.resize(nx * ny, 0.0);
        let d = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
        let edges: Vec<f32> = d
            .cdf()
            .iter()
            .chain(d.marginal())
            .flat_map(|&c| [c, c.next_down(), c.next_up()])
            .collect();
        let points = u.iter().flat_map(|&a| edges.iter().map(move |&b| Vec2::new(b, a)))
            .chain(u.iter().flat_map(|&a| edges.iter().map(move |&b| Vec2::new(a, b))));
        for u in points.take(4000) {
            for m in [1.0 / 65536.0, 1e-3, 0.3] {
                let margin = Vec2::splat(m);
                let (s, same) = d.sample_and_same_cell(u, margin);
                let plain = d.sample(u);
                prop_assert_eq!(s.p.x.to_bits(), plain.p.x.to_bits());
                prop_assert_eq!(s.p.y.to_bits(), plain.p.y.to_bits());
                prop_assert_eq!(s.pdf.to_bits(), plain.pdf.to_bits());
                prop_assert_eq!(same, d.same_cell_around(s.p, margin), "u {} m {}", u, m);
            }
        }
    }

    /// The short-row count gives the number of entries `<= u` of a
    /// sorted row of 8 to 64 entries, for u below, inside, on and above
    /// its entries, and 0 for NaN.
    #[test]
    fn short_row_counts_match_partition_point(values in prop::collection::vec(0.0f32..1.0, 64), blocks in 1usize..=8, u in prop::collection::vec(-0.5f32..1.5, 8)) {
        let mut row = values[..blocks * SHORT_WINDOW].to_vec();
        row.sort_by(f32::total_cmp);
        for u in u.iter().copied().chain(row.iter().copied()).chain([f32::MAX]) {
            let expected = row.partition_point(|&c| c <= u);
            prop_assert_eq!(count_linear(&row, u), expected, "u {}", u);
        }
        prop_assert_eq!(count_linear(&row, f32::NAN), 0);
    }

    /// `sample_batch` returns exactly what `sample` does, in full stages
    /// and in the remainder, for u anywhere (CDF entries, 0, 1, NaN and
    /// out of range included) and tables of every shape: rows shorter
    /// than eight, not a power of two, and longer than `LINEAR_ROW`.
    #[test]
    fn batches_equal_single_samples(values in table(600), nx in 1usize..70, n in 0usize..200, seed in 0u64..1000) {
        let ny = values.len().div_ceil(nx);
        let mut v = values.clone();
        v.resize(nx * ny, 0.0);
        let d2 = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
        let d1 = PiecewiseConstant1D::new(&values).unwrap();
        let mut state = seed;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let specials = [0.0, -0.0, 1.0, -1.0, 2.0, f32::NAN, ONE_MINUS_EPSILON, f32::MIN_POSITIVE];
        let mut coordinate = |cdf: &[f32]| {
            let pick = next();
            if pick < 0.2 {
                cdf[(next() * cdf.len() as f32) as usize]
            } else if pick < 0.25 {
                specials[(next() * specials.len() as f32) as usize]
            } else {
                next()
            }
        };
        let u2: Vec<Vec2> = (0..n)
            .map(|_| Vec2::new(coordinate(d2.cdf()), coordinate(d2.marginal())))
            .collect();
        // Every fourth 1D number exactly on one of its own CDF entries.
        let u1: Vec<f32> = u2
            .iter()
            .enumerate()
            .map(|(k, u)| if k % 4 == 1 { d1.cdf()[k % d1.cdf().len()] } else { u.x })
            .collect();
        let mut out2 = vec![Sample2D::default(); n + 3];
        let mut out1 = vec![Sample1D::default(); n];
        d2.sample_batch(&u2, &mut out2);
        // The staged scalar path, which CPUs without AVX2 take.
        let mut staged = vec![Sample2D::default(); n];
        d2.sample_batch_lanes(&u2, &mut staged);
        prop_assert_eq!(&staged[..], &out2[..n]);
        d1.sample_batch(&u1, &mut out1);
        for k in 0..n {
            prop_assert_eq!(out2[k], d2.sample(u2[k]));
            prop_assert_eq!(out1[k], d1.sample(u1[k]));
        }
        prop_assert!(out2[n..].iter().all(|s| *s == Sample2D::default()));
        // pdf_batch at the samples, beside them, and at the raw u
        // (outside the square and NaN included).
        let mut points: Vec<Vec2> = out2[..n].iter().map(|s| s.p).collect();
        points.extend(out2[..n].iter().map(|s| Vec2::new(s.p.x.next_up(), s.p.y.next_down())));
        points.extend(&u2);
        let mut densities = vec![0.0f32; points.len()];
        d2.pdf_batch(&points, &mut densities);
        for (&b, &p) in densities.iter().zip(&points) {
            prop_assert_eq!(b.to_bits(), d2.pdf(p).to_bits(), "pdf_batch at {}", p);
        }
    }
}

/// `sample_each` draws every lane from its own distribution, exactly as
/// `sample` does: stages of one shape (the lanes path), stages mixing
/// shapes (the scalar stages) and the tail.
#[test]
fn each_lane_draws_from_its_own_table() {
    let table = |seed: usize, nx: usize, ny: usize| -> PiecewiseConstant2D {
        let values: Vec<f32> = (0..nx * ny)
            .map(|k| {
                if (k * 31 + seed).is_multiple_of(11) {
                    0.0
                } else {
                    ((k * 7 + seed) % 13) as f32
                }
            })
            .collect();
        PiecewiseConstant2D::new(&values, nx, ny).unwrap()
    };
    let same_shape: Vec<PiecewiseConstant2D> = (0..5).map(|s| table(s, 32, 64)).collect();
    let odd_shape = table(9, 5, 3);
    let mut state = 99u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let n = 64 * 3 + 17;
    let mut lanes: Vec<&PiecewiseConstant2D> =
        (0..n).map(|k| &same_shape[(k * 3 + k / 7) % 5]).collect();
    // The second stage mixes in another shape.
    lanes[64 + 5] = &odd_shape;
    let mut u: Vec<Vec2> = (0..n).map(|_| Vec2::new(next(), next())).collect();
    u[1] = Vec2::new(f32::NAN, 1.0);
    u[2] = Vec2::new(-3.0, 0.0);
    u[3] = Vec2::new(same_shape[0].cdf()[5], same_shape[0].marginal()[7]);
    let mut out = vec![Sample2D::default(); n + 2];
    PiecewiseConstant2D::sample_each(&lanes, &u, &mut out);
    for k in 0..n {
        assert_eq!(out[k], lanes[k].sample(u[k]), "lane {k}");
    }
    assert_eq!(out[n..], [Sample2D::default(); 2]);
    let mut staged = vec![Sample2D::default(); n];
    PiecewiseConstant2D::sample_each_lanes(&lanes, &u, &mut staged);
    assert_eq!(staged, out[..n]);
    // The box tests in the lanes answer as the scalar test does, inside
    // and outside the cell (a margin of 0.01 is a third of a column).
    for m in [1e-5f32, 0.01, 0.05] {
        let margin = Vec2::splat(m);
        let mut drawn = vec![Sample2D::default(); n];
        let mut same = vec![false; n];
        PiecewiseConstant2D::sample_each_and_same_cell(&lanes, &u, margin, &mut drawn, &mut same);
        assert_eq!(drawn, out[..n]);
        let expected: Vec<bool> = (0..n)
            .map(|k| lanes[k].same_cell_around(out[k].p, margin))
            .collect();
        assert_eq!(same, expected, "margin {m}");
        assert!(same.iter().any(|&s| s) && same.iter().any(|&s| !s));
    }
    // Densities bit for bit, at the raw u (outside the square and NaN
    // included) and at draws from other lanes' tables.
    let mut points = u.clone();
    points.extend((0..n).map(|k| out[(k + 3) % n].p));
    let each: Vec<&PiecewiseConstant2D> = lanes.iter().chain(&lanes).copied().collect();
    let mut densities = vec![0.0f32; points.len()];
    PiecewiseConstant2D::pdf_each(&each, &points, &mut densities);
    for k in 0..points.len() {
        assert_eq!(
            densities[k].to_bits(),
            each[k].pdf(points[k]).to_bits(),
            "lane {k}"
        );
    }
    assert!(densities.iter().filter(|&&d| d > 0.0).count() > n);
}

/// Tables with zeros and a wide dynamic range.
/// Each boundary k / g of a guide of g cells and the floats on either
/// side of it.
fn near_guide_boundaries(g: usize) -> impl Iterator<Item = f32> {
    (0..g).flat_map(move |k| {
        let b = k as f32 / g as f32;
        [b.next_down().max(0.0), b, b.next_up()]
    })
}

fn table(max_len: usize) -> impl Strategy<Value = Vec<f32>> {
    prop::collection::vec(
        prop_oneof![Just(0.0f32), 0.0f32..10.0, 1e-20f32..1e-10, 1e10f32..1e20],
        1..max_len,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn one_d_sample_pdf_invert_agree(values in table(40), u in 0.0f32..1.0) {
        let d = PiecewiseConstant1D::new(&values).unwrap();
        let s = d.sample(u);
        prop_assert!((0.0..1.0).contains(&s.x));
        prop_assert!(s.pdf > 0.0 && s.pdf.is_finite());
        prop_assert_eq!(d.pdf(s.x), s.pdf);
        let back = d.invert(s.x);
        prop_assert!((back - u).abs() <= 1e-4, "u {} -> x {} -> {}", u, s.x, back);
    }

    #[test]
    fn two_d_sample_pdf_invert_agree(
        values in table(60), nx in 1usize..8, ux in 0.0f32..1.0, uy in 0.0f32..1.0
    ) {
        let ny = values.len().div_ceil(nx);
        let mut v = values.clone();
        v.resize(nx * ny, 0.0);
        let d = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
        let u = Vec2::new(ux, uy);
        let s = d.sample(u);
        prop_assert!((0.0..1.0).contains(&s.p.x) && (0.0..1.0).contains(&s.p.y));
        prop_assert!(s.pdf > 0.0 && s.pdf.is_finite());
        prop_assert_eq!(d.pdf(s.p), s.pdf);
        let back = d.invert(s.p);
        prop_assert!((back - u).abs().max_element() <= 1e-4, "u {} -> {} -> {}", u, s.p, back);
    }

    /// The stored density integrates to one (a zero table is uniform).
    #[test]
    fn two_d_density_is_normalised(values in table(60), nx in 1usize..8) {
        let ny = values.len().div_ceil(nx);
        let mut v = values.clone();
        v.resize(nx * ny, 0.0);
        let d = PiecewiseConstant2D::new(&v, nx, ny).unwrap();
        let total: f64 = d.func().iter().map(|&p| p as f64).sum::<f64>() / (nx * ny) as f64;
        prop_assert!((total - 1.0).abs() < 1e-5, "{}", total);
    }
}
