//! A fixed workload for `valgrind --tool=callgrind`, whose instruction
//! counts are repeatable whatever the machine's load: the uniform,
//! `adaptive:dp` and `outgoing:chi2` samplers on the built-in nickel at the
//! isotropic resolution, `sample` and `pdf` one call at a time (wo changing
//! every call) and the batch forms (`sample_batch`, `sample_each`, and for
//! `outgoing:chi2` also `pdf_batch` and `pdf_each`), 10^5 each.
//!
//! ```text
//! cargo build --release -p acdf-conformance --example instruction_count
//! valgrind --tool=callgrind --toggle-collect=workload_uniform_sample \
//!     target/release/examples/instruction_count
//! ```
//! (one `--toggle-collect=workload_*` per workload below).

use acdf_core::{BxdfSample, BxdfSampler, Vec2, Vec3};
use acdf_tabulated::Resolution;
use acdf_uniform::{PiecewiseConstantBuilder, UniformBrdfSampler};
use std::hint::black_box;

const N: usize = 100_000;

fn inputs() -> (Vec<Vec3>, Vec<Vec2>) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let wo = (0..N)
        .map(|_| {
            let (t, p) = (next() * 1.5, next() * std::f32::consts::TAU);
            Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
        })
        .collect();
    let u = (0..N).map(|_| Vec2::new(next(), next())).collect();
    (wo, u)
}

#[no_mangle]
#[inline(never)]
pub fn workload_uniform_sample(s: &dyn BxdfSampler, wo: &[Vec3], u: &[Vec2]) -> f32 {
    wo.iter()
        .zip(u)
        .map(|(&wo, &u)| s.sample(wo, u).map_or(0.0, |x| x.pdf))
        .sum()
}

#[no_mangle]
#[inline(never)]
pub fn workload_uniform_pdf(s: &dyn BxdfSampler, wo: &[Vec3], wi: &[Vec3]) -> f32 {
    wo.iter().zip(wi).map(|(&wo, &wi)| s.pdf(wo, wi)).sum()
}

#[no_mangle]
#[inline(never)]
pub fn workload_adaptive_sample(s: &dyn BxdfSampler, wo: &[Vec3], u: &[Vec2]) -> f32 {
    // A different sum, so that the linker does not fold this workload
    // into the uniform one.
    wo.iter()
        .zip(u)
        .map(|(&wo, &u)| s.sample(wo, u).map_or(1.0, |x| x.wi.z))
        .sum()
}

#[no_mangle]
#[inline(never)]
pub fn workload_uniform_batch(
    s: &dyn BxdfSampler,
    wo: Vec3,
    u: &[Vec2],
    out: &mut [Option<BxdfSample>],
) {
    s.sample_batch(wo, u, out);
}

#[no_mangle]
#[inline(never)]
pub fn workload_adaptive_batch(
    s: &dyn BxdfSampler,
    wo: Vec3,
    u: &[Vec2],
    out: &mut [Option<BxdfSample>],
) {
    s.sample_batch(wo, u, out);
    out[0] = None;
}

#[no_mangle]
#[inline(never)]
pub fn workload_uniform_each(
    s: &dyn BxdfSampler,
    wo: &[Vec3],
    u: &[Vec2],
    out: &mut [Option<BxdfSample>],
) {
    s.sample_each(wo, u, out);
}

#[no_mangle]
#[inline(never)]
pub fn workload_adaptive_each(
    s: &dyn BxdfSampler,
    wo: &[Vec3],
    u: &[Vec2],
    out: &mut [Option<BxdfSample>],
) {
    s.sample_each(wo, u, out);
    out[0] = None;
}

#[no_mangle]
#[inline(never)]
pub fn workload_outgoing_sample(s: &dyn BxdfSampler, wo: &[Vec3], u: &[Vec2]) -> f32 {
    wo.iter()
        .zip(u)
        .map(|(&wo, &u)| s.sample(wo, u).map_or(2.0, |x| x.wi.x))
        .sum()
}

#[no_mangle]
#[inline(never)]
pub fn workload_outgoing_pdf(s: &dyn BxdfSampler, wo: &[Vec3], wi: &[Vec3]) -> f32 {
    wo.iter()
        .zip(wi)
        .map(|(&wo, &wi)| s.pdf(wo, wi) + 1.0)
        .sum()
}

