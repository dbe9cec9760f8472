//! A driver for instruction counts of a sampler's hot paths, which are
//! repeatable on a loaded machine where timings are not.
//!
//! `hotpath build SAMPLER MATERIAL FILE` builds a sampler (default
//! options) and saves it, so that the profiled run does not build;
//! `hotpath run FILE N [pdf|batch|each|all]` loads it and makes N calls
//! of `sample`, one per (wo, u) with wo cycling through the 64 outgoing
//! directions of `acdf bench`, then (`pdf`, `all`) `pdf` of every draw,
//! then (`batch`, `all`) `sample_batch` and `pdf_batch` for one wo in
//! chunks of 4096, then (`each`, `all`) `sample_each` of the same pairs
//! and `pdf_each` of the draws, in chunks of 4096. Each runs in a function
//! of its own (`hot_sample`, `hot_pdf`, `hot_batch`, `hot_pdf_batch`,
//! `hot_each`, `hot_pdf_each`) for callgrind to count:
//!
//! ```sh
//! cargo build --release -p acdf --example hotpath
//! target/release/examples/hotpath build outgoing:chi2 builtin:nickel o.acdfs
//! valgrind --tool=callgrind --toggle-collect='*hot_*' \
//!   target/release/examples/hotpath run o.acdfs 200000
//! callgrind_annotate --inclusive=yes callgrind.out.*
//! ```
use acdf::material::load_material;
use acdf::registry::{load_sampler, make_sampler, save_sampler, SamplerOps, SamplerOptions};
use acdf::spec::MaterialSpec;
use acdf_core::geometry::spherical_direction;
use acdf_core::{BxdfSampler, Vec2, Vec3};
use rand::{Rng, SeedableRng};

/// `sample` for each pair, the draws kept.
#[inline(never)]
fn hot_sample<S: BxdfSampler>(s: &S, wos: &[Vec3], u: &[Vec2], out: &mut Vec<(Vec3, Vec3)>) {
    for (&wo, &u) in wos.iter().zip(u) {
        if let Some(d) = s.sample(wo, u) {
            out.push((wo, d.wi));
        }
    }
}

/// `pdf` of each pair, summed.
#[inline(never)]
fn hot_pdf<S: BxdfSampler>(s: &S, pairs: &[(Vec3, Vec3)]) -> f32 {
    let mut t = 0.0;
    for &(wo, wi) in pairs {
        t += s.pdf(wo, wi);
    }
    t
}

/// `sample_batch` for one wo.
#[inline(never)]
fn hot_batch<S: BxdfSampler>(
    s: &S,
    wo: Vec3,
    u: &[Vec2],
    out: &mut [Option<acdf_core::BxdfSample>],
) {
    for (uc, oc) in u.chunks(4096).zip(out.chunks_mut(4096)) {
        s.sample_batch(wo, uc, oc);
    }
}

/// `pdf_batch` for one wo.
#[inline(never)]
fn hot_pdf_batch<S: BxdfSampler>(s: &S, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
    for (ic, oc) in wi.chunks(4096).zip(out.chunks_mut(4096)) {
        s.pdf_batch(wo, ic, oc);
    }
}

/// `sample_each` of the pairs, in chunks of 4096.
#[inline(never)]
fn hot_each<S: BxdfSampler>(
    s: &S,
    wos: &[Vec3],
    u: &[Vec2],
    out: &mut [Option<acdf_core::BxdfSample>],
) {
    for ((wc, uc), oc) in wos
        .chunks(4096)
        .zip(u.chunks(4096))
        .zip(out.chunks_mut(4096))
    {
        s.sample_each(wc, uc, oc);
    }
}

/// `pdf_each` of the pairs, in chunks of 4096.
#[inline(never)]
fn hot_pdf_each<S: BxdfSampler>(s: &S, wos: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
    for ((wc, ic), oc) in wos
        .chunks(4096)
        .zip(wi.chunks(4096))
        .zip(out.chunks_mut(4096))
    {
        s.pdf_each(wc, ic, oc);
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    match args[1].as_str() {
        "build" => {
            let spec: MaterialSpec = args[3].parse().unwrap();
            let material = load_material(&spec, None).unwrap();
            let s = make_sampler(&args[2], &material, &SamplerOptions::default()).unwrap();
            s.build_all().unwrap();
            save_sampler(&s, std::path::Path::new(&args[4])).unwrap();
        }
        "run" => {
            let s = load_sampler(std::path::Path::new(&args[2])).unwrap();
            let n: usize = args[3].parse().unwrap();
            let what = args.get(4).map(String::as_str).unwrap_or("all");
            let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
            let u: Vec<Vec2> = (0..n)
                .map(|_| Vec2::new(rng.random(), rng.random()))
                .collect();
            let dirs: Vec<Vec3> = (0..64)
                .map(|k| {
                    let t = (k as f32 + 0.5) / 64.0;
                    spherical_direction(
                        (5.0 + 75.0 * t).to_radians(),
                        std::f32::consts::TAU * (k as f32 * 0.618_034).fract(),
                    )
                })
                .collect();
            let wos: Vec<Vec3> = (0..n).map(|k| dirs[k % 64]).collect();
            let mut pairs = Vec::with_capacity(n);
            hot_sample(&s, &wos, &u, &mut pairs);
            if what == "all" || what == "pdf" {
                println!("pdf sum {}", hot_pdf(&s, &pairs));
            }
            if what == "all" || what == "batch" {
                let wo = spherical_direction(0.6, 1.3);
                let mut out = vec![None; n];
                hot_batch(&s, wo, &u, &mut out);
                let wi: Vec<Vec3> = out.iter().flatten().map(|d| d.wi).collect();
                let mut dens = vec![0.0; wi.len()];
                hot_pdf_batch(&s, wo, &wi, &mut dens);
                println!("batch sum {}", dens.iter().sum::<f32>());
            }
            if what == "all" || what == "each" {
                let mut out = vec![None; n];
                hot_each(&s, &wos, &u, &mut out);
                let (wo, wi): (Vec<Vec3>, Vec<Vec3>) = pairs.iter().copied().unzip();
                let mut dens = vec![0.0; wi.len()];
                hot_pdf_each(&s, &wo, &wi, &mut dens);
                println!("each sum {}", dens.iter().sum::<f32>());
            }
            println!("{} draws", pairs.len());
        }
        _ => panic!(
            "usage: hotpath build SAMPLER MATERIAL FILE | hotpath run FILE N [pdf|batch|each|all]"
        ),
    }
}
