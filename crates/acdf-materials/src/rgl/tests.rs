//! Tests of the tensor reader, the bilinear warp and the RGL evaluation,
//! including the Mitsuba 3 reference values when the shared data is present.

use super::*;
use acdf_core::{Distribution2D, Vec2};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};

use super::{shared_dir as rgl_dir, SHARED_FILES as FILES};

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A small valid material: n_θ = 3 slices, 5 × 5 vndf, 4 × 4 luminance and
/// RGB grids, with some negative RGB values.
fn synthetic_bytes() -> Vec<u8> {
    synthetic_bytes_with(|_, _| {})
}

/// [`synthetic_bytes`] after `change(name, values)` on each float field.
fn synthetic_bytes_with(change: impl Fn(&str, &mut Vec<f32>)) -> Vec<u8> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let (nt, vn, n) = (3usize, 5usize, 4usize);
    let theta: Vec<f32> = vec![0.0, 0.7, 1.5];
    let phi: Vec<f32> = vec![0.0];
    let sigma: Vec<f32> = (0..10).map(|i| 1.0 + 0.1 * (i % 5) as f32).collect();
    let ndf: Vec<f32> = (0..10).map(|i| 2.0 - 0.3 * (i % 5) as f32).collect();
    let vndf: Vec<f32> = (0..nt * vn * vn)
        .map(|k| {
            if k % vn == 0 {
                0.0
            } else {
                rng.random::<f32>() + 0.1
            }
        })
        .collect();
    let lum: Vec<f32> = (0..nt * n * n)
        .map(|_| rng.random::<f32>() + 0.05)
        .collect();
    let rgb: Vec<f32> = (0..nt * 3 * n * n)
        .map(|_| rng.random::<f32>() * 2.0 - 0.5)
        .collect();
    let changed = |name: &str, mut v: Vec<f32>| {
        change(name, &mut v);
        v
    };
    let (theta, phi, sigma, ndf) = (
        changed("theta_i", theta),
        changed("phi_i", phi),
        changed("sigma", sigma),
        changed("ndf", ndf),
    );
    let (vndf, lum, rgb) = (
        changed("vndf", vndf),
        changed("luminance", lum),
        changed("rgb", rgb),
    );
    write_tensor_file(&[
        ("version", Dtype::U32, &[2], &[1, 0, 0, 0, 0, 0, 0, 0]),
        ("description", Dtype::U8, &[4], b"test"),
        ("phi_i", Dtype::F32, &[1], &f32_bytes(&phi)),
        ("theta_i", Dtype::F32, &[nt], &f32_bytes(&theta)),
        ("sigma", Dtype::F32, &[2, 5], &f32_bytes(&sigma)),
        ("ndf", Dtype::F32, &[2, 5], &f32_bytes(&ndf)),
        ("vndf", Dtype::F32, &[1, nt, vn, vn], &f32_bytes(&vndf)),
        ("luminance", Dtype::F32, &[1, nt, n, n], &f32_bytes(&lum)),
        ("rgb", Dtype::F32, &[1, nt, 3, n, n], &f32_bytes(&rgb)),
        ("jacobian", Dtype::U8, &[1], &[1]),
    ])
}

fn synthetic() -> RglBrdf {
    RglBrdf::from_tensor(&TensorFile::from_bytes(&synthetic_bytes()).unwrap(), "syn").unwrap()
}

fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    acdf_core::geometry::spherical_direction(theta_deg.to_radians(), phi_deg.to_radians())
}

// ---------------------------------------------------------------- tensor file

#[test]
fn tensor_file_round_trips_fields() {
    let f = TensorFile::from_bytes(&synthetic_bytes()).unwrap();
    assert_eq!(f.version(), (1, 0));
    assert_eq!(f.fields().len(), 10);
    let theta = f.field("theta_i").unwrap();
    assert_eq!(theta.dtype, Dtype::F32);
    assert_eq!(theta.shape, vec![3]);
    assert_eq!(theta.to_f32(), vec![0.0, 0.7, 1.5]);
    assert_eq!(theta.offset % 8, 0);
    assert_eq!(f.field("description").unwrap().bytes(), b"test");
    assert_eq!(f.field("version").unwrap().to_f64(), vec![1.0, 0.0]);
    assert!(f.field("nope").is_none());
    assert!(matches!(f.require("nope"), Err(RglError::MissingField(n)) if n == "nope"));
}

