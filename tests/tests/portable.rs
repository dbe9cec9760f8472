//! The portable and the vectorised paths give the same bits.
//!
//! Every batch and one-at-a-time entry point that chooses its code by the
//! CPU (`acdf_core::cpu`) runs twice on the same inputs, once with the
//! portable path forced and once on the detected one, and every output is
//! compared by `to_bits()`: the distributions' `sample_batch`, `pdf_batch`
//! and `SliceDistribution` batch forms, the tabulated samplers' `sample`,
//! `pdf` and batch forms, the outgoing sampler's, the environment samplers'
//! `sample` and `pdf`, the searches of `acdf_core::search` and the
//! many-angle sines and cosines. The inputs hold random numbers and the
//! edges (u = 0, -0, next to 1, 1, NaN, out of range), tables with zero
//! rows, and tables of odd sizes that fill no lane evenly.
//!
//! This file is a test binary of its own: while a test here forces the
//! portable path, the process-wide switch moves every thread of this
//! process, and no test of another file is affected. Within the file each
//! test holds `cpu::lock_paths()`, so that no other test flips the switch
//! between its two runs. On a CPU without AVX2 and FMA (or AVX-512), or
//! with `ACDF_CPU=portable`, both runs take the same path; the test says so
//! in a printed line and still compares.

use acdf_adaptive_cdf::{AdaptiveCdf1D, AdaptiveCdf2D, DouglasPeucker};
use acdf_core::cpu::{self, Features, PathLock};
use acdf_core::search::{self, Guide};
use acdf_core::{
    BxdfSample, BxdfSampler, Distribution1D, Sample1D, Sample2D, Vec2, Vec3, ONE_MINUS_EPSILON,
};
use acdf_tabulated::{Resolution, SliceDistribution};
use acdf_uniform::UniformBrdfSampler;
use acdf_uniform::{PiecewiseConstant1D, PiecewiseConstant2D, PiecewiseConstantBuilder};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// An output compared by its bits.
trait Bits {
    fn bits(&self) -> Vec<u32>;
}

impl Bits for f32 {
    fn bits(&self) -> Vec<u32> {
        vec![self.to_bits()]
    }
}

impl Bits for bool {
    fn bits(&self) -> Vec<u32> {
        vec![*self as u32]
    }
}

impl Bits for usize {
    fn bits(&self) -> Vec<u32> {
        vec![*self as u32, (*self >> 32) as u32]
    }
}

impl Bits for Sample1D {
    fn bits(&self) -> Vec<u32> {
        vec![self.x.to_bits(), self.pdf.to_bits()]
    }
}

impl Bits for Sample2D {
    fn bits(&self) -> Vec<u32> {
        vec![self.p.x.to_bits(), self.p.y.to_bits(), self.pdf.to_bits()]
    }
}

/// The bits of a draw, a direction and its density; `u32::MAX` for none.
fn draw_bits(draw: Option<(Vec3, f32)>) -> Vec<u32> {
    match draw {
        None => vec![u32::MAX],
        Some((d, pdf)) => vec![d.x.to_bits(), d.y.to_bits(), d.z.to_bits(), pdf.to_bits()],
    }
}

impl Bits for Option<BxdfSample> {
    fn bits(&self) -> Vec<u32> {
        draw_bits(self.as_ref().map(|s| (s.wi, s.pdf)))
    }
}

impl Bits for Option<acdf_core::SphereSample> {
    fn bits(&self) -> Vec<u32> {
        draw_bits(self.as_ref().map(|s| (s.dir, s.pdf)))
    }
}

impl<A: Bits, B: Bits> Bits for (A, B) {
    fn bits(&self) -> Vec<u32> {
        let mut v = self.0.bits();
        v.extend(self.1.bits());
        v
    }
}

