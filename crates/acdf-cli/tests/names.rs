//! Every name the library knows reaches the command line: each simplifier
//! of the adaptive plug-in's table and each sampler family of the registry's
//! table parses, appears in the `--help` of every subcommand that takes a
//! sampler, and builds a sampler through the `acdf` binary; unknown names
//! are errors that list the known ones. The names are read from the two
//! tables themselves, so a table entry the command line cannot reach fails
//! here.

use std::process::{Command, Output};

use acdf::registry::{saved_sampler_names, SAMPLERS};
use acdf::spec::SamplerSpec;
use acdf_adaptive_cdf::simplify::SIMPLIFIERS;

fn acdf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_acdf"))
        .args(args)
        .output()
        .expect("the acdf binary runs")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8(bytes.to_vec()).unwrap()
}

/// Every sampler name, built from the tables directly (not from the
/// registry's own list of names): each family, and `adaptive:SIMPLIFIER`
/// for each simplifier of a family that takes them.
fn names_from_tables() -> Vec<(String, &'static acdf::registry::SamplerFamily)> {
    let mut out = Vec::new();
    for family in SAMPLERS {
        out.push((family.name.to_string(), family));
        if family.simplifiers {
            for s in SIMPLIFIERS {
                out.push((format!("{}:{}", family.name, s.name), family));
            }
        }
    }
    out
}

#[test]
fn every_table_name_parses_and_round_trips() {
    for (name, family) in names_from_tables() {
        let spec: SamplerSpec = name.parse().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(spec.family().name, family.name);
        if name.contains(':') {
            assert_eq!(spec.to_string(), name);
        }
    }
    assert!(!SIMPLIFIERS.is_empty() && SAMPLERS.iter().any(|f| f.simplifiers));
}

#[test]
fn every_table_name_is_in_the_help_of_every_subcommand_that_takes_a_sampler() {
    let saved = saved_sampler_names();
    for sub in ["sample", "pdf", "build", "report", "render"] {
        let o = acdf(&[sub, "--help"]);
        assert!(o.status.success(), "{sub} --help");
        let help = text(&o.stdout);
        for (name, _) in names_from_tables() {
            if sub == "build" && !saved.contains(&name) {
                continue;
            }
            // Whole words only: `adaptive:dp` must not pass for `adaptive:dp-perp`.
            let found = help
                .split(|c: char| c.is_whitespace() || c == ',' || c == '(' || c == ')')
                .any(|w| w == name);
            assert!(found, "`acdf {sub} --help` lacks `{name}`:\n{help}");
        }
    }
    for s in SIMPLIFIERS {
        let o = acdf(&["sweep", "--help"]);
        assert!(
            text(&o.stdout).contains(s.name),
            "sweep --help lacks {}",
            s.name
        );
    }
}

/// A 16 × 8 sky with one bright texel, for the families that sample BRDF
/// × environment.
fn small_map(dir: &std::path::Path) -> std::path::PathBuf {
    let path = dir.join("sky.hdr");
    let img = image::Rgb32FImage::from_fn(16, 8, |x, y| {
        image::Rgb(if (x, y) == (3, 2) {
            [500.0; 3]
        } else {
            [0.5; 3]
        })
    });
    image::DynamicImage::ImageRgb32F(img).save(&path).unwrap();
    path
}

#[test]
fn every_table_name_builds_a_sampler_from_the_command_line() {
    let material = acdf::load_material(&"builtin:nickel".parse().unwrap(), None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let map = small_map(dir.path());
    let map = map.to_str().unwrap();
    for (name, family) in names_from_tables() {
        let mut args = vec![
            "sample",
            "--material",
            "builtin:nickel",
            "--sampler",
            &name,
            "--resolution",
            "4x1x16x8",
            "--wo",
            "30,0",
            "--n",
            "20",
        ];
        if family.environment {
            // Without them it is refused, naming both.
            let err = text(&acdf(&args).stderr);
            assert!(
                err.contains("--envmap") && err.contains("--normal"),
                "{name}: {err}"
            );
            args.extend(["--envmap", map, "--normal", "40,30"]);
        }
        let o = acdf(&args);
        let usable = family.requires.as_ref().is_none_or(|r| (r.met)(&material));
        if usable {
            assert!(o.status.success(), "{name}: {}", text(&o.stderr));
            let out = text(&o.stdout);
            assert_eq!(out.lines().count(), 21, "{name}");
            assert!(out.lines().skip(1).any(|l| l.ends_with(",1")), "{name}");
        } else {
            // A family a built-in material cannot serve (rgl needs a .bsdf
            // file) is still reached: the error is its requirement.
            let err = text(&o.stderr);
            assert!(
                err.contains("cannot be used with material"),
                "{name}: {err}"
            );
        }
    }
}

#[test]
fn unknown_names_list_every_known_one() {
    for bad in ["bogus", "adaptive:bogus", "uniform:dp"] {
        let o = acdf(&[
            "sample",
            "--material",
            "builtin:nickel",
            "--sampler",
            bad,
            "--wo",
            "30,0",
        ]);
        assert!(!o.status.success());
        let err = text(&o.stderr);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(&format!("unknown sampler `{bad}`")), "{err}");
        for (name, _) in names_from_tables() {
            assert!(err.contains(&name), "{err} lacks {name}");
        }
    }
    let o = acdf(&[
        "sweep",
        "--material",
        "builtin:nickel",
        "--simplifiers",
        "bogus",
    ]);
    let err = text(&o.stderr);
    for s in SIMPLIFIERS {
        assert!(err.contains(s.name), "{err} lacks {}", s.name);
    }
    let e = acdf_adaptive_cdf::simplifier_by_name("bogus")
        .unwrap_err()
        .to_string();
    for s in SIMPLIFIERS {
        assert!(e.contains(s.name), "{e} lacks {}", s.name);
    }
}
