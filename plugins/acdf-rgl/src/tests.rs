//! Tests of the RGL sampler: the acdf contract, sample/pdf consistency, and
//! the Mitsuba 3 reference pdfs and albedos when the shared data is present.

use super::*;
use acdf_core::geometry::spherical_direction;
use acdf_core::Brdf;
use acdf_materials::rgl::{write_tensor_file, Dtype, TensorFile};
use rand::{Rng, SeedableRng};
use std::path::Path;

use acdf_materials::rgl::{shared_dir as rgl_dir, SHARED_FILES as FILES};

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A small smooth isotropic material: 3 θ_i slices, 9 × 9 vndf peaked
/// towards the mirror direction, 6 × 6 luminance and RGB.
fn synthetic() -> Arc<RglBrdf> {
    synthetic_with(1)
}

/// The same with `np` φ_i slices (anisotropic for np > 2).
fn synthetic_with(np: usize) -> Arc<RglBrdf> {
    let (nt, vn, n) = (3usize, 9usize, 6usize);
    let mut vndf = Vec::new();
    for t in 0..np * nt {
        for j in 0..vn {
            for i in 0..vn {
                let x = i as f32 / (vn - 1) as f32;
                let y = j as f32 / (vn - 1) as f32;
                vndf.push(
                    x * (-(x - 0.3).powi(2) * 8.0).exp() * (1.2 + (6.0 * y + t as f32).sin()),
                );
            }
        }
    }
    let lum: Vec<f32> = (0..np * nt * n * n)
        .map(|k| 0.3 + ((k * 37 % 11) as f32) / 10.0)
        .collect();
    let rgb: Vec<f32> = (0..np * nt * 3 * n * n)
        .map(|k| 0.2 + ((k * 13 % 7) as f32) / 10.0)
        .collect();
    let sigma: Vec<f32> = (0..10).map(|i| 1.0 + 0.05 * (i % 5) as f32).collect();
    let ndf: Vec<f32> = (0..10).map(|i| 1.5 - 0.2 * (i % 5) as f32).collect();
    let phi: Vec<f32> = (0..np)
        .map(|k| -3.0 + 6.0 * k as f32 / (np.max(2) - 1) as f32)
        .collect();
    let bytes = write_tensor_file(&[
        ("phi_i", Dtype::F32, &[np], &f32_bytes(&phi)),
        (
            "theta_i",
            Dtype::F32,
            &[nt],
            &f32_bytes(&[0.0, 0.8, 1.5707964]),
        ),
        ("sigma", Dtype::F32, &[2, 5], &f32_bytes(&sigma)),
        ("ndf", Dtype::F32, &[2, 5], &f32_bytes(&ndf)),
        ("vndf", Dtype::F32, &[np, nt, vn, vn], &f32_bytes(&vndf)),
        ("luminance", Dtype::F32, &[np, nt, n, n], &f32_bytes(&lum)),
        ("rgb", Dtype::F32, &[np, nt, 3, n, n], &f32_bytes(&rgb)),
    ]);
    let file = TensorFile::from_bytes(&bytes).unwrap();
    Arc::new(RglBrdf::from_tensor(&file, "synthetic").unwrap())
}

fn dir(theta_deg: f64, phi_deg: f64) -> Vec3 {
    spherical_direction(theta_deg.to_radians() as f32, phi_deg.to_radians() as f32)
}

fn open(name: &str) -> Option<Arc<RglBrdf>> {
    let d = rgl_dir()?;
    Some(Arc::new(
        RglBrdf::open(d.join(format!("{name}.bsdf"))).unwrap(),
    ))
}

/// Every sample has a unit wi above the horizon and a finite pdf > 0 that
/// pdf(wo, wi) reproduces to 1e-3 relative.
fn check_consistency(sampler: &RglSampler, wos: &[Vec3], n: usize, seed: u64) -> f64 {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut worst = 0.0f64;
    for &wo in wos {
        for _ in 0..n {
            let u = Vec2::new(rng.random(), rng.random());
            let Some(s) = sampler.sample(wo, u) else {
                continue;
            };
            assert!(s.wi.z > 0.0 && (s.wi.length() - 1.0).abs() < 1e-5);
            assert!(s.pdf.is_finite() && s.pdf > 0.0);
            let p = sampler.pdf(wo, s.wi);
            let rel = ((p - s.pdf) / s.pdf).abs() as f64;
            worst = worst.max(rel);
            assert!(rel < 1e-3, "wo {wo} u {u}: sample pdf {} vs pdf {p}", s.pdf);
        }
    }
    worst
}