/// Run `f` on the portable path, then on the detected one, and assert
/// that every output has the same bits; returns how many were compared.
fn same_bits<T: Bits + std::fmt::Debug>(
    paths: &PathLock,
    what: &str,
    f: impl Fn() -> Vec<T>,
) -> usize {
    let portable = paths.portable(&f);
    assert_eq!(cpu::features(), cpu::detected(), "detection restored");
    let detected = f();
    assert_eq!(portable.len(), detected.len(), "{what}: lengths");
    for (k, (p, d)) in portable.iter().zip(&detected).enumerate() {
        assert_eq!(
            p.bits(),
            d.bits(),
            "{what}, output {k}: portable {p:?}, vectorised {d:?}"
        );
    }
    portable.len()
}

/// Take the switch and say which paths this machine compares.
fn lock() -> PathLock {
    let paths = cpu::lock_paths();
    let detected = cpu::detected();
    if !detected.avx2_fma {
        println!("this CPU (or ACDF_CPU) gives no AVX2+FMA: the lanes are not compared");
    }
    if !detected.mask_compares {
        println!(
            "this CPU (or ACDF_CPU) gives no AVX-512 F+VL+BW: its mask compare is not compared"
        );
    }
    paths
}

/// Uniform numbers: random ones, then the edges.
fn numbers(rng: &mut Pcg64, n: usize) -> Vec<f32> {
    let mut v: Vec<f32> = (0..n).map(|_| rng.random::<f32>()).collect();
    v.extend(EDGES);
    v
}

const EDGES: [f32; 12] = [
    0.0,
    -0.0,
    ONE_MINUS_EPSILON,
    0.999_999_9,
    1.0,
    f32::NAN,
    -1.0,
    2.0,
    f32::INFINITY,
    f32::NEG_INFINITY,
    1e-40,
    0.5,
];

/// Points of the square: random, every pair of edges, the cells' edges.
fn points(rng: &mut Pcg64, n: usize, nx: usize, ny: usize) -> Vec<Vec2> {
    let mut p: Vec<Vec2> = (0..n)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect();
    for &x in &EDGES {
        for &y in &EDGES {
            p.push(Vec2::new(x, y));
        }
    }
    for k in 0..=nx.max(ny) {
        let (x, y) = (k as f32 / nx as f32, k as f32 / ny as f32);
        p.extend([
            Vec2::new(x, rng.random()),
            Vec2::new(x.next_down(), rng.random()),
            Vec2::new(rng.random(), y),
            Vec2::new(rng.random(), y.next_up()),
        ]);
    }
    p
}

/// A table of `nx` × `ny` with peaks, zero rows (every `zero_every`-th),
/// and zero cells.
fn table(rng: &mut Pcg64, nx: usize, ny: usize, zero_every: usize) -> Vec<f32> {
    (0..nx * ny)
        .map(|k| {
            let (x, y) = (k % nx, k / nx);
            let zero_row = zero_every > 0 && y % zero_every == zero_every - 1;
            if zero_row || (x * 7 + y) % 11 == 3 {
                0.0
            } else if (x + 3 * y) % 29 == 0 {
                50.0 * rng.random::<f32>()
            } else {
                rng.random::<f32>()
            }
        })
        .collect()
}

/// Shapes that fill the lanes evenly and shapes that fill none.
const SHAPES: [(usize, usize); 9] = [
    (32, 256),
    (1, 1),
    (1, 7),
    (3, 1),
    (2, 2),
    (7, 33),
    (33, 17),
    (17, 300),
    (64, 9),
];

/// Batch lengths around the stages of 32 and chunks of 64.
fn lengths(n: usize) -> [usize; 6] {
    [n, 0, 1, 31, 33, 97.min(n)]
}