#[test]
fn every_dtype_converts() {
    let f16_bytes = [0x00u8, 0x3c, 0x00, 0xc0, 0x01, 0x00, 0x00, 0x7c]; // 1, -2, 2^-24, inf
    let bytes = write_tensor_file(&[
        ("a", Dtype::I8, &[2], &[0xff, 3]),
        ("b", Dtype::I16, &[1], &(-300i16).to_le_bytes()),
        ("c", Dtype::U64, &[1], &7u64.to_le_bytes()),
        ("d", Dtype::I64, &[1], &(-9i64).to_le_bytes()),
        ("e", Dtype::F64, &[1], &0.25f64.to_le_bytes()),
        ("f", Dtype::F16, &[4], &f16_bytes),
        ("g", Dtype::U16, &[1], &500u16.to_le_bytes()),
        ("h", Dtype::I32, &[1], &(-5i32).to_le_bytes()),
    ]);
    let f = TensorFile::from_bytes(&bytes).unwrap();
    let v = |n: &str| f.field(n).unwrap().to_f64();
    assert_eq!(v("a"), vec![-1.0, 3.0]);
    assert_eq!(v("b"), vec![-300.0]);
    assert_eq!(v("c"), vec![7.0]);
    assert_eq!(v("d"), vec![-9.0]);
    assert_eq!(v("e"), vec![0.25]);
    assert_eq!(v("f"), vec![1.0, -2.0, 2f64.powi(-24), f64::INFINITY]);
    assert_eq!(v("g"), vec![500.0]);
    assert_eq!(v("h"), vec![-5.0]);
    assert_eq!(f.field("e").unwrap().to_f32(), vec![0.25]);
}

/// Patch the header of a one-field file and return the parse error.
fn one_field_error(patch: impl Fn(&mut Vec<u8>)) -> RglError {
    let mut b = write_tensor_file(&[("x", Dtype::F32, &[2], &f32_bytes(&[1.0, 2.0]))]);
    patch(&mut b);
    TensorFile::from_bytes(&b).unwrap_err()
}

// Layout of the one-field file: magic 0..12, version 12..14, count 14..18,
// name_len 18..20, name 20, ndim 21..23, dtype 23, offset 24..32, shape 32..40.
#[test]
fn header_errors_have_their_own_variants() {
    assert!(matches!(
        one_field_error(|b| b[0] = b'T'),
        RglError::BadMagic
    ));
    assert!(matches!(
        TensorFile::from_bytes(b"tensor"),
        Err(RglError::BadMagic)
    ));
    assert!(matches!(
        one_field_error(|b| b[12] = 2),
        RglError::Version { major: 2, minor: 0 }
    ));
    assert!(matches!(
        one_field_error(|b| b[23] = 12),
        RglError::Dtype { .. }
    ));
    assert!(matches!(
        one_field_error(|b| b[23] = 0),
        RglError::Dtype { .. }
    ));
    assert!(matches!(
        one_field_error(|b| b[24..32].copy_from_slice(&(1u64 << 40).to_le_bytes())),
        RglError::OutOfBounds { .. }
    ));
    assert!(matches!(
        one_field_error(|b| b[24..32].copy_from_slice(&u64::MAX.to_le_bytes())),
        RglError::OutOfBounds { .. }
    ));
    assert!(matches!(
        one_field_error(|b| b[32..40].copy_from_slice(&(u64::MAX / 2).to_le_bytes())),
        RglError::Shape { .. }
    ));
    assert!(matches!(
        one_field_error(|b| b[32..40].copy_from_slice(&3u64.to_le_bytes())),
        RglError::OutOfBounds { .. }
    ));
    assert!(matches!(
        one_field_error(|b| b[14] = 2),
        RglError::Field { index: 1, .. }
    ));
    assert!(matches!(
        one_field_error(|b| b.truncate(30)),
        RglError::Field { index: 0, .. }
    ));
    assert!(matches!(
        one_field_error(|b| b[20] = 0xff),
        RglError::Field { .. }
    ));
    assert!(matches!(
        one_field_error(|b| b.truncate(15)),
        RglError::Field { .. }
    ));
    let dup = write_tensor_file(&[("x", Dtype::U8, &[1], &[1]), ("x", Dtype::U8, &[1], &[1])]);
    assert!(matches!(
        TensorFile::from_bytes(&dup),
        Err(RglError::Field { index: 1, .. })
    ));
}