#[test]
fn synthetic_sample_and_pdf_agree() {
    let s = RglSampler::new(synthetic());
    let wos = [
        dir(0.0, 0.0),
        dir(1e-3, 40.0),
        dir(30.0, 10.0),
        dir(60.0, 200.0),
        dir(89.0, 300.0),
    ];
    check_consistency(&s, &wos, 20_000, 1);
}

/// An anisotropic file (3 φ_i slices, blended over φ_i as well): samples
/// carry the pdf that `pdf` reports, and the pdf integrates to the accepted
/// fraction (midpoint rule, as in `pdf_mass_equals_acceptance_rate`).
#[test]
fn anisotropic_sample_and_pdf_agree() {
    let brdf = synthetic_with(3);
    assert!(!brdf.is_isotropic());
    let s = RglSampler::new(brdf);
    let wos = [dir(10.0, 20.0), dir(50.0, 100.0), dir(75.0, 250.0)];
    check_consistency(&s, &wos, 5_000, 9);
    pdf_mass_check(&s, &wos[1..], 10);
}

#[test]
fn real_sample_and_pdf_agree() {
    let Some(dir0) = rgl_dir() else {
        acdf_materials::testing::skip_without_data(
            "shared RGL data not found (set ACDF_SHARED_DATA)",
        );
        return;
    };
    let _ = dir0;
    let wos = [
        dir(0.5, 0.0),
        dir(30.0, 10.0),
        dir(60.0, 200.0),
        dir(85.0, 300.0),
    ];
    for name in FILES {
        let s = RglSampler::new(open(name).unwrap());
        let worst = check_consistency(&s, &wos, 5_000, 2);
        println!("{name}: worst relative sample-pdf/pdf gap {worst:.1e}");
    }
}

/// The contract for invalid input: `None` / 0 for wo at or below the
/// horizon or not finite, pdf 0 for wi below, and u outside [0, 1) usable.
#[test]
fn invalid_input_is_handled() {
    let s = RglSampler::new(synthetic());
    let u = Vec2::new(0.3, 0.6);
    for wo in [
        Vec3::new(1.0, 0.0, 0.0),
        -Vec3::Z,
        Vec3::splat(f32::NAN),
        dir(100.0, 0.0),
    ] {
        assert!(s.sample(wo, u).is_none());
        assert_eq!(s.pdf(wo, Vec3::Z), 0.0);
    }
    let wo = dir(30.0, 0.0);
    assert_eq!(s.pdf(wo, -Vec3::Z), 0.0);
    assert_eq!(s.pdf(wo, Vec3::new(1.0, 0.0, 0.0)), 0.0);
    assert_eq!(s.pdf(wo, Vec3::splat(f32::NAN)), 0.0);
    for u in [
        Vec2::new(f32::NAN, 0.5),
        Vec2::new(-3.0, 7.0),
        Vec2::ONE,
        Vec2::ZERO,
        Vec2::splat(f32::INFINITY),
    ] {
        if let Some(x) = s.sample(wo, u) {
            assert!(x.wi.is_finite() && x.pdf.is_finite() && x.pdf > 0.0);
        }
    }
    assert_eq!(s.name(), "rgl");
    assert!(s.storage_bytes() > 0);
}

/// The pdf integrates to the probability that a draw is not rejected:
/// midpoint rule over (cos θ, φ) with 400 × 400 cells against the accepted
/// fraction of 200k draws (binomial standard error below 1.2e-3; the
/// tolerance 6e-3 also covers the quadrature error).
#[test]
fn pdf_mass_equals_acceptance_rate() {
    let s = RglSampler::new(synthetic());
    pdf_mass_check(&s, &[dir(20.0, 0.0), dir(70.0, 120.0)], 3);
}

