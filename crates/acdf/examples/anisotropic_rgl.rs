//! Write an anisotropic RGL `.bsdf` file: an anisotropic GGX microfacet
//! lobe in the RGL `tensor_file` layout, for measuring samplers on an
//! anisotropic material from the command line (the shared data has no
//! anisotropic RGL file).
//!
//! ```sh
//! cargo run -p acdf --release --example anisotropic_rgl -- target/aniso-ggx.bsdf [ALPHA_X ALPHA_Y]
//! acdf report --material target/aniso-ggx.bsdf --sampler outgoing:chi2 ...
//! ```
//!
//! The file's NDF is D(m) of GGX with roughness α_x (0.1 unless given)
//! along x and α_y (0.3 unless given) along y, tabulated over absolute (u_θ, u_φ) on 64 × 64 points;
//! σ(ω) = ∫ D(m) max(0, ω·m) dω_m (the projected area, by the midpoint rule
//! on 512 × 512 cells of m) on 16 × 16 points of (u_θ, u_φ) of ω; the
//! visible-normal density and the luminance are uniform and the RGB a
//! constant 0.8, so that f_r cos θ_i = 0.8 D(m) / (4 σ(wo)): a lobe without
//! shadowing or Fresnel, anisotropic through D alone. Three φ_i slices mark
//! the file as anisotropic.

use acdf_materials::rgl::{write_tensor_file, Dtype, TensorFile};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// The GGX density of normals of roughness (α_x, α_y) at (θ, φ), per
/// solid angle.
fn ggx((alpha_x, alpha_y): (f64, f64), theta: f64, phi: f64) -> f64 {
    let (s, c) = theta.sin_cos();
    let k = (phi.cos() / alpha_x).powi(2) + (phi.sin() / alpha_y).powi(2);
    let q = c * c + s * s * k;
    1.0 / (PI * alpha_x * alpha_y * q * q)
}

/// (θ, φ) of square coordinates u_θ = sqrt(2θ/π), u_φ = (φ + π) / 2π.
fn angles(u_theta: f64, u_phi: f64) -> (f64, f64) {
    (u_theta * u_theta * FRAC_PI_2, TAU * u_phi - PI)
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .cloned()
        .unwrap_or_else(|| "aniso-ggx.bsdf".to_string());
    let alpha = |i: usize, default: f64| {
        args.get(i)
            .map_or(default, |a| a.parse().expect("a roughness"))
    };
    let alphas = (alpha(2, 0.1), alpha(3, 0.3));
    let n = 64;
    let mut ndf = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let (t, p) = angles(i as f64 / (n - 1) as f64, j as f64 / (n - 1) as f64);
            ndf.push(ggx(alphas, t, p) as f32);
        }
    }
    // σ(ω) by the midpoint rule over m: 512 cells in cos θ_m, 512 in φ_m.
    let (mc, mp) = (512, 512);
    let normals: Vec<([f64; 3], f64)> = (0..mc * mp)
        .map(|k| {
            let cos = (k / mp) as f64 / mc as f64 + 0.5 / mc as f64;
            let phi = TAU * ((k % mp) as f64 + 0.5) / mp as f64;
            let sin = (1.0 - cos * cos).sqrt();
            let m = [sin * phi.cos(), sin * phi.sin(), cos];
            (m, ggx(alphas, cos.acos(), phi) * TAU / (mc * mp) as f64)
        })
        .collect();
    let ns = 16;
    let mut sigma = Vec::with_capacity(ns * ns);
    for j in 0..ns {
        for i in 0..ns {
            let (t, p) = angles(i as f64 / (ns - 1) as f64, j as f64 / (ns - 1) as f64);
            let w = [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()];
            let s: f64 = normals
                .iter()
                .map(|(m, d)| d * (w[0] * m[0] + w[1] * m[1] + w[2] * m[2]).max(0.0))
                .sum();
            sigma.push(s.max(1e-6) as f32);
        }
    }
    let (np, nt, nv) = (3usize, 2usize, 2usize);
    let phi_i = [-PI as f32, 0.0, PI as f32];
    let theta_i = [0.0f32, FRAC_PI_2 as f32];
    let ones = vec![1.0f32; np * nt * nv * nv];
    let rgb = vec![0.8f32; np * nt * 3 * nv * nv];
    let bytes = write_tensor_file(&[
        ("phi_i", Dtype::F32, &[np], &f32_bytes(&phi_i)),
        ("theta_i", Dtype::F32, &[nt], &f32_bytes(&theta_i)),
        ("sigma", Dtype::F32, &[ns, ns], &f32_bytes(&sigma)),
        ("ndf", Dtype::F32, &[n, n], &f32_bytes(&ndf)),
        ("vndf", Dtype::F32, &[np, nt, nv, nv], &f32_bytes(&ones)),
        (
            "luminance",
            Dtype::F32,
            &[np, nt, nv, nv],
            &f32_bytes(&ones),
        ),
        ("rgb", Dtype::F32, &[np, nt, 3, nv, nv], &f32_bytes(&rgb)),
    ]);
    TensorFile::from_bytes(&bytes).expect("the file reads back");
    acdf_io::fsio::write_atomic(std::path::Path::new(&path), |w| w.write_all(&bytes))
        .expect("write the file");
    println!("wrote {path} ({} bytes)", bytes.len());
}
