use super::*;
use acdf_core::geometry::spherical_direction;
use acdf_core::{Brdf, Rgb};
use acdf_tabulated::persist::{seal, ByteWriter, PersistError};
use rand::{Rng, SeedableRng};
use std::sync::Arc;

fn nickel() -> Arc<dyn Brdf> {
    acdf_materials::builtin("nickel").expect("built-in nickel")
}

/// A material whose f_r cos θ_i is the density of a given mixture, so that
/// the fit has a known answer.
struct MixtureBrdf(Mixture);

impl Brdf for MixtureBrdf {
    fn name(&self) -> &str {
        "mixture"
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::ZERO;
        }
        Rgb::splat(self.0.pdf(wo, wi) / wi.z)
    }
    fn is_isotropic(&self) -> bool {
        true
    }
}

/// The parameters take 32 bytes, within the 64 the family is allowed, and
/// the sampler reports exactly that.
#[test]
fn storage_is_the_parameters_within_64_bytes() {
    assert_eq!(STORAGE_BYTES, 32);
    let s = LobesSampler::new(nickel().as_ref()).unwrap();
    assert_eq!(s.storage_bytes(), STORAGE_BYTES);
    assert!(s.storage_bytes() <= 64);
}

/// The fit of a material whose f_r cos θ_i is a mixture's density finds
/// that mixture's roughness and weights, and does at least as well as it:
/// the truth is not quite the optimum, since its GGX draws that fall below
/// the horizon are lost.
#[test]
fn the_fit_recovers_a_mixture() {
    let truth = Mixture::new(Lobes::new(0.3, &[(0.7, 0.2)]).unwrap());
    let brdf = MixtureBrdf(truth);
    let options = FitOptions::default();
    let fit = fit_with(&brdf, &options).unwrap();
    let floor = objective(&brdf, truth.lobes(), &options).unwrap();
    let (_, alpha) = fit.lobes.lobes().next().unwrap();
    assert!((alpha - 0.2).abs() < 0.02, "{fit:?}");
    assert!((fit.lobes.diffuse() - 0.3).abs() < 0.05, "{fit:?}");
    assert!(fit.objective <= floor, "{fit:?} against {floor}");
    assert_eq!(
        objective(&brdf, &fit.lobes, &options).unwrap(),
        fit.objective
    );
}

/// A Lambertian material keeps no GGX lobe: cosine sampling is exact for
/// it (relative variance 0 up to the quadrature), and no lobe gains the
/// 2% a lobe must bring. Its sampler draws and evaluates like cosine
/// sampling.
#[test]
fn a_lambertian_material_keeps_no_lobe() {
    let lambert = acdf_materials::builtin("lambert").expect("built-in lambert");
    let fit = fit_with(lambert.as_ref(), &FitOptions::default()).unwrap();
    assert_eq!(fit.lobes.count(), 0, "{fit:?}");
    assert_eq!(fit.lobes.diffuse(), 1.0);
    assert!(fit.by_count[0] < 1e-3, "{fit:?}");
    let sampler = LobesSampler::new(lambert.as_ref()).unwrap();
    let wo = spherical_direction(0.7, 0.2);
    let s = sampler.sample(wo, Vec2::new(0.3, 0.8)).unwrap();
    let cosine = s.wi.z * FRAC_1_PI;
    assert!((s.pdf - cosine).abs() <= 1e-6 * cosine, "{s:?}");
    assert!((sampler.pdf(wo, s.wi) - cosine).abs() <= 1e-6 * cosine);
    let nan_cost = FitOptions {
        draw_cost: [1.0, f64::NAN, 2.0, 2.0],
        ..FitOptions::default()
    };
    assert!(matches!(
        fit_with(lambert.as_ref(), &nan_cost),
        Err(Error::InvalidParameter {
            name: "draw_cost",
            ..
        })
    ));
}

/// The lobe count weighs variance by the time of a draw: a material whose
/// best lobe lowers the variance by less than the lobe's cost keeps none,
/// and keeps it when draws cost the same whatever the count.
#[test]
fn a_lobe_is_kept_only_where_it_pays_for_its_time() {
    // Mostly cosine, and a broad GGX lobe: one lobe lowers the variance a
    // little, far less than twice.
    let truth = Mixture::new(Lobes::new(0.95, &[(0.05, 1.5)]).unwrap());
    let brdf = MixtureBrdf(truth);
    let fit = fit_with(&brdf, &FitOptions::default()).unwrap();
    assert!(fit.by_count[1] < fit.by_count[0], "{fit:?}");
    assert!(fit.by_count[1] * 2.0 > fit.by_count[0], "{fit:?}");
    assert_eq!(fit.lobes.count(), 0, "{fit:?}");
    let free = FitOptions {
        draw_cost: [1.0; MAX_LOBES + 1],
        ..FitOptions::default()
    };
    assert!(fit_with(&brdf, &free).unwrap().lobes.count() >= 1);
}