/// Every batch form of a 2D distribution against the same inputs, as the
/// `SliceDistribution` trait offers them.
fn compare_2d<D: SliceDistribution + std::fmt::Debug>(
    paths: &PathLock,
    name: &str,
    dists: &[D],
    rng: &mut Pcg64,
) -> usize {
    let mut compared = 0;
    let (nx, ny) = (37, 41);
    let u = points(rng, 700, nx, ny);
    let mut margins = vec![Vec2::ZERO, Vec2::splat(1e-5), Vec2::new(1e-3, 0.05)];
    margins.push(Vec2::splat(f32::NAN));
    for (i, d) in dists.iter().enumerate() {
        for n in lengths(u.len()) {
            let what = format!("{name} {i}: n {n}");
            compared += same_bits(paths, &format!("{what} sample_batch"), || {
                let mut out = vec![Sample2D::default(); n];
                d.sample_batch(&u[..n], &mut out);
                out
            });
            compared += same_bits(paths, &format!("{what} pdf_batch"), || {
                let mut out = vec![0.0f32; n];
                d.pdf_batch(&u[..n], &mut out);
                out
            });
            for &m in &margins {
                compared += same_bits(paths, &format!("{what} sample_batch_and_same_cell"), || {
                    let mut out = vec![Sample2D::default(); n];
                    let mut same = vec![false; n];
                    d.sample_batch_and_same_cell(&u[..n], m, &mut out, &mut same);
                    out.into_iter().zip(same).collect::<Vec<_>>()
                });
            }
            compared += same_bits(paths, &format!("{what} sample, pdf"), || {
                u[..n]
                    .iter()
                    .map(|&u| (d.sample(u), d.pdf(u)))
                    .collect::<Vec<_>>()
            });
        }
    }
    // Each lane its own distribution: runs of one, mixed shapes, mixed
    // shapes within a stage.
    let orders: Vec<Vec<&D>> = vec![
        (0..u.len()).map(|_| &dists[0]).collect(),
        (0..u.len())
            .map(|k| &dists[(k * 7 + k / 5) % dists.len()])
            .collect(),
        (0..u.len())
            .map(|k| &dists[(k / 32) % dists.len()])
            .collect(),
    ];
    for (o, each) in orders.iter().enumerate() {
        for n in lengths(u.len()) {
            let what = format!("{name}: order {o}, n {n}");
            compared += same_bits(paths, &format!("{what} sample_each"), || {
                let mut out = vec![Sample2D::default(); n];
                D::sample_each(&each[..n], &u[..n], &mut out);
                out
            });
            compared += same_bits(paths, &format!("{what} pdf_each"), || {
                let mut out = vec![0.0f32; n];
                D::pdf_each(&each[..n], &u[..n], &mut out);
                out
            });
            for &m in &margins {
                compared += same_bits(paths, &format!("{what} sample_each_and_same_cell"), || {
                    let mut out = vec![Sample2D::default(); n];
                    let mut same = vec![false; n];
                    D::sample_each_and_same_cell(&each[..n], &u[..n], m, &mut out, &mut same);
                    out.into_iter().zip(same).collect::<Vec<_>>()
                });
            }
        }
    }
    compared
}

/// `sample_batch` of a 1D distribution and its one-at-a-time forms.
fn compare_1d(paths: &PathLock, name: &str, d: &dyn Distribution1D, u: &[f32]) -> usize {
    let mut compared = 0;
    for n in lengths(u.len()) {
        compared += same_bits(paths, &format!("{name}: n {n} sample_batch"), || {
            let mut out = vec![Sample1D::default(); n];
            d.sample_batch(&u[..n], &mut out);
            out
        });
        compared += same_bits(paths, &format!("{name}: n {n} sample, pdf"), || {
            u[..n]
                .iter()
                .map(|&u| (d.sample(u), d.pdf(u)))
                .collect::<Vec<_>>()
        });
    }
    compared
}

#[test]
fn forcing_switches_and_restores() {
    let paths = lock();
    let detected = cpu::detected();
    assert_eq!(cpu::features(), detected);
    paths.force_portable(true);
    assert_eq!(cpu::features(), Features::PORTABLE);
    assert!(cpu::avx2().is_none() && !cpu::mask_compares());
    paths.force_portable(false);
    assert_eq!(cpu::features(), detected);
    assert_eq!(paths.portable(cpu::features), Features::PORTABLE);
    assert_eq!(cpu::features(), detected);
    paths.force_portable(true);
    drop(paths);
    assert_eq!(
        cpu::features(),
        detected,
        "dropping the lock restores detection"
    );
    println!("detected: {detected:?}");
}

