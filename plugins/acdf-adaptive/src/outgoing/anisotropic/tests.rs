use super::*;
use rand::{Rng, SeedableRng};

/// An anisotropic Gaussian lobe on the half vector, wider along x, over
/// a small diffuse floor.
struct Brushed;
impl Brdf for Brushed {
    fn name(&self) -> &str {
        "brushed"
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if !(wo.z > 0.0 && wi.z > 0.0) {
            return Rgb::ZERO;
        }
        let h = (wo + wi).normalize_or_zero();
        if !(h.z > 0.0) {
            return Rgb::ZERO;
        }
        let e = (h.x * h.x / 0.09 + h.y * h.y / 0.0025) / (h.z * h.z);
        Rgb::splat(0.05 + 3.0 * (-e).exp())
    }
    fn is_isotropic(&self) -> bool {
        false
    }
}

fn nickel() -> Arc<dyn Brdf> {
    acdf_materials::builtin("nickel").expect("built-in nickel")
}

/// A small sampler: 16 θ_o × 16 φ_o nodes, 64 × 16 half-vector cells.
fn small(brdf: Arc<dyn Brdf>) -> AnisotropicOutgoingSampler {
    let builder = OutgoingBuilder::by_name("chi2", None, 16).unwrap();
    AnisotropicOutgoingSampler::new(brdf, "8x8x64x16".parse().unwrap(), builder, 16).unwrap()
}