fn pdf_mass_check(s: &RglSampler, wos: &[Vec3], seed: u64) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    for &wo in wos {
        let n = 400;
        let mut mass = 0.0f64;
        for a in 0..n {
            let z = (a as f64 + 0.5) / n as f64;
            let theta = z.acos();
            for b in 0..n {
                let phi = (b as f64 + 0.5) / n as f64 * std::f64::consts::TAU;
                let wi = spherical_direction(theta as f32, phi as f32);
                mass += s.pdf_f64(wo, wi);
            }
        }
        mass *= std::f64::consts::TAU / (n * n) as f64;
        let draws = 200_000;
        let accepted = (0..draws)
            .filter(|_| {
                s.sample(wo, Vec2::new(rng.random(), rng.random()))
                    .is_some()
            })
            .count() as f64
            / draws as f64;
        assert!(mass <= 1.0 + 6e-3);
        assert!(
            (mass - accepted).abs() < 6e-3,
            "wo {wo}: mass {mass} accepted {accepted}"
        );
    }
}

/// Histogram of 400k draws over 8 (cos θ) × 16 (φ) bins against the pdf
/// integrated over each bin (16 × 16 midpoints per bin): chi-square with at
/// most 127 degrees of freedom below 190 (significance about 2e-4).
#[test]
fn samples_follow_the_pdf() {
    let s = RglSampler::new(synthetic());
    let wo = dir(40.0, 30.0);
    let (nz, np, sub, n) = (8usize, 16usize, 16usize, 400_000usize);
    let mut hist = vec![0f64; nz * np];
    let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
    for _ in 0..n {
        if let Some(x) = s.sample(wo, Vec2::new(rng.random(), rng.random())) {
            let a = ((x.wi.z as f64 * nz as f64) as usize).min(nz - 1);
            let phi = acdf_core::geometry::phi(x.wi) as f64;
            let b = ((phi / std::f64::consts::TAU * np as f64) as usize).min(np - 1);
            hist[a * np + b] += 1.0;
        }
    }
    let mut chi2 = 0.0;
    let mut dof = 0;
    for a in 0..nz {
        for b in 0..np {
            let mut mass = 0.0;
            for i in 0..sub {
                let z = (a as f64 + (i as f64 + 0.5) / sub as f64) / nz as f64;
                for j in 0..sub {
                    let phi = (b as f64 + (j as f64 + 0.5) / sub as f64) / np as f64
                        * std::f64::consts::TAU;
                    let wi = spherical_direction(z.acos() as f32, phi as f32);
                    mass += s.pdf_f64(wo, wi);
                }
            }
            let expected = mass * std::f64::consts::TAU / (nz * np * sub * sub) as f64 * n as f64;
            if expected > 5.0 {
                chi2 += (hist[a * np + b] - expected).powi(2) / expected;
                dof += 1;
            }
        }
    }
    assert!(dof > 60, "too few populated bins: {dof}");
    assert!(chi2 < 190.0, "chi2 = {chi2} over {dof} bins");
}