/// Two fits of the same material give the same bits.
#[test]
fn the_fit_is_deterministic() {
    let brdf = nickel();
    let a = fit_with(brdf.as_ref(), &FitOptions::default()).unwrap();
    let b = fit_with(brdf.as_ref(), &FitOptions::default()).unwrap();
    assert_eq!(a, b);
    assert!(a.objective.is_finite() && a.evaluations > 100);
}

/// Saved and loaded, a sampler draws the same bits.
#[test]
fn save_and_load_give_the_same_draws() {
    let brdf = nickel();
    let s = LobesSampler::new(brdf.as_ref()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nickel.acdfs");
    s.save(&path).unwrap();
    let loaded = LobesSampler::load(&path).unwrap();
    assert_eq!(loaded.lobes(), s.lobes());
    assert_eq!(loaded.material().fingerprint, brdf.fingerprint());
    assert_eq!(loaded.material().name, brdf.name());
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    for k in 0..2_000 {
        let wo = spherical_direction(1.55 * (k as f32 / 2_000.0), 0.3 * k as f32);
        let u = Vec2::new(rng.random(), rng.random());
        let (a, b) = (s.sample(wo, u), loaded.sample(wo, u));
        assert_eq!(
            a.map(|d| (d.wi.to_array().map(f32::to_bits), d.pdf.to_bits())),
            b.map(|d| (d.wi.to_array().map(f32::to_bits), d.pdf.to_bits()))
        );
    }
}

/// A body of a lobes file with the given fields, sealed.
fn file(count: u32, diffuse: f32, lobes: &[(f32, f32)]) -> Vec<u8> {
    let mut w = ByteWriter::new();
    w.string(persist::KIND);
    w.u32(persist::LOBES_VERSION);
    w.string("test");
    w.u8(1);
    w.u64(7);
    w.u32(count);
    w.f32(diffuse);
    for &(a, b) in lobes {
        w.f32(a);
        w.f32(b);
    }
    seal(&w.into_bytes())
}

/// Hostile files give typed errors naming the cause.
#[test]
fn hostile_files_are_typed_errors() {
    let good = file(1, 0.5, &[(0.5, 0.1)]);
    assert!(LobesSampler::from_bytes(&good).is_ok());
    assert!(matches!(
        LobesSampler::from_bytes(&file(1, 0.5, &[(0.5, f32::NAN)])),
        Err(PersistError::Table(Error::NonFinite { index: 2, .. }))
    ));
    assert!(matches!(
        LobesSampler::from_bytes(&file(1, f32::NAN, &[(0.5, 0.1)])),
        Err(PersistError::Table(Error::NonFinite { index: 0, .. }))
    ));
    assert!(matches!(
        LobesSampler::from_bytes(&file(1, 0.5, &[(0.6, 0.1)])),
        Err(PersistError::Table(Error::InvalidParameter { .. }))
    ));
    assert!(matches!(
        LobesSampler::from_bytes(&file(1, 0.5, &[(0.5, 0.0)])),
        Err(PersistError::Table(Error::InvalidParameter { .. }))
    ));
    assert!(matches!(
        LobesSampler::from_bytes(&file(1, 0.0, &[(1.0, 0.1)])),
        Err(PersistError::Table(Error::InvalidParameter { .. }))
    ));
    let four = [(0.2, 0.1); 4];
    assert!(matches!(
        LobesSampler::from_bytes(&file(4, 0.2, &four)),
        Err(PersistError::Invalid {
            field: "lobe count",
            ..
        })
    ));
    // No GGX lobe is cosine sampling, which must then carry all the weight.
    assert!(LobesSampler::from_bytes(&file(0, 1.0, &[])).is_ok());
    assert!(matches!(
        LobesSampler::from_bytes(&file(0, 0.5, &[])),
        Err(PersistError::Table(Error::InvalidParameter { .. }))
    ));
    // A count larger than the bytes that follow.
    assert!(matches!(
        LobesSampler::from_bytes(&file(3, 0.5, &[(0.5, 0.1)])),
        Err(PersistError::FieldOverrun { .. })
    ));
    for len in 0..good.len() {
        assert!(LobesSampler::from_bytes(&good[..len]).is_err(), "{len}");
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.acdfs");
    std::fs::write(&path, &good[..good.len() - 3]).unwrap();
    assert!(matches!(
        LobesSampler::load(&path),
        Err(PersistError::Truncated { .. })
    ));
}

/// The constructor refuses what no fit produces.
#[test]
fn bad_parameters_are_refused() {
    assert!(Lobes::new(0.5, &[]).is_err());
    assert_eq!(Lobes::new(1.0, &[]).unwrap().count(), 0);
    assert!(Lobes::new(0.2, &[(0.2, 0.1); 4]).is_err());
    assert!(Lobes::new(0.5, &[(0.5, 2.0)]).is_err());
    assert!(Lobes::new(0.5, &[(0.5, f32::INFINITY)]).is_err());
    assert!(Lobes::new(0.6, &[(0.5, 0.1), (-0.1, 0.3)]).is_err());
    let ok = Lobes::new(0.1, &[(0.5, 0.01), (0.2, 0.1), (0.2, 1.0)]).unwrap();
    assert_eq!(ok.count(), 3);
}

/// Weights that sum to a little more than 1 (within the constructor's
/// tolerance) with a last lobe of weight 0 give that lobe probability 0,
/// not a negative one: every density is non-negative.
#[test]
fn weights_summing_past_1_give_no_negative_density() {
    let lobes = Lobes::new(0.5, &[(0.50009, 0.1), (0.0, 0.01)]).unwrap();
    let s = Mixture::new(lobes);
    assert!(s.probability.iter().all(|&p| p >= 0.0), "{s:?}");
    let wo = spherical_direction(0.5, 0.2);
    for k in 0..100 {
        let wi = spherical_direction(1.5 * k as f32 / 100.0, 0.2);
        assert!(s.pdf(wo, wi) >= 0.0);
    }
}

/// At grazing wo and u next to 1 (and outside [0, 1)) every draw is valid
/// and agrees with `pdf`; nothing is NaN.
#[test]
fn grazing_and_extreme_u_give_no_nan() {
    let lobes = Lobes::new(0.01, &[(0.5, ALPHA_MIN), (0.29, 0.05), (0.2, ALPHA_MAX)]).unwrap();
    let s = Mixture::new(lobes);
    let edge = [
        0.0,
        1e-30,
        0.5,
        ONE_MINUS_EPSILON,
        1.0,
        -1.0,
        f32::NAN,
        f32::INFINITY,
    ];
    let mut picks = [0usize; 4];
    for theta in [0.0f32, 45.0, 80.0, 89.0, 89.5, 89.9, 89.99, 89.999] {
        let wo = spherical_direction(theta.to_radians(), 0.7);
        for k in 0..=1000 {
            let a = k as f32 / 1000.0 * ONE_MINUS_EPSILON;
            picks[s.pick(clamp_unit(a)).0] += 1;
            for b in edge {
                for u in [Vec2::new(a, b), Vec2::new(b, a)] {
                    if let Some(d) = s.sample(wo, u) {
                        assert!(d.wi.is_finite() && d.wi.z > 0.0, "{theta} {u}");
                        assert!(d.pdf.is_finite() && d.pdf > 0.0, "{theta} {u}");
                        assert_eq!(d.pdf, s.pdf(wo, d.wi));
                        assert!((d.wi.length() - 1.0).abs() < 1e-5);
                    }
                }
            }
        }
        let p = s.pdf(wo, -wo);
        assert!(p.is_finite() && p >= 0.0);
        assert_eq!(s.pdf(wo, Vec3::new(1.0, 0.0, 0.0)), 0.0);
        assert_eq!(s.pdf(wo, Vec3::new(0.0, 0.0, -1.0)), 0.0);
    }
    // Every component gets draws in proportion to its weight.
    assert!(picks.iter().all(|&n| n > 0), "{picks:?}");
    for wo in [Vec3::X, -Vec3::Z, Vec3::splat(f32::NAN)] {
        assert!(s.sample(wo, Vec2::splat(0.3)).is_none());
        assert_eq!(s.pdf(wo, Vec3::Z), 0.0);
    }
}
