//! The noise-free measures on the three measured materials of `acdf
//! report` (`nbrdf:NAME`, baked into MERL tables): the quadrature's
//! relative variance against Monte Carlo estimates, and every figure
//! finite. Skipped, with the reason printed, without the shared data.

use acdf::{load_material, make_sampler, MaterialSpec, SamplerOps, SamplerOptions, Sky};
use acdf_experiments::efficiency::{measure_efficiencies, EfficiencyConfig};

const MATERIALS: [&str; 3] = ["nickel", "blue-metallic-paint", "gray-plastic"];

fn have_data() -> bool {
    let found = acdf::material::nbrdf_weights_path(None).is_some_and(|p| p.is_file());
    if !found {
        acdf::materials::testing::skip_without_data(
            "no Neural-BRDF weights (set ACDF_SHARED_DATA)",
        );
    }
    found
}

/// Wherever the Monte Carlo estimate's stated error (three standard
/// errors at its number of draws, from the estimator's fourth moment) is
/// under 5%, the quadrature's relative variance lies within it; that
/// happens for enough rows to mean something (tabulated samplers mixed
/// with 5% cosine sampling, whose weights are bounded, and cosine
/// sampling; without the mix the tabulated samplers' weights reach
/// hundreds of times their mean, and 2^16 draws per direction leave errors
/// of 50% and more: `docs/results.md`, "Why the Monte Carlo estimate is not
/// the measure"). Every figure is finite.
#[test]
fn quadrature_agrees_with_monte_carlo_where_its_error_is_small() {
    if !have_data() {
        return;
    }
    let env = Sky::dome();
    let config = EfficiencyConfig {
        samples_per_direction: 1 << 16,
        timing_samples_per_direction: 64,
        timing_repeats: 1,
        ..EfficiencyConfig::default()
    };
    let mut checked = Vec::new();
    for name in MATERIALS {
        let spec: MaterialSpec = format!("nbrdf:{name}").parse().unwrap();
        let m = load_material(&spec, None).unwrap();
        let mut samplers = Vec::new();
        for mix in [0.05f32] {
            let options = SamplerOptions {
                cosine_mix: mix,
                ..SamplerOptions::default()
            };
            for s in ["uniform", "adaptive:chi2", "adaptive:dp"] {
                let sampler = make_sampler(s, &m, &options).unwrap();
                sampler.build_all().unwrap();
                samplers.push((format!("{s} mix {mix}"), sampler));
            }
        }
        samplers.push((
            "cosine".into(),
            make_sampler("cosine", &m, &SamplerOptions::default()).unwrap(),
        ));
        let refs: Vec<&dyn acdf::core::BxdfSampler> = samplers
            .iter()
            .map(|(_, s)| s as &dyn acdf::core::BxdfSampler)
            .collect();
        let measured = measure_efficiencies(m.brdf.as_ref(), &refs, &env, &config);
        for ((label, _), e) in samplers.iter().zip(&measured) {
            let r = e.noise_free.relative_variance;
            let mc = e.monte_carlo.as_ref().unwrap();
            for x in [
                r,
                e.noise_free.firefly,
                mc.relative_variance,
                mc.relative_variance_rel_se,
                mc.sample_rel_se,
                e.efficiency,
            ] {
                assert!(x.is_finite() && x > 0.0, "{name} {label}: {e:?}");
            }
            let stated = 3.0 * mc.relative_variance_rel_se;
            println!(
                "{name} {label}: quadrature {r:.4e}, Monte Carlo {:.4e} (±{:.1}%), firefly {:.0}",
                mc.relative_variance,
                100.0 * stated,
                e.noise_free.firefly
            );
            if stated < 0.05 {
                assert!(
                    (mc.relative_variance - r).abs() <= stated * r,
                    "{name} {label}: quadrature {r} against {mc:?}"
                );
                checked.push(format!("{name} {label}"));
            }
        }
    }
    assert!(checked.len() >= 4, "only {checked:?} were checked");
}