/// pdf of the built-in sampler against Mitsuba 3 on the reference pairs:
/// relative 1e-3 for every file (chm_mint included: it is within 8e-6)
/// plus absolute 1e-6; the pairs at
/// θ_m = 0 have pdf exactly 0 in both.
///
/// The exact mirror pairs (θ_m ≈ 3.5e-17 in f64) are special: there the
/// density grows like sqrt(θ_m), and Mitsuba's f32 half vector lands one ulp
/// off the pole at 30° (cos θ_m = 1 − 2^-24, θ_m = 2^-24 ≈ 6e-8), which makes
/// its pdf 41,000 times the f64 value (0.113 instead of 2.75e-6 for the
/// felt). Such rows are checked at the pair whose half vector has that
/// θ_m (same φ_m), which reproduces Mitsuba to the same tolerance; rows where
/// Mitsuba's f32 half vector stayed on the pole match as they are.
#[test]
fn reference_pdf_matches_mitsuba() {
    let Some(dir) = rgl_dir() else {
        acdf_materials::testing::skip_without_data(
            "shared RGL data not found (set ACDF_SHARED_DATA)",
        );
        return;
    };
    let text = std::fs::read_to_string(dir.join("reference_eval_mitsuba3.csv")).unwrap();
    let mut worst = 0.0f64;
    let mut rows = 0;
    for name in FILES {
        let s = RglSampler::new(open(name).unwrap());
        let rtol = 1e-3;
        let mut worst_file = 0.0f64;
        for line in text.lines().skip(1).filter(|l| l.starts_with(name)) {
            let c: Vec<f64> = line
                .split(',')
                .skip(1)
                .map(|x| x.parse().unwrap())
                .collect();
            let v = |k: usize| Vec3::new(c[k] as f32, c[k + 1] as f32, c[k + 2] as f32);
            let (wo, wi, want) = (v(4), v(7), c[13]);
            let mut got = s.pdf_f64(wo, wi);
            let wm = (wo + wi).normalize();
            let mirror = acdf_core::geometry::sin_theta(wm) < 1e-9 && wm.z < 1.0 + 1e-9;
            if mirror && (got - want).abs() > rtol * want + 1e-6 {
                // θ_m = 2^-24 towards φ_m = atan2(wm.y, wm.x), as Mitsuba's f32 did.
                let theta_m = 2f64.powi(-24);
                let phi_m = (wm.y as f64).atan2(wm.x as f64);
                let m = glam::DVec3::new(
                    theta_m.sin() * phi_m.cos(),
                    theta_m.sin() * phi_m.sin(),
                    theta_m.cos(),
                );
                let w = wo.as_dvec3();
                let wi2 = (2.0 * w.dot(m) * m - w).as_vec3();
                got = s.pdf_f64(wo, wi2);
                println!("{name} wo {wo}: mirror pair checked at theta_m = 2^-24: {got:.6e} vs {want:.6e}");
            }
            assert!(
                (got - want).abs() <= rtol * want + 1e-6,
                "{name} wo {wo} wi {wi}: pdf {got} want {want}"
            );
            if want > 0.0 {
                worst_file = worst_file.max((got - want).abs() / want);
            } else {
                assert_eq!(got, 0.0);
            }
            rows += 1;
        }
        println!("{name}: worst relative pdf error {worst_file:.2e}");
        worst = worst.max(worst_file);
    }
    assert_eq!(rows, 70);
    println!("worst relative pdf error against Mitsuba 3: {worst:.2e}");
}

/// One row of `reference_albedo_mitsuba3.csv`.
struct AlbedoRow {
    file: String,
    theta_deg: f64,
    albedo: [f64; 3],
    stderr_g: f64,
    n: f64,
    mass: f64,
}

