//! Fuzz-style tests of every reader of outside input (issue 29): MERL
//! tables, RGL `.bsdf` files, Neural-BRDF weights, saved samplers, Radiance
//! `.hdr` environment maps and the directions read from stdin. Each starts from a valid input and applies
//! random edits (bit flips, overwritten counts and offsets with extreme
//! values, cuts, appended and inserted bytes), or takes random bytes, for a
//! fixed number of proptest cases with a fixed seed (proptest's default
//! deterministic runner). Whatever the input, a reader gives a value or a
//! typed error: no panic, no NaN from what it loaded, and memory stays
//! bounded (the memory limit is lowered to 256 MiB for this process, and
//! the peak resident size is checked at the end of each test).
//!
//! The file forms (`MerlTable::read`, `TensorFile::read`,
//! `persist::read_file`, `NbrdfLibrary::read_files`) are exercised too, on
//! edits that lie about sizes in the header.
//!
//! Adding a reader is one `fuzz_reader!` line below, with a seed and a
//! function from bytes to a checked result.

use std::sync::OnceLock;

use acdf::materials::merl::MerlTable;
use acdf::materials::nbrdf::{NbrdfLibrary, WEIGHTS_PER_MATERIAL};
use acdf::materials::rgl::{write_tensor_file, Dtype, RglBrdf, TensorFile};
use acdf_adaptive::AdaptiveBrdfSampler;
use acdf_adaptive_cdf::AdaptiveBuilder;
use acdf_core::{Brdf, BxdfSampler, Vec2, Vec3};
use acdf_lobes::{Lobes, LobesSampler};
use acdf_outgoing::{AnisotropicOutgoingSampler, OutgoingBuilder};
use acdf_tabulated::{Resolution, TabulatedBrdfSampler};
use acdf_uniform::{PiecewiseConstantBuilder, UniformBrdfSampler};
use proptest::prelude::*;

/// The memory limit of this process: far above what the seeds need, far
/// below what a lying header would ask for.
const LIMIT: u64 = 256 << 20;

fn setup() {
    acdf_io::limits::set_memory_limit(LIMIT);
}

/// The peak resident size of this process so far, from /proc (Linux).
fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Memory stayed bounded: the tests of this file together never held more
/// than 2 GiB (the largest seed, a MERL file, is 35 MB).
fn assert_memory_bounded() {
    if let Some(peak) = peak_resident_bytes() {
        assert!(peak < 2 << 30, "peak resident size {peak} bytes");
    }
}

/// One edit of a byte string.
#[derive(Debug, Clone)]
enum Edit {
    /// Flip bit `bit` of the byte at `at` (as a fraction of the length).
    Flip { at: f64, bit: u8 },
    /// Overwrite 1, 2, 4 or 8 bytes at `at` with an extreme value.
    Word { at: f64, width: usize, value: u64 },
    /// Overwrite a word in the first 64 bytes (where headers are).
    HeaderWord { at: usize, width: usize, value: u64 },
    /// Keep only the first `at` of the bytes.
    Cut { at: f64 },
    /// Append bytes.
    Append(Vec<u8>),
    /// Insert bytes at `at`.
    Insert { at: f64, bytes: Vec<u8> },
}

fn extreme() -> impl Strategy<Value = u64> {
    prop_oneof![
        Just(0u64),
        Just(1),
        Just(u64::MAX),
        Just(u32::MAX as u64),
        Just(i32::MAX as u64),
        Just(0x8000_0000),
        Just(0x7FF0_0000_0000_0000), // +inf as f64
        Just(0x7F80_0000),           // +inf as f32
        Just(0x7FC0_0000),           // NaN as f32
        Just(f64::MAX.to_bits()),
        Just(1e308f64.to_bits()),
        Just((-1.0f64).to_bits()),
        Just(300f32.to_bits() as u64),
        any::<u64>(),
    ]
}

