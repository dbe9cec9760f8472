//! The C and C++ examples (`examples/c/sample.c`,
//! `examples/cpp/direct_lighting.cpp`), built with the system's compilers
//! against the static library and run, their numbers checked against
//! acdf's own:
//! - every draw of the C example equals, bit for bit, the draw of the same
//!   sampler built in Rust for the same wo and u, and the density of each
//!   drawn direction equals `acdf pdf`'s (the command line, run on them);
//!   the same for an environment sampler against `acdf env-pdf`;
//! - the C++ direct-lighting estimates by BRDF sampling, light sampling
//!   and MIS agree within five standard errors of their difference.

use std::path::{Path, PathBuf};
use std::process::Command;

use acdf::env_registry::{make_env_sampler, EnvSamplerOptions};
use acdf::{load_material, make_sampler, SamplerOptions};
use acdf_core::{BxdfSampler, SphereSampler, Vec2, Vec3};

/// The folder of this test's executable: `target/PROFILE/deps`, where
/// cargo leaves `libacdf_capi.a`.
fn deps_dir() -> PathBuf {
    std::env::current_exe()
        .unwrap()
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The `acdf` command beside the deps folder (`cargo test --workspace`
/// builds it before any test runs).
fn acdf_bin() -> PathBuf {
    let bin = deps_dir().parent().unwrap().join("acdf");
    assert!(
        bin.is_file(),
        "{} is missing: run the workspace's tests (cargo test --workspace --release)",
        bin.display()
    );
    bin
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Compile `source` with `compiler` against the static library into
/// `out`; the system libraries are those a Rust static library needs on
/// Linux.
fn compile(compiler: &str, flags: &[&str], source: &Path, out: &Path) {
    let lib = deps_dir().join("libacdf_capi.a");
    assert!(lib.is_file(), "{} is missing", lib.display());
    let include = Path::new(env!("CARGO_MANIFEST_DIR")).join("include");
    let status = Command::new(compiler)
        .args(flags)
        .arg("-I")
        .arg(&include)
        .arg(source)
        .arg(&lib)
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(out)
        .status()
        .unwrap_or_else(|e| panic!("cannot run {compiler}: {e}"));
    assert!(
        status.success(),
        "{compiler} failed on {}",
        source.display()
    );
}

fn run(program: &Path, args: &[&str], stdin: Option<&str>) -> String {
    use std::io::Write;
    let mut child = Command::new(program)
        .args(args)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut input = child.stdin.take().unwrap();
    if let Some(text) = stdin {
        input.write_all(text.as_bytes()).unwrap();
    }
    drop(input);
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{} {args:?}: {}",
        program.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Rows of comma-separated numbers.
fn rows(text: &str) -> Vec<Vec<f32>> {
    text.lines()
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect()
}

fn shared_map(name: &str) -> Option<PathBuf> {
    let path = acdf::materials::shared_data_dir()?
        .join("envmaps")
        .join(name);
    path.is_file().then_some(path)
}

#[test]
fn the_c_example_draws_what_acdf_draws() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("sample");
    compile(
        "cc",
        &["-std=c11", "-O2", "-Wall", "-Werror"],
        &workspace().join("examples/c/sample.c"),
        &program,
    );
    let spec = "builtin:nickel";
    let material = load_material(&spec.parse().unwrap(), None).unwrap();
    for (name, degrees) in [
        ("adaptive:chi2", "30,45"),
        ("outgoing:chi2", "60,170"),
        ("uniform", "0,0"),
    ] {
        // wo exactly as `acdf pdf --wo` reads it, passed to C digit for digit.
        let wo = acdf::spec::parse_direction_degrees(degrees).unwrap();
        let wo_arg = format!("{:e},{:e},{:e}", wo.x, wo.y, wo.z);
        let out = run(&program, &[spec, name, &wo_arg, "500"], None);
        let drawn = rows(&out);
        assert_eq!(drawn.len(), 500);
        let sampler = make_sampler(name, &material, &SamplerOptions::default()).unwrap();
        let mut valid = Vec::new();
        for r in &drawn {
            let expected = sampler.sample(wo, Vec2::new(r[0], r[1]));
            match expected {
                Some(s) => {
                    assert_eq!(
                        [r[2], r[3], r[4], r[5]],
                        [s.wi.x, s.wi.y, s.wi.z, s.pdf],
                        "{name}: u = ({}, {})",
                        r[0],
                        r[1]
                    );
                    assert_eq!(r[6], sampler.pdf(wo, s.wi), "{name}");
                    valid.push(r);
                }
                None => assert_eq!(&r[2..], &[0.0; 5], "{name}"),
            }
        }
        assert!(valid.len() > 400, "{name}: {} draws", valid.len());
        // The command line's densities of the same directions.
        let directions: String = valid
            .iter()
            .map(|r| format!("{},{},{}\n", r[2], r[3], r[4]))
            .collect();
        let cli = run(
            &acdf_bin(),
            &[
                "pdf",
                "--material",
                spec,
                "--sampler",
                name,
                "--wo",
                degrees,
            ],
            Some(&directions),
        );
        let cli: Vec<f32> = cli.lines().map(|l| l.parse().unwrap()).collect();
        assert_eq!(cli.len(), valid.len());
        // `acdf pdf` looks the drawn direction up as `acdf_sampler_pdf`
        // does; the draw's own density agrees with both to 1e-4, the
        // samplers' contract.
        for (r, p) in valid.iter().zip(&cli) {
            assert!((r[6] - p).abs() <= 1e-6 * r[6], "{name}: {} vs {p}", r[6]);
            assert!((r[5] - p).abs() <= 1e-4 * r[5], "{name}: {} vs {p}", r[5]);
        }
    }
}

#[test]
fn the_c_example_draws_environment_directions_as_acdf_does() {
    let Some(map) = shared_map("rooitou_park_1k.hdr") else {
        acdf::materials::testing::skip_without_data(
            "no ../shared/data/envmaps/rooitou_park_1k.hdr",
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("sample");
    compile(
        "cc",
        &["-std=c11", "-O2", "-Wall", "-Werror"],
        &workspace().join("examples/c/sample.c"),
        &program,
    );
    let env = std::sync::Arc::new(acdf::lights::EnvMap::open(&map).unwrap());
    let normal = Vec3::new(0.3, -0.4, 0.866_025_4);
    let normal_arg = format!("{:e},{:e},{:e}", normal.x, normal.y, normal.z);
    for name in ["uniform", "oriented:dp"] {
        let out = run(
            &program,
            &["--env", map.to_str().unwrap(), name, &normal_arg, "300"],
            None,
        );
        let sampler = make_env_sampler(name, &env, &EnvSamplerOptions::default()).unwrap();
        for r in rows(&out) {
            match sampler.sample(Some(normal), Vec2::new(r[0], r[1])) {
                Some(d) => {
                    assert_eq!([r[2], r[3], r[4], r[5]], [d.dir.x, d.dir.y, d.dir.z, d.pdf]);
                    assert_eq!(r[6], sampler.pdf(Some(normal), d.dir));
                }
                None => assert_eq!(&r[2..], &[0.0; 5]),
            }
        }
    }
}

#[test]
fn the_cpp_example_estimates_agree_across_strategies() {
    let Some(map) = shared_map("rooitou_park_1k.hdr") else {
        acdf::materials::testing::skip_without_data(
            "no ../shared/data/envmaps/rooitou_park_1k.hdr",
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("direct_lighting");
    compile(
        "c++",
        &["-std=c++17", "-O2", "-Wall", "-Werror"],
        &workspace().join("examples/cpp/direct_lighting.cpp"),
        &program,
    );
    let out = run(
        &program,
        &[
            "builtin:nickel",
            map.to_str().unwrap(),
            "30,60",
            "40,20",
            "40000",
        ],
        None,
    );
    let lines: Vec<(String, [f64; 3], f64)> = out
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let v = |k: usize| f[k].parse::<f64>().unwrap();
            (f[0].to_string(), [v(1), v(2), v(3)], v(4))
        })
        .collect();
    assert_eq!(
        lines.iter().map(|l| l.0.as_str()).collect::<Vec<_>>(),
        ["brdf", "light", "mis"]
    );
    let luminance = |c: &[f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    for (name, rgb, se) in &lines {
        assert!(
            rgb.iter().all(|v| v.is_finite() && *v > 0.0) && se.is_finite(),
            "{name}: {rgb:?} ± {se}"
        );
    }
    for a in 0..3 {
        for b in a + 1..3 {
            let (la, lb) = (luminance(&lines[a].1), luminance(&lines[b].1));
            let se = (lines[a].2.powi(2) + lines[b].2.powi(2)).sqrt();
            assert!(
                (la - lb).abs() <= 5.0 * se,
                "{} {la} and {} {lb} differ by more than 5 x {se}",
                lines[a].0,
                lines[b].0
            );
        }
    }
}