/// Directional albedo ∫ f_r cos dω of the unclipped data (as Mitsuba
/// reports it), estimated with 2^18 draws of our sampler per angle (seeded),
/// against Mitsuba's 2^20-draw estimate. Green, whose reference standard
/// error is in the CSV, must lie within 3 combined standard errors. For red
/// and blue the reference error is estimated as ours scaled by
/// sqrt(2^18 / 2^20) (the same estimator with 4× the draws), and the bound is
/// 3.85 combined standard errors: Bonferroni over all 84 comparisons at a
/// family-wise significance of 1%.
///
/// The accepted fraction is printed, not asserted: it equals the quadrature
/// of our pdf over the upper hemisphere (see `pdf_mass_equals_acceptance_rate`)
/// and our pdf matches Mitsuba's pointwise, yet the CSV's
/// `pdf_mass_above_horizon` is 1.00000 where ours is 0.996 (felt, 0°) down to
/// 0.914 (chm_mint, 0°). The albedos agree, so the difference is in what the
/// reference counted as rejected (most likely draws below the horizon that
/// got weight 0 but were not flagged), not in the distribution.
#[test]
fn reference_albedo_matches_mitsuba() {
    let Some(dir) = rgl_dir() else {
        acdf_materials::testing::skip_without_data(
            "shared RGL data not found (set ACDF_SHARED_DATA)",
        );
        return;
    };
    let text = std::fs::read_to_string(dir.join("reference_albedo_mitsuba3.csv")).unwrap();
    let rows: Vec<AlbedoRow> = text
        .lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            let f = |k: usize| c[k].trim().parse::<f64>().unwrap();
            AlbedoRow {
                file: c[0].to_string(),
                theta_deg: f(1),
                n: f(2),
                albedo: [f(3), f(4), f(5)],
                stderr_g: f(6),
                mass: f(8),
            }
        })
        .collect();
    assert_eq!(rows.len(), 28);
    let n = 1usize << 18;
    let dir = dir.as_path();
    let results: Vec<String> = std::thread::scope(|scope| {
        let handles: Vec<_> = rows
            .chunks(8)
            .map(|chunk| {
                scope.spawn(move || {
                    let mut out = Vec::new();
                    for row in chunk {
                        out.push(albedo_check(dir, row, n));
                    }
                    out
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    for r in results {
        println!("{r}");
    }
}

fn albedo_check(dir: &Path, row: &AlbedoRow, n: usize) -> String {
    let brdf = Arc::new(RglBrdf::open(dir.join(&row.file)).unwrap());
    let s = RglSampler::new(brdf.clone());
    let wo = dir_f64(row.theta_deg);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(0x5eed ^ row.theta_deg as u64);
    let (mut sum, mut sum2) = ([0f64; 3], [0f64; 3]);
    let mut accepted = 0usize;
    for _ in 0..n {
        let Some(x) = s.sample(wo, Vec2::new(rng.random(), rng.random())) else {
            continue;
        };
        accepted += 1;
        let w = brdf.fr_cos_unclipped(wo, x.wi) / x.pdf as f64;
        assert!(w.is_finite());
        for c in 0..3 {
            sum[c] += w[c];
            sum2[c] += w[c] * w[c];
        }
    }
    let nf = n as f64;
    let mut report = format!("{} {:>2}°:", row.file, row.theta_deg);
    let mut se_ours = [0f64; 3];
    for c in 0..3 {
        let mean = sum[c] / nf;
        se_ours[c] = ((sum2[c] / nf - mean * mean).max(0.0) / (nf - 1.0)).sqrt();
    }
    for c in 0..3 {
        let mean = sum[c] / nf;
        let se_ref = if c == 1 {
            row.stderr_g
        } else {
            se_ours[c] * (nf / row.n).sqrt()
        };
        let combined = (se_ours[c].powi(2) + se_ref.powi(2)).sqrt();
        let z = (mean - row.albedo[c]) / combined;
        report += &format!(" {:.5} (ref {:.5}, z {:+.2})", mean, row.albedo[c], z);
        let bound = if c == 1 { 3.0 } else { 3.85 };
        assert!(
            z.abs() <= bound,
            "{} at {}°: channel {c} albedo {mean} vs {} (combined se {combined})",
            row.file,
            row.theta_deg,
            row.albedo[c]
        );
    }
    let frac = accepted as f64 / nf;
    report += &format!(" accepted {frac:.5} (ref {:.5})", row.mass);
    report
}

/// The reference CSV puts ω_i at azimuth 0.
fn dir_f64(theta_deg: f64) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin() as f32, 0.0, t.cos() as f32)
}

/// The material's unclipped f_r and the clipped `Brdf::eval` differ only
/// where a channel is negative.
#[test]
fn sampler_weights_are_finite_for_the_clipped_brdf() {
    let Some(brdf) = open("chm_mint_rgb") else {
        acdf_materials::testing::skip_without_data(
            "shared RGL data not found (set ACDF_SHARED_DATA)",
        );
        return;
    };
    let s = RglSampler::new(brdf.clone());
    let mut rng = rand_pcg::Pcg64::seed_from_u64(6);
    for wo in [dir(0.0, 0.0), dir(45.0, 0.0), dir(80.0, 90.0)] {
        for _ in 0..20_000 {
            if let Some(x) = s.sample(wo, Vec2::new(rng.random(), rng.random())) {
                let w = brdf.eval(wo, x.wi) * x.wi.z / x.pdf;
                assert!(w.is_finite() && w.min_element() >= 0.0);
            }
        }
    }
}