#[test]
fn piecewise_constant_distributions() {
    let paths = lock();
    let mut rng = Pcg64::seed_from_u64(1);
    let mut compared = 0;
    let mut dists = Vec::new();
    for (k, &(nx, ny)) in SHAPES.iter().enumerate() {
        let values = table(&mut rng, nx, ny, [0, 5, 3][k % 3]);
        dists.push(PiecewiseConstant2D::new(&values, nx, ny).unwrap());
        let u = numbers(&mut rng, 600);
        let d = PiecewiseConstant1D::new(&values).unwrap();
        compared += compare_1d(&paths, &format!("uniform 1D {nx}x{ny}"), &d, &u);
    }
    // All zero: the uniform fallback.
    dists.push(PiecewiseConstant2D::new(&[0.0; 96], 8, 12).unwrap());
    let zero = PiecewiseConstant1D::new(&[0.0; 40]).unwrap();
    compared += compare_1d(&paths, "uniform 1D zero", &zero, &numbers(&mut rng, 100));
    compared += compare_2d(&paths, "uniform 2D", &dists, &mut rng);
    // Only one shape per stage reaches the per-lane lanes path.
    let one_shape: Vec<PiecewiseConstant2D> = (0..3)
        .map(|z| PiecewiseConstant2D::new(&table(&mut rng, 32, 64, z * 4), 32, 64).unwrap())
        .collect();
    compared += compare_2d(&paths, "uniform 2D 32x64", &one_shape, &mut rng);
    println!("uniform distributions: {compared} outputs compared");
}

#[test]
fn adaptive_distributions() {
    let paths = lock();
    let mut rng = Pcg64::seed_from_u64(2);
    let simplifier = DouglasPeucker::vertical();
    let mut compared = 0;
    let mut dists = Vec::new();
    for (k, &(nx, ny)) in SHAPES.iter().enumerate() {
        let values = table(&mut rng, nx, ny, [0, 5, 3][k % 3]);
        for tolerance in [0.0, 1e-3, 0.05] {
            let d = AdaptiveCdf2D::from_values(&values, nx, ny, &simplifier, tolerance).unwrap();
            dists.push(d);
            let d = AdaptiveCdf1D::from_values(&values, &simplifier, tolerance).unwrap();
            let u = numbers(&mut rng, 400);
            let name = format!("adaptive 1D {nx}x{ny} at {tolerance}");
            compared += compare_1d(&paths, &name, &d, &u);
        }
    }
    dists.push(AdaptiveCdf2D::from_values(&[0.0; 96], 8, 12, &simplifier, 0.01).unwrap());
    dists.push(
        AdaptiveCdf2D::from_values_pinned(
            &table(&mut rng, 32, 256, 7),
            32,
            256,
            &simplifier,
            1e-3,
            1,
        )
        .unwrap(),
    );
    compared += compare_2d(&paths, "adaptive 2D", &dists, &mut rng);
    println!("adaptive distributions: {compared} outputs compared");
}

/// Outgoing directions: random over the hemisphere, and the edges (the
/// pole, grazing, the horizon, below it, not unit, not finite).
fn directions(rng: &mut Pcg64, n: usize) -> Vec<Vec3> {
    let mut v: Vec<Vec3> = (0..n)
        .map(|_| {
            let (t, p) = (
                rng.random::<f32>() * std::f32::consts::FRAC_PI_2,
                rng.random::<f32>() * std::f32::consts::TAU,
            );
            Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
        })
        .collect();
    v.extend([
        Vec3::Z,
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.999_999, 0.0, 0.001_414),
        Vec3::new(0.6, 0.0, -0.8),
        Vec3::new(0.3, 0.4, 2.0),
        Vec3::new(f32::NAN, 0.0, 1.0),
        Vec3::new(0.0, 0.0, f32::INFINITY),
        Vec3::ZERO,
    ]);
    v
}

