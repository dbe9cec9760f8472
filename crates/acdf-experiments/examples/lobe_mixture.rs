//! Whether a fitted-lobe sampler helps `outgoing:chi2` at small storage:
//! the relative variance of the one-sample mixture w · p_lobes + (1 − w) ·
//! p_outgoing, for several lobe shares w, over that of the 32x16x256x32
//! table.
//!
//! ```sh
//! cargo run --release -p acdf-experiments --example lobe_mixture -- \
//!     --materials chrome,ss440 --tolerances 2e-3,1e-2,5e-2 --shares 0,0.05,0.2,0.5
//! ```
//!
//! For each material: the table's relative variance r₀ and the lobes'
//! (by quadrature, 512 × 256 cells at the 12 standard outgoing directions
//! under the sky, as the survey), then for each tolerance of
//! `outgoing:chi2` (no storage cap) its storage and r / r₀ at each share.

use acdf::core::{BxdfSample, BxdfSampler, HemisphereGrid};
use acdf::tabulated::Resolution;
use acdf::{load_material, make_sampler, MaterialSpec, SamplerOptions, Sky};
use acdf_experiments::efficiency::{paper_table, EfficiencyConfig, Integrands};
use acdf_outgoing::{OutgoingBuilder, OutgoingSampler};
use glam::{Vec2, Vec3};

/// Draws from `lobes` with probability `share`, else from `table`; the
/// density is the mixture's.
struct Mixture<'a> {
    table: &'a dyn BxdfSampler,
    lobes: &'a dyn BxdfSampler,
    share: f32,
}

impl BxdfSampler for Mixture<'_> {
    fn name(&self) -> &str {
        "mixture"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        let w = self.share;
        let wi = if u.x < w {
            self.lobes.sample(wo, Vec2::new(u.x / w, u.y))?.wi
        } else {
            let ux = ((u.x - w) / (1.0 - w)).min(1.0 - f32::EPSILON / 2.0);
            self.table.sample(wo, Vec2::new(ux, u.y))?.wi
        };
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then_some(BxdfSample { wi, pdf })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.share * self.lobes.pdf(wo, wi) + (1.0 - self.share) * self.table.pdf(wo, wi)
    }
    fn storage_bytes(&self) -> usize {
        self.table.storage_bytes() + self.lobes.storage_bytes()
    }
}

fn main() {
    let mut materials = vec!["chrome".to_string()];
    let mut tolerances = vec![1e-2];
    let mut shares = vec![0.0f32, 0.05, 0.2, 0.5];
    let args: Vec<String> = std::env::args().skip(1).collect();
    let list = |s: &str| s.split(',').map(String::from).collect::<Vec<_>>();
    for pair in args.chunks(2) {
        match (pair[0].as_str(), pair.get(1)) {
            ("--materials", Some(v)) => materials = list(v),
            ("--tolerances", Some(v)) => {
                tolerances = list(v).iter().filter_map(|k| k.parse().ok()).collect()
            }
            ("--shares", Some(v)) => {
                shares = list(v)
                    .iter()
                    .filter_map(|k| k.parse().ok())
                    .filter(|w| (0.0..1.0).contains(w))
                    .collect()
            }
            _ => {
                eprintln!("lobe_mixture: unknown option {}", pair[0]);
                std::process::exit(2);
            }
        }
    }
    let resolution = Resolution::ISOTROPIC;
    let env = Sky::dome();
    let config = EfficiencyConfig {
        grid: HemisphereGrid::HalfVector { n_v: 512, n_x: 256 },
        ..EfficiencyConfig::default()
    };
    for name in &materials {
        let spec: MaterialSpec = format!("nbrdf:{name}").parse().expect("a material");
        let material = load_material(&spec, None).expect("the material");
        let q = Integrands::new(material.brdf.as_ref(), &env, &config);
        let reference = paper_table(&material).expect("the reference");
        let r0 = q.noise_free(&reference).relative_variance;
        let lobes = make_sampler("lobes", &material, &SamplerOptions::default()).expect("lobes");
        let r_lobes = q.noise_free(&lobes).relative_variance;
        println!("{name}: table r0 {r0:.4e}, lobes r/r0 {:.3}", r_lobes / r0);
        println!("tolerance bytes | r/r0 at lobe share {shares:?}");
        for &tolerance in &tolerances {
            let builder = OutgoingBuilder {
                max_bytes: None,
                ..OutgoingBuilder::by_name("chi2", Some(tolerance), 4 * resolution.theta_o).unwrap()
            };
            let table = OutgoingSampler::new(material.brdf.clone(), resolution, builder)
                .expect("the sampler");
            let ratios: Vec<String> = shares
                .iter()
                .map(|&share| {
                    let m = Mixture {
                        table: &table,
                        lobes: &lobes,
                        share,
                    };
                    format!("{:.3}", q.noise_free(&m).relative_variance / r0)
                })
                .collect();
            println!(
                "{tolerance:.1e} {} | {}",
                table.storage_bytes(),
                ratios.join(" ")
            );
        }
    }
}
