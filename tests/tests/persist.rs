//! Saving and loading built samplers (`acdf_tabulated::persist`): for every
//! sampler family that can be saved, a round trip is bit-identical, the file
//! is the tables plus a small header, and every kind of corruption gives a
//! typed error without a panic.

use acdf_adaptive::AdaptiveBrdfSampler;
use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_core::geometry::spherical_direction;
use acdf_core::{BxdfSampler, Vec2};
use acdf_tabulated::persist::{
    peek_kind, Persist, PersistBuilder, PersistError, ENVELOPE_BYTES, FORMAT_VERSION,
};
use acdf_tabulated::{Resolution, TabulatedBrdfSampler};
use acdf_uniform::{PiecewiseConstantBuilder, UniformBrdfSampler};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};

fn small<B: PersistBuilder>(material: &str, builder: B) -> TabulatedBrdfSampler<B> {
    let brdf = acdf_materials::builtin(material).unwrap();
    let res: Resolution = "4x1x16x8".parse().unwrap();
    TabulatedBrdfSampler::new(brdf, res, builder)
        .unwrap()
        .with_cosine_mix(0.05)
        .unwrap()
}

fn uniform(material: &str) -> UniformBrdfSampler {
    small(material, PiecewiseConstantBuilder)
}

fn adaptive(material: &str, simplifier: &str) -> AdaptiveBrdfSampler {
    small(
        material,
        AdaptiveBuilder::by_name(simplifier, None).unwrap(),
    )
}

type Drawn = Option<([f32; 3], u32)>;

/// The same (wi, pdf) bits for 2000 draws over several wo, and the same pdf
/// bits for arbitrary directions.
fn assert_bit_identical(a: &dyn BxdfSampler, b: &dyn BxdfSampler) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
    for theta_deg in [0.0f32, 20.0, 45.0, 70.0, 89.0] {
        let wo = spherical_direction(theta_deg.to_radians(), 0.7);
        for _ in 0..400 {
            let u = Vec2::new(rng.random(), rng.random());
            let sa: Drawn = a.sample(wo, u).map(|s| (s.wi.to_array(), s.pdf.to_bits()));
            let sb: Drawn = b.sample(wo, u).map(|s| (s.wi.to_array(), s.pdf.to_bits()));
            assert_eq!(sa, sb);
            let wi = spherical_direction(rng.random::<f32>() * 1.6, rng.random::<f32>() * 6.3);
            assert_eq!(a.pdf(wo, wi).to_bits(), b.pdf(wo, wi).to_bits());
        }
    }
}

fn round_trip<B>(sampler: TabulatedBrdfSampler<B>, kind: &str)
where
    B: PersistBuilder,
    B::Dist: Persist,
{
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sampler.acdfs");
    sampler.save(&path).unwrap();
    let loaded = TabulatedBrdfSampler::<B>::load(&path).unwrap();
    assert_eq!(loaded.name(), sampler.name());
    assert_eq!(loaded.resolution(), sampler.resolution());
    assert_eq!(loaded.brdf().name(), sampler.brdf().name());
    assert_eq!(loaded.cosine_mix(), sampler.cosine_mix());
    assert_eq!(loaded.storage_bytes(), sampler.storage_bytes());
    assert_bit_identical(&sampler, &loaded);
    assert_eq!(peek_kind(&std::fs::read(&path).unwrap()).unwrap(), kind);
}

#[test]
fn save_load_round_trips_are_bit_identical() {
    for material in ["nickel", "lambert"] {
        round_trip(uniform(material), "uniform");
        for simplifier in ["dp", "optimal", "chi2"] {
            round_trip(adaptive(material, simplifier), "adaptive");
        }
    }
}

/// A file of one family does not load as the other.
#[test]
fn the_wrong_family_is_a_named_error() {
    let bytes = uniform("lambert").to_bytes().unwrap();
    assert!(matches!(
        AdaptiveBrdfSampler::from_bytes(&bytes),
        Err(PersistError::WrongKind { .. })
    ));
    let bytes = adaptive("lambert", "dp").to_bytes().unwrap();
    assert!(matches!(
        UniformBrdfSampler::from_bytes(&bytes),
        Err(PersistError::WrongKind { .. })
    ));
}

/// The uniform file holds the tables and little else: per slice, two
/// dimensions, two array lengths and the integral (24 bytes) beyond the f32
/// CDFs.
#[test]
fn file_size_is_the_tables_plus_a_small_header() {
    let sampler = uniform("nickel");
    let bytes = sampler.to_bytes().unwrap();
    let res = sampler.resolution();
    let table_bytes = res.slices() * (res.theta_h * res.phi_h + res.theta_h) * 4;
    let header = bytes.len() - table_bytes - 24 * res.slices();
    assert!(
        (ENVELOPE_BYTES..128).contains(&header),
        "header {header} bytes"
    );
}

fn every_flip_and_cut_is_rejected<B>(bytes: &[u8])
where
    B: PersistBuilder,
    B::Dist: Persist,
{
    for byte in (0..bytes.len())
        .step_by(7)
        .chain(bytes.len() - 8..bytes.len())
    {
        for bit in 0..8 {
            let mut bad = bytes.to_vec();
            bad[byte] ^= 1 << bit;
            assert!(
                TabulatedBrdfSampler::<B>::from_bytes(&bad).is_err(),
                "flip {byte}:{bit}"
            );
        }
    }
    for len in (0..bytes.len()).step_by(13) {
        let Err(err) = TabulatedBrdfSampler::<B>::from_bytes(&bytes[..len]) else {
            panic!("truncated to {len} bytes but loaded");
        };
        assert!(
            matches!(err, PersistError::BadMagic | PersistError::Truncated { .. }),
            "{len}: {err}"
        );
    }
}