/// Directions to take densities at: `draws` turned by `shift` (so that
/// each pair's direction is another pair's draw), the edge directions of
/// [`directions`] written over the first.
fn with_edges(mut draws: Vec<Vec3>, shift: usize, rng: &mut Pcg64) -> Vec<Vec3> {
    draws.rotate_left(shift);
    let edges = directions(rng, 0);
    draws[..edges.len()].copy_from_slice(&edges);
    draws
}

/// Every entry point of a tabulated sampler, with the batch forms fed the
/// same pairs.
fn compare_sampler(paths: &PathLock, name: &str, s: &dyn BxdfSampler, rng: &mut Pcg64) -> usize {
    let mut compared = 0;
    let wo = directions(rng, 400);
    let u = points(rng, wo.len(), 32, 256);
    let u = &u[..wo.len()];
    // Incident directions: the draws of the portable path, and the edges.
    let draws = wo
        .iter()
        .zip(u)
        .map(|(&wo, &u)| s.sample(wo, u).map_or(Vec3::Z, |d| d.wi))
        .collect();
    let wi = with_edges(draws, 3, rng);
    compared += same_bits(paths, &format!("{name} sample"), || {
        wo.iter()
            .zip(u)
            .map(|(&wo, &u)| s.sample(wo, u))
            .collect::<Vec<_>>()
    });
    compared += same_bits(paths, &format!("{name} pdf"), || {
        wo.iter()
            .zip(&wi)
            .map(|(&wo, &wi)| s.pdf(wo, wi))
            .collect::<Vec<_>>()
    });
    for n in [wo.len(), 1, 63, 65, 130] {
        compared += same_bits(paths, &format!("{name} sample_each {n}"), || {
            let mut out = vec![None; n];
            s.sample_each(&wo[..n], &u[..n], &mut out);
            out
        });
        compared += same_bits(paths, &format!("{name} pdf_each {n}"), || {
            let mut out = vec![0.0f32; n];
            s.pdf_each(&wo[..n], &wi[..n], &mut out);
            out
        });
    }
    for &one in wo.iter().step_by(37).chain(&wo[wo.len() - 9..]) {
        compared += same_bits(paths, &format!("{name} sample_batch at {one}"), || {
            let mut out = vec![None; u.len()];
            s.sample_batch(one, u, &mut out);
            out
        });
        compared += same_bits(paths, &format!("{name} pdf_batch at {one}"), || {
            let mut out = vec![0.0f32; wi.len()];
            s.pdf_batch(one, &wi, &mut out);
            out
        });
    }
    compared
}

#[test]
fn tabulated_samplers_on_nickel() {
    let paths = lock();
    let mut rng = Pcg64::seed_from_u64(3);
    let nickel = acdf_materials::builtin("nickel").expect("built-in nickel");
    let mut compared = 0;
    for resolution in [Resolution::ISOTROPIC, Resolution::new(5, 3, 17, 7).unwrap()] {
        let uniform =
            UniformBrdfSampler::new(nickel.clone(), resolution, PiecewiseConstantBuilder).unwrap();
        uniform.build_all().unwrap();
        compared += compare_sampler(&paths, &format!("uniform {resolution}"), &uniform, &mut rng);
        let mixed = UniformBrdfSampler::new(nickel.clone(), resolution, PiecewiseConstantBuilder)
            .unwrap()
            .with_cosine_mix(0.1)
            .unwrap();
        compared += compare_sampler(
            &paths,
            &format!("uniform+cosine {resolution}"),
            &mixed,
            &mut rng,
        );
        let adaptive =
            acdf_adaptive::adaptive_sampler(nickel.clone(), resolution, "dp", None).unwrap();
        adaptive.build_all().unwrap();
        compared += compare_sampler(
            &paths,
            &format!("adaptive:dp {resolution}"),
            &adaptive,
            &mut rng,
        );
    }
    println!("tabulated samplers: {compared} outputs compared");
}