fn edit() -> impl Strategy<Value = Edit> {
    let width = prop_oneof![Just(1usize), Just(2), Just(4), Just(8)];
    prop_oneof![
        4 => (0.0..1.0f64, 0u8..8).prop_map(|(at, bit)| Edit::Flip { at, bit }),
        3 => (0.0..1.0f64, width.clone(), extreme())
            .prop_map(|(at, width, value)| Edit::Word { at, width, value }),
        4 => (0usize..64, width, extreme())
            .prop_map(|(at, width, value)| Edit::HeaderWord { at, width, value }),
        2 => (0.0..1.0f64).prop_map(|at| Edit::Cut { at }),
        1 => proptest::collection::vec(any::<u8>(), 1..64).prop_map(Edit::Append),
        1 => (0.0..1.0f64, proptest::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(at, bytes)| Edit::Insert { at, bytes }),
    ]
}

fn apply(seed: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut b = seed.to_vec();
    let place = |at: f64, len: usize| ((at * len as f64) as usize).min(len.saturating_sub(1));
    for e in edits {
        match e {
            Edit::Flip { at, bit } if !b.is_empty() => {
                let k = place(*at, b.len());
                b[k] ^= 1 << bit;
            }
            Edit::Word { at, width, value } if b.len() >= *width => {
                let k = place(*at, b.len() - width + 1);
                b[k..k + width].copy_from_slice(&value.to_le_bytes()[..*width]);
            }
            Edit::HeaderWord { at, width, value } if b.len() >= at + width => {
                b[*at..at + width].copy_from_slice(&value.to_le_bytes()[..*width]);
            }
            Edit::Cut { at } => {
                let k = (at * b.len() as f64) as usize;
                b.truncate(k);
            }
            Edit::Append(extra) => b.extend_from_slice(extra),
            Edit::Insert { at, bytes } => {
                let k = (at * b.len() as f64) as usize;
                b.splice(k..k, bytes.iter().copied());
            }
            _ => {}
        }
    }
    b
}

/// Either edits of the seed or, one case in eight, random bytes.
fn input(seed: fn() -> &'static [u8]) -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        7 => proptest::collection::vec(edit(), 1..5).prop_map(move |e| apply(seed(), &e)),
        1 => proptest::collection::vec(any::<u8>(), 0..512),
    ]
}

/// What a loaded BRDF gives: finite, non-negative values.
fn check_brdf(brdf: &dyn Brdf) {
    for (wo, wi) in [
        (Vec3::new(0.3, 0.1, 0.9), Vec3::new(-0.2, 0.4, 0.8)),
        (Vec3::Z, Vec3::new(0.9, 0.0, 0.1)),
        (Vec3::new(0.99, 0.0, 0.01), Vec3::new(-0.99, 0.0, 0.01)),
    ] {
        let f = brdf.eval(wo, wi);
        assert!(f.is_finite() && f.min_element() >= 0.0, "{f}");
    }
    let _ = brdf.fingerprint();
}

/// What a loaded sampler gives: `None` or a finite positive pdf, and
/// finite non-negative densities.
fn check_sampler(s: &dyn BxdfSampler) {
    let wo = Vec3::new(0.4, 0.2, 0.89).normalize();
    for u in [
        Vec2::new(0.1, 0.9),
        Vec2::new(0.5, 0.5),
        Vec2::new(0.99, 0.01),
    ] {
        if let Some(d) = s.sample(wo, u) {
            assert!(
                d.pdf.is_finite() && d.pdf > 0.0 && d.wi.is_finite(),
                "{d:?}"
            );
        }
    }
    let p = s.pdf(wo, Vec3::new(-0.3, 0.1, 0.95).normalize());
    assert!(p.is_finite() && p >= 0.0, "{p}");
}

