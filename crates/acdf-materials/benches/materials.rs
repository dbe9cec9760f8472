//! Speed of the material sources: loading a 35 MB MERL file, and `eval` of
//! each kind of BRDF (the samplers call it millions of times).

use std::hint::black_box;

use acdf_core::geometry::spherical_direction;
use acdf_core::Brdf;
use acdf_materials::merl::{Interpolation, MerlTable};
use acdf_materials::{analytic, nbrdf};
use criterion::{criterion_group, criterion_main, Criterion};

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

criterion_group!(benches, merl_io, eval);
criterion_main!(benches);
