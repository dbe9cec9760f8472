//! End-to-end tests of the environment subcommands (`env-sample`,
//! `env-pdf`, `env-report`) on small maps written by the test, and their
//! bad inputs: a truncated `.hdr`, a header declaring a huge size,
//! /dev/zero, an image that is not lat-long, a black map, NaN texels, an
//! unknown sampler. Each gives one line on stderr and a non-zero exit, no
//! panic and nothing NaN on stdout.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{acdf, acdf_stdin};

use acdf::env_registry::{env_sampler_names, ENV_SAMPLERS};

fn text(b: &[u8]) -> String {
    String::from_utf8(b.to_vec()).unwrap()
}

fn assert_one_line_error(o: &Output, needle: &str) {
    assert!(!o.status.success(), "unexpectedly succeeded");
    let err = text(&o.stderr);
    assert_eq!(err.lines().count(), 1, "stderr: {err}");
    assert!(err.contains(needle), "stderr `{err}` lacks `{needle}`");
    assert!(
        !err.contains("panicked") && !err.contains("internal error"),
        "{err}"
    );
    assert!(!text(&o.stdout).to_lowercase().contains("nan"));
}

/// Write a `width` × `height` OpenEXR image with texel f(column, row).
fn write_exr(path: &Path, width: u32, height: u32, f: impl Fn(u32, u32) -> [f32; 3]) {
    let img = image::Rgb32FImage::from_fn(width, height, |x, y| image::Rgb(f(x, y)));
    image::DynamicImage::ImageRgb32F(img).save(path).unwrap();
}

/// A 64 × 32 sky with a bright spot, as `.exr` and `.hdr`.
fn sky(dir: &Path) -> (PathBuf, PathBuf) {
    let f = |x: u32, y: u32| {
        if (20..23).contains(&x) && (5..8).contains(&y) {
            [300.0, 280.0, 250.0]
        } else if y < 16 {
            [0.3, 0.5, 1.0]
        } else {
            [0.1, 0.1, 0.1]
        }
    };
    let exr = dir.join("sky.exr");
    write_exr(&exr, 64, 32, f);
    let hdr = dir.join("sky.hdr");
    let img = image::Rgb32FImage::from_fn(64, 32, |x, y| image::Rgb(f(x, y)));
    image::DynamicImage::ImageRgb32F(img).save(&hdr).unwrap();
    (exr, hdr)
}

#[test]
fn env_sample_and_env_pdf_agree() {
    let dir = tempfile::tempdir().unwrap();
    let (exr, hdr) = sky(dir.path());
    for (map, sampler, normal) in [
        (&exr, "uniform", None),
        (&hdr, "adaptive:chi2", None),
        (&exr, "oriented", Some("30,200")),
        (&hdr, "adaptive-comp", Some("180,0")),
    ] {
        let map = map.to_str().unwrap();
        let mut args = vec!["--env", map, "--sampler", sampler];
        if let Some(n) = normal {
            args.extend(["--normal", n]);
        }
        let mut sample = vec!["env-sample", "--n", "200", "--seed", "5"];
        sample.extend(&args);
        let o = acdf(&sample);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let csv = text(&o.stdout);
        let mut lines = csv.lines();
        assert_eq!(lines.next(), Some("x,y,z,pdf"));
        let rows: Vec<Vec<f32>> = lines
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 200);
        for r in &rows {
            let len = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
            assert!(
                (len - 1.0).abs() < 1e-5 && r[3] > 0.0 && r[3].is_finite(),
                "{r:?}"
            );
        }
        let mut pdf = vec!["env-pdf"];
        pdf.extend(&args);
        let o = acdf_stdin(&pdf, &csv);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let back: Vec<f32> = text(&o.stdout)
            .lines()
            .map(|l| l.parse().unwrap())
            .collect();
        assert_eq!(back.len(), rows.len());
        for (r, p) in rows.iter().zip(&back) {
            assert!(
                (r[3] - p).abs() <= 1e-5 * r[3],
                "{sampler}: {} vs {p}",
                r[3]
            );
        }
    }
}

