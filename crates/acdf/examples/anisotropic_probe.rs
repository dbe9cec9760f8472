//! Where the anisotropic outgoing sampler's variance and bytes go: for a
//! material, the relative variance by quadrature (as `acdf report`
//! computes it: the procedural sky without its sun, 1024 × 512 half-vector
//! cells, at each of the report's 12 outgoing directions) of the
//! 32x16x256x32 uniform table and of the anisotropic outgoing sampler at
//! the default (capped) tolerance and at the tolerances given, with the
//! sampler's arc, frame, θ_o rows, φ_o breakpoints per row and bytes per
//! row.
//!
//! ```sh
//! cargo run -p acdf --release --example anisotropic_probe -- target/aniso-ggx.bsdf [TOL ...]
//! ```
//!
//! A tolerance is `TOL` or `TOL/BUDGET` (the budget otherwise follows
//! the tolerance); prefixed with `none:` it builds without the φ_o
//! symmetry (`none:` alone: the default tolerance, capped).

use acdf::env::{Environment, Sky};
use acdf::material::load_material;
use acdf::registry::{make_sampler, SamplerOptions};
use acdf_core::geometry::{spherical_direction, Frame};
use acdf_core::quadrature::{HemisphereGrid, Integrand};
use acdf_core::{BxdfSampler, Vec3};
use acdf_outgoing::anisotropic::{Symmetry, ANISOTROPIC_FINE_PER_CELL, FINE_PHI_PER_CELL};
use acdf_outgoing::{AnisotropicOutgoingSampler, OutgoingBuilder};
use acdf_tabulated::Resolution;

fn relative_variances(integrands: &[Integrand], s: &dyn BxdfSampler) -> Vec<f64> {
    integrands
        .iter()
        .map(|q| q.moments(s).relative_variance())
        .collect()
}

fn print(label: &str, bytes: usize, rv: &[f64]) {
    let mean = rv.iter().sum::<f64>() / rv.len() as f64;
    let by: Vec<String> = rv.iter().map(|v| format!("{v:.3}")).collect();
    println!(
        "{label:<28} {bytes:>9} B  mean {mean:.4e}  by wo [{}]",
        by.join(" ")
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .ok_or("usage: anisotropic_probe FILE [TOL ...]")?;
    let material = load_material(&path.parse()?, None)?;
    let sky = Sky::dome();
    let frame = Frame::from_z(Vec3::Y);
    let light = |wi: Vec3| sky.radiance(frame.to_world(wi));
    let mut wos = Vec::new();
    for theta in [10.0f32, 30.0, 50.0, 70.0] {
        for phi in [0.0f32, 120.0, 240.0] {
            wos.push(spherical_direction(theta.to_radians(), phi.to_radians()));
        }
    }
    let grid = HemisphereGrid::HalfVector {
        n_v: 1024,
        n_x: 512,
    };
    let integrands: Vec<Integrand> = wos
        .iter()
        .map(|&wo| Integrand::new(&*material.brdf, wo, grid, Some(&light)))
        .collect();
    let r: Resolution = "32x16x256x32".parse()?;
    let options = SamplerOptions {
        resolution: r,
        ..Default::default()
    };
    let uniform = make_sampler("uniform", &material, &options)?;
    print(
        "uniform 32x16x256x32",
        uniform.storage_bytes(),
        &relative_variances(&integrands, &uniform),
    );
    let mut tolerances: Vec<Option<String>> = vec![None];
    tolerances.extend(args.map(Some));
    for t in tolerances {
        let (symmetry, spec) = match &t {
            Some(t) if t.starts_with("none:") => (Some(Symmetry::None), Some(&t[5..])),
            Some(t) => (None, Some(&t[..])),
            None => (None, None),
        };
        // TOL or TOL/BUDGET.
        let (tol, budget) = match spec.map(|s| s.split_once('/')) {
            Some(Some((t, b))) => (Some(t.parse::<f64>()?), Some(b.parse::<f64>()?)),
            Some(None) if spec != Some("") => (Some(spec.unwrap_or("").parse::<f64>()?), None),
            _ => (None, None),
        };
        let mut builder = OutgoingBuilder::anisotropic_by_name(
            "chi2",
            tol,
            r.theta_o * ANISOTROPIC_FINE_PER_CELL,
        )?;
        if let Some(b) = budget {
            builder.budget = b;
        }
        let start = std::time::Instant::now();
        let s = AnisotropicOutgoingSampler::with_symmetry(
            material.brdf.clone(),
            r,
            builder,
            r.phi_o * FINE_PHI_PER_CELL,
            symmetry,
        )?;
        let built = start.elapsed().as_secs_f64();
        let rows = s.phi_breakpoint_angles();
        let theta = s.theta_breakpoint_angles();
        let per_row: Vec<String> = (0..rows.len())
            .map(|k| {
                let slices = &s.slices()[s.row_start(k)..s.row_start(k) + rows[k].len()];
                let bytes: usize = slices.iter().map(|x| x.storage_bytes()).sum();
                format!("{:.0}°:{}/{}B", theta[k].to_degrees(), rows[k].len(), bytes)
            })
            .collect();
        println!(
            "outgoing tol {:.4} budget {:.4} {:?} {:?} built in {built:.0} s; rows {}",
            s.builder().tolerance,
            s.builder().budget,
            s.symmetry(),
            s.frame(),
            per_row.join(" ")
        );
        print(
            &format!("outgoing {}", t.as_deref().unwrap_or("default")),
            s.storage_bytes(),
            &relative_variances(&integrands, &s),
        );
    }
    Ok(())
}