fn cell(lock: &'static OnceLock<Vec<u8>>, make: impl FnOnce() -> Vec<u8>) -> &'static [u8] {
    lock.get_or_init(make)
}

fn merl_seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    cell(&SEED, || {
        let mut out = Vec::new();
        MerlTable::tabulate(&acdf::materials::analytic::lambert())
            .write_to(&mut out)
            .unwrap();
        out
    })
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn rgl_seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    cell(&SEED, || {
        let ramp = |n: usize, base: f32| -> Vec<f32> {
            (0..n).map(|k| base + (k % 7) as f32 * 0.1).collect()
        };
        let (nt, v, n) = (2usize, 4usize, 3usize);
        write_tensor_file(&[
            ("description", Dtype::U8, &[4], b"fuzz"),
            ("phi_i", Dtype::F32, &[1], &f32_bytes(&[0.0])),
            ("theta_i", Dtype::F32, &[nt], &f32_bytes(&[0.0, 1.2])),
            ("sigma", Dtype::F32, &[2, 3], &f32_bytes(&ramp(6, 1.0))),
            ("ndf", Dtype::F32, &[2, 3], &f32_bytes(&ramp(6, 0.5))),
            (
                "vndf",
                Dtype::F32,
                &[1, nt, v, v],
                &f32_bytes(&ramp(nt * v * v, 0.2)),
            ),
            (
                "luminance",
                Dtype::F32,
                &[1, nt, n, n],
                &f32_bytes(&ramp(nt * n * n, 0.3)),
            ),
            (
                "rgb",
                Dtype::F32,
                &[1, nt, 3, n, n],
                &f32_bytes(&ramp(nt * 3 * n * n, 0.1)),
            ),
        ])
    })
}

/// A real RGL file from the shared data, when present.
fn real_rgl_seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    cell(&SEED, || {
        acdf::materials::rgl::shared_dir()
            .and_then(|d| std::fs::read(d.join("paper_white_rgb.bsdf")).ok())
            .unwrap_or_else(|| rgl_seed().to_vec())
    })
}

const NAMES: &str = "first\nsecond\n";

fn nbrdf_seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    cell(&SEED, || {
        let w: Vec<f32> = (0..2 * WEIGHTS_PER_MATERIAL)
            .map(|k| ((k * 37 % 101) as f32 - 50.0) * 0.004)
            .collect();
        f32_bytes(&w)
    })
}

fn small<B: acdf_tabulated::persist::PersistBuilder>(builder: B) -> Vec<u8>
where
    B::Dist: acdf_tabulated::persist::Persist,
{
    let brdf = acdf::materials::builtin("nickel").unwrap();
    let res: Resolution = "3x1x8x4".parse().unwrap();
    TabulatedBrdfSampler::new(brdf, res, builder)
        .unwrap()
        .with_cosine_mix(0.1)
        .unwrap()
        .to_bytes()
        .unwrap()
}

fn uniform_seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    cell(&SEED, || small(PiecewiseConstantBuilder))
}

fn adaptive_seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    cell(&SEED, || {
        small(AdaptiveBuilder::by_name("chi2", None).unwrap())
    })
}

/// Built-in nickel claiming to depend on both azimuths.
struct Anisotropic(std::sync::Arc<dyn Brdf>);
impl Brdf for Anisotropic {
    fn name(&self) -> &str {
        "anisotropic-nickel"
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> acdf_core::Rgb {
        self.0.eval(wo, wi)
    }
    fn is_isotropic(&self) -> bool {
        false
    }
}

/// A small anisotropic outgoing sampler's file (8 θ_o x 8 φ_o nodes,
/// 16 x 8 half-vector cells).
fn anisotropic_outgoing_seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    cell(&SEED, || {
        let nickel = acdf::materials::builtin("nickel").unwrap();
        let builder = OutgoingBuilder::by_name("chi2", None, 8).unwrap();
        let res: Resolution = "4x4x16x8".parse().unwrap();
        AnisotropicOutgoingSampler::new(std::sync::Arc::new(Anisotropic(nickel)), res, builder, 8)
            .unwrap()
            .to_bytes()
    })
}

