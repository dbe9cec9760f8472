//! Throughput of the adaptive distributions on the slice `acdf bench`
//! times: the built-in nickel at the isotropic resolution, middle outgoing
//! cell (256 θ_h rows × 32 φ_h columns), simplified by Douglas-Peucker at
//! its default tolerance (the default `adaptive` sampler). The 2D
//! distribution is timed with `sample` one draw at a time, `sample_batch`,
//! `pdf`, `same_cell_around`, `sample_and_same_cell` and its build;
//! the 1D distribution (the slice's row sums, the marginal's table) with
//! `sample`, `sample_batch` and `pdf`. `acdf bench` times the uniform
//! table of the same slice beside it.

use acdf_adaptive_cdf::{
    AdaptiveBuilder, AdaptiveCdf1D, AdaptiveCdf2D, DouglasPeucker, Simplifier,
};
use acdf_core::{Distribution1D, Distribution2D, Sample1D, Sample2D, TableBuilder, Vec2};
use acdf_tabulated::{tabulate_slice, Resolution, SliceDistribution};
use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::hint::black_box;

const BATCH: usize = 4096;

fn uniform_pairs(seed: u64) -> Vec<Vec2> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..BATCH)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect()
}

/// The slice `acdf bench` uses: (values, n_x = φ_h, n_y = θ_h).
fn nickel_slice() -> (Vec<f32>, usize, usize) {
    let nickel = acdf_materials::builtin("nickel").unwrap();
    let res = Resolution::ISOTROPIC;
    let values = tabulate_slice(&*nickel, &res, res.theta_o / 2, 0);
    (values, res.phi_h, res.theta_h)
}

fn distribution_2d(c: &mut Criterion) {
    let (values, nx, ny) = nickel_slice();
    let builder = AdaptiveBuilder::by_name("dp", None).unwrap();
    let d: AdaptiveCdf2D = builder.build_slice(&values, nx, ny).unwrap();
    let u = uniform_pairs(1);
    let points: Vec<Vec2> = u.iter().map(|&u| d.sample(u).p).collect();
    let mut group = c.benchmark_group("adaptive_2d_nickel_256x32");
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("sample_batch", |b| {
        let mut out = vec![Sample2D::default(); BATCH];
        b.iter(|| {
            d.sample_batch(black_box(&u), &mut out);
            black_box(&out);
        })
    });
    group.bench_function("sample", |b| {
        let mut out = vec![Sample2D::default(); BATCH];
        b.iter(|| {
            for (o, &u) in out.iter_mut().zip(black_box(&u)) {
                *o = d.sample(u);
            }
            black_box(&out);
        })
    });
    group.bench_function("pdf", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for &p in black_box(&points) {
                acc += d.pdf(p);
            }
            black_box(acc)
        })
    });
    group.bench_function("pdf_batch", |b| {
        let mut out = vec![0.0f32; BATCH];
        b.iter(|| {
            d.pdf_batch(black_box(&points), &mut out);
            black_box(&out);
        })
    });
    group.bench_function("same_cell_around", |b| {
        let margin = Vec2::splat(1e-4);
        b.iter(|| {
            let mut inside = 0usize;
            for &p in black_box(&points) {
                inside += d.same_cell_around(p, margin) as usize;
            }
            black_box(inside)
        })
    });
    group.bench_function("sample_and_same_cell", |b| {
        let margin = Vec2::splat(1e-4);
        let mut out = vec![(Sample2D::default(), false); BATCH];
        b.iter(|| {
            for (o, &u) in out.iter_mut().zip(black_box(&u)) {
                *o = d.sample_and_same_cell(u, margin);
            }
            black_box(&out);
        })
    });
    group.finish();

    let mut group = c.benchmark_group("adaptive_2d_nickel_256x32_build");
    group.bench_function("build", |b| {
        b.iter_batched(
            || values.clone(),
            |v| builder.build_slice(&v, nx, ny).unwrap(),
            BatchSize::SmallInput,
        )
    });
    group.finish();
}

fn distribution_1d(c: &mut Criterion) {
    let (values, nx, _) = nickel_slice();
    let rows: Vec<f32> = values.chunks_exact(nx).map(|r| r.iter().sum()).collect();
    let simplifier = DouglasPeucker::vertical();
    let d = AdaptiveCdf1D::from_values(&rows, &simplifier, simplifier.default_tolerance()).unwrap();
    let u: Vec<f32> = uniform_pairs(3).iter().map(|u| u.x).collect();
    let points: Vec<f32> = u.iter().map(|&u| d.sample(u).x).collect();
    let mut group = c.benchmark_group("adaptive_1d_nickel_rows_256");
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("sample_batch", |b| {
        let mut out = vec![Sample1D::default(); BATCH];
        b.iter(|| {
            d.sample_batch(black_box(&u), &mut out);
            black_box(&out);
        })
    });
    group.bench_function("sample", |b| {
        let mut out = vec![Sample1D::default(); BATCH];
        b.iter(|| {
            for (o, &u) in out.iter_mut().zip(black_box(&u)) {
                *o = d.sample(u);
            }
            black_box(&out);
        })
    });
    group.bench_function("pdf", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for &x in black_box(&points) {
                acc += d.pdf(x);
            }
            black_box(acc)
        })
    });
    group.finish();
}

criterion_group!(benches, distribution_2d, distribution_1d);
criterion_main!(benches);
