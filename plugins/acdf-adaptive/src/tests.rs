use crate::{adaptive_sampler, average_resolution};
use acdf_adaptive_cdf::SIMPLIFIER_NAMES;
use acdf_core::Vec2;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

#[test]
fn the_brdf_sampler_is_the_tabulated_sampler_with_adaptive_slices() {
    use acdf_core::{BxdfSampler, Vec3};
    use acdf_tabulated::Resolution;
    let res = Resolution::new(4, 1, 64, 16).unwrap();
    let brdf = acdf_materials::builtin("nickel").unwrap();
    // The uniform tables of this resolution: one f32 per cell.
    let table_bytes = res.theta_o * res.phi_o * res.theta_h * res.phi_h * 4;
    for name in SIMPLIFIER_NAMES {
        let sampler = adaptive_sampler(brdf.clone(), res, name, None).unwrap();
        assert_eq!(sampler.name(), format!("adaptive:{name}"));
        assert_eq!(average_resolution(&sampler), (0.0, 0.0));
        sampler.build_all().unwrap();
        let (theta_h, phi_h) = average_resolution(&sampler);
        assert!((2.0..=65.0).contains(&theta_h) && (2.0..=17.0).contains(&phi_h));
        assert!(sampler.storage_bytes() > 0);
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let mut rng = Pcg64::seed_from_u64(9);
        let mut drawn = 0;
        for _ in 0..2000 {
            if let Some(s) = sampler.sample(wo, Vec2::new(rng.random(), rng.random())) {
                drawn += 1;
                assert!(s.wi.z > 0.0 && s.pdf > 0.0 && s.pdf.is_finite());
                let p = sampler.pdf(wo, s.wi);
                assert!(
                    (p - s.pdf).abs() <= 1e-4 * s.pdf,
                    "{name}: {p} vs {}",
                    s.pdf
                );
            }
        }
        assert!(drawn > 1500, "{name}: only {drawn} draws above the horizon");
        assert!(sampler
            .sample(Vec3::new(0.0, 0.0, -1.0), Vec2::splat(0.5))
            .is_none());
    }
    let chi2 = adaptive_sampler(brdf, res, "chi2", None).unwrap();
    chi2.build_all().unwrap();
    assert!(chi2.storage_bytes() < table_bytes);
    assert!(adaptive_sampler(
        acdf_materials::builtin("lambert").unwrap(),
        res,
        "nope",
        None
    )
    .is_err());
    assert!(acdf_adaptive_cdf::AdaptiveBuilder::by_name("dp", Some(-1.0)).is_err());
}