/// A mixture of a cosine lobe and two GGX lobes, as the fit makes them.
fn lobes_seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    cell(&SEED, || {
        let lobes = Lobes::new(0.3, &[(0.5, 0.05), (0.2, 0.4)]).unwrap();
        let material = acdf_tabulated::persist::StoredMaterial {
            name: "nickel".into(),
            isotropic: true,
            fingerprint: 7,
        };
        LobesSampler::from_lobes(lobes, material).to_bytes()
    })
}

fn read_lobes(bytes: &[u8]) {
    if let Ok(s) = LobesSampler::from_bytes(bytes) {
        check_sampler(&s);
    }
}

/// A 32 x 16 map with a bright spot, as a Radiance file (run-length
/// encoded scanlines, as the `image` crate writes them).
fn hdr_seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    cell(&SEED, || {
        let img = image::Rgb32FImage::from_fn(32, 16, |x, y| {
            let spot = if (x, y) == (5, 3) { 50.0 } else { 0.0 };
            image::Rgb([0.2 + spot, 0.1 * y as f32, 1.0 / (1.0 + x as f32)])
        });
        let mut bytes = Vec::new();
        image::DynamicImage::ImageRgb32F(img)
            .write_to(
                &mut std::io::Cursor::new(&mut bytes),
                image::ImageFormat::Hdr,
            )
            .unwrap();
        bytes
    })
}

/// An environment map read from the bytes of a `.hdr` file: on success,
/// finite non-negative texels and a sampler whose draws have finite,
/// positive densities that its pdf agrees with.
fn read_hdr(bytes: &[u8]) {
    let Ok(map) = acdf::lights::EnvMap::from_file_bytes(bytes, std::path::Path::new("fuzz.hdr"))
    else {
        return;
    };
    assert!(map
        .texels()
        .iter()
        .all(|t| t.is_finite() && t.min_element() >= 0.0));
    if map.is_black() {
        return;
    }
    let map = std::sync::Arc::new(map);
    let s = acdf::env_registry::make_env_sampler(
        "adaptive:dp",
        &map,
        &acdf::env_registry::EnvSamplerOptions::default(),
    )
    .unwrap();
    for u in [Vec2::new(0.1, 0.2), Vec2::new(0.7, 0.9)] {
        if let Some(d) = acdf_core::SphereSampler::sample(&s, None, u) {
            assert!(d.pdf.is_finite() && d.pdf > 0.0 && d.dir.is_finite());
            assert_eq!(acdf_core::SphereSampler::pdf(&s, None, d.dir), d.pdf);
        }
    }
}

fn read_merl(bytes: &[u8]) {
    if let Ok(t) = MerlTable::from_bytes(bytes, "fuzz.binary") {
        check_brdf(&t);
    }
}

fn read_rgl(bytes: &[u8]) {
    if let Ok(file) = TensorFile::from_bytes(bytes) {
        if let Ok(brdf) = RglBrdf::from_tensor(&file, "fuzz") {
            check_brdf(&brdf);
            check_sampler(&acdf_rgl::RglSampler::new(std::sync::Arc::new(brdf)));
        }
    }
}

fn read_nbrdf(bytes: &[u8]) {
    if let Ok(lib) = NbrdfLibrary::from_bytes(bytes, NAMES, "fuzz.f32") {
        for name in ["first", "second"] {
            if let Ok(net) = lib.material(name) {
                check_brdf(&net);
            }
        }
    }
}

fn read_uniform(bytes: &[u8]) {
    if let Ok(s) = UniformBrdfSampler::from_bytes(bytes) {
        check_sampler(&s);
    }
}

fn read_adaptive(bytes: &[u8]) {
    if let Ok(s) = AdaptiveBrdfSampler::from_bytes(bytes) {
        check_sampler(&s);
    }
}

fn read_anisotropic_outgoing(bytes: &[u8]) {
    if let Ok(s) = AnisotropicOutgoingSampler::from_bytes(bytes) {
        check_sampler(&s);
    }
}

