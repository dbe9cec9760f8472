//! The C and C++ examples (`examples/c/sample.c`,
//! `examples/cpp/direct_lighting.cpp`), built with the system's compilers
//! against the static library and run, their numbers checked against
//! acdf's own:
//! - every draw of the C example equals, bit for bit, the draw of
//!   `acdf sample` (and `acdf env-sample`) for the same wo (normal) and the
//!   same uniform pairs, and `acdf pdf` of the drawn directions is the
//!   library's density of them;
//! - the C++ direct-lighting estimates by BRDF sampling, light sampling
//!   and MIS agree within five standard errors of their difference.

use std::path::{Path, PathBuf};
use std::process::Command;

use acdf::{load_material, make_sampler, SamplerOptions};
use acdf_core::{BxdfSampler, Vec2, Vec3};

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

/// The uniform pairs `acdf sample --seed SEED` and `acdf env-sample --seed
/// SEED` draw with, one "u0,u1" line each, digit for digit.
fn pairs(seed: u64, n: usize) -> String {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let u = Vec2::new(rng.random(), rng.random());
            format!("{:e},{:e}\n", u.x, u.y)
        })
        .collect()
}

fn c_example(dir: &Path) -> PathBuf {
    let program = dir.join("sample");
    compile(
        "cc",
        &["-std=c11", "-O2", "-Wall", "-Werror"],
        &workspace().join("examples/c/sample.c"),
        &program,
    );
    program
}

/// Every draw of the C example, for the pairs of `acdf sample --seed 7`,
/// equals `acdf sample`'s bit for bit, for several samplers and materials;
/// and `acdf pdf` of the drawn directions equals the library's density of
/// them, and the drawn density to 1e-4 (the samplers' contract).
#[test]
fn the_c_example_draws_what_acdf_sample_draws() {
    let dir = tempfile::tempdir().unwrap();
    let program = c_example(dir.path());
    let mut cases = vec![
        ("builtin:nickel", "adaptive:chi2", "30,45"),
        ("builtin:nickel", "outgoing:chi2", "60,170"),
        ("builtin:nickel", "uniform", "0,0"),
        ("builtin:nickel", "cosine", "85,10"),
        ("builtin:gray-plastic", "adaptive:dp", "45,300"),
    ];
    let rgl = acdf::materials::rgl::shared_dir().map(|d| d.join("ilm_solo_m_68_rgb.bsdf"));
    let rgl = rgl
        .filter(|p| p.is_file())
        .map(|p| p.to_str().unwrap().to_string());
    match &rgl {
        Some(path) => {
            cases.push((path, "rgl", "30,45"));
            cases.push((path, "adaptive:chi2", "70,20"));
        }
        None => acdf::materials::testing::skip_without_data("no RGL material for the C example"),
    }
    let n = 400;
    let input = pairs(7, n);
    for (spec, name, degrees) in cases {
        // wo exactly as `acdf sample --wo` reads it, passed to C digit for digit.
        let wo = acdf::spec::parse_direction_degrees(degrees).unwrap();
        let wo_arg = format!("{:e},{:e},{:e}", wo.x, wo.y, wo.z);
        let from_c = rows(&run(&program, &[spec, name, &wo_arg], Some(&input)));
        let common = ["--material", spec, "--sampler", name, "--wo", degrees];
        let mut args = vec!["sample"];
        args.extend(common);
        args.extend(["--n", "400", "--seed", "7"]);
        let cli = run(&acdf_bin(), &args, None);
        let from_cli = rows(&cli.lines().skip(1).collect::<Vec<_>>().join("\n"));
        assert_eq!(from_c.len(), n, "{spec} {name}");
        assert_eq!(from_c, from_cli, "{spec} {name} wo {degrees}");
        let valid: Vec<&Vec<f32>> = from_c.iter().filter(|r| r[4] == 1.0).collect();
        assert!(valid.len() > n / 2, "{spec} {name}: {} draws", valid.len());
        let directions: String = valid
            .iter()
            .map(|r| format!("{},{},{}\n", r[0], r[1], r[2]))
            .collect();
        let mut args = vec!["pdf"];
        args.extend(common);
        let cli = run(&acdf_bin(), &args, Some(&directions));
        let material = load_material(&spec.parse().unwrap(), None).unwrap();
        let sampler = make_sampler(name, &material, &SamplerOptions::default()).unwrap();
        for (r, line) in valid.iter().zip(cli.lines()) {
            let p: f32 = line.parse().unwrap();
            assert_eq!(
                p,
                sampler.pdf(wo, Vec3::new(r[0], r[1], r[2])),
                "{spec} {name}"
            );
            assert!(
                (r[3] - p).abs() <= 1e-4 * r[3],
                "{spec} {name}: {} vs {p}",
                r[3]
            );
        }
    }
}

/// The same for environment samplers against `acdf env-sample`.
#[test]
fn the_c_example_draws_what_acdf_env_sample_draws() {
    let Some(map) = shared_map("rooitou_park_1k.hdr") else {
        acdf::materials::testing::skip_without_data(
            "no ../shared/data/envmaps/rooitou_park_1k.hdr",
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let program = c_example(dir.path());
    let normal = acdf::env_registry::parse_sphere_direction_degrees("30,60").unwrap();
    let normal_arg = format!("{:e},{:e},{:e}", normal.x, normal.y, normal.z);
    let input = pairs(5, 300);
    let map = map.to_str().unwrap();
    for name in ["uniform", "uniform-comp", "adaptive:chi2", "oriented:dp"] {
        let from_c = rows(&run(
            &program,
            &["--env", map, name, &normal_arg],
            Some(&input),
        ));
        let cli = run(
            &acdf_bin(),
            &[
                "env-sample",
                "--env",
                map,
                "--sampler",
                name,
                "--normal",
                "30,60",
                "--n",
                "300",
                "--seed",
                "5",
            ],
            None,
        );
        let from_cli = rows(&cli.lines().skip(1).collect::<Vec<_>>().join("\n"));
        assert_eq!(from_c.len(), 300, "{name}");
        assert_eq!(from_c, from_cli, "{name}");
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