#[test]
fn every_bit_flip_and_truncation_is_rejected() {
    every_flip_and_cut_is_rejected::<PiecewiseConstantBuilder>(
        &uniform("nickel").to_bytes().unwrap(),
    );
    every_flip_and_cut_is_rejected::<AdaptiveBuilder>(
        &adaptive("nickel", "dp").to_bytes().unwrap(),
    );
}

#[test]
fn named_errors_for_foreign_future_and_wrong_size_files() {
    let bytes = uniform("lambert").to_bytes().unwrap();
    assert!(matches!(
        UniformBrdfSampler::from_bytes(b"P6 this is an image"),
        Err(PersistError::BadMagic)
    ));
    let mut future = bytes.clone();
    future[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    assert!(matches!(
        UniformBrdfSampler::from_bytes(&future),
        Err(PersistError::FutureVersion { .. })
    ));
    let mut long = bytes.clone();
    long.push(0);
    assert!(matches!(
        UniformBrdfSampler::from_bytes(&long),
        Err(PersistError::TrailingBytes { extra: 1 })
    ));
    // An absurd body length in the header is compared with the file length,
    // never allocated.
    let mut absurd = bytes.clone();
    absurd[12..20].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(matches!(
        UniformBrdfSampler::from_bytes(&absurd),
        Err(PersistError::Truncated { .. })
    ));
}

#[test]
fn an_interrupted_save_leaves_no_file_under_the_final_name() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-dir").join("x.acdfs");
    assert!(matches!(
        uniform("lambert").save(&missing),
        Err(PersistError::File(_))
    ));
    assert!(!missing.exists());
    // Overwriting replaces the old file whole and leaves no temporary file.
    let path = dir.path().join("x.acdfs");
    std::fs::write(&path, b"old").unwrap();
    uniform("lambert").save(&path).unwrap();
    UniformBrdfSampler::load(&path).unwrap();
    let entries = std::fs::read_dir(dir.path()).unwrap().count();
    assert_eq!(entries, 1, "temporary file left behind");
}

/// Apply overwrites, a cut and an extension to a valid file.
fn mutate(mut bytes: Vec<u8>, edits: &[(usize, u8)], cut: Option<usize>, extra: &[u8]) -> Vec<u8> {
    for &(at, value) in edits {
        let n = bytes.len();
        bytes[at % n] = value;
    }
    if let Some(c) = cut {
        let n = bytes.len();
        bytes.truncate(c % (n + 1));
    }
    bytes.extend_from_slice(extra);
    bytes
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Mutated valid files (overwritten, cut, extended) never panic.
    #[test]
    fn mutated_files_never_panic(
        edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..8),
        cut in any::<Option<usize>>(),
        extra in proptest::collection::vec(any::<u8>(), 0..4),
    ) {
        let bytes = mutate(uniform("lambert").to_bytes().unwrap(), &edits, cut, &extra);
        let _ = UniformBrdfSampler::from_bytes(&bytes);
        let bytes = mutate(adaptive("nickel", "dp").to_bytes().unwrap(), &edits, cut, &extra);
        let _ = AdaptiveBrdfSampler::from_bytes(&bytes);
    }

    /// Random bytes behind a valid magic never load and never panic.
    #[test]
    fn random_bodies_never_panic(body in proptest::collection::vec(any::<u8>(), 0..256)) {
        let mut bytes = b"ACDFSMP\0".to_vec();
        bytes.extend(body);
        prop_assert!(UniformBrdfSampler::from_bytes(&bytes).is_err());
        prop_assert!(AdaptiveBrdfSampler::from_bytes(&bytes).is_err());
    }
}

/// `bytes` with the resolution field `index` (0 θ_o, 1 φ_o, 2 θ_h, 3 φ_h) of
/// the 4x1x16x8 files of [`small`] set to `value`, and the checksum made
/// valid again: an edit a checksum does not catch.
fn with_resolution_field(bytes: &[u8], index: usize, value: u32) -> Vec<u8> {
    let body = &bytes[ENVELOPE_BYTES - 4..bytes.len() - 4];
    let fields: Vec<u8> = [4u32, 1, 16, 8]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let at = body
        .windows(fields.len())
        .position(|w| w == fields.as_slice())
        .expect("the resolution fields");
    let mut body = body.to_vec();
    let field = at + 4 * index;
    body[field..field + 4].copy_from_slice(&value.to_le_bytes());
    acdf_tabulated::persist::seal(&body)
}

/// A resolution edited in the header, with the checksum recomputed, is
/// refused: the slices' own tables say which θ_h and φ_h they were built on.
#[test]
fn an_edited_resolution_is_refused() {
    let files = [
        ("uniform", uniform("nickel").to_bytes().unwrap()),
        ("adaptive:dp", adaptive("nickel", "dp").to_bytes().unwrap()),
        (
            "adaptive:chi2",
            adaptive("nickel", "chi2").to_bytes().unwrap(),
        ),
    ];
    for (name, bytes) in &files {
        // The unedited body, resealed, still loads.
        let same = with_resolution_field(bytes, 2, 16);
        assert_eq!(&same, bytes, "{name}");
        for (index, value) in [(2, 1), (3, 1), (2, 7), (3, 3)] {
            let edited = with_resolution_field(bytes, index, value);
            let err = match name.starts_with("uniform") {
                true => UniformBrdfSampler::from_bytes(&edited).map(|_| ()),
                false => AdaptiveBrdfSampler::from_bytes(&edited).map(|_| ()),
            }
            .expect_err(&format!("{name}: field {index} = {value} loaded"));
            assert!(
                matches!(
                    err,
                    PersistError::Invalid {
                        field: "resolution",
                        ..
                    }
                ),
                "{name}: field {index} = {value}: {err}"
            );
        }
    }
}
