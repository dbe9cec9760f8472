//! Environment draws never fail where the table has mass: at the edges of
//! [0, 1) in u, at the last texel with mass of a row, beside texels without
//! mass, on constructed maps and on a shared map; and every draw's density
//! is `pdf` of its direction.

use std::sync::Arc;

use acdf::core::{Rgb, SphereSampler, Vec2, Vec3, ONE_MINUS_EPSILON};
use acdf::env_registry::{make_env_sampler, parse_sphere_direction_degrees, EnvSamplerOptions};
use acdf::lights::EnvMap;
use rand::{Rng, SeedableRng};

/// u at and next to the edges of [0, 1), and the middle.
const EDGE_U: [f32; 6] = [
    0.0,
    f32::MIN_POSITIVE,
    1e-7,
    0.5,
    1.0 - 1e-7,
    ONE_MINUS_EPSILON,
];

const SAMPLERS: [&str; 6] = [
    "uniform",
    "uniform-comp",
    "adaptive:dp",
    "adaptive:chi2",
    "adaptive-comp:dp",
    "oriented:dp",
];

/// Every draw of `sampler` with normal `normal` from the edge pairs and
/// `random` pseudo-random pairs: `Some`, with a density equal to `pdf`.
fn assert_every_draw_succeeds(label: &str, map: &Arc<EnvMap>, normal: Vec3, random: usize) {
    for name in SAMPLERS {
        let s = make_env_sampler(name, map, &EnvSamplerOptions::default()).unwrap();
        let mut us: Vec<Vec2> = EDGE_U
            .iter()
            .flat_map(|&a| EDGE_U.iter().map(move |&b| Vec2::new(a, b)))
            .collect();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        us.extend((0..random).map(|_| Vec2::new(rng.random(), rng.random())));
        for u in us {
            let Some(d) = s.sample(Some(normal), u) else {
                panic!("{label}, {name}: no draw for u = {u}");
            };
            let p = s.pdf(Some(normal), d.dir);
            assert!(
                (p - d.pdf).abs() <= 1e-4 * d.pdf,
                "{label}, {name}, u = {u}: drawn density {} but pdf {p}",
                d.pdf
            );
        }
    }
}

fn map(width: usize, height: usize, value: impl Fn(usize, usize) -> f32) -> Arc<EnvMap> {
    Arc::new(EnvMap::from_fn(width, height, |k, j| Rgb::splat(value(k, j))).unwrap())
}

#[test]
fn one_bright_texel() {
    let m = map(64, 32, |k, j| if (k, j) == (17, 9) { 100.0 } else { 0.0 });
    assert_every_draw_succeeds("one bright texel", &m, Vec3::Z, 20_000);
}

#[test]
fn mass_only_in_the_last_column() {
    let m = map(64, 32, |k, _| if k == 63 { 1.0 } else { 0.0 });
    assert_every_draw_succeeds("the last column", &m, Vec3::Z, 20_000);
}

#[test]
fn a_row_whose_last_texels_are_zero() {
    let m = map(64, 32, |k, j| {
        if j == 12 && k >= 56 {
            0.0
        } else {
            1.0 + (k % 7) as f32
        }
    });
    assert_every_draw_succeeds("a row ending in zeros", &m, Vec3::Z, 20_000);
}

/// The draw that failed on a shared map: the compensated table of
/// empty_warehouse_01 with the normal at (40°, 75°), the stream of
/// `acdf env-sample --seed 20261121`.
#[test]
fn the_compensated_table_of_a_shared_map() {
    let Some(dir) = acdf::materials::shared_data_dir() else {
        acdf::materials::testing::skip_without_data("no shared data directory");
        return;
    };
    let path = dir.join("envmaps/empty_warehouse_01_1k.hdr");
    if !path.is_file() {
        acdf::materials::testing::skip_without_data(format_args!("{} is absent", path.display()));
        return;
    }
    let m = Arc::new(EnvMap::open(&path).unwrap());
    let normal = parse_sphere_direction_degrees("40,75").unwrap();
    let s = make_env_sampler("uniform-comp", &m, &EnvSamplerOptions::default()).unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(20261121);
    for k in 0..500_000 {
        let u = Vec2::new(rng.random(), rng.random());
        assert!(
            s.sample(Some(normal), u).is_some(),
            "draw {k}, u = {u}: no draw"
        );
    }
}
