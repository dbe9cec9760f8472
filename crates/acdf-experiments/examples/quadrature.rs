//! How fine the quadrature of the noise-free relative variance must be, and
//! how it compares with Monte Carlo estimates of growing size.
//!
//! ```sh
//! cargo run --release -p acdf-experiments --example quadrature
//! cargo run --release -p acdf-experiments --example quadrature -- \
//!     --materials nbrdf:nickel --samplers uniform,cosine --draws 17,20,23
//! ```
//!
//! For each material and sampler: the relative variance by quadrature
//! ([`acdf_experiments::efficiency::Integrands`]) on half-vector grids from 256 × 32 to
//! 4096 × 512 cells per outgoing direction, then Monte Carlo estimates with
//! 2^k draws per direction for each k of `--draws`, with their relative
//! standard errors. The measured materials need the shared data
//! (`nbrdf:NAME`).

use acdf::core::{BxdfSampler, HemisphereGrid};
use acdf::SamplerOps as _;
use acdf::{load_material, make_sampler, MaterialSpec, SamplerOptions, Sky};
use acdf_experiments::efficiency::{measure_efficiency, EfficiencyConfig, Integrands};

fn main() {
    let mut materials = vec![
        "nbrdf:nickel".to_string(),
        "nbrdf:blue-metallic-paint".to_string(),
        "nbrdf:gray-plastic".to_string(),
    ];
    let mut samplers = vec!["uniform".to_string(), "adaptive:chi2".to_string()];
    let mut draws = vec![17u32];
    let args: Vec<String> = std::env::args().skip(1).collect();
    let list = |s: &str| s.split(',').map(String::from).collect::<Vec<_>>();
    for pair in args.chunks(2) {
        match (pair[0].as_str(), pair.get(1)) {
            ("--materials", Some(v)) => materials = list(v),
            ("--samplers", Some(v)) => samplers = list(v),
            ("--draws", Some(v)) => draws = list(v).iter().filter_map(|k| k.parse().ok()).collect(),
            _ => {
                eprintln!("quadrature: unknown option {}", pair[0]);
                std::process::exit(2);
            }
        }
    }
    let env = Sky::dome();
    let grids = [(256, 32), (512, 64), (1024, 128), (2048, 256), (4096, 512)];
    println!(
        "| material | sampler | {} |",
        grids.map(|(v, x)| format!("{v}x{x}")).join(" | ")
    );
    println!("|---|---|{}", "---:|".repeat(grids.len()));
    let mut mc_lines = Vec::new();
    for name in &materials {
        let spec: MaterialSpec = match name.parse() {
            Ok(s) => s,
            Err(e) => {
                eprintln!("quadrature: {e}");
                std::process::exit(2);
            }
        };
        let material = match load_material(&spec, None) {
            Ok(m) => m,
            Err(e) => {
                println!("skipping {name}: {e}");
                continue;
            }
        };
        for s in &samplers {
            let sampler = make_sampler(s, &material, &SamplerOptions::default())
                .and_then(|x| x.build_all().map(|()| x))
                .unwrap_or_else(|e| {
                    eprintln!("quadrature: {e}");
                    std::process::exit(2);
                });
            let by_grid: Vec<String> = grids
                .iter()
                .map(|&(n_v, n_x)| {
                    let config = EfficiencyConfig {
                        grid: HemisphereGrid::HalfVector { n_v, n_x },
                        ..EfficiencyConfig::default()
                    };
                    let q = Integrands::new(material.brdf.as_ref(), &env, &config);
                    format!("{:.4e}", q.noise_free(&sampler).relative_variance)
                })
                .collect();
            println!("| {name} | {s} | {} |", by_grid.join(" | "));
            for &k in &draws {
                for seed in [2005u64, 7] {
                    let config = EfficiencyConfig {
                        samples_per_direction: 1 << k,
                        timing_samples_per_direction: 16,
                        timing_repeats: 1,
                        seed,
                        ..EfficiencyConfig::default()
                    };
                    let e = measure_efficiency(material.brdf.as_ref(), &sampler, &env, &config);
                    let mc = e.monte_carlo.expect("draws were asked for");
                    mc_lines.push(format!(
                        "| {name} | {} | 2^{k} | {seed} | {:.4e} | {:.1}% |",
                        sampler.name(),
                        mc.relative_variance,
                        100.0 * mc.relative_variance_rel_se
                    ));
                }
            }
        }
    }
    println!("\n| material | sampler | draws per direction | seed | Monte Carlo | ± (1 s.e.) |");
    println!("|---|---|---:|---:|---:|---:|");
    for l in mc_lines {
        println!("{l}");
    }
}
