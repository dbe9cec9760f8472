//! The relative variance of one-sample estimators of direct lighting from
//! an environment map, ∫ f_r(wo, wi) cos θ_i L(wi) dω_i, computed by
//! quadrature (no draws; `acdf_core::quadrature`, 256 × 512 equal-area
//! cells): the BRDF sampler (`outgoing:chi2`), the light sampler
//! (`oriented:chi2`), their one-sample balance mixture (½ each: MIS with
//! the balance heuristic, one draw), and the product sampler at several
//! defensive shares δ. Every built-in material but near-mirror (whose
//! lobe is narrower than the quadrature's cells) and, when present, RGL
//! ilm_solo_m_68, under the four shared maps, at normals (θ, φ) = (0, 0),
//! (60°, 120°) and (100°, 300°), wo at θ_o = 30° and 75°.
//!
//! ```text
//! cargo run --release -p acdf-conformance --example product_variance [BLOCK_COLUMNS] [VARIANTS]
//! ```
//!
//! (BLOCK_COLUMNS: the product's block columns, 64 by default. VARIANTS:
//! instead of the δs, product samplers at δ = 0.15 with other options,
//! comma-separated, each `N:c₀:k:γ` — mass draws, mass prior, sub-cells
//! per block side, refinement light share (`ProductOptions`), e.g.
//! `0:0:1:0,64:4:4:0.1`.)
//!
//! Per case one line: the relative variances, and the product's at each δ
//! divided by the best of the three others. Then per map the median and
//! the worst of that ratio over the cases.

use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_adaptive_env::{oriented_env_sampler, OrientedEnvSampler};
use acdf_core::quadrature::{HemisphereGrid, Integrand};
use acdf_core::{Brdf, BxdfSample, BxdfSampler, Frame, SphereSampler, Vec2, Vec3};
use acdf_lights::{EnvMap, NormalGrid};
use acdf_outgoing::{OutgoingBuilder, OutgoingSampler, FINE_PER_CELL};
use acdf_product::{ProductEnv, ProductOptions, ProductSampler};
use acdf_tabulated::Resolution;
use std::sync::Arc;

/// The light sampler at one normal, as a sampler of the local frame.
struct LightInFrame<'a> {
    light: &'a OrientedEnvSampler,
    frame: Frame,
}

