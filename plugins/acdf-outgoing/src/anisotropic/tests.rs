use super::*;
use rand::{Rng, SeedableRng};

/// An anisotropic Gaussian lobe on the half vector's slopes, wider along
/// x, over a small diffuse floor, turned by `turn` radians about the
/// normal and its centre moved to the slopes `shift`: unmoved
/// ([`brushed`]) it keeps both mirrors; turned, only the turn by π; moved
/// along x, only the mirror y → −y; moved along both, nothing.
struct Moved {
    turn: f32,
    shift: (f32, f32),
}
impl Brdf for Moved {
    fn name(&self) -> &str {
        "moved"
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if !(wo.z > 0.0 && wi.z > 0.0) {
            return Rgb::ZERO;
        }
        let h = (wo + wi).normalize_or_zero();
        if !(h.z > 0.0) {
            return Rgb::ZERO;
        }
        let (sx, sy) = (h.x / h.z - self.shift.0, h.y / h.z - self.shift.1);
        let (s, c) = self.turn.sin_cos();
        let (a, b) = (c * sx + s * sy, c * sy - s * sx);
        Rgb::splat(0.05 + 3.0 * (-(a * a / 0.09 + b * b / 0.0025)).exp())
    }
    fn is_isotropic(&self) -> bool {
        false
    }
}

/// The unmoved lobe.
fn brushed() -> Arc<dyn Brdf> {
    Arc::new(Moved {
        turn: 0.0,
        shift: (0.0, 0.0),
    })
}

fn nickel() -> Arc<dyn Brdf> {
    acdf_materials::builtin("nickel").expect("built-in nickel")
}

/// A small sampler round the whole φ_o circle (no symmetry used, so that
/// the seam and the rows' breakpoints are tested on the circle): 16 θ_o ×
/// 16 φ_o nodes, 64 × 16 half-vector cells.
fn small(brdf: Arc<dyn Brdf>) -> AnisotropicOutgoingSampler {
    small_with(brdf, Some(Symmetry::None))
}

/// [`small`] with the symmetry given (`None`: found).
fn small_with(brdf: Arc<dyn Brdf>, symmetry: Option<Symmetry>) -> AnisotropicOutgoingSampler {
    let builder = OutgoingBuilder::anisotropic_by_name("chi2", None, 16).unwrap();
    AnisotropicOutgoingSampler::with_symmetry(
        brdf,
        "8x8x64x16".parse().unwrap(),
        builder,
        16,
        symmetry,
    )
    .unwrap()
}