#[test]
fn env_report_writes_its_table_json_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let (exr, _) = sky(dir.path());
    let json = dir.path().join("out/env.json");
    let svg = dir.path().join("out/env.svg");
    let o = acdf(&[
        "env-report",
        "--env",
        exr.to_str().unwrap(),
        "--sampler",
        "uniform",
        "--sampler",
        "adaptive:dp",
        "--sampler",
        "oriented",
        "--sampler",
        "uniform-comp",
        "--normal-cells",
        "2x4,4x8",
        "--mc-samples",
        "500",
        "--timing-samples",
        "500",
        "--timing-passes",
        "1",
        "--json",
        json.to_str().unwrap(),
        "--plot",
        svg.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let table = text(&o.stdout);
    for name in [
        "uniform",
        "adaptive:dp",
        "oriented:dp (2x4)",
        "oriented:dp (4x8)",
        "uniform-comp",
    ] {
        assert!(table.contains(name), "{table}");
    }
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 5);
    assert_eq!(rows[0]["relative_efficiency"], 1.0);
    assert!(rows[4]["relative_efficiency"].is_null());
    assert_eq!(rows[0]["per_normal"].as_array().unwrap().len(), 34);
    let built = rows[2]["built_nodes"].as_array().unwrap();
    assert!(built[0].as_u64().unwrap() <= built[1].as_u64().unwrap());
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
}

#[test]
fn bad_maps_and_names_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (_, hdr) = sky(dir.path());
    let bytes = std::fs::read(&hdr).unwrap();
    let truncated = dir.path().join("truncated.hdr");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let square = dir.path().join("square.exr");
    write_exr(&square, 16, 16, |_, _| [1.0, 1.0, 1.0]);
    let black = dir.path().join("black.exr");
    write_exr(&black, 16, 8, |_, _| [0.0, 0.0, 0.0]);
    let nan = dir.path().join("nan.exr");
    write_exr(&nan, 16, 8, |x, y| {
        if (x, y) == (3, 2) {
            [f32::NAN, 1.0, 1.0]
        } else {
            [1.0, 1.0, 1.0]
        }
    });
    // A header declaring 2^20 x 2^19 texels on no body: refused from the
    // header, before anything is allocated or read.
    let huge = dir.path().join("huge.hdr");
    std::fs::write(
        &huge,
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 524288 +X 1048576\n",
    )
    .unwrap();
    // A device behind a map's name: refused from its first bytes.
    let zero = dir.path().join("zero.hdr");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let path = |p: &PathBuf| p.to_str().unwrap().to_string();
    for (map, needle) in [
        (path(&huge), "more than the memory limit"),
        (path(&zero), "cannot decode"),
        ("/dev/zero".to_string(), "not an image"),
        (path(&truncated), "cannot decode"),
        (path(&square), "twice as wide"),
        (path(&black), "every texel is 0"),
        (path(&nan), "(column 3, row 2) has a non-finite value"),
        (path(&dir.path().join("missing.hdr")), "missing.hdr"),
    ] {
        for sub in ["env-sample", "env-report"] {
            let o = acdf(
                &[sub, "--env", &map, "--mc-samples", "10"]
                    [..if sub == "env-sample" { 3 } else { 5 }],
            );
            assert_one_line_error(&o, needle);
        }
    }
    // --repair sets the NaN to 0 and says so.
    let o = acdf(&["env-sample", "--env", &path(&nan), "--repair", "--n", "5"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("set 1 non-finite"));
    assert!(!text(&o.stdout).to_lowercase().contains("nan"));
    // An unknown sampler lists every name.
    let o = acdf(&["env-sample", "--env", &path(&hdr), "--sampler", "nope"]);
    assert_one_line_error(&o, "unknown sampler `nope`");
    for name in env_sampler_names() {
        assert!(text(&o.stderr).contains(&name));
    }
    let o = acdf(&["env-sample", "--env", &path(&hdr), "--normal", "190,0"]);
    assert_one_line_error(&o, "is not in [0, 180]");
    let o = acdf(&["env-report", "--env", &path(&hdr), "--normal-cells", "0x3"]);
    assert_one_line_error(&o, "normal cells");
}

/// The help states the default chi2 tolerance the registry uses.
#[test]
fn the_help_states_the_default_chi2_tolerance() {
    let default = format!("{} for chi2", acdf::env_registry::ENV_CHI2_TOLERANCE);
    for sub in ["env-sample", "env-pdf", "env-report"] {
        let help = text(&acdf(&[sub, "--help"]).stdout).replace(char::is_whitespace, " ");
        let help = help.split_whitespace().collect::<Vec<_>>().join(" ");
        assert!(
            help.contains(&default),
            "`acdf {sub} --help` lacks `{default}`"
        );
    }
}

/// Every family of the table, and every `FAMILY:SIMPLIFIER`, is in the help
/// of the three subcommands.
#[test]
fn every_env_sampler_name_is_in_the_help() {
    assert!(!ENV_SAMPLERS.is_empty());
    for sub in ["env-sample", "env-pdf", "env-report"] {
        let help = text(&acdf(&[sub, "--help"]).stdout);
        for name in env_sampler_names() {
            let found = help
                .split(|c: char| c.is_whitespace() || c == ',')
                .any(|w| w == name);
            assert!(found, "`acdf {sub} --help` lacks `{name}`");
        }
    }
}
