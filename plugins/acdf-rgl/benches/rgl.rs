//! Throughput of the RGL file's own sampler and of the material's
//! evaluation, on two shared RGL materials (the near-diffuse paper and the
//! near-specular chm_mint) at θ_o = 30°, and of the bilinear warp alone on a
//! 128 × 128 table. The RGL groups are skipped with a message when the shared
//! data is absent.

use acdf_core::geometry::spherical_direction;
use acdf_core::{Brdf, BxdfSampler, Distribution2D, Sample2D, Vec2, Vec3};
use acdf_rgl::{Bilinear2D, RglBrdf, RglSampler};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
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

fn bilinear(c: &mut Criterion) {
    let n = 128;
    let values: Vec<f32> = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f32 / n as f32, (k / n) as f32 / n as f32);
            x * (-(x * 6.0).powi(2)).exp() * (1.2 + (6.0 * y).sin())
        })
        .collect();
    let d = Bilinear2D::new(n, n, &values).unwrap();
    let u = uniform_pairs(1);
    let points: Vec<Vec2> = u.iter().map(|&u| d.sample(u).p).collect();
    let mut group = c.benchmark_group("bilinear_2d_128x128");
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("sample", |b| {
        let mut out = vec![Sample2D::default(); BATCH];
        b.iter(|| {
            d.sample_batch(black_box(&u), &mut out);
            black_box(&out);
        })
    });
    group.bench_function("invert", |b| {
        b.iter(|| {
            for &p in &points {
                black_box(d.invert(black_box(p)));
            }
        })
    });
    group.finish();
}

fn rgl(c: &mut Criterion) {
    let Some(dir) = acdf_materials::rgl::shared_dir() else {
        println!("skipping the RGL groups: shared data not found (set ACDF_SHARED_DATA)");
        return;
    };
    let wo = spherical_direction(30f32.to_radians(), 1.0);
    for stem in ["paper_white_rgb", "chm_mint_rgb"] {
        let path = dir.join(format!("{stem}.bsdf"));
        let Ok(brdf) = RglBrdf::open(&path) else {
            println!("skipping {stem}: {} does not load", path.display());
            continue;
        };
        let brdf = Arc::new(brdf);
        let sampler = RglSampler::new(brdf.clone());
        let u = uniform_pairs(2);
        let wis: Vec<Vec3> = u
            .iter()
            .filter_map(|&u| sampler.sample(wo, u).map(|s| s.wi))
            .collect();
        let mut group = c.benchmark_group(format!("rgl_{stem}"));
        group.throughput(Throughput::Elements(BATCH as u64));
        group.bench_function("sample", |b| {
            let mut out = vec![None; BATCH];
            b.iter(|| {
                sampler.sample_batch(wo, black_box(&u), &mut out);
                black_box(&out);
            })
        });
        group.throughput(Throughput::Elements(wis.len() as u64));
        group.bench_function("pdf", |b| {
            let mut out = vec![0.0; wis.len()];
            b.iter(|| {
                sampler.pdf_batch(wo, black_box(&wis), &mut out);
                black_box(&out);
            })
        });
        group.bench_function("eval", |b| {
            b.iter(|| {
                for &wi in &wis {
                    black_box(brdf.eval(wo, black_box(wi)));
                }
            })
        });
        group.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .measurement_time(std::time::Duration::from_secs(2))
        .warm_up_time(std::time::Duration::from_millis(500));
    targets = bilinear, rgl
}
criterion_main!(benches);
