//! The fast sampling paths of the adaptive distributions against the
//! plain ones.

use super::*;
use crate::curve::f32_below;
use crate::simplify::DouglasPeucker;
use acdf_core::ONE_MINUS_EPSILON;

/// The segment of `v` by a plain binary search over all the vertices:
/// partition_point(e <= v) - 1, kept in [0, m - 2].
fn plain_segment(sorted: &[f32], v: f32) -> usize {
    sorted
        .partition_point(|&e| e <= v)
        .saturating_sub(1)
        .min(sorted.len() - 2)
}

/// The reference sample of a curve: the segment by a plain binary
/// search, then x = x_i + (u - c_i) / (c_{i+1} - c_i) (x_{i+1} - x_i)
/// clamped into [x_i, x_{i+1}), written out plainly.
fn plain_sample(curve: Curve<'_>, u: f32) -> (Sample1D, usize) {
    let u = clamp_unit(u);
    if curve.is_uniform() {
        return (Sample1D { x: u, pdf: 1.0 }, 0);
    }
    let (xs, cdf) = (curve.xs(), curve.cdfs());
    let i = plain_segment(cdf, u);
    let (c0, c1) = (cdf[i], cdf[i + 1]);
    let (x0, x1) = (xs[i], xs[i + 1]);
    let t = ((u - c0) / (c1 - c0)).clamp(0.0, 1.0);
    let x = x0 + t * (x1 - x0);
    let x = x.clamp(x0, f32_below(x1)).min(ONE_MINUS_EPSILON);
    let pdf = (c1 - c0) / (x1 - x0);
    (Sample1D { x, pdf }, i)
}

/// The reference density: the segment by a plain binary search.
fn plain_pdf(curve: Curve<'_>, x: f32) -> f32 {
    if !(0.0..1.0).contains(&x) {
        0.0
    } else if curve.is_uniform() {
        1.0
    } else {
        curve.density(plain_segment(curve.xs(), x))
    }
}

