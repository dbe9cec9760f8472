use super::*;
use acdf_core::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use acdf_core::Rgb;
use acdf_lights::EnvMap;
use rand::{Rng, SeedableRng};

/// p = cos θ_i / π, the simplest BRDF sampler (plug-ins do not depend on
/// each other, so not `acdf-cosine`'s).
struct CosineSampler;

impl BxdfSampler for CosineSampler {
    fn name(&self) -> &str {
        "cosine"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        let wi = square_to_cosine_hemisphere(u);
        let pdf = cosine_hemisphere_pdf(wi);
        (is_valid_outgoing(wo) && pdf > 0.0).then_some(BxdfSample { wi, pdf })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if is_valid_outgoing(wo) {
            cosine_hemisphere_pdf(wi)
        } else {
            0.0
        }
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

fn sun_map() -> EnvMap {
    EnvMap::from_fn(64, 32, |k, j| {
        if (k, j) == (8, 6) {
            Rgb::splat(5000.0)
        } else {
            Rgb::splat(0.1)
        }
    })
    .unwrap()
}

fn sampler(map: &EnvMap, normal: Vec3, defensive: f32) -> ProductSampler {
    let options = ProductOptions {
        defensive,
        ..ProductOptions::default()
    };
    let env = ProductEnv::new(
        Arc::new(map.clone()),
        options.block_columns,
        2,
        options.sub_cells,
    )
    .unwrap();
    ProductSampler::new(Arc::new(CosineSampler), Arc::new(env), normal, options).unwrap()
}

/// Draws carry the density `pdf` gives, above the horizon, and follow
/// the map: with a sun, most draws go towards it.
#[test]
fn draws_agree_with_the_density_and_follow_the_light() {
    let map = sun_map();
    let s = sampler(&map, Vec3::Z, 0.15);
    let sun = map.direction_of(map.grid().texel_centre(8, 6));
    let wo = Vec3::new(0.2, 0.1, 0.9).normalize();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let mut near = 0;
    let n = 20_000;
    for _ in 0..n {
        let u = Vec2::new(rng.random(), rng.random());
        let d = s.sample(wo, u).unwrap();
        assert!(d.wi.z > 0.0 && (d.wi.length() - 1.0).abs() < 1e-5);
        assert_eq!(d.pdf, s.pdf(wo, d.wi));
        if d.wi.dot(sun) > 0.99 {
            near += 1;
        }
    }
    assert!(near as f64 > 0.5 * n as f64, "{near} of {n} near the sun");
    assert_eq!(s.name(), "product:cosine");
}

/// ∫ f dω over the sphere (world directions) by the midpoint rule on a
/// lat-long grid `per` times finer than a `w` × `h` map's texels, so that
/// no cell straddles a texel's edge.
fn world_integral(w: usize, h: usize, per: usize, f: impl Fn(Vec3) -> f64) -> f64 {
    let grid = acdf_lights::LatLong::new(w * per, h * per);
    let mut sum = 0.0;
    for j in 0..h * per {
        let omega = grid.texel_solid_angle(j);
        for k in 0..w * per {
            sum += f(grid.texel_direction(k, j)) * omega;
        }
    }
    sum
}

/// The density integrates (midpoint rule on a grid aligned with the
/// texels, a smooth map) to the share of draws that succeed: the blocks
/// straddle the horizon, and draws of theirs below it are `None`. With
/// blocks of one texel, and with blocks of 4 × 4 texels drawn through
/// their sub-cells (the refined density); with 64 mass draws.
#[test]
fn the_density_integrates_to_the_share_of_draws() {
    let map = EnvMap::from_fn(64, 32, |k, j| {
        Rgb::splat(1.0 + 0.1 * j as f32 + 0.05 * k as f32)
    })
    .unwrap();
    for block_columns in [64, 16] {
        for (normal, delta) in [
            (Vec3::Z, 0.15),
            (-Vec3::Z, 0.0),
            (Vec3::new(0.3, 0.4, 0.5), 0.0),
            (Vec3::new(1.0, -0.0, 0.2), 1.0),
        ] {
            let options = ProductOptions {
                defensive: delta,
                block_columns,
                mass_draws: 64,
                ..ProductOptions::default()
            };
            let env = ProductEnv::new(Arc::new(map.clone()), block_columns, 2, 4).unwrap();
            let s = ProductSampler::new(Arc::new(CosineSampler), Arc::new(env), normal, options)
                .unwrap();
            let frame = Frame::from_z(s.normal());
            let wo = Vec3::new(0.5, -0.2, 0.6).normalize();
            let integral = world_integral(64, 32, 8, |d| s.pdf(wo, frame.to_local(d)) as f64);
            let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
            let n = 100_000;
            let drawn = (0..n)
                .filter(|_| {
                    s.sample(wo, Vec2::new(rng.random(), rng.random()))
                        .is_some()
                })
                .count() as f64
                / n as f64;
            let case = format!("{block_columns} {normal} {delta}");
            assert!(integral <= 1.0 + 2e-3, "{case}: {integral}");
            assert!(
                (integral - drawn).abs() < 5e-3,
                "{case}: {integral} against {drawn}"
            );
        }
    }
}

/// Directions uniform in the cone of half-angle α about `axis` (local):
/// a narrow analytic lobe.
struct ConeSampler {
    axis: Vec3,
    cos_alpha: f32,
}

impl BxdfSampler for ConeSampler {
    fn name(&self) -> &str {
        "cone"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        let z = 1.0 - u.x * (1.0 - self.cos_alpha);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * u.y;
        let wi = Frame::from_z(self.axis).to_world(Vec3::new(r * phi.cos(), r * phi.sin(), z));
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then_some(BxdfSample { wi, pdf })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if is_valid_outgoing(wo) && wi.z > 0.0 && wi.normalize().dot(self.axis) >= self.cos_alpha {
            1.0 / (std::f32::consts::TAU * (1.0 - self.cos_alpha))
        } else {
            0.0
        }
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

/// A lobe of 6° half-angle, narrower than a block (22.5°), across the
/// edge of two blocks, neither of whose 2 × 2 points it reaches, with a
/// one-texel sun in one of them: the blocks' weights from 64 draws of the BRDF
/// sampler (their mass) give the sun's block a share within 0.1 of its true
/// share of the product ∫_b p_S L dω (quadrature), where the point
/// densities alone (N = 0) give no block a weight at all. Drawn through
/// the sub-cells, the sun's share of the draws is within 0.1 of its true
/// share too, where drawing the block's texels by light alone (k = 1)
/// gives it less than half of that (most of the block's light lies
/// outside the lobe).
#[test]
fn a_narrow_lobe_under_a_sun_gets_its_true_product_mass() {
    let (w, h) = (512, 256);
    let (sun_k, sun_j) = (98, 48);
    let (sun_light, sky) = (400.0, 1.0);
    let map = EnvMap::from_fn(w, h, |k, j| {
        Rgb::splat(if (k, j) == (sun_k, sun_j) {
            sun_light
        } else {
            sky
        })
    })
    .unwrap();
    let axis = map.direction_of(map.grid().texel_centre(96, 48));
    let sun = map.direction_of(map.grid().texel_centre(sun_k, sun_j));
    let cone = ConeSampler {
        axis,
        cos_alpha: 6f32.to_radians().cos(),
    };
    assert!(axis.z > 0.5 && sun.dot(axis) > cone.cos_alpha);
    let wo = Vec3::new(0.1, 0.2, 0.9).normalize();
    let frame = Frame::from_z(Vec3::Z);
    let map = Arc::new(map);
    let env = ProductEnv::new(map.clone(), 16, 2, 4).unwrap();
    let block_of = |d: Vec3| env.cell_density(d).unwrap().0;
    let (sun_block, other) = (
        block_of(sun),
        block_of(map.direction_of(map.grid().texel_centre(94, 48))),
    );
    assert_ne!(sun_block, other);
    // The true product mass per block, and the sun's texel's part.
    let mut mass = vec![0f64; env.block_count()];
    let mut sun_mass = 0.0;
    let fine = acdf_lights::LatLong::new(4 * w, 4 * h);
    for j in 0..4 * h {
        let omega = fine.texel_solid_angle(j);
        for k in 0..4 * w {
            let d = fine.texel_direction(k, j);
            let p = cone.pdf(wo, d) as f64;
            if p > 0.0 {
                let m = p * map.radiance(d).x as f64 * omega;
                mass[block_of(d)] += m;
                if map.texel_of(d) == Some((sun_k, sun_j)) {
                    sun_mass += m;
                }
            }
        }
    }
    let total: f64 = mass.iter().sum();
    let true_share = mass[sun_block] / total;
    assert!((0.3..0.95).contains(&true_share), "{true_share}");
    let query = |env: &ProductEnv, options: ProductOptions| {
        let points = env.local_points(&frame);
        ProductQuery::build(env, frame, &points, &cone, wo, &options)
    };
    let with_mass = ProductOptions {
        mass_draws: 64,
        ..ProductOptions::default()
    };
    let q = query(&env, with_mass);
    let share = q.block_share(sun_block) as f64;
    eprintln!("sun block: true share {true_share:.3}, mass-weighted {share:.3}");
    assert!(
        (share - true_share).abs() < 0.1,
        "{share} against {true_share}"
    );
    let points_only = query(
        &env,
        ProductOptions {
            mass_draws: 0,
            ..ProductOptions::default()
        },
    );
    assert_eq!(points_only.grid_share(), 0.0);
    // The share of block draws that reach the sun's texel, against its
    // share of the product.
    let sun_draws = |env: &ProductEnv, q: &ProductQuery| {
        let n = 20_000;
        let hits = (0..n)
            .filter(|&i| {
                let u = Vec2::new(
                    (i as f32 + 0.5) / n as f32 * 0.85 + 0.15,
                    ((i as f32) * 0.618_034).fract(),
                );
                q.sample(env, &cone, u)
                    .is_some_and(|d| map.texel_of(frame.to_world(d.wi)) == Some((sun_k, sun_j)))
            })
            .count();
        hits as f64 / n as f64
    };
    let want = sun_mass / total;
    let refined = sun_draws(&env, &q);
    let coarse = ProductEnv::new(map.clone(), 16, 2, 1).unwrap();
    let unrefined = sun_draws(&coarse, &query(&coarse, with_mass));
    eprintln!("draws on the sun: true {want:.3}, refined {refined:.3}, light alone {unrefined:.3}");
    assert!((refined - want).abs() < 0.1, "{refined} against {want}");
    assert!(unrefined < 0.5 * want, "{unrefined} against {want}");
}

/// A black map leaves the BRDF sampler alone; bad input is refused or
/// answered with 0 / `None`.
#[test]
fn black_maps_and_bad_input() {
    let black = EnvMap::from_fn(8, 4, |_, _| Rgb::ZERO).unwrap();
    let s = sampler(&black, Vec3::Z, 0.15);
    let wo = Vec3::new(0.0, 0.6, 0.8);
    let d = s.sample(wo, Vec2::new(0.3, 0.7)).unwrap();
    assert_eq!(d, CosineSampler.sample(wo, Vec2::new(0.3, 0.7)).unwrap());
    assert_eq!(s.query(wo).unwrap().grid_share(), 0.0);
    assert!(s.sample(-wo, Vec2::splat(0.5)).is_none());
    assert_eq!(s.pdf(-wo, wo), 0.0);
    assert_eq!(s.pdf(wo, -wo), 0.0);
    assert_eq!(s.pdf(wo, Vec3::new(f32::NAN, 0.0, 1.0)), 0.0);
    let env = Arc::new(ProductEnv::new(Arc::new(black), 8, 1, 4).unwrap());
    let bad_normal = ProductSampler::new(
        Arc::new(CosineSampler),
        env,
        Vec3::new(f32::NAN, 0.0, 1.0),
        ProductOptions::default(),
    );
    assert!(matches!(
        bad_normal,
        Err(Error::InvalidParameter { name: "normal", .. })
    ));
    for bad in [
        ProductOptions {
            block_columns: 0,
            ..ProductOptions::default()
        },
        ProductOptions {
            defensive: 1.5,
            ..ProductOptions::default()
        },
        ProductOptions {
            defensive: f32::NAN,
            ..ProductOptions::default()
        },
    ] {
        assert!(bad.validate().is_err(), "{bad:?}");
    }
}

/// A query formed over two shading points and used at a third (another
/// frame and wo, as a renderer uses a pixel's query across the pixel):
/// every draw of `sample_at` carries the density `pdf_at` gives; that
/// density integrates (midpoint rule) to the share of draws that succeed;
/// and f L cos / p with f = 1 / π estimates the irradiance of the third
/// point over π, ∫ L cos dω / π by quadrature, within 4 standard errors
/// (two-sided significance 6e-5, seed fixed). Weighing the same draws by
/// the density of the query's own frame (`pdf`, the mistake the frame
/// argument exists to avoid) is rejected: |z| > 4.
#[test]
fn a_query_used_at_another_shading_point_keeps_an_exact_density() {
    let map = EnvMap::from_fn(64, 32, |k, j| {
        Rgb::splat(if (20..26).contains(&k) && (8..12).contains(&j) {
            40.0
        } else {
            0.5 + 0.02 * k as f32
        })
    })
    .unwrap();
    let env = ProductEnv::new(Arc::new(map.clone()), 32, 1, 4).unwrap();
    let frame_of = |x: f32, y: f32| Frame::from_z(Vec3::new(x, y, 1.0).normalize());
    let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
    let q = ProductQuery::build_over(
        &env,
        &[(frame_of(0.3, 0.0), wo), (frame_of(0.4, 0.1), wo)],
        &CosineSampler,
        &ProductOptions::default(),
    );
    assert!(q.grid_share() > 0.8);
    // The third point: a normal 20 degrees away, another wo.
    let (frame, wo2) = (frame_of(0.7, -0.2), Vec3::new(-0.2, 0.3, 0.8).normalize());
    let (nz, nphi) = (300, 600);
    let (mut integral, mut irradiance) = (0f64, 0f64);
    for i in 0..nz {
        for j in 0..nphi {
            let z = (i as f32 + 0.5) / nz as f32;
            let phi = std::f32::consts::TAU * (j as f32 + 0.5) / nphi as f32;
            let r = (1.0 - z * z).sqrt();
            let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            integral += q.pdf_at(&env, &CosineSampler, &frame, wo2, wi) as f64;
            let l = map.radiance(frame.to_world(wi)).x as f64;
            irradiance += l * z as f64;
        }
    }
    let cell = std::f64::consts::TAU / (nz * nphi) as f64;
    let (integral, want) = (integral * cell, irradiance * cell / std::f64::consts::PI);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(21);
    let n = 200_000;
    let (mut drawn, mut right, mut wrong) = (0usize, Vec::new(), Vec::new());
    for _ in 0..n {
        let u = Vec2::new(rng.random(), rng.random());
        let (a, b) = match q.sample_at(&env, &CosineSampler, &frame, wo2, u) {
            Some(d) => {
                assert!(d.wi.z > 0.0);
                assert_eq!(d.pdf, q.pdf_at(&env, &CosineSampler, &frame, wo2, d.wi));
                assert_eq!(d.brdf_pdf, CosineSampler.pdf(wo2, d.wi));
                drawn += 1;
                let g = map.radiance(frame.to_world(d.wi)).x as f64 * d.wi.z as f64
                    / std::f64::consts::PI;
                let own = q.pdf(&env, &CosineSampler, d.wi) as f64;
                (g / d.pdf as f64, if own > 0.0 { g / own } else { 0.0 })
            }
            None => (0.0, 0.0),
        };
        right.push(a);
        wrong.push(b);
    }
    let share = drawn as f64 / n as f64;
    assert!(integral <= 1.0 + 2e-3, "{integral}");
    assert!(
        (integral - share).abs() < 5e-3,
        "{integral} against {share}"
    );
    let z = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
        (m - want) / (var / v.len() as f64).sqrt()
    };
    let (z_right, z_wrong) = (z(&right), z(&wrong));
    assert!(z_right.abs() < 4.0, "z {z_right}");
    assert!(z_wrong.abs() > 4.0, "the query's own frame: z {z_wrong}");
}