/// A field's dtype, shape and bytes, as `write_tensor_file` takes them.
type FieldParts = (Dtype, Vec<usize>, Vec<u8>);

#[test]
fn material_errors_name_the_field() {
    let base = TensorFile::from_bytes(&synthetic_bytes()).unwrap();
    let rebuild = |edit: &dyn Fn(&str, &TensorField) -> Option<FieldParts>| {
        let owned: Vec<(String, Dtype, Vec<usize>, Vec<u8>)> = base
            .fields()
            .iter()
            .filter_map(|f| edit(&f.name, f).map(|(d, s, b)| (f.name.clone(), d, s, b)))
            .collect();
        let refs: Vec<(&str, Dtype, &[usize], &[u8])> = owned
            .iter()
            .map(|(n, d, s, b)| (n.as_str(), *d, s.as_slice(), b.as_slice()))
            .collect();
        let t = TensorFile::from_bytes(&write_tensor_file(&refs)).unwrap();
        RglBrdf::from_tensor(&t, "x").unwrap_err()
    };
    let keep = |f: &TensorField| Some((f.dtype, f.shape.clone(), f.bytes().to_vec()));
    let e = rebuild(&|n, f| if n == "ndf" { None } else { keep(f) });
    assert!(
        matches!(e, RglError::MissingField(ref n) if n == "ndf"),
        "{e}"
    );
    let e = rebuild(&|n, f| {
        if n == "vndf" {
            let mut v = f.to_f32();
            v[7] = f32::NAN;
            Some((f.dtype, f.shape.clone(), f32_bytes(&v)))
        } else {
            keep(f)
        }
    });
    assert!(
        matches!(e, RglError::NonFinite { ref field, index: 7, .. } if field == "vndf"),
        "{e}"
    );
    let e = rebuild(&|n, f| {
        if n == "theta_i" {
            Some((f.dtype, f.shape.clone(), f32_bytes(&[0.0, 0.7, 0.7])))
        } else {
            keep(f)
        }
    });
    assert!(
        matches!(e, RglError::Invalid { ref field, .. } if field == "theta_i"),
        "{e}"
    );
    let e = rebuild(&|n, f| {
        if n == "rgb" {
            Some((f.dtype, vec![1, 3, 3, 16], f.bytes().to_vec()))
        } else {
            keep(f)
        }
    });
    assert!(
        matches!(e, RglError::Shape { ref field, .. } if field == "rgb"),
        "{e}"
    );
    let e = rebuild(&|n, f| {
        if n == "sigma" {
            Some((Dtype::U32, f.shape.clone(), f.bytes().to_vec()))
        } else {
            keep(f)
        }
    });
    assert!(
        matches!(e, RglError::Dtype { ref field, .. } if field == "sigma"),
        "{e}"
    );
}