fn direction(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// The φ_o breakpoints adapt: an isotropic material, whose slices do not
/// depend on φ_o in the sampler's frame, keeps one φ_o breakpoint in every
/// θ_o row (one slice per row); the anisotropic lobe keeps several, and
/// each row keeps what its θ_o needs: one on the normal, where φ_o is
/// undefined (the lobe is measured in the absolute frame), and not the
/// same count in every row.
#[test]
fn phi_breakpoints_adapt_to_the_anisotropy() {
    let iso = small_with(nickel(), None);
    assert_eq!(iso.symmetry(), Symmetry::None);
    let rows = iso.phi_breakpoint_angles();
    assert!(rows.iter().all(|r| r == &[0.0]), "{rows:?}");
    assert_eq!(iso.slices().len(), iso.theta_breakpoint_angles().len());
    let aniso = small(brushed());
    assert_eq!(aniso.frame(), PhiFrame::Absolute);
    let rows = aniso.phi_breakpoint_angles();
    assert_eq!(rows.len(), aniso.theta_breakpoint_angles().len());
    assert_eq!(rows[0], vec![0.0]);
    let counts: Vec<usize> = rows.iter().map(Vec::len).collect();
    assert!(counts.iter().any(|&c| c >= 3), "{counts:?}");
    assert_eq!(aniso.slices().len(), counts.iter().sum::<usize>());
    for k in 0..rows.len() {
        assert_eq!(aniso.row_start(k), counts[..k].iter().sum::<usize>());
    }
    assert!(aniso.slices().len() > iso.slices().len());
}

/// A wo at breakpoint m of θ_o row k draws from that row's slice m alone
/// (its blend weight is 1 to rounding), for every row and breakpoint: each
/// row's φ_o breakpoints address its own slices.
#[test]
fn a_wo_at_a_breakpoint_blends_its_own_slice() {
    let s = small(brushed());
    let theta = s.theta_breakpoint_angles();
    for (k, row) in s.phi_breakpoint_angles().iter().enumerate() {
        // On the normal φ_o is 0 whatever the direction's azimuth.
        let theta_k = theta[k].min(89.99f32.to_radians());
        for (m, &phi) in row.iter().enumerate() {
            let (slices, weights) = s.blend_of(direction(theta_k, phi + 1e-5));
            let own: f32 = slices
                .iter()
                .zip(&weights)
                .filter(|&(&i, _)| i == s.row_start(k) + m)
                .map(|(_, &w)| w)
                .sum();
            assert!(
                own > 0.99,
                "row {k}, breakpoint {m}: {slices:?} {weights:?}"
            );
        }
    }
}

/// The row with the most φ_o breakpoints that has a row after it (at
/// least three breakpoints, so that wo can be put between its inner ones).
fn busiest_row(s: &AnisotropicOutgoingSampler) -> usize {
    let rows = s.phi_breakpoint_angles();
    let k = (0..rows.len() - 1).max_by_key(|&k| rows[k].len()).unwrap();
    assert!(rows[k].len() >= 3, "{rows:?}");
    k
}

/// Samples carry the density `pdf` reports, for wo on the normal, at and
/// between breakpoints, across the φ_o seam and next to the horizon, and
/// most draws return a direction (a draw from a slice tabulated at
/// another wo may reflect below the horizon; 89.7 to 96.3% return one at
/// these wo with the seed below).
#[test]
fn sample_and_pdf_agree() {
    let s = small(brushed()).with_cosine_mix(0.05).unwrap();
    let theta = s.theta_breakpoint_angles();
    let k = busiest_row(&s);
    let phi = &s.phi_breakpoint_angles()[k];
    let wos = [
        direction(0.0, 0.0),
        direction(theta[k], phi[1]),
        direction(0.5 * (theta[k] + theta[k + 1]), 0.5 * (phi[1] + phi[2])),
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
        assert!(drawn > 4_400, "{wo}: {drawn}");
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
    let s = small(brushed()).with_cosine_mix(0.05).unwrap();
    let theta = s.theta_breakpoint_angles();
    let k = busiest_row(&s);
    let phi = &s.phi_breakpoint_angles()[k];
    let mut rng = rand_pcg::Pcg64::seed_from_u64(26);
    let u: Vec<Vec2> = (0..200)
        .map(|_| Vec2::new(rng.random(), rng.random()))
        .chain([Vec2::ZERO, Vec2::new(1.0, -0.5), Vec2::new(f32::NAN, 0.5)])
        .collect();
    for wo in [
        direction(theta[k], phi[1]),
        direction(0.5 * (theta[k] + theta[k + 1]), 0.5 * (phi[1] + phi[2])),
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
/// inner φ_o breakpoint of a row, for θ_o halfway to the next row (both
/// rows blended): just below and just above, the densities of fixed wi
/// agree to within the change of the blend weights.
#[test]
fn pdf_is_continuous_in_phi_o() {
    let s = small(brushed());
    let k = busiest_row(&s);
    let phi = &s.phi_breakpoint_angles()[k];
    let rows = s.theta_breakpoint_angles();
    let theta = 0.5 * (rows[k] + rows[k + 1]);
    let wis = spread_wis();
    for at in [0.0, phi[phi.len() / 2]] {
        let compared = compare_densities(&s, &wis, |e| direction(theta, at + e));
        assert!(compared > 20, "φ_o {at}: {compared}");
    }
    // The slices on either side of the row's seam differ: the continuity
    // is the blend's.
    assert_ne!(
        s.slices()[s.row_start(k)],
        s.slices()[s.row_start(k + 1) - 1]
    );
}

/// The density is continuous in θ_o across a θ_o breakpoint whose row
/// keeps another number of φ_o breakpoints than the row before it: just
/// below and just above, the densities of fixed wi agree to within the
/// change of the blend weights.
#[test]
fn pdf_is_continuous_in_theta_o_between_rows_of_other_phi_o_breakpoints() {
    let s = small(brushed());
    let rows = s.phi_breakpoint_angles();
    let theta = s.theta_breakpoint_angles();
    let k = (1..rows.len() - 1)
        .find(|&k| rows[k].len() != rows[k - 1].len())
        .expect("rows of different φ_o breakpoint counts");
    let wis = spread_wis();
    for phi_o in [0.4f32, 2.9] {
        let compared = compare_densities(&s, &wis, |e| direction(theta[k] + e, phi_o));
        assert!(compared > 20, "θ_o {}: {compared}", theta[k]);
    }
}

/// Directions spread over the upper hemisphere.
fn spread_wis() -> Vec<Vec3> {
    (0..40)
        .map(|k| direction(0.02 + 1.5 * k as f32 / 40.0, 0.3 + 0.15 * k as f32))
        .collect()
}

/// Compare the densities of `wis` at `wo(-1e-4)` and `wo(1e-4)`: within 2%
/// where positive; the number of positive ones compared.
fn compare_densities(
    s: &AnisotropicOutgoingSampler,
    wis: &[Vec3],
    wo: impl Fn(f32) -> Vec3,
) -> usize {
    let mut compared = 0;
    for &wi in wis {
        let below = s.pdf(wo(-1e-4), wi);
        let above = s.pdf(wo(1e-4), wi);
        if below > 0.0 {
            compared += 1;
            assert!(
                (below - above).abs() <= 0.02 * below,
                "{below} against {above} at {wi}"
            );
        }
    }
    compared
}

/// The density integrates (midpoint rule on 256 × 512 equal-area cells of
/// wi) to the share of draws that return a direction, for wo between
/// breakpoints: a draw from a slice tabulated at another θ_o may reflect
/// below the horizon and is refused, and the four-slice mixture is
/// otherwise normalised.
#[test]
fn pdf_integrates_to_the_acceptance_rate() {
    let s = small(brushed());
    let theta = s.theta_breakpoint_angles();
    let k = busiest_row(&s);
    let phi = &s.phi_breakpoint_angles()[k];
    let wo = direction(0.5 * (theta[k] + theta[k + 1]), 0.5 * (phi[0] + phi[1]));
    assert_pdf_integrates_to_the_acceptance_rate(&s, wo, 7);
}

/// The density at `wo` integrated (midpoint rule on 256 × 512 equal-area
/// cells of wi) is within 0.01 of the share of 200,000 draws (seed
/// `seed`) that return a direction; the acceptance rate's standard error
/// is under 1.2e-3 at that count.
fn assert_pdf_integrates_to_the_acceptance_rate(
    s: &AnisotropicOutgoingSampler,
    wo: Vec3,
    seed: u64,
) {
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
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
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
    let s = small(brushed()).with_cosine_mix(0.1).unwrap();
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
        OutgoingBuilder::anisotropic_by_name("chi2", None, 16).unwrap(),
    )
    .unwrap()
    .to_bytes();
    assert!(!persist::is_anisotropic(&iso).unwrap());
    assert!(AnisotropicOutgoingSampler::from_bytes(&iso).is_err());
}

/// A file of the earlier layout, one set of φ_o breakpoints for every θ_o
/// row, is taken for an anisotropic file and refused with the reason.
#[test]
fn tensor_layout_files_are_refused_with_the_reason() {
    let mut w = acdf_tabulated::persist::ByteWriter::new();
    w.string(crate::persist::KIND);
    w.u32(2);
    w.string("outgoing:chi2");
    let bytes = acdf_tabulated::persist::seal(&w.into_bytes());
    assert!(persist::is_anisotropic(&bytes).unwrap());
    let e = AnisotropicOutgoingSampler::from_bytes(&bytes)
        .err()
        .unwrap();
    assert!(e.to_string().contains("build the sampler again"), "{e}");
}

/// A well-sealed file whose fields lie is refused with a typed error
/// naming the field: φ_o breakpoints past a turn, θ_o breakpoints out of
/// order, and more slices than the bytes hold.
#[test]
fn hostile_files_are_typed_errors() {
    let s = small(brushed());
    let field_of = |e: PersistErrorOf| match e {
        acdf_tabulated::persist::PersistError::Invalid { field, .. } => field,
        acdf_tabulated::persist::PersistError::FieldOverrun { field, .. } => field,
        other => panic!("unexpected {other}"),
    };
    type PersistErrorOf = acdf_tabulated::persist::PersistError;
    let mut bad = s.clone();
    bad.phi_breakpoints[1] = vec![0.0, 1.5];
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
    bad.phi_breakpoints[0] = (0..4000).map(|k| k as f32 / 4000.0).collect();
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
    let builder = OutgoingBuilder::anisotropic_by_name("chi2", None, 16).unwrap();
    let r = AnisotropicOutgoingSampler::new(brushed(), "8x8x64x16".parse().unwrap(), builder, 0);
    assert!(matches!(r, Err(Error::InvalidParameter { .. })));
}

/// The builder finds the largest symmetry each lobe has: both mirrors for
/// the brushed lobe, the turn by π for it turned, the mirror y → −y for
/// it moved along x, none for it moved along both axes.
#[test]
fn the_symmetry_found_is_the_lobes() {
    let moved = |turn, shift| Arc::new(Moved { turn, shift }) as Arc<dyn Brdf>;
    for (brdf, expected) in [
        (brushed(), Symmetry::MirrorXY),
        (moved(0.5, (0.0, 0.0)), Symmetry::HalfTurn),
        (moved(0.0, (0.2, 0.0)), Symmetry::MirrorY),
        (moved(0.0, (0.2, 0.15)), Symmetry::None),
    ] {
        assert_eq!(small_with(brdf, None).symmetry(), expected);
    }
}

/// With both mirrors the slices cover a quarter of the φ_o circle: every
/// row's φ_o breakpoints end at 1/4 turn (or the row keeps one, on the
/// normal), fewer slices than round the circle; in every quadrant the
/// density is the arc's at the mirrored pair (bit for bit), draws carry
/// the density `pdf` reports, and the density integrates to the share of
/// draws that return a direction.
#[test]
fn mirrors_keep_a_quarter_of_the_circle() {
    let s = small_with(brushed(), None).with_cosine_mix(0.05).unwrap();
    assert_eq!(s.symmetry(), Symmetry::MirrorXY);
    for row in &s.phi_breakpoints {
        assert!(row.len() == 1 || row[row.len() - 1] == 0.25, "{row:?}");
    }
    assert!(s.slices().len() < small(brushed()).slices().len());
    let mut rng = rand_pcg::Pcg64::seed_from_u64(27);
    for phi in [0.4f32, 2.0, 3.5, 5.5] {
        let wo = direction(0.8, phi);
        for _ in 0..2_000 {
            let u = Vec2::new(rng.random(), rng.random());
            let Some(d) = s.sample(wo, u) else { continue };
            assert_eq!(d.pdf, s.pdf(wo, d.wi));
            let m = Vec3::new(wo.x.abs(), wo.y.abs(), wo.z);
            let mi = Vec3::new(d.wi.x * wo.x.signum(), d.wi.y * wo.y.signum(), d.wi.z);
            assert_eq!(d.pdf.to_bits(), s.pdf(m, mi).to_bits());
        }
    }
    // The third quadrant, between rows and breakpoints.
    assert_pdf_integrates_to_the_acceptance_rate(&s, direction(0.9, 3.9), 28);
}

/// A symmetric sampler saved and loaded keeps its arc and draws; an arc
/// that does not fit the file's node counts and a row that does not end
/// at the arc's end are typed errors.
#[test]
fn symmetric_file_round_trip() {
    let s = small_with(brushed(), None);
    let t = AnisotropicOutgoingSampler::from_bytes(&s.to_bytes()).unwrap();
    assert_eq!(t.symmetry(), Symmetry::MirrorXY);
    for k in 0..100 {
        let u = Vec2::new((k as f32 + 0.5) / 100.0, (k as f32 * 0.618).fract());
        let wo = direction(0.7, 4.0);
        assert_eq!(s.sample(wo, u), t.sample(wo, u));
    }
    let mut bad = s.clone();
    let k = bad
        .phi_breakpoints
        .iter()
        .position(|r| r.len() > 1)
        .unwrap();
    let last = bad.phi_breakpoints[k].len() - 1;
    bad.phi_breakpoints[k][last] = 0.3;
    let e = AnisotropicOutgoingSampler::from_bytes(&bad.to_bytes())
        .err()
        .unwrap();
    assert!(e.to_string().contains("phi_o breakpoints"), "{e}");
    let mut bad = s.clone();
    bad.fine_phi = 18;
    let e = AnisotropicOutgoingSampler::from_bytes(&bad.to_bytes())
        .err()
        .unwrap();
    assert!(e.to_string().contains("phi_o symmetry"), "{e}");
}