fn direction(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// The φ_o breakpoints adapt: an isotropic material, whose slices do not
/// depend on φ_o in the sampler's frame, keeps one φ_o breakpoint (one
/// slice per θ_o breakpoint); the anisotropic lobe keeps several.
#[test]
fn phi_breakpoints_adapt_to_the_anisotropy() {
    let iso = small(nickel());
    assert_eq!(iso.phi_breakpoint_angles(), vec![0.0]);
    assert_eq!(iso.slices().len(), iso.theta_breakpoint_angles().len());
    let aniso = small(Arc::new(Brushed));
    let phi = aniso.phi_breakpoint_angles();
    assert!(phi.len() >= 3, "{phi:?}");
    assert_eq!(
        aniso.slices().len(),
        phi.len() * aniso.theta_breakpoint_angles().len()
    );
    assert!(aniso.storage_bytes() > iso.storage_bytes());
}

/// Samples carry the density `pdf` reports, for wo on the normal, at and
/// between breakpoints, across the φ_o seam and next to the horizon.
#[test]
fn sample_and_pdf_agree() {
    let s = small(Arc::new(Brushed)).with_cosine_mix(0.05).unwrap();
    let theta = s.theta_breakpoint_angles();
    let phi = s.phi_breakpoint_angles();
    let wos = [
        direction(0.0, 0.0),
        direction(theta[1], phi[1]),
        direction(0.5 * (theta[1] + theta[2]), 0.5 * (phi[1] + phi[2])),
        direction(0.7, TAU - 1e-4),
        direction(0.7, 1e-4),
        direction(89.9f32.to_radians(), 2.0),
    ];
    let mut rng = rand_pcg::Pcg64::seed_from_u64(25);
    for wo in wos {
        let mut drawn = 0;
        for _ in 0..5_000 {
            let u = Vec2::new(rng.random(), rng.random());
            let Some(d) = s.sample(wo, u) else { continue };
            drawn += 1;
            assert!(d.wi.z > 0.0 && (d.wi.length() - 1.0).abs() < 1e-5);
            assert_eq!(d.pdf, s.pdf(wo, d.wi));
        }
        assert!(drawn > 4_500, "{wo}: {drawn}");
    }
}

/// `sample_batch` and `pdf_batch`, which find the blend of wo once, give
/// the bits of `sample` and `pdf` one call at a time, for wo at and
/// between breakpoints, across the φ_o seam, and invalid; wi without a
/// density among the others.
#[test]
fn batch_forms_equal_single_calls() {
    let bits =
        |d: &Option<BxdfSample>| d.map(|d| (d.wi.to_array().map(f32::to_bits), d.pdf.to_bits()));
    let s = small(Arc::new(Brushed)).with_cosine_mix(0.05).unwrap();
    let theta = s.theta_breakpoint_angles();
    let phi = s.phi_breakpoint_angles();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(26);
    let u: Vec<Vec2> = (0..200)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .chain([Vec2::ZERO, Vec2::new(1.0, -0.5), Vec2::new(f32::NAN, 0.5)])
        .collect();
    for wo in [
        direction(theta[1], phi[1]),
        direction(0.5 * (theta[1] + theta[2]), 0.5 * (phi[1] + phi[2])),
        direction(0.7, TAU - 1e-4),
        Vec3::new(0.0, 0.0, -1.0),
    ] {
        let mut drawn = vec![None; u.len()];
        s.sample_batch(wo, &u, &mut drawn);
        for (&u, d) in u.iter().zip(&drawn) {
            assert_eq!(bits(&s.sample(wo, u)), bits(d), "{wo} {u}");
        }
        let wis: Vec<Vec3> = drawn
            .iter()
            .map(|d| d.map_or(direction(0.3, 2.0), |d| d.wi))
            .chain([Vec3::new(0.0, 0.0, -1.0), -wo, Vec3::NAN])
            .collect();
        let mut densities = vec![0.0; wis.len()];
        s.pdf_batch(wo, &wis, &mut densities);
        for (&wi, &p) in wis.iter().zip(&densities) {
            assert_eq!(s.pdf(wo, wi).to_bits(), p.to_bits(), "{wo} {wi}");
        }
    }
}

/// The density is continuous in wo across the φ_o seam and across an
/// inner φ_o breakpoint: just below and just above, the densities of fixed
/// wi agree to within the change of the blend weights.
#[test]
fn pdf_is_continuous_in_phi_o() {
    let s = small(Arc::new(Brushed));
    let phi = s.phi_breakpoint_angles();
    let theta = 0.6f32;
    let wis: Vec<Vec3> = (0..40)
        .map(|k| direction(0.02 + 1.5 * k as f32 / 40.0, 0.3 + 0.15 * k as f32))
        .collect();
    for at in [0.0, phi[phi.len() / 2]] {
        let mut compared = 0;
        for &wi in &wis {
            let below = s.pdf(direction(theta, at - 1e-4), wi);
            let above = s.pdf(direction(theta, at + 1e-4), wi);
            if below > 0.0 {
                compared += 1;
                assert!(
                    (below - above).abs() <= 0.02 * below,
                    "φ_o {at}: {below} against {above} at {wi}"
                );
            }
        }
        assert!(compared > 20);
    }
    // The slices on either side of the seam differ: the continuity is
    // the blend's.
    let n = phi.len();
    assert_ne!(s.slices()[n], s.slices()[2 * n - 1]);
}

/// The density integrates (midpoint rule on 256 × 512 equal-area cells of
/// wi) to the share of draws that return a direction, for wo between
/// breakpoints: a draw from a slice tabulated at another θ_o may reflect
/// below the horizon and is refused, and the four-slice mixture is
/// otherwise normalised.
#[test]
fn pdf_integrates_to_the_acceptance_rate() {
    let s = small(Arc::new(Brushed));
    let theta = s.theta_breakpoint_angles();
    let phi = s.phi_breakpoint_angles();
    let wo = direction(0.5 * (theta[1] + theta[2]), 0.5 * (phi[0] + phi[1]));
    let (n_cos, n_phi) = (256, 512);
    let mut sum = 0.0f64;
    for i in 0..n_cos {
        let cos = (i as f32 + 0.5) / n_cos as f32;
        for j in 0..n_phi {
            let wi = direction(cos.acos(), TAU * (j as f32 + 0.5) / n_phi as f32);
            sum += s.pdf(wo, wi) as f64;
        }
    }
    let integral = sum * std::f64::consts::TAU / (n_cos * n_phi) as f64;
    let n = 200_000;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let accepted = (0..n)
        .filter(|_| {
            s.sample(wo, Vec2::new(rng.random(), rng.random()))
                .is_some()
        })
        .count() as f64
        / n as f64;
    // The acceptance rate's standard error is under 1.2e-3 at n = 200,000.
    assert!(
        (integral - accepted).abs() < 0.01,
        "{integral} against {accepted}"
    );
}

/// Saved and loaded, the sampler gives the same draws and storage; a
/// flipped byte and a truncated file are errors.
#[test]
fn file_round_trip() {
    let s = small(Arc::new(Brushed)).with_cosine_mix(0.1).unwrap();
    let bytes = s.to_bytes();
    assert!(persist::is_anisotropic(&bytes).unwrap());
    let t = AnisotropicOutgoingSampler::from_bytes(&bytes).unwrap();
    assert_eq!(t.storage_bytes(), s.storage_bytes());
    assert_eq!(t.brdf().fingerprint(), s.brdf().fingerprint());
    assert!(!t.brdf().is_isotropic());
    for wo in [direction(0.7, 0.4), direction(1.2, 5.0)] {
        for k in 0..100 {
            let u = Vec2::new((k as f32 + 0.5) / 100.0, (k as f32 * 0.618).fract());
            assert_eq!(s.sample(wo, u), t.sample(wo, u));
        }
    }
    let mut bad = bytes.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x10;
    assert!(AnisotropicOutgoingSampler::from_bytes(&bad).is_err());
    assert!(AnisotropicOutgoingSampler::from_bytes(&bytes[..bytes.len() - 3]).is_err());
    // The isotropic reader refuses the anisotropic layout, and the other way round.
    assert!(crate::OutgoingSampler::from_bytes(&bytes).is_err());
    let iso = crate::OutgoingSampler::new(
        nickel(),
        "8x1x64x16".parse().unwrap(),
        OutgoingBuilder::by_name("chi2", None, 16).unwrap(),
    )
    .unwrap()
    .to_bytes();
    assert!(!persist::is_anisotropic(&iso).unwrap());
    assert!(AnisotropicOutgoingSampler::from_bytes(&iso).is_err());
}

/// A well-sealed file whose fields lie is refused with a typed error
/// naming the field: φ_o breakpoints past a turn, θ_o breakpoints out of
/// order, and more slices than the bytes hold.
#[test]
fn hostile_files_are_typed_errors() {
    let s = small(Arc::new(Brushed));
    let field_of = |e: PersistErrorOf| match e {
        acdf_tabulated::persist::PersistError::Invalid { field, .. } => field,
        acdf_tabulated::persist::PersistError::FieldOverrun { field, .. } => field,
        other => panic!("unexpected {other}"),
    };
    type PersistErrorOf = acdf_tabulated::persist::PersistError;
    let mut bad = s.clone();
    bad.phi_breakpoints = vec![0.0, 1.5];
    let e = AnisotropicOutgoingSampler::from_bytes(&bad.to_bytes())
        .err()
        .unwrap();
    assert_eq!(field_of(e), "phi_o breakpoints");
    let mut bad = s.clone();
    bad.theta_breakpoints.swap(1, 2);
    let e = AnisotropicOutgoingSampler::from_bytes(&bad.to_bytes())
        .err()
        .unwrap();
    assert_eq!(field_of(e), "theta_o breakpoints");
    // Many φ_o breakpoints, few slices: the slice count overruns the file.
    let mut bad = s.clone();
    bad.phi_breakpoints = (0..4000).map(|k| k as f32 / 4000.0).collect();
    let e = AnisotropicOutgoingSampler::from_bytes(&bad.to_bytes())
        .err()
        .unwrap();
    assert_eq!(field_of(e), "slices");
    // A slice whose CDF runs backwards.
    let mut bad = s.clone();
    let slice = &bad.slices[1];
    let mut c = slice.marginal_cdf().to_vec();
    let last = c.len() - 2;
    c.swap(1, last);
    bad.slices[1] = PackedCdf2D::from_arrays(
        slice.marginal_pos(),
        &c,
        slice.offsets(),
        slice.conditional_pos().to_vec(),
        slice.conditional_cdf(),
    );
    let e = AnisotropicOutgoingSampler::from_bytes(&bad.to_bytes())
        .err()
        .unwrap();
    assert_eq!(field_of(e), "slice");
    assert!(AnisotropicOutgoingSampler::from_bytes(&s.to_bytes()).is_ok());
}

/// Bad parameters are typed errors.
#[test]
fn bad_parameters_are_refused() {
    let builder = OutgoingBuilder::by_name("chi2", None, 16).unwrap();
    let r = AnisotropicOutgoingSampler::new(
        Arc::new(Brushed),
        "8x8x64x16".parse().unwrap(),
        builder,
        0,
    );
    assert!(matches!(r, Err(Error::InvalidParameter { .. })));
}