/// Finding 10 of issue 29: a field whose data overlaps the header or
/// another field, angles outside their range and tables of zeros are typed
/// errors (such files loaded and returned values like 2.6e33).
#[test]
fn overlapping_fields_wild_angles_and_zero_tables_are_refused() {
    let good = synthetic_bytes();
    let rgb_offset = TensorFile::from_bytes(&good)
        .unwrap()
        .field("rgb")
        .unwrap()
        .offset;
    // The descriptor: name length, "rgb", dimension count, dtype, offset.
    let name_at = good.windows(5).position(|w| w == b"\x03\x00rgb").unwrap() + 2;
    let offset_at = name_at + 3 + 2 + 1;
    assert_eq!(good[offset_at..offset_at + 8], rgb_offset.to_le_bytes());
    for (offset, overlapped) in [(0u64, "the header"), (rgb_offset - 8, "field `luminance`")] {
        let mut bad = good.clone();
        bad[offset_at..offset_at + 8].copy_from_slice(&offset.to_le_bytes());
        let e = TensorFile::from_bytes(&bad).unwrap_err();
        assert!(
            matches!(&e, RglError::Overlap { field, .. } if field == "rgb"),
            "{e}"
        );
        assert!(e.to_string().contains(overlapped), "{e}");
    }
    let invalid = |bytes: Vec<u8>, field: &str| {
        let e = RglBrdf::from_tensor(&TensorFile::from_bytes(&bytes).unwrap(), "bad").unwrap_err();
        assert!(
            matches!(&e, RglError::Invalid { field: f, .. } if f == field),
            "{field}: {e}"
        );
    };
    // The field edited (and named in the error), and the edit.
    type Edit = fn(&mut [f32]);
    let cases: [(&str, Edit); 9] = [
        ("theta_i", |v| v[2] = 300.0),
        ("theta_i", |v| v[0] = -0.5),
        ("phi_i", |v| v[0] = 100.0),
        ("vndf", |v| v.fill(0.0)),
        ("sigma", |v| v.fill(0.0)),
        ("luminance", |v| v.fill(0.0)),
        ("ndf", |v| v.fill(0.0)),
        ("rgb", |v| v.fill(0.0)),
        // One slice of zeros is enough to refuse a density.
        ("vndf", |v| v[25..50].fill(0.0)),
    ];
    for (field, edit) in cases {
        invalid(
            synthetic_bytes_with(|n, v| {
                if n == field {
                    edit(v)
                }
            }),
            field,
        );
    }
    invalid(
        synthetic_bytes_with(|n, v| {
            if n == "sigma" {
                v[3] = -1.0
            }
        }),
        "sigma",
    );
}

#[test]
fn errors_from_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("broken.bsdf");
    std::fs::write(&p, b"not a tensor").unwrap();
    let e = RglBrdf::open(&p).unwrap_err();
    assert!(matches!(e.kind(), RglError::BadMagic));
    assert!(e.to_string().contains("broken.bsdf"), "{e}");
    let e = RglBrdf::open(dir.path().join("missing.bsdf")).unwrap_err();
    assert!(matches!(e, RglError::File(_)) && e.to_string().contains("missing.bsdf"));
    let p = dir.path().join("good_one.bsdf");
    std::fs::write(&p, synthetic_bytes()).unwrap();
    let b = RglBrdf::open(&p).unwrap();
    assert_eq!(b.name(), "good_one");
    assert_eq!(b.description(), "test");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// Any byte string parses or fails with an error; never a panic.
    #[test]
    fn random_bytes_never_panic(mut bytes in proptest::collection::vec(any::<u8>(), 0..200), magic in any::<bool>()) {
        if magic && bytes.len() >= 14 {
            bytes[..12].copy_from_slice(TENSOR_MAGIC);
            bytes[12] = 1;
        }
        if let Ok(t) = TensorFile::from_bytes(&bytes) {
            let _ = RglBrdf::from_tensor(&t, "x");
        }
    }

    /// A valid file with a few bytes of its header (or anywhere) overwritten
    /// or the file cut short: an error or a usable material, never a panic,
    /// and a material that loads evaluates to finite values.
    #[test]
    fn mutated_files_never_panic(
        edits in proptest::collection::vec((0usize..1000, any::<u8>()), 1..6),
        cut in proptest::option::of(0usize..3000),
    ) {
        let mut bytes = synthetic_bytes();
        let header_len = 512.min(bytes.len());
        for (pos, v) in edits {
            let i = if pos < 800 { pos % header_len } else { pos * 7 % bytes.len() };
            bytes[i] = v;
        }
        if let Some(c) = cut {
            bytes.truncate(c.min(bytes.len()));
        }
        if let Ok(t) = TensorFile::from_bytes(&bytes) {
            if let Ok(b) = RglBrdf::from_tensor(&t, "x") {
                for (wo, wi) in [(dir(10.0, 0.0), dir(40.0, 170.0)), (Vec3::Z, Vec3::Z)] {
                    let f = b.eval(wo, wi);
                    prop_assert!(f.is_finite() && f.min_element() >= 0.0);
                }
            }
        }
    }

    /// eval is finite and non-negative for any pair of directions, including
    /// non-unit and degenerate ones.
    #[test]
    fn eval_is_finite_and_non_negative(
        a in proptest::array::uniform3(-2.0f32..2.0), b in proptest::array::uniform3(-2.0f32..2.0)
    ) {
        let brdf = synthetic();
        let f = brdf.eval(Vec3::from(a), Vec3::from(b));
        prop_assert!(f.is_finite() && f.min_element() >= 0.0);
        if a[2] <= 0.0 || b[2] <= 0.0 {
            prop_assert_eq!(f, Vec3::ZERO);
        }
    }
}

