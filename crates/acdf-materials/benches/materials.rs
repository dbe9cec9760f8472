//! Speed of the material sources: loading a 35 MB MERL file, `eval` of
//! each kind of BRDF (the samplers call it millions of times), and the
//! luminance of a MERL table over the half-vector rings of one tabulated
//! slice (what building a sampler from a table costs).

use std::hint::black_box;

use acdf_core::geometry::spherical_direction;
use acdf_core::Brdf;
use acdf_core::{Rgb, Vec3};
use acdf_materials::merl::{Interpolation, MerlTable};
use acdf_materials::{analytic, nbrdf};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

fn merl_io(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("nickel-lafortune.binary");
    let table = MerlTable::tabulate(&analytic::nickel());
    table.write(&path).expect("write the table");
    let mut group = c.benchmark_group("merl");
    group.sample_size(10);
    group.bench_function("read 35 MB", |b| {
        b.iter(|| MerlTable::read(black_box(&path)).expect("read back"))
    });
    group.bench_function("write 35 MB", |b| {
        b.iter(|| table.write(black_box(&path)).expect("write"))
    });
    group.bench_function("tabulate nickel (Lafortune)", |b| {
        b.iter(|| MerlTable::tabulate(black_box(&analytic::nickel())))
    });
    group.finish();
}

fn eval(c: &mut Criterion) {
    let wo = spherical_direction(0.6, 0.2);
    let wi = spherical_direction(0.5, 3.0);
    let mut group = c.benchmark_group("eval");
    let lambert = analytic::lambert();
    group.bench_function("lambert", |b| {
        b.iter(|| lambert.eval(black_box(wo), black_box(wi)))
    });
    let nickel = analytic::nickel();
    group.bench_function("lafortune nickel", |b| {
        b.iter(|| nickel.eval(black_box(wo), black_box(wi)))
    });
    let table = MerlTable::tabulate(&nickel);
    for interpolation in [Interpolation::Nearest, Interpolation::Trilinear] {
        let t = table.clone().with_interpolation(interpolation);
        group.bench_function(format!("merl {interpolation:?}"), |b| {
            b.iter(|| t.eval(black_box(wo), black_box(wi)))
        });
    }
    match nbrdf::NbrdfLibrary::load_shared().and_then(|lib| lib.material("nickel")) {
        Ok(net) => {
            group.bench_function("neural nickel", |b| {
                b.iter(|| net.eval(black_box(wo), black_box(wi)))
            });
        }
        Err(e) => println!("skipping the network benchmark: {e}"),
    }
    group.finish();
}

/// A table seen only through `eval`, so that it gets the default
/// `luminance_half_ring` (one `eval` per half vector).
struct EvalOnly<'a>(&'a MerlTable);

impl Brdf for EvalOnly<'_> {
    fn name(&self) -> &str {
        self.0.name()
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.0.eval(wo, wi)
    }
    fn is_isotropic(&self) -> bool {
        true
    }
}

/// The half-vector rings of one slice as the uniform sampler tabulates it at
/// the paper resolution: 256 θ_h cells × 2 sub-rows, θ_h = (π/2) v², and
/// 32 φ_h cells × 2 sub-columns, for the middle θ_o cell (θ_o ≈ 0.418).
fn slice_rings(c: &mut Criterion) {
    let (rows, columns_n) = (2 * 256, 2 * 32);
    let rings: Vec<(f32, f32)> = (0..rows)
        .map(|r| {
            let v = (r as f32 + 0.5) / rows as f32;
            (std::f32::consts::FRAC_PI_2 * v * v).sin_cos()
        })
        .collect();
    let columns: Vec<(f32, f32)> = (0..columns_n)
        .map(|c| {
            let (s, co) = (std::f32::consts::TAU * (c as f32 + 0.5) / columns_n as f32).sin_cos();
            (co, s)
        })
        .collect();
    let theta_o = std::f32::consts::FRAC_PI_2 * (16.5f32 / 32.0).powi(2);
    let wo = spherical_direction(theta_o, 0.0);
    let table = MerlTable::tabulate(&analytic::nickel());
    let mut group = c.benchmark_group("merl_slice_rings");
    group.throughput(Throughput::Elements((rows * columns_n) as u64));
    let mut out = vec![0.0f32; columns_n];
    for interpolation in [Interpolation::Nearest, Interpolation::Trilinear] {
        let t = table.clone().with_interpolation(interpolation);
        group.bench_function(format!("luminance_half_ring {interpolation:?}"), |b| {
            b.iter(|| {
                for &ring in &rings {
                    t.luminance_half_ring(black_box(wo), ring, &columns, &mut out);
                    black_box(&out);
                }
            })
        });
    }
    let eval_only = EvalOnly(&table);
    group.bench_function("eval per half vector Trilinear", |b| {
        b.iter(|| {
            for &ring in &rings {
                eval_only.luminance_half_ring(black_box(wo), ring, &columns, &mut out);
                black_box(&out);
            }
        })
    });
    group.finish();
}

criterion_group!(benches, merl_io, eval, slice_rings);
criterion_main!(benches);
