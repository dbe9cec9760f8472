//! A driver for instruction counts of an environment sampler's `sample`,
//! which are repeatable on a loaded machine where timings are not (the
//! environment counterpart of the `hotpath` example).
//!
//! `env_hotpath MAP SAMPLER N RUN [batch]` builds SAMPLER (any name of
//! `acdf env-sample --help`, default options) over the lat-long map MAP,
//! builds the normal cells the normals of `acdf env-report` need, then
//! makes N calls of `sample` in the function `hot_env`, one per uniform
//! pair, the normal cycling through those normals and held for RUN
//! consecutive calls (RUN = 0: no normal, the plain luminance table of an
//! orientation-aware sampler). With `batch`, each run of RUN pairs is one
//! call of `sample_batch` instead, in the function `hot_env_batch`. For
//! callgrind to count:
//!
//! ```sh
//! cargo build --release -p acdf-experiments --example env_hotpath
//! valgrind --tool=callgrind --toggle-collect='*hot_env*' \
//!   target/release/examples/env_hotpath ../shared/data/envmaps/rooitou_park_1k.hdr \
//!   oriented:dp 200000 64
//! callgrind_annotate --inclusive=yes callgrind.out.*
//! ```
use acdf::env_registry::{make_env_sampler, EnvSamplerOptions};
use acdf::lights::EnvMap;
use acdf_core::{SphereSampler, Vec2, Vec3};
use rand::{Rng, SeedableRng};
use std::hint::black_box;
use std::sync::Arc;

/// `sample` for each pair, the normal `normals[(i / run) % len]` (none for
/// `run` = 0); the sum of the densities.
#[inline(never)]
fn hot_env<S: SphereSampler>(s: &S, normals: &[Vec3], u: &[Vec2], run: usize) -> f32 {
    let mut total = 0.0;
    for (i, &u) in u.iter().enumerate() {
        let normal = (run > 0).then(|| normals[(i / run.max(1)) % normals.len()]);
        if let Some(d) = s.sample(black_box(normal), black_box(u)) {
            total += d.pdf;
        }
    }
    total
}

/// `sample_batch` for each run of `run` pairs (at least 1), the normal
/// `normals[k % len]` for the k-th run; the sum of the densities.
#[inline(never)]
fn hot_env_batch<S: SphereSampler>(s: &S, normals: &[Vec3], u: &[Vec2], run: usize) -> f32 {
    let mut out = vec![None; run.max(1)];
    let mut total = 0.0;
    for (k, uc) in u.chunks(run.max(1)).enumerate() {
        let normal = normals[k % normals.len()];
        s.sample_batch(Some(black_box(normal)), black_box(uc), &mut out[..uc.len()]);
        total += out[..uc.len()].iter().flatten().map(|d| d.pdf).sum::<f32>();
    }
    total
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let batch = args.len() == 6 && args[5] == "batch";
    if args.len() != 5 && !batch {
        eprintln!("usage: env_hotpath MAP SAMPLER N RUN [batch]");
        std::process::exit(2);
    }
    let map = match EnvMap::open(std::path::Path::new(&args[1])) {
        Ok(m) => Arc::new(m),
        Err(e) => {
            eprintln!("{}: {e}", args[1]);
            std::process::exit(1);
        }
    };
    let s = match make_env_sampler(&args[2], &map, &EnvSamplerOptions::default()) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{}: {e}", args[2]);
            std::process::exit(1);
        }
    };
    let (Ok(n), Ok(run)) = (args[3].parse::<usize>(), args[4].parse::<usize>()) else {
        eprintln!("N and RUN are counts");
        std::process::exit(2);
    };
    let normals = acdf_experiments::env_report::standard_normals();
    for &normal in &normals {
        s.pdf(Some(normal), Vec3::Z);
    }
    let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
    let u: Vec<Vec2> = (0..n)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .collect();
    let total = if batch {
        hot_env_batch(&s, &normals, &u, run)
    } else {
        hot_env(&s, &normals, &u, run)
    };
    println!("density sum {total}");
}