// ------------------------------------------------------------ bilinear warp

fn random_grid(nx: usize, ny: usize, seed: u64) -> Vec<f32> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    (0..nx * ny)
        .map(|k| if k % 7 == 3 { 0.0 } else { rng.random::<f32>() })
        .collect()
}

#[test]
fn bilinear_sample_and_invert_are_inverse() {
    let d = Bilinear2D::new(6, 5, &random_grid(6, 5, 1)).unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(2);
    for _ in 0..20_000 {
        let u = DVec2::new(rng.random(), rng.random());
        let (p, pdf) = d.view().sample(u);
        let (back, pdf2) = d.view().invert(p);
        assert!(
            (back - u).abs().max_element() < 1e-5,
            "{u} -> {p} -> {back}"
        );
        assert!((pdf - pdf2).abs() <= 1e-6 * pdf.max(1.0));
        assert!(pdf > 0.0);
        approx::assert_relative_eq!(pdf, d.view().density(p), max_relative = 1e-9);
    }
}

/// The density integrates to 1 (midpoint rule, exact enough for a bilinear
/// function on a fine grid) and the integral of the raw values is reported.
#[test]
fn bilinear_density_integrates_to_one() {
    let values = random_grid(4, 7, 3);
    let d = Bilinear2D::new(4, 7, &values).unwrap();
    let n = 600;
    let mut sum = 0.0;
    for a in 0..n {
        for b in 0..n {
            let p = Vec2::new((a as f32 + 0.5) / n as f32, (b as f32 + 0.5) / n as f32);
            sum += d.pdf(p) as f64;
        }
    }
    approx::assert_relative_eq!(sum / (n * n) as f64, 1.0, max_relative = 1e-4);
    // Σ_cells mean(corners) / ((nx-1)(ny-1)).
    let v = |i: usize, j: usize| values[j * 4 + i] as f64;
    let mut expect = 0.0;
    for j in 0..6 {
        for i in 0..3 {
            expect += (v(i, j) + v(i + 1, j) + v(i, j + 1) + v(i + 1, j + 1)) / 4.0;
        }
    }
    approx::assert_relative_eq!(d.integral(), expect / 18.0, max_relative = 1e-9);
    assert_eq!(d.pdf(Vec2::new(1.0, 0.5)), 0.0);
    assert_eq!(d.pdf(Vec2::new(f32::NAN, 0.5)), 0.0);
}

/// Histogram of 200k samples on a 10 × 10 grid against the integrated density:
/// chi-square with 99 degrees of freedom below 150 (significance about 6e-4).
#[test]
fn bilinear_samples_follow_the_density() {
    let d = Bilinear2D::new(5, 4, &random_grid(5, 4, 4)).unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    let (nb, n) = (10usize, 200_000usize);
    let mut hist = vec![0f64; nb * nb];
    for _ in 0..n {
        let s = d.sample(Vec2::new(rng.random(), rng.random()));
        assert!(s.p.x < 1.0 && s.p.y < 1.0 && s.pdf > 0.0);
        hist[(s.p.y * nb as f32) as usize * nb + (s.p.x * nb as f32) as usize] += 1.0;
    }
    let sub = 20;
    let mut chi2 = 0.0;
    for by in 0..nb {
        for bx in 0..nb {
            let mut mass = 0.0;
            for a in 0..sub {
                for b in 0..sub {
                    let p = Vec2::new((bx * sub + a) as f32 + 0.5, (by * sub + b) as f32 + 0.5)
                        / (nb * sub) as f32;
                    mass += d.pdf(p) as f64;
                }
            }
            let expected = mass / (nb * nb * sub * sub) as f64 * n as f64;
            chi2 += (hist[by * nb + bx] - expected).powi(2) / expected;
        }
    }
    assert!(chi2 < 150.0, "chi2 = {chi2}");
}