/// A linear congruential stream of f32 in [0, 1).
fn stream(mut state: u64) -> impl FnMut() -> f32 {
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// The uniform numbers to test at: random ones, the ends, NaN, and every
/// CDF value of `cdf` with its neighbours (the segment boundaries).
fn numbers(next: &mut impl FnMut() -> f32, cdf: &[f32]) -> Vec<f32> {
    let mut u: Vec<f32> = (0..1000).map(|_| next()).collect();
    u.extend([0.0, -0.0, ONE_MINUS_EPSILON, 1.0, -1.0, f32::NAN]);
    for &c in cdf {
        u.extend([c, c.next_down(), c.next_up()]);
    }
    u
}

/// The branch-free searches give the plain binary search's samples and
/// densities bit for bit, and `sample_batch` gives `sample`'s, on tables
/// with zero rows, peaks and flat runs, at tolerances that keep few and
/// many vertices (curves that fit the counting window and longer ones
/// that are searched), and at the segment boundaries.
#[test]
fn fast_sampling_matches_the_curve_search() {
    let mut next = stream(7);
    let ny = 96;
    for nx in [16, 48] {
        let values: Vec<f32> = (0..nx * ny)
            .map(|k| {
                let (x, y) = (k % nx, k / nx);
                if y % 7 == 3 {
                    0.0
                } else {
                    let peak = (-((y as f32 - 20.0) / 4.0).powi(2)).exp() * 50.0;
                    peak + 0.1 + (x as f32 * 0.7).sin().abs()
                }
            })
            .collect();
        let simplifier = DouglasPeucker::vertical();
        for tolerance in [0.0, 1e-4, 1e-2] {
            let d = AdaptiveCdf2D::from_values(&values, nx, ny, &simplifier, tolerance).unwrap();
            let m = d.marginal_curve();
            let uy = numbers(&mut next, m.cdfs());
            let mut u: Vec<Vec2> = uy.iter().map(|&y| Vec2::new(next(), y)).collect();
            for j in 0..d.conditional_count() {
                for &c in d.conditional(j).cdfs() {
                    let y = m.xs()[j];
                    u.extend([c, c.next_down(), c.next_up()].map(|x| Vec2::new(x, y)));
                }
            }
            for &u in &u {
                let (sy, j) = plain_sample(m, u.y);
                let (sx, _) = plain_sample(d.conditional(j), u.x);
                let expected = Sample2D {
                    p: Vec2::new(sx.x, sy.x),
                    pdf: sy.pdf * sx.pdf,
                };
                let s = d.sample(u);
                assert_eq!(s, expected, "nx {nx} tolerance {tolerance} u {u}");
                assert_eq!(d.pdf(s.p), s.pdf, "nx {nx} tolerance {tolerance} u {u}");
            }
            // Every length of batch, so the tail past the last full
            // group of lanes is covered too.
            for n in [u.len(), 1, 7, 8, 9, 17] {
                let mut out = vec![Sample2D::default(); n];
                d.sample_batch(&u[..n], &mut out);
                for (o, &u) in out.iter().zip(&u) {
                    assert_eq!(*o, d.sample(u));
                }
            }
            let mut out = vec![Sample2D::default(); u.len()];
            d.sample_batch(&u, &mut out);
            // The staged scalar path, which CPUs without AVX2 take.
            let mut staged = vec![Sample2D::default(); u.len()];
            d.sample_batch_lanes::<false>(&u, &mut staged, Vec2::ZERO, &mut []);
            assert_eq!(staged, out);
            // The densities at random points, at the samples and at the
            // vertex positions are the plain search's.
            let mut points: Vec<Vec2> = u[..500].to_vec();
            points.extend(out.iter().map(|s| s.p));
            for j in 0..d.conditional_count() {
                let y = m.xs()[j];
                for &x in d.conditional(j).xs() {
                    points.extend([x, x.next_down(), x.next_up()].map(|x| Vec2::new(x, y)));
                }
            }
            for &x in m.xs() {
                points.extend([x, x.next_down(), x.next_up()].map(|y| Vec2::new(0.5, y)));
            }
            for &p in &points {
                let j = plain_segment(m.xs(), p.y);
                let py = plain_pdf(m, p.y);
                let expected = if py == 0.0 || !(0.0..1.0).contains(&p.x) {
                    0.0
                } else {
                    py * plain_pdf(d.conditional(j), p.x)
                };
                assert_eq!(d.pdf(p), expected, "{p}");
            }
            points.extend([f32::NAN, -0.0, -1e-30, 1.0, 2.0].map(|v| Vec2::new(v, 0.5)));
            points.extend([f32::NAN, -0.0, 1.0].map(|v| Vec2::new(0.5, v)));
            let mut batch = vec![0.0f32; points.len()];
            d.pdf_batch(&points, &mut batch);
            for (&b, &p) in batch.iter().zip(&points) {
                assert_eq!(b.to_bits(), d.pdf(p).to_bits(), "pdf_batch at {p}");
            }
            // Where the box is said to lie in one segment, the density at
            // its corners is the density at its centre; most boxes
            // qualify. Asked with the draw, the answer is the same.
            let mut inside = 0;
            for (s, &u) in out[..1000].iter().zip(&u) {
                for m in [1e-5f32, 1e-3, 0.05] {
                    let margin = Vec2::splat(m);
                    let same = d.same_cell_around(s.p, margin);
                    assert_eq!(d.sample_and_same_cell(u, margin), (*s, same), "{u}");
                    if same {
                        inside += 1;
                        for c in [
                            Vec2::new(-1.0, -1.0),
                            Vec2::new(-1.0, 1.0),
                            Vec2::ONE,
                            Vec2::new(1.0, -1.0),
                        ] {
                            assert_eq!(d.pdf(s.p + c * margin), s.pdf, "{s:?} {m}");
                        }
                    }
                }
            }
            assert!(inside > 1000, "{inside}");
            // The batch form gives the same samples and answers, tail
            // included.
            for m in [1e-5f32, 1e-3, 0.05] {
                let margin = Vec2::splat(m);
                let n = 1003;
                let mut batch = vec![Sample2D::default(); n];
                let mut same = vec![false; n];
                d.sample_batch_and_same_cell(&u[..n], margin, &mut batch, &mut same);
                let mut staged = (vec![Sample2D::default(); n], vec![false; n]);
                d.sample_batch_lanes::<true>(&u[..n], &mut staged.0, margin, &mut staged.1);
                assert_eq!(staged, (batch.clone(), same.clone()));
                for k in 0..n {
                    assert_eq!(
                        (batch[k], same[k]),
                        d.sample_and_same_cell(u[k], margin),
                        "{}",
                        u[k]
                    );
                }
            }
        }
    }
}

/// Draws from a different distribution in every lane (peaked, flat,
/// with empty conditionals, all zero) give each distribution's own
/// sample and box test, in full stages and in the tail.
#[test]
fn each_lane_draws_from_its_own_distribution() {
    let mut next = stream(23);
    let simplifier = DouglasPeucker::vertical();
    let (nx, ny) = (32, 64);
    let peaked: Vec<f32> = (0..nx * ny)
        .map(|k| if k % 97 == 5 { 50.0 } else { next() * next() })
        .collect();
    let flat = vec![1.0f32; nx * ny];
    let zero = vec![0.0f32; nx * ny];
    let mut dists = vec![
        AdaptiveCdf2D::from_values(&peaked, nx, ny, &simplifier, 1e-3).unwrap(),
        AdaptiveCdf2D::from_values(&flat, nx, ny, &simplifier, 1e-2).unwrap(),
        AdaptiveCdf2D::from_values(&zero, nx, ny, &simplifier, 1e-2).unwrap(),
    ];
    dists.push(AdaptiveCdf2D::from_parts(
        vec![0.0, 0.5, 1.0, 0.0, 0.25, 1.0],
        vec![0, 0, 2],
        vec![0.0, 1.0, 0.0, 1.0],
        1.0,
    ));
    let n = 203;
    let lanes: Vec<&AdaptiveCdf2D> = (0..n)
        .map(|k| &dists[(k * 7 + k / 5) % dists.len()])
        .collect();
    let mut u: Vec<Vec2> = (0..n).map(|_| Vec2::new(next(), next())).collect();
    u[3] = Vec2::new(f32::NAN, 1.0);
    u[4] = Vec2::new(-1.0, ONE_MINUS_EPSILON);
    for m in [1e-5f32, 0.05] {
        let margin = Vec2::splat(m);
        let mut out = vec![Sample2D::default(); n];
        let mut same = vec![false; n];
        AdaptiveCdf2D::sample_each_and_same_cell(&lanes, &u, margin, &mut out, &mut same);
        for k in 0..n {
            assert_eq!(
                (out[k], same[k]),
                lanes[k].sample_and_same_cell(u[k], margin),
                "lane {k}"
            );
        }
    }
    // Densities at the raw u (outside the square and NaN included) and
    // at draws from the other distributions.
    let mut points = u.clone();
    points.extend((0..n).map(|k| lanes[(k + 1) % n].sample(u[k]).p));
    let each: Vec<&AdaptiveCdf2D> = lanes.iter().chain(&lanes).copied().collect();
    let mut densities = vec![0.0f32; points.len()];
    AdaptiveCdf2D::pdf_each(&each, &points, &mut densities);
    for k in 0..points.len() {
        assert_eq!(
            densities[k].to_bits(),
            each[k].pdf(points[k]).to_bits(),
            "lane {k}"
        );
    }
}

/// A conditional stored empty (the uniform stand-in) gives x = u and
/// density 1 in `sample`, `sample_batch` and `pdf` alike, even where its
/// marginal segment carries mass (a decoded file may hold that).
#[test]
fn empty_conditionals_sample_uniformly_in_every_path() {
    let d = AdaptiveCdf2D::from_parts(
        vec![0.0, 0.5, 1.0, 0.0, 0.25, 1.0],
        vec![0, 0, 2],
        vec![0.0, 1.0, 0.0, 1.0],
        1.0,
    );
    let mut next = stream(5);
    let u: Vec<Vec2> = (0..203).map(|_| Vec2::new(next(), next())).collect();
    let mut out = vec![Sample2D::default(); u.len()];
    d.sample_batch(&u, &mut out);
    for (o, &u) in out.iter().zip(&u) {
        let s = d.sample(u);
        assert_eq!(*o, s);
        assert_eq!(d.pdf(s.p), s.pdf);
        if u.y < 0.25 {
            assert_eq!((s.p.x, s.pdf), (u.x, 0.5), "{u}");
        }
    }
    let points: Vec<Vec2> = out.iter().map(|s| s.p).collect();
    let mut densities = vec![0.0f32; points.len()];
    d.pdf_batch(&points, &mut densities);
    for (s, &p) in out.iter().zip(&densities) {
        assert_eq!(p, s.pdf);
    }
}

/// The 1D distribution's searches give the plain search's samples,
/// densities and segments, and its `sample_batch` gives `sample`'s, for
/// curves of 2 to 200 vertices.
#[test]
fn fast_1d_sampling_matches_the_curve_search() {
    let mut next = stream(11);
    let simplifier = DouglasPeucker::vertical();
    for n in [1, 2, 3, 5, 31, 32, 33, 34, 35, 64, 199] {
        let values: Vec<f32> = (0..n)
            .map(|k| if k % 5 == 2 { 0.0 } else { 0.05 + next() })
            .collect();
        let d = AdaptiveCdf1D::from_values(&values, &simplifier, 0.0).unwrap();
        let curve = d.curve();
        let u = numbers(&mut next, curve.cdfs());
        for &u in &u {
            let s = d.sample(u);
            assert_eq!(s, plain_sample(curve, u).0, "n {n} u {u}");
            assert_eq!(d.pdf(s.x), s.pdf);
            assert_eq!(d.pdf(u), plain_pdf(curve, u), "n {n} x {u}");
            let x = if u > 0.0 { u } else { 0.0 };
            assert_eq!(d.segment_of(u), plain_segment(curve.xs(), x));
        }
        let mut out = vec![Sample1D::default(); u.len()];
        d.sample_batch(&u, &mut out);
        for (o, &u) in out.iter().zip(&u) {
            assert_eq!(*o, d.sample(u));
        }
        // The staged scalar path, which CPUs without AVX2 take.
        let mut staged = vec![Sample1D::default(); u.len()];
        d.sample_batch_lanes(&u, &mut staged);
        assert_eq!(staged, out);
    }
}
