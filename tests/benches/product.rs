//! The product sampler's costs beside the samplers it combines: cutting a
//! map into blocks (once per map), the evaluation points of one shading
//! normal and forming the product for one wo (once per shading point),
//! one draw and one density from a formed product; and for comparison one
//! draw of the BRDF sampler it wraps (`outgoing:chi2`) and of the
//! orientation-aware light sampler (`oriented:chi2`). nickel under
//! rooitou_park (the shared data; a synthetic 1024 × 512 sky with a sun
//! without it), 64 × 32 blocks (forming the product also at 32 × 16 and
//! 128 × 64), 2 × 2 points per block, δ = 0.15. The
//! heap bytes of the blocks, of one normal's points and of one formed
//! product are printed first.
//!
//! ```text
//! cargo bench -p acdf-conformance --bench product
//! ```

use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_adaptive_env::oriented_env_sampler;
use acdf_core::{BxdfSampler, Frame, Rgb, SphereSampler, Vec2, Vec3};
use acdf_lights::{EnvMap, NormalGrid};
use acdf_outgoing::{OutgoingBuilder, OutgoingSampler, FINE_PER_CELL};
use acdf_product::{ProductEnv, ProductOptions, ProductQuery};
use acdf_tabulated::Resolution;
use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use std::hint::black_box;
use std::sync::Arc;

fn map() -> Arc<EnvMap> {
    let shared = acdf_materials::shared_data_dir()
        .map(|d| d.join("envmaps/rooitou_park_1k.hdr"))
        .filter(|p| p.is_file());
    Arc::new(match shared {
        Some(path) => EnvMap::open(&path).expect("the shared map loads"),
        None => EnvMap::from_fn(1024, 512, |k, j| {
            if (300..303).contains(&k) && (100..103).contains(&j) {
                Rgb::splat(50_000.0)
            } else {
                Rgb::new(0.3, 0.5, 1.0) * (1.0 + j as f32 / 512.0)
            }
        })
        .expect("a valid map"),
    })
}

/// A few (normal, wo) pairs, cycled through so that no cache helps.
fn cases() -> Vec<(Vec3, Vec3)> {
    (0..16)
        .map(|k| {
            let t = k as f32 * 0.37;
            let normal = Vec3::new(t.cos() * 0.6, t.sin() * 0.6, 0.5 + 0.03 * k as f32).normalize();
            let wo = Vec3::new(0.4 * (1.3 * t).cos(), 0.4 * (1.3 * t).sin(), 0.8).normalize();
            (normal, wo)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let map = map();
    let options = ProductOptions::default();
    let brdf = acdf_materials::builtin("nickel").expect("nickel");
    let r = Resolution::ISOTROPIC;
    let builder = OutgoingBuilder::by_name("chi2", None, r.theta_o * FINE_PER_CELL).unwrap();
    let outgoing = OutgoingSampler::new(brdf, r, builder).unwrap();
    let env = ProductEnv::new(
        map.clone(),
        options.block_columns,
        options.points_per_side,
        options.sub_cells,
    )
    .unwrap();
    let cases = cases();
    let (normal, wo) = cases[0];
    let frame = Frame::from_z(normal);
    let points = env.local_points(&frame);
    let query = ProductQuery::build(&env, frame, &points, &outgoing, wo, &options);
    eprintln!(
        "bytes: blocks {} (map {}x{}), one normal's points {}, one product {}; outgoing:chi2 {}",
        env.storage_bytes(),
        map.size().0,
        map.size().1,
        points.storage_bytes(),
        query.storage_bytes(),
        outgoing.storage_bytes()
    );

    let mut g = c.benchmark_group("product");
    g.sample_size(20);
    g.bench_function("blocks_per_map", |b| {
        b.iter(|| {
            ProductEnv::new(
                black_box(map.clone()),
                options.block_columns,
                options.points_per_side,
                options.sub_cells,
            )
            .unwrap()
        })
    });
    let mut k = 0;
    g.bench_function("query_points_and_product", |b| {
        b.iter(|| {
            k = (k + 1) % cases.len();
            let (normal, wo) = cases[k];
            let frame = Frame::from_z(normal);
            let points = env.local_points(&frame);
            ProductQuery::build(&env, frame, &points, &outgoing, wo, &options)
        })
    });
    g.bench_function("query_product_only", |b| {
        b.iter_batched(
            || {
                k = (k + 1) % cases.len();
                cases[k].1
            },
            |wo| ProductQuery::build(&env, frame, &points, &outgoing, wo, &options),
            BatchSize::SmallInput,
        )
    });
    for columns in [32, 128] {
        let other = ProductEnv::new(
            map.clone(),
            columns,
            options.points_per_side,
            options.sub_cells,
        )
        .unwrap();
        let other_points = other.local_points(&frame);
        let name = format!("query_product_only_{columns}x{}_blocks", columns / 2);
        g.bench_function(&name, |b| {
            b.iter_batched(
                || {
                    k = (k + 1) % cases.len();
                    cases[k].1
                },
                |wo| {
                    let (env, points) = (&other, &other_points);
                    ProductQuery::build(env, frame, points, &outgoing, wo, &options)
                },
                BatchSize::SmallInput,
            )
        });
    }
    let us: Vec<Vec2> = (0..1024)
        .map(|i| {
            Vec2::new(
                ((i as f32) * 0.618_034).fract(),
                ((i as f32) * 0.754_877).fract(),
            )
        })
        .collect();
    let mut i = 0;
    g.bench_function("draw", |b| {
        b.iter(|| {
            i = (i + 1) % us.len();
            query.sample(&env, &outgoing, black_box(us[i]))
        })
    });
    let wis: Vec<Vec3> = us
        .iter()
        .filter_map(|&u| query.sample(&env, &outgoing, u).map(|s| s.wi))
        .collect();
    g.bench_function("pdf", |b| {
        b.iter(|| {
            i = (i + 1) % wis.len();
            query.pdf(&env, &outgoing, black_box(wis[i]))
        })
    });
    g.bench_function("outgoing_chi2_draw", |b| {
        b.iter(|| {
            i = (i + 1) % us.len();
            outgoing.sample(wo, black_box(us[i]))
        })
    });
    let light = oriented_env_sampler(
        map.clone(),
        AdaptiveBuilder::by_name("chi2", None).unwrap(),
        NormalGrid::new(16, 32).unwrap(),
        0.0,
    )
    .unwrap();
    light.sample(Some(normal), Vec2::splat(0.5));
    g.bench_function("oriented_chi2_draw", |b| {
        b.iter(|| {
            i = (i + 1) % us.len();
            light.sample(Some(normal), black_box(us[i]))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