#[test]
fn bilinear_edge_cases() {
    let zero = Bilinear2D::new(3, 3, &[0.0; 9]).unwrap();
    assert_eq!(zero.integral(), 0.0);
    approx::assert_relative_eq!(zero.pdf(Vec2::new(0.3, 0.6)), 1.0, max_relative = 1e-6);
    let s = zero.sample(Vec2::new(0.25, 0.75));
    assert!((s.p - Vec2::new(0.25, 0.75)).length() < 1e-6);
    assert!(matches!(
        Bilinear2D::new(0, 3, &[]),
        Err(acdf_core::Error::EmptyTable { .. })
    ));
    // One vertex along x: constant in x, linear in y.
    let col = Bilinear2D::new(1, 3, &[1.0, 2.0, 3.0]).unwrap();
    approx::assert_relative_eq!(col.pdf(Vec2::new(0.1, 0.5)), 1.0, max_relative = 1e-6);
    approx::assert_relative_eq!(col.pdf(Vec2::new(0.9, 0.0)), 0.5, max_relative = 1e-6);
    approx::assert_relative_eq!(col.integral(), 2.0, max_relative = 1e-9);
    assert!(Bilinear2D::new(3, 3, &[1.0; 8]).is_err());
    assert!(Bilinear2D::new(2, 2, &[1.0, f32::NAN, 1.0, 1.0]).is_err());
    let d = Bilinear2D::new(3, 2, &[0.0, 1.0, 0.0, 0.0, 2.0, 0.0]).unwrap();
    for u in [
        Vec2::new(f32::NAN, -1.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(2.0, f32::INFINITY),
        Vec2::ZERO,
    ] {
        let s = d.sample(u);
        assert!(s.p.is_finite() && s.p.cmplt(Vec2::ONE).all() && s.p.cmpge(Vec2::ZERO).all());
        assert!(s.pdf.is_finite());
        let back = d.invert(s.p);
        assert!(back.is_finite());
    }
}

#[test]
fn param_blend_follows_the_axes() {
    let axis = [0.0f32, 1.0, 3.0];
    let b = ParamBlend::new(&[0.0], &axis, 5.0, 2.0);
    let t: Vec<_> = b.terms().collect();
    assert_eq!(t, vec![(1, 0.5), (2, 0.5)]);
    let b = ParamBlend::new(&[0.0], &axis, 0.0, -1.0);
    assert_eq!(b.terms().collect::<Vec<_>>(), vec![(0, 1.0)]);
    let b = ParamBlend::new(&[0.0], &axis, 0.0, 9.0);
    assert_eq!(b.terms().collect::<Vec<_>>(), vec![(2, 1.0)]);
    let b = ParamBlend::new(&[0.0], &axis, 0.0, f64::NAN);
    assert_eq!(b.terms().collect::<Vec<_>>(), vec![(0, 1.0)]);
    // Two axes: slice = k0 · 3 + k1.
    let b = ParamBlend::new(&[0.0, 2.0], &axis, 0.5, 0.5);
    let mut t: Vec<_> = b.terms().collect();
    t.sort_by_key(|x| x.0);
    assert_eq!(t, vec![(0, 0.375), (1, 0.375), (3, 0.125), (4, 0.125)]);
}

/// A blend of two slices samples the blended density, which is also what
/// its inverse undoes.
#[test]
fn blended_stack_samples_the_blend() {
    let mut values = random_grid(5, 5, 8);
    values.extend(random_grid(5, 5, 9));
    let stack = BilinearStack::new(2, 5, 5, &values).unwrap();
    let blend = ParamBlend::new(&[0.0], &[0.0, 1.0], 0.0, 0.3);
    let view = stack.at(blend);
    approx::assert_relative_eq!(view.total(), 1.0, max_relative = 1e-6);
    let (a, b) = (stack.slices()[0].view(), stack.slices()[1].view());
    let mut rng = rand_pcg::Pcg64::seed_from_u64(10);
    for _ in 0..5000 {
        let u = DVec2::new(rng.random(), rng.random());
        let (p, pdf) = view.sample(u);
        let expect = 0.7 * a.density(p) + 0.3 * b.density(p);
        approx::assert_relative_eq!(pdf, expect, max_relative = 1e-9);
        let (back, _) = view.invert(p);
        assert!((back - u).abs().max_element() < 1e-5);
    }
}

// ------------------------------------------------------------ evaluation

/// Negative density entries read as zero: the material equals the one with
/// those entries set to 0.
#[test]
fn negative_density_entries_count_as_zero() {
    let base = TensorFile::from_bytes(&synthetic_bytes()).unwrap();
    let with = |v3: f32| {
        let owned: Vec<(String, Dtype, Vec<usize>, Vec<u8>)> = base
            .fields()
            .iter()
            .map(|f| {
                let mut bytes = f.bytes().to_vec();
                if f.name == "luminance" {
                    let mut v = f.to_f32();
                    v[3] = v3;
                    bytes = f32_bytes(&v);
                }
                (f.name.clone(), f.dtype, f.shape.clone(), bytes)
            })
            .collect();
        let refs: Vec<(&str, Dtype, &[usize], &[u8])> = owned
            .iter()
            .map(|(n, d, s, b)| (n.as_str(), *d, s.as_slice(), b.as_slice()))
            .collect();
        RglBrdf::from_tensor(
            &TensorFile::from_bytes(&write_tensor_file(&refs)).unwrap(),
            "x",
        )
        .unwrap()
    };
    let (neg, zero) = (with(-1.0), with(0.0));
    assert_eq!(neg.luminance_density(), zero.luminance_density());
}

#[test]
fn synthetic_material_keeps_the_brdf_contract() {
    let b = synthetic();
    assert!(b.is_isotropic());
    assert_eq!(b.grid_size(), (4, 4));
    assert_eq!(b.theta_i(), &[0.0, 0.7, 1.5]);
    // Some direction pair has a negative unclipped channel, which eval clamps.
    let mut rng = rand_pcg::Pcg64::seed_from_u64(12);
    let mut negatives = 0;
    for _ in 0..2000 {
        let wo = dir(rng.random::<f32>() * 89.0, rng.random::<f32>() * 360.0);
        let wi = dir(rng.random::<f32>() * 89.0, rng.random::<f32>() * 360.0);
        let raw = b.eval_unclipped(wo, wi);
        let f = b.eval(wo, wi);
        for c in 0..3 {
            assert_eq!(f[c], raw[c].max(0.0) as f32);
            negatives += (raw[c] < 0.0) as usize;
        }
        let fc = b.fr_cos_unclipped(wo, wi);
        assert!((raw * wi.z as f64 - fc).abs().max_element() <= 1e-5 * fc.abs().max_element());
    }
    assert!(negatives > 0);
    assert_eq!(b.eval(Vec3::Z, -Vec3::Z), Vec3::ZERO);
    assert_eq!(b.eval(Vec3::new(1.0, 0.0, 0.0), Vec3::Z), Vec3::ZERO);
    assert_eq!(b.eval(Vec3::splat(f32::NAN), Vec3::Z), Vec3::ZERO);
    assert_eq!(b.eval(Vec3::ZERO, Vec3::Z), Vec3::ZERO);
    // A grazing wi keeps f_r finite.
    let f = b.eval(dir(30.0, 0.0), Vec3::new(1.0, 0.0, 1e-30));
    assert!(f.is_finite());
}

/// Isotropy: rotating both directions about the normal leaves f_r unchanged.
#[test]
fn synthetic_material_is_rotation_invariant() {
    let b = synthetic();
    for (t, p) in [(20.0, 30.0), (50.0, 200.0), (80.0, 300.0)] {
        let (wo, wi) = (dir(t, 10.0), dir(40.0, p));
        let rot = glam::Quat::from_rotation_z(1.234);
        let f = b.eval_unclipped(wo, wi);
        let g = b.eval_unclipped(rot * wo, rot * wi);
        assert!((f - g).abs().max_element() <= 1e-4 * f.abs().max_element().max(1e-3));
    }
}

/// One row of `reference_eval_mitsuba3.csv`.
pub(crate) struct EvalRow {
    pub file: String,
    pub wi: Vec3,
    pub wo: Vec3,
    pub fcos: [f64; 3],
    #[allow(dead_code)]
    pub pdf: f64,
}

pub(crate) fn read_eval_csv(dir: &Path) -> Vec<EvalRow> {
    let text = std::fs::read_to_string(dir.join("reference_eval_mitsuba3.csv")).unwrap();
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            let num = |k: usize| c[k].trim().parse::<f64>().unwrap();
            let v = |k: usize| Vec3::new(num(k) as f32, num(k + 1) as f32, num(k + 2) as f32);
            EvalRow {
                file: c[0].to_string(),
                wi: v(5),
                wo: v(8),
                fcos: [num(11), num(12), num(13)],
                pdf: num(14),
            }
        })
        .collect()
}

