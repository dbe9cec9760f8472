//! Throughput of the cosine sampler, the floor every tabulated sampler is
//! compared with: `sample` and `pdf` one call at a time (wo changing every
//! call, as in a path tracer) and their batch forms for one wo.

use acdf_core::{BxdfSampler, Vec2, Vec3};
use acdf_cosine::CosineSampler;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::hint::black_box;

const BATCH: usize = 4096;

fn cosine(c: &mut Criterion) {
    let mut rng = Pcg64::seed_from_u64(5);
    let u: Vec<Vec2> = (0..BATCH)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect();
    // Outgoing directions spread over the upper hemisphere.
    let wos: Vec<Vec3> = (0..BATCH)
        .map(|k| {
            let t = (k as f32 + 0.5) / BATCH as f32;
            let (sin_t, cos_t) = (0.05 + 1.3 * t).sin_cos();
            let phi = std::f32::consts::TAU * (k as f32 * 0.618_034).fract();
            Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
        })
        .collect();
    let s = CosineSampler;
    let drawn: Vec<(Vec3, Vec3)> = wos
        .iter()
        .zip(&u)
        .filter_map(|(&wo, &u)| s.sample(wo, u).map(|b| (wo, b.wi)))
        .collect();
    let mut group = c.benchmark_group("cosine_sampler");
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("sample", |b| {
        let mut out = vec![None; BATCH];
        b.iter(|| {
            for ((o, &wo), &u) in out.iter_mut().zip(black_box(&wos)).zip(black_box(&u)) {
                *o = s.sample(wo, u);
            }
            black_box(&out);
        })
    });
    group.bench_function("sample_batch", |b| {
        let mut out = vec![None; BATCH];
        b.iter(|| {
            s.sample_batch(black_box(wos[7]), black_box(&u), &mut out);
            black_box(&out);
        })
    });
    group.throughput(Throughput::Elements(drawn.len() as u64));
    group.bench_function("pdf", |b| {
        b.iter(|| {
            let mut total = 0.0f32;
            for &(wo, wi) in black_box(&drawn) {
                total += s.pdf(wo, wi);
            }
            black_box(total)
        })
    });
    group.finish();
}

criterion_group!(benches, cosine);
criterion_main!(benches);