/// The outgoing sampler (its AVX2 copies of `sample`, `pdf` and the batch
/// forms against the portable ones), plain and with a cosine mix.
#[test]
fn outgoing_sampler_on_nickel() {
    let paths = lock();
    let mut rng = Pcg64::seed_from_u64(5);
    let nickel = acdf_materials::builtin("nickel").expect("built-in nickel");
    let builder = acdf_outgoing::OutgoingBuilder::by_name("chi2", None, 64).unwrap();
    let resolution = Resolution::new(16, 1, 64, 16).unwrap();
    let plain = acdf_outgoing::OutgoingSampler::new(nickel, resolution, builder).unwrap();
    let mut compared = compare_sampler(&paths, "outgoing:chi2", &plain, &mut rng);
    let mixed = plain.with_cosine_mix(0.1).unwrap();
    compared += compare_sampler(&paths, "outgoing:chi2+cosine", &mixed, &mut rng);
    println!("outgoing sampler: {compared} outputs compared");
}

/// The environment samplers' `sample` and `pdf` (their AVX2 copies against
/// the portable ones) on a 64 × 32 map with a sun, a dark band and a row
/// of zeros: the uniform, adaptive and orientation-aware samplers, the last
/// with and without a defensive share, for normals over the sphere and at
/// the edges (the poles, no normal, not unit, not finite).
#[test]
fn environment_samplers_on_a_map() {
    use acdf_core::SphereSampler;
    let paths = lock();
    let mut rng = Pcg64::seed_from_u64(6);
    let map = std::sync::Arc::new(
        acdf_lights::EnvMap::from_fn(64, 32, |k, j| {
            let v = if (k as i64 - 20).abs() < 2 && (j as i64 - 9).abs() < 2 {
                500.0
            } else if j == 20 {
                0.0
            } else if j > 24 {
                0.02
            } else {
                0.5 + (k as f32 * 0.37).sin().abs()
            };
            acdf_core::Rgb::splat(v)
        })
        .unwrap(),
    );
    let mut normals: Vec<Option<Vec3>> = directions(&mut rng, 120)
        .into_iter()
        .map(|d| Some(if rng.random::<bool>() { d } else { -d }))
        .collect();
    normals.extend([
        None,
        Some(Vec3::new(0.0, 0.0, -1.0)),
        Some(Vec3::new(0.0, 0.0, 3.0)),
    ]);
    let u = points(&mut rng, normals.len(), 64, 32);
    let u = &u[..normals.len()];
    let builder = || acdf_adaptive_cdf::AdaptiveBuilder::by_name("dp", None).unwrap();
    let grid = acdf_lights::NormalGrid::new(4, 8).unwrap();
    let samplers: Vec<(&str, Box<dyn SphereSampler>)> = vec![
        (
            "uniform",
            Box::new(
                acdf_uniform::uniform_env_sampler(&map, acdf_lights::TableKind::Luminance).unwrap(),
            ),
        ),
        (
            "adaptive:dp",
            Box::new(
                acdf_adaptive_env::adaptive_env_sampler(
                    &map,
                    acdf_lights::TableKind::Luminance,
                    &builder(),
                )
                .unwrap(),
            ),
        ),
        (
            "oriented:dp",
            Box::new(
                acdf_adaptive_env::oriented_env_sampler(map.clone(), builder(), grid, 0.0).unwrap(),
            ),
        ),
        (
            "oriented:dp defensive",
            Box::new(
                acdf_adaptive_env::oriented_env_sampler(map.clone(), builder(), grid, 0.25)
                    .unwrap(),
            ),
        ),
        // Columns found by octant compares with three tangents, and by
        // bins of the pseudo-azimuth (12 is not a multiple of 8).
        (
            "oriented:dp 4x32",
            Box::new(
                acdf_adaptive_env::oriented_env_sampler(
                    map.clone(),
                    builder(),
                    acdf_lights::NormalGrid::new(4, 32).unwrap(),
                    0.0,
                )
                .unwrap(),
            ),
        ),
        (
            "oriented:dp 3x12",
            Box::new(
                acdf_adaptive_env::oriented_env_sampler(
                    map.clone(),
                    builder(),
                    acdf_lights::NormalGrid::new(3, 12).unwrap(),
                    0.0,
                )
                .unwrap(),
            ),
        ),
    ];
    let mut compared = 0;
    for (name, s) in &samplers {
        // Directions: the portable path's draws, and the edges.
        let draws = normals
            .iter()
            .zip(u)
            .map(|(&n, &u)| s.sample(n, u).map_or(Vec3::Z, |d| d.dir))
            .collect();
        let dirs = with_edges(draws, 5, &mut rng);
        compared += same_bits(&paths, &format!("{name} sample"), || {
            normals
                .iter()
                .zip(u)
                .map(|(&n, &u)| s.sample(n, u))
                .collect::<Vec<_>>()
        });
        compared += same_bits(&paths, &format!("{name} pdf"), || {
            normals
                .iter()
                .zip(&dirs)
                .map(|(&n, &d)| s.pdf(n, d))
                .collect::<Vec<_>>()
        });
    }
    println!("environment samplers: {compared} outputs compared");
}