#[test]
fn all_seven_files_load() {
    let Some(dir) = rgl_dir() else {
        crate::testing::skip_without_data("shared RGL data not found (set ACDF_SHARED_DATA)");
        return;
    };
    for name in FILES {
        let b = RglBrdf::open(dir.join(format!("{name}.bsdf"))).unwrap();
        assert_eq!(b.name(), name);
        assert!(b.is_isotropic());
        assert_eq!(b.theta_i().len(), 8);
        let n = if name == "cg_sunflower_rgb" { 64 } else { 32 };
        assert_eq!(b.grid_size(), (n, n));
        assert_eq!((b.vndf().nx(), b.vndf().ny()), (128, 128));
        assert!(!b.description().is_empty());
    }
}

/// f_r cos θ against Mitsuba 3 (Mitsuba's si.wi is our wo): relative 1e-3
/// plus an absolute 1e-5, for every file. The near-specular chm_mint, whose
/// sharp peak the shared data's `rgl-material-database/README.md` warns
/// about, is within 1.3e-4 on these ten pairs, so it needs no looser bound.
#[test]
fn reference_eval_matches_mitsuba() {
    let Some(dir) = rgl_dir() else {
        crate::testing::skip_without_data("shared RGL data not found (set ACDF_SHARED_DATA)");
        return;
    };
    let rows = read_eval_csv(&dir);
    assert_eq!(rows.len(), 70);
    let mut worst = 0.0f64;
    for name in FILES {
        let b = RglBrdf::open(dir.join(format!("{name}.bsdf"))).unwrap();
        let rtol = 1e-3;
        let mut worst_file = 0.0f64;
        for row in rows.iter().filter(|r| r.file.starts_with(name)) {
            let got = b.fr_cos_unclipped(row.wi, row.wo);
            for c in 0..3 {
                let err = (got[c] - row.fcos[c]).abs();
                worst_file = worst_file.max(err / row.fcos[c].abs().max(1e-3));
                assert!(
                    err <= rtol * row.fcos[c].abs() + 1e-5,
                    "{name} wi {} wo {}: channel {c} got {} want {}",
                    row.wi,
                    row.wo,
                    got[c],
                    row.fcos[c]
                );
            }
            // The clipped eval is the unclipped one, floored at 0, over cos.
            let f = b.eval(row.wi, row.wo);
            for c in 0..3 {
                let want = (got[c] / row.wo.z as f64).max(0.0);
                assert!((f[c] as f64 - want).abs() <= 1e-5 * want.max(1.0));
            }
        }
        println!("{name}: worst relative f_r cos error {worst_file:.2e}");
        worst = worst.max(worst_file);
    }
    println!("worst relative f_r cos error against Mitsuba 3: {worst:.2e}");
}

/// The negative-value policy on real data: chm_mint at normal incidence has
/// R ≈ −121.8 in Mitsuba; eval reports 0 for that channel.
#[test]
fn negative_channels_are_clipped() {
    let Some(dir) = rgl_dir() else {
        crate::testing::skip_without_data("shared RGL data not found (set ACDF_SHARED_DATA)");
        return;
    };
    let b = RglBrdf::open(dir.join("chm_mint_rgb.bsdf")).unwrap();
    let raw = b.fr_cos_unclipped(Vec3::Z, Vec3::Z);
    assert!(raw.x < -100.0, "{raw}");
    let f = b.eval(Vec3::Z, Vec3::Z);
    assert_eq!(f.x, 0.0);
    assert!(f.y > 400.0);
}
