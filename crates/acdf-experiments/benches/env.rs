//! Time per call of environment sampling against BRDF sampling: `sample`
//! of the environment samplers (the shading normal changing on every call,
//! as in a renderer) beside `sample` of the BRDF samplers (the outgoing
//! direction changing on every call), one thread. The orientation-aware
//! sampler is also timed with each normal held for 64 consecutive calls,
//! and with one normal for all calls.
//!
//! The map is `rooitou_park_1k.hdr` of the shared data when present (a
//! sun holding 66% of the energy), else a generated 1024 × 512 sky with a
//! small sun; the BRDF samplers are the registry's on the built-in nickel
//! at 32x1x256x32.
//!
//! ```sh
//! cargo bench -p acdf-experiments --bench env
//! ACDF_ENV_TOLERANCE=4e-3 cargo bench -p acdf-experiments --bench env -- oriented
//! ```
//!
//! `ACDF_ENV_TOLERANCE` sets the simplifier tolerance of the adaptive and
//! oriented environment samplers (`--tolerance` of `acdf env-report`;
//! default: the simplifier's own). `ACDF_ENV_NORMALS=K` cycles through the
//! first K of the report's 34 normals only (each in a region of its own),
//! which sets how many region tables the orientation-aware sampler's draws
//! spread over:
//!
//! ```sh
//! ACDF_ENV_NORMALS=8 cargo bench -p acdf-experiments --bench env -- oriented
//! ```

use std::hint::black_box;
use std::sync::Arc;

use acdf::env_registry::{make_env_sampler, EnvSamplerOptions};
use acdf::lights::EnvMap;
use acdf::{load_material, make_sampler, MaterialSpec, SamplerOptions};
use acdf_core::{BxdfSampler, Rgb, SphereSampler, Vec2, Vec3};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rand::{Rng, SeedableRng};

const CALLS: usize = 4096;

/// Consecutive calls that share a normal in the coherent variant.
const COHERENT_RUN: usize = 64;

/// The shared map, or a generated sky with a sun.
fn map() -> (String, Arc<EnvMap>) {
    if let Some(dir) = acdf::materials::shared_data_dir() {
        let path = dir.join("envmaps/rooitou_park_1k.hdr");
        if let Ok(m) = EnvMap::open(&path) {
            return ("rooitou_park".into(), Arc::new(m));
        }
    }
    let m = EnvMap::from_fn(1024, 512, |k, j| {
        let sun = (k as i64 - 300).abs() < 3 && (j as i64 - 150).abs() < 3;
        if sun {
            Rgb::splat(1e5)
        } else if j < 256 {
            Rgb::new(0.3, 0.5, 1.0) * (1.0 + j as f32 / 256.0)
        } else {
            Rgb::splat(0.2)
        }
    })
    .expect("a valid generated map");
    ("generated_sky".into(), Arc::new(m))
}

fn uniforms(seed: u64) -> Vec<Vec2> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    (0..CALLS)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect()
}

fn env(c: &mut Criterion) {
    let (label, map) = map();
    let u = uniforms(1);
    let mut normals: Vec<Vec3> = acdf_experiments::env_report::standard_normals();
    if let Ok(k) = std::env::var("ACDF_ENV_NORMALS") {
        let k: usize = k
            .parse()
            .ok()
            .filter(|k| (1..=normals.len()).contains(k))
            .unwrap_or_else(|| panic!("ACDF_ENV_NORMALS: a count from 1 to {}", normals.len()));
        normals.truncate(k);
    }
    let options = EnvSamplerOptions {
        tolerance: std::env::var("ACDF_ENV_TOLERANCE").ok().map(|t| {
            t.parse()
                .expect("ACDF_ENV_TOLERANCE: a positive number, e.g. 4e-3")
        }),
        ..EnvSamplerOptions::default()
    };
    let mut group = c.benchmark_group(format!("env_sample_{label}"));
    group.throughput(Throughput::Elements(CALLS as u64));
    for name in ["uniform", "adaptive:dp", "adaptive:chi2", "oriented:dp"] {
        let s = make_env_sampler(name, &map, &options).expect("builds");
        // Build the cells the normals need before timing, and say how much
        // the draws spread over (the growth is the regions' tables; the
        // plain samplers build nothing here).
        let before = s.storage_bytes();
        for &n in &normals {
            s.pdf(Some(n), Vec3::Z);
        }
        let built = s.storage_bytes() - before;
        if built > 0 {
            eprintln!(
                "{name}: the tables of the {} normals' regions take {:.1} KiB",
                normals.len(),
                built as f64 / 1024.0
            );
        }
        group.bench_function(name, |b| {
            b.iter(|| {
                for (i, &u) in u.iter().enumerate() {
                    let n = normals[i % normals.len()];
                    black_box(s.sample(Some(black_box(n)), black_box(u)));
                }
            })
        });
        if name == "oriented:dp" {
            // The same normals, each for a run of consecutive calls, as a
            // renderer's neighbouring pixels on one surface give: the
            // region's table stays in cache, which separates the cost of
            // the draw from that of its cache misses.
            group.bench_function("oriented:dp, coherent normals", |b| {
                b.iter(|| {
                    for (i, &u) in u.iter().enumerate() {
                        let n = normals[(i / COHERENT_RUN) % normals.len()];
                        black_box(s.sample(Some(black_box(n)), black_box(u)));
                    }
                })
            });
            // One normal for every call: one region's table, warm in the
            // caches, so what is left is the work of a call.
            let n = normals[1.min(normals.len() - 1)];
            group.bench_function("oriented:dp, one normal", |b| {
                b.iter(|| {
                    for &u in &u {
                        black_box(s.sample(Some(black_box(n)), black_box(u)));
                    }
                })
            });
        }
    }
    group.finish();
}

fn brdf(c: &mut Criterion) {
    let spec: MaterialSpec = "builtin:nickel".parse().expect("a built-in material");
    let m = load_material(&spec, None).expect("loads");
    let u = uniforms(2);
    let wo: Vec<Vec3> = (0..64)
        .map(|i| {
            let t = (5.0 + 80.0 * (i as f32 / 64.0)).to_radians();
            let p = i as f32 * 2.4;
            Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
        })
        .collect();
    let mut group = c.benchmark_group("brdf_sample_nickel");
    group.throughput(Throughput::Elements(CALLS as u64));
    for name in ["uniform", "adaptive:dp", "adaptive:chi2"] {
        let s = make_sampler(name, &m, &SamplerOptions::default()).expect("builds");
        acdf::SamplerOps::build_all(&s).expect("builds");
        group.bench_function(name, |b| {
            b.iter(|| {
                for (i, &u) in u.iter().enumerate() {
                    black_box(s.sample(black_box(wo[i % wo.len()]), black_box(u)));
                }
            })
        });
    }
    group.finish();
}

criterion_group!(benches, env, brdf);
criterion_main!(benches);