#[no_mangle]
#[inline(never)]
pub fn workload_outgoing_batch(
    s: &dyn BxdfSampler,
    wo: Vec3,
    u: &[Vec2],
    out: &mut [Option<BxdfSample>],
) {
    s.sample_batch(wo, u, out);
    out[1] = None;
}

#[no_mangle]
#[inline(never)]
pub fn workload_outgoing_each(
    s: &dyn BxdfSampler,
    wo: &[Vec3],
    u: &[Vec2],
    out: &mut [Option<BxdfSample>],
) {
    s.sample_each(wo, u, out);
    out[1] = None;
}

#[no_mangle]
#[inline(never)]
pub fn workload_outgoing_pdf_batch(s: &dyn BxdfSampler, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
    s.pdf_batch(wo, wi, out);
}

#[no_mangle]
#[inline(never)]
pub fn workload_outgoing_pdf_each(s: &dyn BxdfSampler, wo: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
    s.pdf_each(wo, wi, out);
    out[1] = 0.0;
}

fn main() {
    let nickel = acdf_materials::builtin("nickel").expect("built-in nickel");
    let uniform = UniformBrdfSampler::new(
        nickel.clone(),
        Resolution::ISOTROPIC,
        PiecewiseConstantBuilder,
    )
    .expect("sampler");
    let builder = acdf_outgoing::OutgoingBuilder::by_name("chi2", None, 64).expect("builder");
    let outgoing =
        acdf_outgoing::OutgoingSampler::new(nickel.clone(), Resolution::ISOTROPIC, builder)
            .expect("sampler");
    let adaptive = acdf_adaptive::adaptive_sampler(nickel, Resolution::ISOTROPIC, "dp", None)
        .expect("sampler");
    uniform.build_all().expect("slices");
    adaptive.build_all().expect("slices");
    let (wo, u) = inputs();
    let wi: Vec<Vec3> = wo
        .iter()
        .zip(&u)
        .map(|(&wo, &u)| uniform.sample(wo, u).map_or(Vec3::Z, |s| s.wi))
        .collect();
    let mut out = vec![None; N];
    let mut total = 0.0;
    total += workload_uniform_sample(black_box(&uniform), &wo, &u);
    total += workload_uniform_pdf(black_box(&uniform), &wo, &wi);
    total += workload_adaptive_sample(black_box(&adaptive), &wo, &u);
    let wo_one = Vec3::new(0.3, 0.2, 0.932_737_9);
    workload_uniform_batch(black_box(&uniform), wo_one, &u, &mut out);
    total += out.iter().flatten().map(|s| s.pdf).sum::<f32>();
    workload_adaptive_batch(black_box(&adaptive), wo_one, &u, &mut out);
    total += out.iter().flatten().map(|s| s.pdf).sum::<f32>();
    workload_uniform_each(black_box(&uniform), &wo, &u, &mut out);
    total += out.iter().flatten().map(|s| s.pdf).sum::<f32>();
    workload_adaptive_each(black_box(&adaptive), &wo, &u, &mut out);
    total += out.iter().flatten().map(|s| s.pdf).sum::<f32>();
    total += workload_outgoing_sample(black_box(&outgoing), &wo, &u);
    total += workload_outgoing_pdf(black_box(&outgoing), &wo, &wi);
    workload_outgoing_batch(black_box(&outgoing), wo_one, &u, &mut out);
    total += out.iter().flatten().map(|s| s.pdf).sum::<f32>();
    workload_outgoing_each(black_box(&outgoing), &wo, &u, &mut out);
    total += out.iter().flatten().map(|s| s.pdf).sum::<f32>();
    let mut densities = vec![0.0; N];
    workload_outgoing_pdf_batch(black_box(&outgoing), wo_one, &wi, &mut densities);
    total += densities.iter().sum::<f32>();
    workload_outgoing_pdf_each(black_box(&outgoing), &wo, &wi, &mut densities);
    total += densities.iter().sum::<f32>();
    println!("{total:e}");
}