/// One proptest per reader: `fuzz_reader!(name, cases, seed, read)`.
macro_rules! fuzz_reader {
    ($name:ident, $cases:expr, $seed:expr, $read:expr) => {
        proptest! {
            #![proptest_config(ProptestConfig {
                cases: $cases,
                failure_persistence: None,
                ..ProptestConfig::default()
            })]
            #[test]
            fn $name(bytes in input($seed)) {
                setup();
                ($read)(&bytes);
                assert_memory_bounded();
            }
        }
    };
}

fuzz_reader!(merl_tables, 24, merl_seed, read_merl);
fuzz_reader!(rgl_files, 400, rgl_seed, read_rgl);
fuzz_reader!(rgl_shared_file, 12, real_rgl_seed, read_rgl);
fuzz_reader!(nbrdf_weights, 300, nbrdf_seed, read_nbrdf);
fuzz_reader!(uniform_sampler_files, 300, uniform_seed, read_uniform);
fuzz_reader!(adaptive_sampler_files, 300, adaptive_seed, read_adaptive);
fuzz_reader!(
    anisotropic_outgoing_files,
    300,
    anisotropic_outgoing_seed,
    read_anisotropic_outgoing
);
fuzz_reader!(lobes_sampler_files, 300, lobes_seed, read_lobes);
fuzz_reader!(hdr_images, 300, hdr_seed, read_hdr);

/// The file forms, on inputs whose header lies about the size: each is
/// refused from the header and the file's size, before the body is read.
#[test]
fn file_readers_check_sizes_before_reading() {
    setup();
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, bytes: &[u8]| {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    };
    // A MERL header of the right dimensions on a short body.
    let mut merl = merl_seed()[..4096].to_vec();
    merl.truncate(4096);
    assert!(matches!(
        MerlTable::read(write("short.binary", &merl)),
        Err(acdf::materials::MaterialError::Truncated { .. })
    ));
    // A sampler file announcing 2^62 bytes of body.
    let mut sampler = uniform_seed().to_vec();
    sampler[12..20].copy_from_slice(&(1u64 << 62).to_le_bytes());
    let err = acdf_tabulated::persist::read_file(&write("lying.acdfs", &sampler))
        .err()
        .unwrap();
    assert!(err.to_string().contains("truncated"), "{err}");
    // A names list of 10^6 materials for a weight file of two records.
    let names: String = (0..1_000_000).map(|k| format!("m{k}\n")).collect();
    let weights = write("w.f32", nbrdf_seed());
    let err = NbrdfLibrary::read_files(&weights, &write("names.txt", names.as_bytes()))
        .err()
        .unwrap();
    assert!(err.to_string().contains("names"), "{err}");
    // An RGL field whose size overflows.
    let mut rgl = rgl_seed().to_vec();
    let at = rgl.windows(5).position(|w| w == b"\x03\x00rgb").unwrap() + 5 + 2 + 1 + 8;
    rgl[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(TensorFile::read(write("huge.bsdf", &rgl)).is_err());
    assert_memory_bounded();
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, failure_persistence: None, ..ProptestConfig::default() })]

    /// Lines of stdin: any text gives a unit direction, zero, nothing (a
    /// blank line or comment) or an error, and an error never echoes more
    /// than a short prefix of the line.
    #[test]
    fn stdin_direction_lines(line in prop_oneof![
        ".{0,200}",
        "[-+0-9eE.,a-z ]{0,60}",
        (any::<f64>(), any::<f64>(), any::<f64>()).prop_map(|(x, y, z)| format!("{x:e},{y},{z:?}")),
        (any::<f32>(), any::<f32>(), any::<f32>(), 0usize..3)
            .prop_map(|(x, y, z, extra)| format!("{x},{y},{z}{}", ",1".repeat(extra))),
    ], columns in 3usize..6) {
        match acdf::spec::parse_direction_line(&line, columns) {
            Ok(Some(v)) => {
                prop_assert!(v.is_finite());
                let len = v.length();
                prop_assert!(len == 0.0 || (len - 1.0).abs() < 1e-5, "{v}");
            }
            Ok(None) => {}
            Err(e) => prop_assert!(e.len() < 220, "{e}"),
        }
    }
}