#[test]
fn searches_and_trigonometry() {
    let paths = lock();
    let mut rng = Pcg64::seed_from_u64(4);
    let mut compared = 0;
    for len in [
        0usize, 1, 2, 3, 7, 8, 9, 31, 32, 33, 63, 64, 65, 100, 257, 1000,
    ] {
        let mut list: Vec<f32> = (0..len).map(|_| rng.random::<f32>()).collect();
        list.sort_by(f32::total_cmp);
        // Runs of equal entries, as flat CDF segments give.
        for k in (1..len).step_by(5) {
            list[k] = list[k - 1];
        }
        let mut data = vec![-1.0f32; 3];
        data.extend(&list);
        data.extend([2.0f32; 40]);
        let mut probes = numbers(&mut rng, 200);
        for &e in &list {
            probes.extend([e, e.next_down(), e.next_up()]);
        }
        let guide = Guide::new(&list, 32);
        compared += same_bits(&paths, &format!("searches of {len}"), || {
            let mut counts = Vec::new();
            for &v in &probes {
                counts.push(search::count_sorted(&list, v));
                counts.push(search::count_one(&data, 3, len, v));
                counts.extend(search::count_at_or_below(&data, 3, len, [v, 0.5, -v, 0.25]));
                if len <= search::WINDOW {
                    counts.push(search::count_window(&data, 3, len, v));
                }
                if !guide.is_empty() {
                    counts.push(guide.count(&data, 3, v, Guide::cell(v, 32)));
                }
                if len % search::SHORT_WINDOW == 0
                    && (1..=search::LINEAR_ROW).contains(&len)
                    && !v.is_nan()
                {
                    counts.push(search::count_linear(&list, v));
                }
            }
            counts
        });
    }
    let mut angles = numbers(&mut rng, 1000);
    angles.extend((0..300).map(|k| (k as f32 - 150.0) / 16.0 + 1.0 / 128.0));
    for n in [angles.len(), 7, 8, 9, 17] {
        compared += same_bits(&paths, &format!("sines and cosines of {n}"), || {
            let (mut sin, mut cos) = (vec![0.0f32; n], vec![0.0f32; n]);
            acdf_core::fast::sin_cos_turns_each(&angles[..n], &mut sin, &mut cos);
            let mut out: Vec<(f32, f32)> = sin.into_iter().zip(cos).collect();
            let (mut sin, mut cos) = (vec![0.0f32; n], vec![0.0f32; n]);
            acdf_core::fast::sin_cos_quarter_turns_each(&angles[..n], &mut sin, &mut cos);
            out.extend(sin.into_iter().zip(cos));
            out
        });
    }
    println!("searches and trigonometry: {compared} outputs compared");
}
