//! Throughput of the uniform tabulation: the 1D distribution at 256 cells
//! and the 2D distribution at 256 × 32 (sample one at a time, sample_batch,
//! pdf, build), the whole sampler on the built-in nickel at the isotropic
//! resolution (all slices built before timing), and the build of every
//! slice at the paper's resolution from a MERL-layout table.

use acdf_core::geometry::spherical_direction;
use acdf_core::{BxdfSampler, Distribution1D, Distribution2D, Sample1D, Sample2D, Vec2, Vec3};
use acdf_materials::merl::MerlTable;
use acdf_tabulated::Resolution;
use acdf_uniform::PiecewiseConstant1D;
use acdf_uniform::{PiecewiseConstant2D, PiecewiseConstantBuilder, UniformBrdfSampler};
use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::hint::black_box;
use std::sync::Arc;

const BATCH: usize = 4096;

fn uniform_pairs(seed: u64) -> Vec<Vec2> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..BATCH)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect()
}

fn distribution(c: &mut Criterion) {
    let (nx, ny) = (32, 256);
    // A peaked, MERL-like slice: a narrow lobe near the first rows.
    let values: Vec<f32> = (0..nx * ny)
        .map(|k| {
            let (x, y) = ((k % nx) as f32 / nx as f32, (k / nx) as f32 / ny as f32);
            0.01 + (-(y * 30.0).powi(2)).exp() * (1.0 + (std::f32::consts::TAU * x).cos())
        })
        .collect();
    let d = PiecewiseConstant2D::new(&values, nx, ny).unwrap();
    let u = uniform_pairs(1);
    let points: Vec<Vec2> = u.iter().map(|&u| d.sample(u).p).collect();
    let mut group = c.benchmark_group("piecewise_constant_2d_256x32");
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("sample", |b| {
        let mut out = vec![Sample2D::default(); BATCH];
        b.iter(|| {
            d.sample_batch(black_box(&u), &mut out);
            black_box(&out);
        })
    });
    group.bench_function("sample one at a time", |b| {
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
    group.bench_function("build", |b| {
        b.iter_batched(
            || values.clone(),
            |v| PiecewiseConstant2D::new(&v, nx, ny).unwrap(),
            BatchSize::SmallInput,
        )
    });
    group.finish();
}

fn distribution_1d(c: &mut Criterion) {
    let n = 256;
    // The marginal of a peaked slice: most mass in the first cells.
    let values: Vec<f32> = (0..n)
        .map(|k| 0.01 + (-(k as f32 / n as f32 * 30.0).powi(2)).exp())
        .collect();
    let d = PiecewiseConstant1D::new(&values).unwrap();
    let u: Vec<f32> = uniform_pairs(3).iter().map(|u| u.x).collect();
    let points: Vec<f32> = u.iter().map(|&u| d.sample(u).x).collect();
    let mut group = c.benchmark_group("piecewise_constant_1d_256");
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("sample", |b| {
        let mut out = vec![Sample1D::default(); BATCH];
        b.iter(|| {
            d.sample_batch(black_box(&u), &mut out);
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

fn sampler(c: &mut Criterion) {
    let nickel = acdf_materials::builtin("nickel").unwrap();
    let s =
        UniformBrdfSampler::new(nickel, Resolution::ISOTROPIC, PiecewiseConstantBuilder).unwrap();
    s.build_all().unwrap();
    let wo = spherical_direction(0.6, 1.3);
    let u = uniform_pairs(2);
    let wi: Vec<Vec3> = u
        .iter()
        .filter_map(|&u| s.sample(wo, u))
        .map(|b| b.wi)
        .collect();
    let mut group = c.benchmark_group("uniform_sampler_nickel_32x1x256x32");
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("sample", |b| {
        let mut out = vec![None; BATCH];
        b.iter(|| {
            s.sample_batch(black_box(wo), black_box(&u), &mut out);
            black_box(&out);
        })
    });
    group.throughput(Throughput::Elements(wi.len() as u64));
    group.bench_function("pdf", |b| {
        let mut out = vec![0.0; wi.len()];
        b.iter(|| {
            s.pdf_batch(black_box(wo), black_box(&wi), &mut out);
            black_box(&out);
        })
    });
    // One outgoing direction per draw, cycling through 64 (a renderer's
    // shading points): one call at a time, and as a wavefront.
    let wos: Vec<Vec3> = (0..BATCH)
        .map(|k| {
            let t = ((k % 64) as f32 + 0.5) / 64.0;
            spherical_direction(
                (5.0 + 75.0 * t).to_radians(),
                std::f32::consts::TAU * (k as f32 * 0.618_034).fract(),
            )
        })
        .collect();
    let pairs: Vec<Vec3> = wos
        .iter()
        .zip(&u)
        .map(|(&wo, &u)| s.sample(wo, u).map_or(Vec3::Z, |b| b.wi))
        .collect();
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("sample one at a time, wo changing", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (&wo, &u) in wos.iter().zip(&u) {
                acc += s.sample(black_box(wo), u).map_or(0.0, |b| b.pdf);
            }
            black_box(acc)
        })
    });
    group.bench_function("sample_each, wo changing", |b| {
        let mut out = vec![None; BATCH];
        b.iter(|| {
            s.sample_each(black_box(&wos), black_box(&u), &mut out);
            black_box(&out);
        })
    });
    group.bench_function("pdf one at a time, wo changing", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (&wo, &wi) in wos.iter().zip(&pairs) {
                acc += s.pdf(black_box(wo), wi);
            }
            black_box(acc)
        })
    });
    group.bench_function("pdf_each, wo changing", |b| {
        let mut out = vec![0.0; BATCH];
        b.iter(|| {
            s.pdf_each(black_box(&wos), black_box(&pairs), &mut out);
            black_box(&out);
        })
    });
    group.finish();
}

fn build_from_merl(c: &mut Criterion) {
    let nickel = acdf_materials::builtin("nickel").unwrap();
    let merl: Arc<dyn acdf_core::Brdf> = Arc::new(MerlTable::tabulate(&*nickel));
    let mut group = c.benchmark_group("uniform_build_all_merl_nickel");
    group.sample_size(10);
    group.bench_function("32x16x256x32", |b| {
        b.iter(|| {
            let s =
                UniformBrdfSampler::new(merl.clone(), Resolution::PAPER, PiecewiseConstantBuilder)
                    .unwrap();
            s.build_all().unwrap();
            black_box(s.storage_bytes())
        })
    });
    group.finish();
}

criterion_group!(
    benches,
    distribution_1d,
    distribution,
    sampler,
    build_from_merl
);
criterion_main!(benches);