impl BxdfSampler for LightInFrame<'_> {
    fn name(&self) -> &str {
        "light"
    }
    fn sample(&self, _: Vec3, _: Vec2) -> Option<BxdfSample> {
        None
    }
    fn pdf(&self, _: Vec3, wi: Vec3) -> f32 {
        self.light.pdf(Some(self.frame.z), self.frame.to_world(wi))
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

/// ½ p_a + ½ p_b.
struct Half<'a>(&'a dyn BxdfSampler, &'a dyn BxdfSampler);

impl BxdfSampler for Half<'_> {
    fn name(&self) -> &str {
        "mis"
    }
    fn sample(&self, _: Vec3, _: Vec2) -> Option<BxdfSample> {
        None
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        0.5 * (self.0.pdf(wo, wi) + self.1.pdf(wo, wi))
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

const DELTAS: [f32; 5] = [0.05, 0.1, 0.15, 0.2, 0.3];

/// The product samplers' options: the δs of [`DELTAS`] with the defaults,
/// or the variants `N:c₀:k:γ` of `spec` (comma-separated) at the default δ.
fn variants(spec: Option<&str>) -> Vec<(String, ProductOptions)> {
    let d = ProductOptions::default();
    match spec {
        None => DELTAS
            .iter()
            .map(|&defensive| {
                (
                    format!("product{defensive}"),
                    ProductOptions { defensive, ..d },
                )
            })
            .collect(),
        Some(spec) => spec
            .split(',')
            .map(|v| {
                let f: Vec<&str> = v.split(':').collect();
                assert_eq!(f.len(), 4, "a variant is N:c0:k:gamma, not {v}");
                let o = ProductOptions {
                    mass_draws: f[0].parse().expect("N"),
                    mass_prior: f[1].parse().expect("c0"),
                    sub_cells: f[2].parse().expect("k"),
                    refine_light_share: f[3].parse().expect("gamma"),
                    ..d
                };
                o.validate().expect("valid options");
                (format!("product[{v}]"), o)
            })
            .collect(),
    }
}

fn direction(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn main() {
    let block_columns: usize = std::env::args()
        .nth(1)
        .map_or(64, |a| a.parse().expect("BLOCK_COLUMNS is a count"));
    let spec = std::env::args().nth(2);
    let variants = variants(spec.as_deref());
    let data = acdf_materials::shared_data_dir().expect("the shared data (ACDF_SHARED_DATA)");
    let mut materials: Vec<(String, Arc<dyn Brdf>)> =
        ["nickel", "gray-plastic", "blue-metallic-paint", "lambert"]
            .iter()
            .map(|n| (n.to_string(), acdf_materials::builtin(n).unwrap()))
            .collect();
    let rgl = data.join("rgl-material-database/ilm_solo_m_68_rgb.bsdf");
    if rgl.is_file() {
        materials.push((
            "ilm_solo_m_68".into(),
            Arc::new(acdf_rgl::RglBrdf::open(&rgl).unwrap()),
        ));
    }
    let bases: Vec<Arc<dyn BxdfSampler>> = materials
        .iter()
        .map(|(_, b)| {
            let r = Resolution::ISOTROPIC;
            let builder =
                OutgoingBuilder::by_name("chi2", None, r.theta_o * FINE_PER_CELL).unwrap();
            Arc::new(OutgoingSampler::new(b.clone(), r, builder).unwrap()) as Arc<dyn BxdfSampler>
        })
        .collect();
    let grid = HemisphereGrid::EqualArea {
        n_cos: 256,
        n_phi: 512,
    };
    let names = variants
        .iter()
        .map(|(n, _)| n.as_str())
        .collect::<Vec<_>>()
        .join(",");
    println!("map,material,normal,theta_o,brdf,light,mis,{names}");
    let mut summary = Vec::new();
    for stem in [
        "empty_warehouse_01",
        "potsdamer_platz",
        "rooitou_park",
        "studio_small_03",
    ] {
        let map = Arc::new(EnvMap::open(&data.join(format!("envmaps/{stem}_1k.hdr"))).unwrap());
        // One cut of the map per sub-cell count.
        let mut envs: Vec<(usize, Arc<ProductEnv>)> = Vec::new();
        for (_, o) in &variants {
            if !envs.iter().any(|(k, _)| *k == o.sub_cells) {
                let env = ProductEnv::new(map.clone(), block_columns, 2, o.sub_cells).unwrap();
                envs.push((o.sub_cells, Arc::new(env)));
            }
        }
        let env_of = |k: usize| envs.iter().find(|(e, _)| *e == k).unwrap().1.clone();
        let light = oriented_env_sampler(
            map.clone(),
            AdaptiveBuilder::by_name("chi2", None).unwrap(),
            NormalGrid::new(16, 32).unwrap(),
            0.0,
        )
        .unwrap();
        let mut ratios: Vec<Vec<f64>> = vec![Vec::new(); variants.len()];
        for ((name, brdf), base) in materials.iter().zip(&bases) {
            for (nt, np) in [(0.0, 0.0), (60.0, 120.0), (100.0, 300.0)] {
                let normal = direction(nt, np);
                let frame = Frame::from_z(normal);
                let radiance = |wi: Vec3| map.radiance(frame.to_world(wi));
                let local_light = LightInFrame {
                    light: &light,
                    frame,
                };
                for theta_o in [30.0, 75.0] {
                    let wo = direction(theta_o, 40.0);
                    let integrand = Integrand::new(brdf.as_ref(), wo, grid, Some(&radiance));
                    if integrand.integral().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                        continue;
                    }
                    let rv = |s: &dyn BxdfSampler| integrand.moments(s).relative_variance();
                    let brdf_rv = rv(base.as_ref());
                    let light_rv = rv(&local_light);
                    let mis_rv = rv(&Half(base.as_ref(), &local_light));
                    let best = brdf_rv.min(light_rv).min(mis_rv);
                    let products: Vec<f64> = variants
                        .iter()
                        .map(|(_, options)| {
                            let env = env_of(options.sub_cells);
                            let p =
                                ProductSampler::new(base.clone(), env, normal, *options).unwrap();
                            rv(&p)
                        })
                        .collect();
                    for (k, p) in products.iter().enumerate() {
                        ratios[k].push(p / best);
                    }
                    println!(
                        "{stem},{name},{nt}/{np},{theta_o},{brdf_rv:.4},{light_rv:.4},{mis_rv:.4},{}",
                        products.iter().map(|p| format!("{p:.4}")).collect::<Vec<_>>().join(",")
                    );
                }
            }
        }
        summary.push((stem, ratios));
    }
    println!();
    println!(
        "product relative variance / best of (brdf, light, mis): median [worst] over the cases"
    );
    println!("map,{names}");
    for (stem, ratios) in summary {
        let cells: Vec<String> = ratios
            .into_iter()
            .map(|mut r| {
                r.sort_by(f64::total_cmp);
                format!("{:.3} [{:.3}]", r[r.len() / 2], r[r.len() - 1])
            })
            .collect();
        println!("{stem},{}", cells.join(","));
    }
}
