//! Where the relative variance of `outgoing:chi2` comes from at small
//! storage: per outgoing angle, for builds that vary the tolerance and the
//! θ_o budget apart.
//!
//! ```sh
//! cargo run --release -p acdf-experiments --example outgoing_small -- \
//!     --materials nbrdf:chrome --tolerances 2e-2,5e-2 --budgets 1e-2,4e-2
//! ```
//!
//! For each material: the relative variance by quadrature (512 × 256 cells,
//! the survey's, at the 12 standard outgoing directions under the sky) of
//! the 32x16x256x32 table, then of the outgoing sampler for every pair of
//! tolerance and budget (no storage cap): storage, kept slices, marginal
//! and conditional vertices, r and r at each θ_o (mean over φ_o).

use acdf::core::{BxdfSampler, HemisphereGrid};
use acdf::tabulated::Resolution;
use acdf::{load_material, MaterialSpec, Sky};
use acdf_experiments::efficiency::{paper_table, EfficiencyConfig, Integrands};
use acdf_outgoing::{OutgoingBuilder, OutgoingSampler};

fn main() {
    let mut materials = vec!["nbrdf:chrome".to_string()];
    let mut tolerances = vec![2e-2];
    let mut budgets = vec![1e-2];
    let mut resolution = Resolution::ISOTROPIC;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let list = |s: &str| s.split(',').map(String::from).collect::<Vec<_>>();
    let numbers = |s: &str| list(s).iter().filter_map(|k| k.parse().ok()).collect();
    for pair in args.chunks(2) {
        match (pair[0].as_str(), pair.get(1)) {
            ("--materials", Some(v)) => materials = list(v),
            ("--tolerances", Some(v)) => tolerances = numbers(v),
            ("--budgets", Some(v)) => budgets = numbers(v),
            ("--resolution", Some(v)) => resolution = v.parse().expect("a resolution"),
            _ => {
                eprintln!("outgoing_small: unknown option {}", pair[0]);
                std::process::exit(2);
            }
        }
    }
    let env = Sky::dome();
    let config = EfficiencyConfig {
        grid: HemisphereGrid::HalfVector { n_v: 512, n_x: 256 },
        ..EfficiencyConfig::default()
    };
    let by_theta = |r: &[f64]| -> String {
        r.chunks(3)
            .map(|c| format!("{:.2e}", c.iter().sum::<f64>() / c.len() as f64))
            .collect::<Vec<_>>()
            .join(" ")
    };
    for name in &materials {
        let spec: MaterialSpec = name.parse().expect("a material");
        let material = load_material(&spec, None).expect("the material");
        let q = Integrands::new(material.brdf.as_ref(), &env, &config);
        let reference = paper_table(&material).expect("the reference");
        let r = q.noise_free(&reference);
        println!(
            "{name} reference r {:.4e} by θ_o 10,30,50,70: {}",
            r.relative_variance,
            by_theta(&r.relative_variance_by_direction)
        );
        println!("tolerance budget bytes slices m c r | by θ_o");
        for &tolerance in &tolerances {
            for &budget in &budgets {
                let builder = OutgoingBuilder {
                    budget,
                    max_bytes: None,
                    ..OutgoingBuilder::by_name("chi2", Some(tolerance), 4 * resolution.theta_o)
                        .unwrap()
                };
                let s = OutgoingSampler::new(material.brdf.clone(), resolution, builder)
                    .expect("the sampler");
                let n = q.noise_free(&s);
                let (m, c) = s.mean_vertices();
                println!(
                    "{tolerance:.1e} {budget:.1e} {} {} {m:.0} {c:.1} {:.4e} | {}",
                    s.storage_bytes(),
                    s.breakpoint_angles().len(),
                    n.relative_variance,
                    by_theta(&n.relative_variance_by_direction)
                );
            }
        }
    }
}
