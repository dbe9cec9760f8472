//! End-to-end tests of the `acdf` command: every subcommand on a built-in
//! material with small sizes, checking what it prints and writes, and the
//! error paths (one line on stderr, non-zero exit, no panic).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{acdf, acdf_stdin};

fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8(o.stderr.clone()).unwrap()
}

fn assert_ok(o: &Output) {
    assert!(o.status.success(), "failed: {}", stderr(o));
}

/// The command failed with exactly one line on stderr and no panic.
fn assert_one_line_error(o: &Output, needle: &str) {
    assert!(!o.status.success(), "unexpectedly succeeded");
    let err = stderr(o);
    assert_eq!(err.lines().count(), 1, "stderr: {err}");
    assert!(err.contains(needle), "stderr `{err}` lacks `{needle}`");
    assert!(!err.contains("panicked"), "{err}");
}

fn shared_data() -> Option<PathBuf> {
    let d = acdf::materials::shared_data_dir();
    if d.is_none() {
        acdf::materials::testing::skip_without_data(
            "no shared data directory (set ACDF_SHARED_DATA)",
        );
    }
    d
}

fn parse_floats(line: &str) -> Vec<f64> {
    line.split(',').map(|f| f.parse().unwrap()).collect()
}

#[test]
fn every_subcommand_has_help() {
    for sub in [
        "sample", "pdf", "eval", "bake", "build", "report", "sweep", "survey", "render", "bench",
    ] {
        let o = acdf(&[sub, "--help"]);
        assert_ok(&o);
        assert!(stdout(&o).contains("Usage"), "{sub}");
    }
}

#[test]
fn sample_prints_header_and_one_row_per_draw() {
    let o = acdf(&[
        "sample",
        "--material",
        "builtin:nickel",
        "--sampler",
        "adaptive:vw",
        "--wo",
        "30,45",
        "--n",
        "200",
        "--seed",
        "3",
    ]);
    assert_ok(&o);
    let out = stdout(&o);
    let mut lines = out.lines();
    assert_eq!(lines.next(), Some("wi_x,wi_y,wi_z,pdf,valid"));
    let rows: Vec<Vec<f64>> = lines.map(parse_floats).collect();
    assert_eq!(rows.len(), 200);
    let mut valid = 0;
    for r in &rows {
        assert_eq!(r.len(), 5);
        if r[4] == 1.0 {
            valid += 1;
            let len = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
            assert!(
                (len - 1.0).abs() < 1e-4 && r[2] > 0.0 && r[3] > 0.0,
                "{r:?}"
            );
        } else {
            assert_eq!(r, &vec![0.0; 5]);
        }
    }
    assert!(valid > 150, "only {valid} valid draws");
    // The same seed gives the same draws.
    let again = acdf(&[
        "sample",
        "--material",
        "builtin:nickel",
        "--sampler",
        "adaptive:vw",
        "--wo",
        "30,45",
        "--n",
        "200",
        "--seed",
        "3",
    ]);
    assert_eq!(stdout(&again), out);
}

/// The cosine sampler's pdf is cos θ_i / π, on every row.
#[test]
fn cosine_rows_have_the_cosine_density() {
    let o = acdf(&[
        "sample",
        "--material",
        "builtin:lambert",
        "--sampler",
        "cosine",
        "--wo",
        "10,0",
        "--n",
        "50",
    ]);
    assert_ok(&o);
    for line in stdout(&o).lines().skip(1) {
        let r = parse_floats(line);
        if r[4] == 1.0 {
            assert!((r[3] - r[2] / std::f64::consts::PI).abs() < 1e-5, "{line}");
        }
    }
}

/// `pdf` reads `sample`'s own output and gives back the densities it drew
/// with: sampling and density evaluation agree through the command line.
/// `acdf sample --n N --seed SEED` with `args`, then `acdf pdf` with the
/// same `args` on its output: each drawn row (wi, pdf, valid) with the
/// density `pdf` gives its direction.
fn sample_then_pdf(args: &[&str], n: &str, seed: &str) -> Vec<(Vec<f64>, f64)> {
    let mut sample_args = vec!["sample"];
    sample_args.extend(args);
    sample_args.extend(["--n", n, "--seed", seed]);
    let s = acdf(&sample_args);
    assert_ok(&s);
    let csv = stdout(&s);
    let mut pdf_args = vec!["pdf"];
    pdf_args.extend(args);
    let p = acdf_stdin(&pdf_args, &csv);
    assert_ok(&p);
    let pdfs: Vec<f64> = stdout(&p).lines().map(|l| l.parse().unwrap()).collect();
    let rows: Vec<Vec<f64>> = csv.lines().skip(1).map(parse_floats).collect();
    assert_eq!(pdfs.len(), rows.len());
    rows.into_iter().zip(pdfs).collect()
}

#[test]
fn pdf_of_sampled_directions_matches_the_sampled_pdf() {
    let args = [
        "--material",
        "builtin:gray-plastic",
        "--sampler",
        "uniform",
        "--wo",
        "40,10",
    ];
    for (row, pdf) in sample_then_pdf(&args, "100", "1") {
        if row[4] == 1.0 {
            assert!(
                (row[3] - pdf).abs() <= 1e-3 * row[3].max(1.0),
                "{row:?} vs {pdf}"
            );
        } else {
            assert_eq!(pdf, 0.0);
        }
    }
}

/// `acdf sample | acdf pdf` at grazing outgoing angles: `pdf` reads the
/// drawn directions back bit for bit (it does not normalise a unit
/// direction again), so every density equals the drawn one to 1e-4. Before
/// that, 176 of nickel's 2,832 draws at 89.9° differed by more than 1e-4,
/// and near-mirror's by up to 13 times at 89.999°.
#[test]
fn pdf_of_grazing_draws_matches_the_sampled_pdf() {
    for (material, sampler, wo) in [
        ("builtin:nickel", "adaptive", "89.9,0"),
        ("builtin:near-mirror", "adaptive", "89.999,0"),
        ("builtin:nickel", "outgoing:chi2", "89.99,0"),
        ("builtin:near-mirror", "uniform", "89.999,45"),
    ] {
        let args = ["--material", material, "--sampler", sampler, "--wo", wo];
        let drawn = sample_then_pdf(&args, "3000", "11");
        let mut valid = 0;
        for (row, pdf) in drawn.iter().filter(|(row, _)| row[4] == 1.0) {
            valid += 1;
            assert!(
                (row[3] - pdf).abs() <= 1e-4 * row[3],
                "{material} {sampler} wo {wo}: drawn {row:?}, pdf {pdf}"
            );
        }
        assert!(valid > 1000, "{material} {sampler} wo {wo}: {valid} draws");
    }
}

#[test]
fn eval_prints_rgb_per_line() {
    let o = acdf_stdin(
        &["eval", "--material", "builtin:lambert", "--wo", "20,0"],
        "0,0,1\n0.5,0.5,0.7\n\n# comment\n0,0,-1\n",
    );
    assert_ok(&o);
    let lines: Vec<Vec<f64>> = stdout(&o).lines().map(parse_floats).collect();
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[0], lines[1], "a Lambertian BRDF is constant");
    assert!(lines[0].iter().all(|&c| c > 0.0));
    assert_eq!(lines[2], vec![0.0; 3], "below the horizon");
}

#[test]
fn malformed_stdin_is_one_line_error() {
    let o = acdf_stdin(
        &[
            "pdf",
            "--material",
            "builtin:lambert",
            "--sampler",
            "cosine",
            "--wo",
            "20,0",
        ],
        "0,0,1\n1,banana,2\n",
    );
    assert_one_line_error(&o, "line 2");
}

#[test]
fn unknown_names_and_missing_files_are_one_line_errors() {
    let base = ["sample", "--wo", "30,0", "--n", "3"];
    let run = |extra: &[&str]| {
        let mut a = base.to_vec();
        a.extend(extra);
        acdf(&a)
    };
    assert_one_line_error(
        &run(&["--material", "builtin:nickel", "--sampler", "bogus"]),
        "unknown sampler `bogus`",
    );
    assert_one_line_error(
        &run(&["--material", "builtin:unobtainium"]),
        "unknown material",
    );
    assert_one_line_error(&run(&["--material", "chrome"]), "unknown material");
    assert_one_line_error(
        &run(&["--material", "/nonexistent/x.binary"]),
        "/nonexistent/x.binary",
    );
    assert_one_line_error(
        &run(&["--material", "/nonexistent/x.bsdf"]),
        "/nonexistent/x.bsdf",
    );
    assert_one_line_error(
        &run(&["--material", "builtin:nickel", "--sampler", "rgl"]),
        "needs an RGL .bsdf",
    );
    assert_one_line_error(
        &run(&["--material", "builtin:nickel", "--resolution", "32x1x0x32"]),
        "resolution",
    );
    let bad_wo = acdf(&["sample", "--material", "builtin:nickel", "--wo", "95,0"]);
    assert_one_line_error(&bad_wo, "direction");
    let report = acdf(&[
        "report",
        "--material",
        "builtin:nickel",
        "--material",
        "nope.txt",
    ]);
    assert_one_line_error(&report, "unknown material `nope.txt`");
}

#[test]
fn truncated_merl_file_is_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.binary");
    std::fs::write(&path, [90u8, 0, 0, 0, 90, 0]).unwrap();
    let o = acdf(&["eval", "--material", path.to_str().unwrap(), "--wo", "10,0"]);
    assert_one_line_error(&o, "cut.binary");
}

/// `bake` writes a MERL file that `eval` reads back: for a Lambertian
/// material the table holds the constant albedo / π.
#[test]
fn bake_round_trips_through_eval() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lambert.binary");
    let p = path.to_str().unwrap();
    let o = acdf(&["bake", "--material", "builtin:lambert", "--out", p]);
    assert_ok(&o);
    assert_eq!(
        std::fs::metadata(&path).unwrap().len(),
        12 + 3 * 90 * 90 * 180 * 8
    );
    let input = "0,0,1\n0.3,0.2,0.9\n";
    let baked = acdf_stdin(&["eval", "--material", p, "--wo", "30,0"], input);
    let direct = acdf_stdin(
        &["eval", "--material", "builtin:lambert", "--wo", "30,0"],
        input,
    );
    assert_ok(&baked);
    for (a, b) in stdout(&baked).lines().zip(stdout(&direct).lines()) {
        for (x, y) in parse_floats(a).iter().zip(parse_floats(b)) {
            assert!((x - y).abs() < 1e-4 * y.max(1e-3), "{a} vs {b}");
        }
    }
}

#[test]
fn bake_a_neural_brdf_when_the_data_is_there() {
    let Some(data) = shared_data() else { return };
    let weights = data.join("merl-neural-brdf/merl_nbrdf_weights.f32");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nickel.binary");
    let o = acdf(&[
        "bake",
        "--material",
        "nbrdf:nickel",
        "--nbrdf-weights",
        weights.to_str().unwrap(),
        "--out",
        path.to_str().unwrap(),
    ]);
    assert_ok(&o);
    let e = acdf_stdin(
        &["eval", "--material", path.to_str().unwrap(), "--wo", "30,0"],
        "0.5,0,0.866\n",
    );
    assert_ok(&e);
    let rgb = parse_floats(stdout(&e).trim());
    assert!(rgb.iter().all(|&c| c > 0.0 && c.is_finite()), "{rgb:?}");
    let unknown = acdf(&[
        "bake",
        "--material",
        "nbrdf:unobtainium",
        "--nbrdf-weights",
        weights.to_str().unwrap(),
        "--out",
        path.to_str().unwrap(),
    ]);
    assert_one_line_error(&unknown, "unknown material");
}

#[test]
fn rgl_sampler_on_a_bsdf_file_when_the_data_is_there() {
    let Some(data) = shared_data() else { return };
    let file = data.join("rgl-material-database/paper_white_rgb.bsdf");
    let o = acdf(&[
        "sample",
        "--material",
        file.to_str().unwrap(),
        "--sampler",
        "rgl",
        "--wo",
        "30,0",
        "--n",
        "20",
    ]);
    assert_ok(&o);
    assert_eq!(stdout(&o).lines().count(), 21);
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The small measurement settings of the command-line tests.
const SMALL: [&str; 8] = [
    "--samples",
    "2048",
    "--timing-samples",
    "64",
    "--timing-repeats",
    "1",
    "--quadrature",
    "128x64",
];

#[test]
fn report_prints_a_table_and_writes_json() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("report.json");
    let mut args = vec!["report", "--material", "builtin:gray-plastic"];
    args.extend(SMALL);
    args.extend(["--json", json.to_str().unwrap()]);
    let o = acdf(&args);
    assert_ok(&o);
    let out = stdout(&o);
    assert!(
        out.starts_with("materials: builtin:gray-plastic (as given)"),
        "{out}"
    );
    assert!(out.contains("12 outgoing directions"), "{out}");
    for s in [
        "uniform (ref.)",
        "adaptive:dp",
        "adaptive:vw",
        "adaptive:rw",
        "adaptive:optimal",
        "adaptive:chi2",
        "cosine",
        "lobes",
    ] {
        assert!(
            out.lines()
                .any(|l| l.contains("gray-plastic") && l.contains(s)),
            "{s}"
        );
    }
    assert!(!out.contains("NaN") && !out.contains("inf"), "{out}");
    let rows = read_json(&json);
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 8);
    for r in rows {
        for key in [
            "material",
            "sampler",
            "storage_bytes",
            "compression_ratio",
            "relative_variance",
            "firefly",
            "mc_relative_variance",
            "mc_relative_variance_rel_se",
            "seconds_per_sampler",
            "seconds_per_eval",
            "efficiency",
            "relative_efficiency",
        ] {
            assert!(r.get(key).is_some(), "missing {key} in {r}");
        }
        assert_eq!(r["material"], "gray-plastic");
        assert!(r["relative_variance"].as_f64().unwrap() > 0.0);
        assert!(r["firefly"].as_f64().unwrap() >= 1.0);
        assert!(r["seconds_per_sampler"].as_f64().unwrap() > 0.0);
    }
    let uniform = &rows[0];
    assert_eq!(uniform["sampler"], "uniform");
    assert_eq!(uniform["is_reference"], true);
    assert_eq!(uniform["compression_ratio"].as_f64(), Some(1.0));
    assert_eq!(uniform["relative_efficiency"].as_f64(), Some(1.0));
    // Every adaptive sampler stores less than the uniform one.
    for r in &rows[1..5] {
        assert!(r["compression_ratio"].as_f64().unwrap() > 1.0, "{r}");
    }
    // All samplers estimate the same reflected luminance (4 standard errors).
    let e0 = uniform["estimate"].as_f64().unwrap();
    for r in rows {
        let (e, se) = (
            r["estimate"].as_f64().unwrap(),
            r["estimate_se"].as_f64().unwrap(),
        );
        let se0 = uniform["estimate_se"].as_f64().unwrap();
        assert!((e - e0).abs() < 4.0 * (se * se + se0 * se0).sqrt(), "{r}");
    }
    // The long help says how each column is computed.
    let help = stdout(&acdf(&["report", "--help"]));
    for column in [
        "rel. variance",
        "Monte Carlo",
        "firefly",
        "ns/sample",
        "ns/eval",
        "efficiency",
    ] {
        assert!(help.contains(column), "{column} missing from the help");
    }
}

/// Without --material, the report runs on the measured materials when the
/// weights are found and on the built-in stand-ins otherwise, and its
/// first line says which.
#[test]
fn report_says_which_materials_it_measures() {
    let mut args = vec!["report", "--sampler", "cosine", "--resolution", "8x1x32x8"];
    args.extend(SMALL);
    let o = Command::new(env!("CARGO_BIN_EXE_acdf"))
        .args(&args)
        .env("ACDF_SHARED_DATA", "/nonexistent/shared-data")
        .output()
        .unwrap();
    assert_ok(&o);
    let out = stdout(&o);
    let first = out.lines().next().unwrap();
    assert!(
        first.starts_with("materials: built-in analytic stand-ins, builtin:nickel"),
        "{first}"
    );
    assert!(
        out.contains("| nickel ") && out.contains("| gray-plastic "),
        "{out}"
    );
    if shared_data().is_none() {
        return;
    }
    let o = acdf(&args);
    assert_ok(&o);
    let out = stdout(&o);
    let first = out.lines().next().unwrap();
    assert!(
        first.starts_with(
            "materials: measured, nbrdf:nickel, nbrdf:blue-metallic-paint, nbrdf:gray-plastic"
        ),
        "{first}"
    );
}

/// A target no tolerance reaches is said so, with the best found; a bad
/// target is a one-line error; nothing prints NaN.
#[test]
fn unreachable_targets_are_reported_with_the_best_found() {
    let mut args = vec![
        "report",
        "--material",
        "builtin:nickel",
        "--resolution",
        "8x1x32x8",
        "--sampler",
        "adaptive:chi2",
        "--sampler",
        "cosine",
        "--target-efficiency",
        "1000",
        "--reference",
        "uniform",
    ];
    args.extend(SMALL);
    let o = acdf(&args);
    assert_ok(&o);
    let out = stdout(&o);
    assert!(out.contains("uniform (ref.)"), "{out}");
    assert!(
        out.contains("adaptive:chi2: no tolerance reaches 1000 x the efficiency of uniform@8x1x32x8; the best found is"),
        "{out}"
    );
    assert!(!out.contains("NaN") && !out.contains("inf"), "{out}");

    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("x.acdfs");
    let o = acdf(&[
        "build",
        "--material",
        "builtin:nickel",
        "--sampler",
        "adaptive:chi2",
        "--resolution",
        "8x1x32x8",
        "--target-efficiency",
        "1000",
        "--reference",
        "uniform",
        "--out",
        file.to_str().unwrap(),
    ]);
    assert_one_line_error(
        &o,
        "no tolerance of adaptive:chi2 reaches 1000 x the efficiency of uniform: the best found is",
    );
    assert!(!file.exists());
    for bad in ["-1", "0", "NaN"] {
        let o = acdf(&[
            "build",
            "--material",
            "builtin:nickel",
            &format!("--target-efficiency={bad}"),
            "--out",
            file.to_str().unwrap(),
        ]);
        assert_one_line_error(&o, "target efficiency");
    }
    let o = acdf(&[
        "build",
        "--material",
        "builtin:nickel",
        "--sampler",
        "uniform",
        "--target-efficiency",
        "0.5",
        "--out",
        file.to_str().unwrap(),
    ]);
    assert_one_line_error(&o, "searches the tolerance of an adaptive sampler");
    let o = acdf(&["report", "--reference", "uniform@32x0x256x32"]);
    assert_one_line_error(&o, "resolution");
}

/// A reachable target builds and saves the sampler the search chose.
#[test]
fn build_meets_a_target_efficiency() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("chi2.acdfs");
    let o = acdf(&[
        "build",
        "--material",
        "builtin:nickel",
        "--sampler",
        "adaptive:chi2",
        "--resolution",
        "8x1x32x8",
        "--target-efficiency",
        "0.5",
        "--reference",
        "uniform",
        "--out",
        file.to_str().unwrap(),
    ]);
    assert_ok(&o);
    let out = stdout(&o);
    assert!(out.contains("adaptive:chi2: tolerance"), "{out}");
    assert!(
        out.contains("meets 0.5 x the efficiency of uniform"),
        "{out}"
    );
    assert!(file.exists());
}

/// An unknown Neural-BRDF material lists the valid names.
#[test]
fn unknown_nbrdf_materials_list_the_valid_names() {
    if shared_data().is_none() {
        return;
    }
    let o = acdf(&["report", "--material", "nbrdf:unobtainium"]);
    assert_one_line_error(
        &o,
        "unknown material `unobtainium`; valid names: alum-bronze",
    );
    let err = stderr(&o);
    for name in ["nickel", "gray-plastic", "yellow-plastic"] {
        assert!(err.contains(name), "{err}");
    }
}

/// The survey on two materials: CSV, JSON, figures and the summary.
#[test]
fn survey_writes_csv_json_figures_and_a_summary() {
    if shared_data().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let o = acdf(&[
        "survey",
        "--materials",
        "nickel,white-paint",
        "--quadrature",
        "128x64",
        "--timing-samples",
        "64",
        "--timing-repeats",
        "1",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert_ok(&o);
    let out = stdout(&o);
    assert!(out.contains("2 materials x 13 samplers in"), "{out}");
    for sampler in [
        "uniform@32x16x256x32",
        "adaptive:chi2@target",
        "adaptive:opheim",
        "outgoing:chi2",
        "cosine",
    ] {
        assert!(
            out.contains(&format!("| {sampler} |")),
            "{sampler} in {out}"
        );
    }
    assert!(!out.contains("NaN") && !out.contains("inf"), "{out}");
    let csv = std::fs::read_to_string(dir.path().join("survey.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * 13);
    let json = read_json(&dir.path().join("survey.json"));
    assert_eq!(json["rows"].as_array().unwrap().len(), 26);
    assert_eq!(json["summary"].as_array().unwrap().len(), 13);
    for row in json["rows"].as_array().unwrap() {
        if row["sampler"] == "uniform@32x16x256x32" {
            assert_eq!(row["compression"].as_f64(), Some(1.0));
            assert_eq!(row["relative_efficiency"].as_f64(), Some(1.0));
        }
        if row["sampler"] == "adaptive:chi2@target" {
            let reached = row["target_reached"].as_bool().unwrap();
            let e = row["relative_efficiency"].as_f64().unwrap();
            assert_eq!(reached, e >= 0.95, "{row}");
        }
    }
    let svg = std::fs::read_to_string(dir.path().join("survey.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("adaptive:chi2@target"));
    let png = image::open(dir.path().join("survey.png")).unwrap();
    assert!(png.width() > 100 && png.height() > 100);
}

/// `acdf survey --frontier` on `materials` at a small resolution, quadrature
/// and timing, with `extra` arguments, writing PREFIX.*.
fn small_frontier(
    materials: &str,
    extra: &[&str],
    prefix: &std::path::Path,
) -> std::process::Output {
    let mut args = vec![
        "survey",
        "--materials",
        materials,
        "--resolution",
        "8x1x32x8",
        "--reference",
        "uniform@8x4x32x8",
        "--quadrature",
        "64x32",
        "--timing-samples",
        "64",
        "--timing-repeats",
        "2",
        "--frontier",
        "--frontier-out",
        prefix.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    acdf(&args)
}

/// The storage frontier on two built-in materials at a small resolution:
/// the CSV's columns, one row per material, family and level, a level
/// reached exactly when the chosen sampler's relative efficiency reaches
/// it, and storage that never shrinks as the level rises.
#[test]
fn survey_frontier_is_monotone_in_the_level() {
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("small");
    let o = small_frontier("builtin:nickel,builtin:gray-plastic", &[], &prefix);
    assert_ok(&o);
    let out = stdout(&o);
    assert!(out.contains("frontier of 2 materials x"), "{out}");
    assert!(out.contains("| ≥ 0.95 in ≤ 1,024 B |"), "{out}");
    let csv = std::fs::read_to_string(dir.path().join("small.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "material,family,level,reached,storage_bytes,relative_efficiency,tolerance,\
         default_storage_bytes,default_relative_efficiency,candidates"
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.iter().all(|r| r.len() == 10), "{csv}");
    let mut families: Vec<&str> = rows.iter().map(|r| r[1]).collect();
    families.sort_unstable();
    families.dedup();
    for f in [
        "cosine",
        "uniform",
        "lobes",
        "adaptive:chi2",
        "adaptive:opheim",
        "outgoing:chi2",
    ] {
        assert!(families.contains(&f), "{f} in {families:?}");
    }
    assert_eq!(rows.len(), 2 * families.len() * 5, "{csv}");
    for material in ["nickel", "gray-plastic"] {
        for family in &families {
            let mine: Vec<&Vec<&str>> = rows
                .iter()
                .filter(|r| r[0] == material && r[1] == *family)
                .collect();
            let levels: Vec<f64> = mine.iter().map(|r| r[2].parse().unwrap()).collect();
            assert_eq!(levels, [0.5, 0.8, 0.95, 1.0, 2.0]);
            let mut last: Option<usize> = Some(0);
            for (r, level) in mine.iter().zip(levels) {
                let reached: bool = r[3].parse().unwrap();
                let storage: Option<usize> = r[4].parse().ok();
                assert_eq!(reached, storage.is_some(), "{r:?}");
                if reached {
                    let e: f64 = r[5].parse().unwrap();
                    assert!(e >= level, "{r:?}");
                    // Higher level, no less storage; nothing reached above
                    // a level not reached.
                    let prev = last.expect("reached after a level not reached");
                    assert!(storage.unwrap() >= prev, "{material} {family}: {mine:?}");
                }
                last = storage;
            }
        }
    }
    let json = read_json(&dir.path().join("small.json"));
    assert_eq!(json["rows"].as_array().unwrap().len(), rows.len());
    assert_eq!(json["summary"].as_array().unwrap().len(), families.len());
    let svg = std::fs::read_to_string(dir.path().join("small.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("outgoing:chi2"));
    let png = image::open(dir.path().join("small.png")).unwrap();
    assert!(png.width() > 100 && png.height() > 100);

    let o = acdf(&[
        "survey",
        "--materials",
        "builtin:nickel",
        "--frontier",
        "0.5,fast",
        "--frontier-out",
        prefix.to_str().unwrap(),
    ]);
    assert_one_line_error(&o, "fast");

    // --families measures only the families named, and refuses others.
    let o = small_frontier(
        "builtin:nickel",
        &["--families", "lobes,outgoing:chi2"],
        &prefix,
    );
    assert_ok(&o);
    let csv = std::fs::read_to_string(dir.path().join("small.csv")).unwrap();
    let mut families: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap())
        .collect();
    families.dedup();
    assert_eq!(families, ["lobes", "outgoing:chi2"], "{csv}");
    let o = acdf(&[
        "survey",
        "--materials",
        "builtin:nickel",
        "--frontier",
        "--families",
        "lobes,adaptive:fast",
    ]);
    assert_one_line_error(&o, "adaptive:fast");
}

#[test]
fn sweep_writes_csv_json_svg_and_png() {
    let dir = tempfile::tempdir().unwrap();
    let o = acdf(&[
        "sweep",
        "--material",
        "builtin:nickel",
        "--simplifiers",
        "dp,optimal",
        "--tolerances",
        "0.005,0.04",
        "--samples",
        "512",
        "--timing-samples",
        "32",
        "--timing-repeats",
        "1",
        "--quadrature",
        "128x64",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert_ok(&o);
    let out = stdout(&o);
    let mut lines = out.lines();
    assert!(lines
        .next()
        .unwrap()
        .starts_with("material,sampler,tolerance,resolution,is_reference"));
    let rows: Vec<&str> = lines.collect();
    // uniform, cosine and lobes, then each simplifier at each tolerance
    // as adaptive:S and (the material being isotropic) outgoing:S.
    assert_eq!(rows.len(), 3 + 2 * 2 * 2);
    assert!(rows.iter().any(|r| r.starts_with("nickel,outgoing:dp,")));
    assert!(rows[0].starts_with("nickel,uniform,"));
    assert!(rows[1].starts_with("nickel,cosine,"));
    assert!(rows[2].starts_with("nickel,lobes,"));
    let csv = std::fs::read_to_string(dir.path().join("sweep-nickel.csv")).unwrap();
    assert_eq!(csv, out);
    let json = read_json(&dir.path().join("sweep-nickel.json"));
    let points = json.as_array().unwrap();
    assert_eq!(points.len(), 11);
    // A looser tolerance keeps fewer vertices, so it stores less.
    let dp: Vec<u64> = points
        .iter()
        .filter(|p| p["sampler"] == "adaptive:dp")
        .map(|p| p["storage_bytes"].as_u64().unwrap())
        .collect();
    assert!(dp[0] > dp[1], "{dp:?}");
    let svg = std::fs::read_to_string(dir.path().join("sweep-nickel.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("adaptive:dp"));
    // Cosine, without tables, is a printed figure; the axis is the
    // relative efficiency.
    assert!(svg.contains("cosine (no tables)") && svg.contains("efficiency relative to"));
    assert!(rows[0].contains(",true,false,"), "{}", rows[0]);
    let png = image::open(dir.path().join("sweep-nickel.png")).unwrap();
    assert!(png.width() > 100 && png.height() > 100);
}

/// The rows of one table of `acdf render`'s output: the lines after the
/// header that follows `title`, up to the next blank or title line.
fn render_rows<'a>(out: &'a str, title: &str) -> Vec<Vec<&'a str>> {
    let mut lines = out.lines().skip_while(|l| !l.starts_with(title)).skip(2);
    let mut rows = Vec::new();
    for l in lines.by_ref() {
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != 7 {
            break;
        }
        rows.push(f);
    }
    rows
}

/// Every strategy writes a decodable EXR and PNG and an RMSE; the
/// side-by-side has one tile per strategy and the reference, over a row of
/// error maps; the convergence plot is written as PNG and SVG; `--json`
/// holds the same tables; a second run reuses the cached reference.
#[test]
fn render_writes_every_strategy_and_caches_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("tables.json");
    let args = [
        "render",
        "--json",
        json.to_str().unwrap(),
        "--material",
        "builtin:blue-metallic-paint",
        "--brdf-sampler",
        "uniform",
        "--env-sampler",
        "uniform",
        "--plane",
        "--pixel-sampling",
        "independent",
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "2",
        "--ref-spp",
        "8",
        "--out",
        dir.path().to_str().unwrap(),
    ];
    let o = acdf(&args);
    assert_ok(&o);
    let out = stdout(&o);
    let rows = render_rows(&out, "equal samples (2 spp)");
    let names: Vec<&str> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(
        names,
        [
            "brdf",
            "light",
            "mis-balance",
            "mis-power",
            "mis-one-sample",
            "mis-adaptive",
            "product",
            "mis-product"
        ],
        "{out}"
    );
    assert_eq!(rows[6][1], "product:uniform 64x32 blocks d=0.15");
    assert_eq!(
        rows[7][1],
        "product:uniform 64x32 blocks d=0.15+uniform-comp c=0.25"
    );
    assert_eq!(rows[2][1], "uniform+uniform-comp");
    assert_eq!(rows[4][1], "uniform+uniform-comp c=0.5");
    assert_eq!(rows[5][1], "uniform+uniform-comp c per pixel");
    for r in &rows {
        let rmse: f64 = r[4].parse().unwrap();
        assert!(rmse.is_finite() && rmse > 0.0, "{r:?}");
    }
    // With independent pixel samples the equal-CPU-time table is
    // modelled: the RMSE at 2 spp scaled by the samples one thread renders
    // in 1 s.
    let cpu = render_rows(&out, "equal CPU time");
    assert_eq!(cpu.len(), 8, "{out}");
    for (r, e) in cpu.iter().zip(&rows) {
        let (spp, rmse, rate): (f64, f64, f64) = (
            r[2].parse().unwrap(),
            r[4].parse().unwrap(),
            r[6].parse().unwrap(),
        );
        let at_spp: f64 = e[4].parse().unwrap();
        // The product strategies spend part of the budget on their
        // queries, once per pixel.
        let all_samples = rate / (24.0 * 16.0);
        if r[0].contains("product") {
            assert!(rate > 1e3 && spp < all_samples && spp > 0.0, "{r:?}");
        } else {
            assert!(
                rate > 1e3 && (spp - all_samples).abs() < 1e-3 * spp + 0.1,
                "{r:?}"
            );
        }
        assert!(
            (rmse - at_spp * (2.0 / spp).sqrt()).abs() < 1e-3 * rmse + 2e-6,
            "{r:?}"
        );
    }
    for name in [
        "reference",
        "brdf",
        "light",
        "mis-balance",
        "mis-power",
        "mis-one-sample",
        "mis-adaptive",
        "product",
        "mis-product",
    ] {
        let img = image::open(dir.path().join(format!("blue-metallic-paint-{name}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (24, 16), "{name}");
        if name != "reference" {
            let exr =
                image::open(dir.path().join(format!("blue-metallic-paint-{name}.exr"))).unwrap();
            assert_eq!((exr.width(), exr.height()), (24, 16), "{name}");
        }
    }
    let side = image::open(dir.path().join("blue-metallic-paint-side-by-side.png")).unwrap();
    assert_eq!(side.width(), 9 * 24 + 8 * 4);
    // The JSON: the scene, and the three tables (equal time only with
    // --seconds) with every strategy and the CSV's figures.
    let v = read_json(&json);
    assert_eq!(v["material"], "builtin:blue-metallic-paint");
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(24), Some(16))
    );
    assert!(v["reference"].as_str().unwrap().ends_with("-reference.exr"));
    let tables = v["tables"].as_array().unwrap();
    let kinds: Vec<&str> = tables.iter().map(|t| t["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["equal_samples", "equal_cpu_time"]);
    for (t, csv) in tables.iter().zip([&rows, &cpu]) {
        let json_rows = t["rows"].as_array().unwrap();
        assert_eq!(json_rows.len(), 8);
        for (j, c) in json_rows.iter().zip(csv) {
            assert_eq!(j["strategy"], c[0]);
            let rmse = j["rmse"].as_f64().unwrap();
            let printed: f64 = c[4].parse().unwrap();
            assert!(rmse.is_finite() && (rmse - printed).abs() <= 1e-6 + 1e-6 * rmse);
        }
    }
    let timings = v["timings"].as_array().unwrap();
    assert_eq!(timings.len(), 8);
    for t in timings {
        let product = t["strategy"].as_str().unwrap().contains("product");
        let setup = t["cpu_seconds_per_pixel_setup"].as_f64().unwrap();
        assert!(t["cpu_seconds_per_camera_sample"].as_f64().unwrap() > 0.0);
        assert_eq!(setup > 0.0, product, "{t}");
    }
    assert!(side.height() > 2 * 16);
    let svg =
        std::fs::read_to_string(dir.path().join("blue-metallic-paint-convergence.svg")).unwrap();
    assert!(svg.contains("mis-power"));
    let o = acdf(&args);
    assert_ok(&o);
    assert!(stderr(&o).contains("cached"), "{}", stderr(&o));
}

/// With stratified pixel samples (the default) the equal-CPU-time table
/// is rendered: each strategy's samples per pixel are the whole number its
/// rate buys in the budget, with a finite RMSE; an unknown pixel sampling
/// is refused with the names of the known ones.
#[test]
fn render_stratified_renders_the_equal_cpu_time_budget() {
    let dir = tempfile::tempdir().unwrap();
    let o = acdf(&[
        "render",
        "--material",
        "builtin:blue-metallic-paint",
        "--brdf-sampler",
        "uniform",
        "--env-sampler",
        "uniform",
        "--strategies",
        "brdf,mis-power,product",
        "--width",
        "12",
        "--height",
        "8",
        "--spp",
        "2",
        "--ref-spp",
        "8",
        "--seconds",
        "0.02",
        "--timing-repeats",
        "2",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert_ok(&o);
    let out = stdout(&o);
    assert!(out.contains("rendered at spp = floor("), "{out}");
    let cpu = render_rows(&out, "equal CPU time");
    assert_eq!(cpu.len(), 3, "{out}");
    for r in &cpu {
        let (spp, rmse, rate): (f64, f64, f64) = (
            r[2].parse().unwrap(),
            r[4].parse().unwrap(),
            r[6].parse().unwrap(),
        );
        assert_eq!(spp, spp.floor(), "{r:?}");
        assert!(spp >= 1.0 && rmse.is_finite() && rmse > 0.0, "{r:?}");
        // At most what the rate buys (the product pays for its queries
        // first; the rate is printed to 5 digits).
        assert!(spp <= 0.02 * rate / 96.0 * (1.0 + 1e-4) + 1.0, "{r:?}");
        if !r[0].contains("product") {
            assert!(spp >= 0.02 * rate / 96.0 * (1.0 - 1e-4) - 1.0, "{r:?}");
        }
    }
    let o = acdf(&[
        "render",
        "--pixel-sampling",
        "jittered",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains("independent, stratified, centre"), "{err}");
}

#[test]
fn render_equal_time_runs_at_least_one_pass() {
    let dir = tempfile::tempdir().unwrap();
    let o = acdf(&[
        "render",
        "--material",
        "builtin:lambert",
        "--brdf-sampler",
        "cosine",
        "--env-sampler",
        "uniform",
        "--strategies",
        "brdf,mis-power",
        "--width",
        "8",
        "--spp",
        "1",
        "--ref-spp",
        "2",
        "--seconds",
        "0.05",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert_ok(&o);
    let out = stdout(&o);
    let rows = render_rows(&out, "equal time");
    assert_eq!(rows.len(), 2, "{out}");
    let spp: usize = rows[0][2].parse().unwrap();
    assert!(spp >= 1);
    let o = acdf(&[
        "render",
        "--material",
        "builtin:lambert",
        "--strategies",
        "brdf,mis",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert_one_line_error(&o, "mis-one-sample");
    for (arg, named) in [
        ("--mis-fraction=1.5", "mis-fraction"),
        ("--mis-fraction=-0.1", "mis-fraction"),
        ("--mis-fraction=NaN", "mis-fraction"),
        ("--timing-repeats=0", "timing-repeats"),
        // A subnormal budget made every equal-CPU-time RMSE infinite.
        ("--seconds=1e-320", "seconds"),
        ("--seconds=0", "seconds"),
        // Thousands of threads ran for minutes before the system refused.
        ("--threads=100000", "threads"),
        ("--product-draws=0", "product-draws"),
        ("--product-blocks=0", "block columns"),
        ("--product-points=2000", "points per side"),
        ("--product-sub-cells=5", "sub-cells per side"),
        ("--product-mass-draws=100000", "mass draws"),
        ("--product-mass-prior=-1", "mass prior"),
        ("--product-light-share=2", "refinement light share"),
    ] {
        let o = acdf(&[
            "render",
            "--material",
            "builtin:lambert",
            arg,
            "--out",
            dir.path().to_str().unwrap(),
        ]);
        assert_one_line_error(&o, named);
    }
}

/// `acdf render` of the built-in Lambertian under `map`, into `out`.
fn render_with_envmap(map: &Path, out: &Path) -> Output {
    acdf(&[
        "render",
        "--material",
        "builtin:lambert",
        "--envmap",
        map.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
}

#[test]
fn render_rejects_a_missing_envmap() {
    let dir = tempfile::tempdir().unwrap();
    let o = render_with_envmap(Path::new("/nonexistent/sky.exr"), dir.path());
    assert_one_line_error(&o, "/nonexistent/sky.exr");
}

/// A map that is black everywhere has nothing to sample: `render` refuses
/// it as the environment commands do.
#[test]
fn render_rejects_a_black_envmap() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("black.hdr");
    let img = image::Rgb32FImage::from_pixel(16, 8, image::Rgb([0.0, 0.0, 0.0]));
    image::DynamicImage::ImageRgb32F(img).save(&map).unwrap();
    assert_one_line_error(&render_with_envmap(&map, dir.path()), "every texel is 0");
}

/// The product strategies on maps with little to weigh: one texel (a
/// single block), and a map black but for one texel below the horizon of
/// most of the sphere. Every pixel of their images and every RMSE is
/// finite; the JSON has both rows.
#[test]
fn render_product_on_degenerate_maps_stays_finite() {
    let dir = tempfile::tempdir().unwrap();
    let one = dir.path().join("one.hdr");
    image::DynamicImage::ImageRgb32F(image::Rgb32FImage::from_pixel(
        1,
        1,
        image::Rgb([2.0, 1.0, 0.5]),
    ))
    .save(&one)
    .unwrap();
    let low = dir.path().join("low.hdr");
    image::DynamicImage::ImageRgb32F(image::Rgb32FImage::from_fn(32, 16, |x, y| {
        image::Rgb(if (x, y) == (5, 15) {
            [1e4; 3]
        } else {
            [0.0; 3]
        })
    }))
    .save(&low)
    .unwrap();
    for map in [&one, &low] {
        let json = dir.path().join("t.json");
        let o = acdf(&[
            "render",
            "--material",
            "builtin:nickel",
            "--strategies",
            "product,mis-product",
            "--plane",
            "--width",
            "12",
            "--spp",
            "4",
            "--ref-spp",
            "4",
            "--envmap",
            map.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
            "--out",
            dir.path().to_str().unwrap(),
        ]);
        assert_ok(&o);
        for name in ["product", "mis-product"] {
            let exr = image::open(dir.path().join(format!("nickel-{name}.exr")))
                .unwrap()
                .to_rgb32f();
            assert!(exr
                .pixels()
                .all(|p| p.0.iter().all(|c| c.is_finite() && *c >= 0.0)));
        }
        let v = read_json(&json);
        for t in v["tables"].as_array().unwrap() {
            let rows = t["rows"].as_array().unwrap();
            assert_eq!(rows.len(), 2);
            assert!(rows
                .iter()
                .all(|r| r["rmse"].as_f64().is_some_and(f64::is_finite)));
        }
    }
}

/// A white latitude-longitude map written as Radiance `.hdr` makes a
/// white furnace: with cosine sampling of a Lambertian material (albedo
/// 0.8) every sample is 1 (background) or 0.8 (sphere), without noise;
/// only the pixels on the outline mix the two. A reference of
/// the wrong size and a file that is not an image are one-line errors.
#[test]
fn render_reads_an_hdr_envmap_and_a_reference() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("white.hdr");
    let img = image::Rgb32FImage::from_pixel(16, 8, image::Rgb([1.0, 1.0, 1.0]));
    image::DynamicImage::ImageRgb32F(img).save(&map).unwrap();
    let base = [
        "render",
        "--material",
        "builtin:lambert",
        "--brdf-sampler",
        "cosine",
        "--strategies",
        "brdf",
        "--width",
        "16",
        "--spp",
        "2",
        "--envmap",
        map.to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
    ];
    let o = acdf(&base);
    assert_ok(&o);
    let out = stdout(&o);
    let rows = render_rows(&out, "equal samples");
    let rmse: f64 = rows[0][4].parse().unwrap();
    assert!(rmse < 0.05, "{rows:?}");
    let exr = image::open(dir.path().join("lambert-brdf.exr"))
        .unwrap()
        .to_rgb32f();
    let values: Vec<f32> = exr.pixels().map(|p| p.0[0]).collect();
    let exact = |x: f32| values.iter().filter(|v| (*v - x).abs() < 1e-5).count();
    assert!(values.iter().all(|v| (0.8 - 1e-5..=1.0 + 1e-5).contains(v)));
    assert!(exact(0.8) > 40 && exact(1.0) > 40 && exact(0.8) + exact(1.0) > 200);
    let mut with_ref = base.to_vec();
    let reference = dir.path().join("lambert-brdf.exr");
    with_ref.extend(["--reference", reference.to_str().unwrap(), "--height", "8"]);
    assert_one_line_error(&acdf(&with_ref), "the reference is 16x16");
    let bad = dir.path().join("bad.exr");
    std::fs::write(&bad, b"not an exr").unwrap();
    assert_one_line_error(&render_with_envmap(&bad, dir.path()), "bad.exr");
}

/// `--export-mitsuba` writes the scene and the resampled map; a material
/// Mitsuba cannot read is a one-line error.
#[test]
fn render_exports_a_mitsuba_scene() {
    let dir = tempfile::tempdir().unwrap();
    let export = dir.path().join("mi");
    let o = acdf(&[
        "render",
        "--material",
        "builtin:lambert",
        "--plane",
        "--width",
        "32",
        "--height",
        "24",
        "--export-mitsuba",
        export.to_str().unwrap(),
    ]);
    assert_ok(&o);
    let xml = std::fs::read_to_string(export.join("scene.xml")).unwrap();
    for s in ["envmap", "diffuse", "rectangle", "\"32\"", "\"24\"", "box"] {
        assert!(xml.contains(s), "{s}: {xml}");
    }
    let map = image::open(export.join("envmap.exr")).unwrap();
    assert_eq!((map.width(), map.height()), (2048, 1025));
    let o = acdf(&[
        "render",
        "--material",
        "builtin:nickel",
        "--export-mitsuba",
        export.to_str().unwrap(),
    ]);
    assert_one_line_error(&o, "builtin:lambert");
}

/// A `--json` path that cannot be written fails before any render: a
/// one-line error naming the file in its way, and no image in `--out`.
#[test]
fn render_json_that_cannot_be_written_fails_first() {
    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("a-file");
    std::fs::write(&blocker, b"x").unwrap();
    let out = dir.path().join("out");
    let json = blocker.join("tables.json");
    let o = acdf(&[
        "render",
        "--material",
        "builtin:nickel",
        "--width",
        "8",
        "--height",
        "6",
        "--spp",
        "2",
        "--ref-spp",
        "8",
        "--json",
        json.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_one_line_error(&o, "a-file");
    let images = std::fs::read_dir(&out).map_or(0, |d| d.count());
    assert_eq!(images, 0);
    assert_eq!(std::fs::read(&blocker).unwrap(), b"x");
}

/// `acdf build` writes a sampler file; `--sampler-file` loads it and samples
/// exactly as the freshly built sampler does; a file of another material, a
/// truncated file and a sampler without tables are one-line errors.
#[test]
fn build_then_sample_from_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("nickel.acdfs");
    let file_s = file.to_str().unwrap();
    let tables = ["--resolution", "8x1x32x16"];
    let mut args = vec![
        "build",
        "--material",
        "builtin:nickel",
        "--sampler",
        "adaptive:optimal",
    ];
    args.extend(tables);
    args.extend(["--out", file_s]);
    let o = acdf(&args);
    assert_ok(&o);
    assert!(stdout(&o).contains("loaded in"), "{}", stdout(&o));
    assert!(file.metadata().unwrap().len() > 0);

    let draw = ["--wo", "40,10", "--n", "200", "--seed", "5"];
    let mut from_file = vec![
        "sample",
        "--material",
        "builtin:nickel",
        "--sampler-file",
        file_s,
    ];
    from_file.extend(draw);
    let mut fresh = vec![
        "sample",
        "--material",
        "builtin:nickel",
        "--sampler",
        "adaptive:optimal",
    ];
    fresh.extend(tables);
    fresh.extend(draw);
    let (a, b) = (acdf(&from_file), acdf(&fresh));
    assert_ok(&a);
    assert_eq!(stdout(&a), stdout(&b));
    assert_eq!(stdout(&a).lines().count(), 201);

    let mut wrong = vec![
        "sample",
        "--material",
        "builtin:lambert",
        "--sampler-file",
        file_s,
    ];
    wrong.extend(draw);
    assert_one_line_error(&acdf(&wrong), "built for material `nickel`");

    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.path().join("cut.acdfs");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let mut truncated = vec!["sample", "--material", "builtin:nickel", "--sampler-file"];
    truncated.push(cut.to_str().unwrap());
    truncated.extend(draw);
    assert_one_line_error(&acdf(&truncated), "truncated");

    let o = acdf(&[
        "build",
        "--material",
        "builtin:nickel",
        "--sampler",
        "cosine",
        "--out",
        file_s,
    ]);
    assert_one_line_error(&o, "only tabulated samplers");
}

#[test]
fn bench_prints_a_table_and_writes_documented_json() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("bench.json");
    let o = acdf(&[
        "bench",
        "--samples",
        "3000",
        "--repeats",
        "1",
        "--build-resolution",
        "2x2x16x8",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_ok(&o);
    let out = stdout(&o);
    for needle in [
        "piecewise_constant_2d",
        "adaptive_2d",
        "uniform",
        "adaptive:dp",
    ] {
        assert!(out.contains(needle), "{needle} missing from\n{out}");
    }
    let v = read_json(&json);
    assert_eq!(v["material"], "nickel");
    assert_eq!(v["samples"], 3000);
    // The processor is named, in the table and the JSON.
    let cpu = v["cpu"].as_str().unwrap();
    assert!(
        !cpu.is_empty() && out.contains(&format!("cpu {cpu}")),
        "{cpu}"
    );
    let positive = |x: &serde_json::Value| x.as_f64().is_some_and(|x| x.is_finite() && x > 0.0);
    // The clock readings are those of a real core (a loop whose chain of
    // additions the compiler or the core shortened would read several
    // times the clock, one removed altogether far more), and the table
    // turns the per-call rates into cycles. The lower bound is loose: on a
    // loaded machine the timing loop shares its core, which can lower the
    // reading to a fraction of the clock.
    for field in ["clock_ghz_start", "clock_ghz_end"] {
        if cfg!(target_arch = "x86_64") {
            let ghz = v[field].as_f64().unwrap_or(f64::NAN);
            assert!((0.05..10.0).contains(&ghz), "{field}: {ghz}");
        } else {
            assert!(v[field].is_null(), "{field}: {}", v[field]);
        }
    }
    assert_eq!(
        out.contains("cycles per call"),
        cfg!(target_arch = "x86_64"),
        "{out}"
    );
    let distributions = v["distributions"].as_array().unwrap();
    assert_eq!(distributions.len(), 2);
    for d in distributions {
        assert_eq!((d["nx"].as_u64(), d["ny"].as_u64()), (Some(32), Some(256)));
        for field in [
            "samples_per_second_one_thread",
            "samples_per_second_all_threads",
            "storage_bytes",
        ] {
            assert!(positive(&d[field]), "{field}: {d}");
        }
    }
    // The adaptive slice is smaller than the uniform one.
    assert!(
        distributions[1]["storage_bytes"].as_u64() < distributions[0]["storage_bytes"].as_u64()
    );
    let samplers = v["samplers"].as_array().unwrap();
    let rows: Vec<(&str, &str)> = samplers
        .iter()
        .map(|s| {
            (
                s["name"].as_str().unwrap(),
                s["resolution"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        rows,
        [
            ("uniform", "32x1x256x32"),
            ("adaptive:dp", "32x1x256x32"),
            ("uniform", "32x16x256x32"),
            ("adaptive:chi2", "32x1x256x32"),
            ("outgoing:chi2", rows[4].1),
        ]
    );
    // Kept slices over the 128 fine θ_o slices, then the mean vertices.
    assert!(rows[4].1.contains("/128x1x"), "{}", rows[4].1);
    // The 32x16x256x32 table stores over 30 times what the recommended
    // configuration does.
    let bytes = |k: usize| samplers[k]["storage_bytes"].as_u64().unwrap();
    assert!(
        bytes(2) > 30 * bytes(3),
        "{} against {}",
        bytes(2),
        bytes(3)
    );
    for s in samplers {
        for field in [
            "sample_per_second",
            "sample_each_per_second",
            "sample_batch_per_second",
            "pdf_per_second",
            "pdf_each_per_second",
            "pdf_batch_per_second",
            "storage_bytes",
        ] {
            assert!(positive(&s[field]), "{field}: {s}");
        }
    }
    let builds = v["builds"].as_array().unwrap();
    assert_eq!(builds.len(), 2);
    for b in builds {
        assert_eq!(b["resolution"], "2x2x16x8");
        assert!(
            positive(&b["seconds"]) && positive(&b["storage_bytes"]),
            "{b}"
        );
    }

    assert_eq!(v["material_spec"], "builtin:nickel");

    let o = acdf(&["bench", "--build-resolution", "2x0x16x8"]);
    assert_one_line_error(&o, "build resolution");
    let o = acdf(&["bench", "--material", "no-such-material", "--samples", "10"]);
    assert_one_line_error(&o, "no-such-material");
}

/// `acdf bench --material` takes any material spec.
#[test]
fn bench_takes_any_material() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("bench.json");
    // `bench_prints_a_table_and_writes_documented_json` runs the built-in
    // default; here a measured material when the data is there.
    if shared_data().is_none() {
        return;
    }
    let m = "nbrdf:gray-plastic";
    let o = acdf(&[
        "bench",
        "--material",
        m,
        "--samples",
        "2000",
        "--repeats",
        "1",
        "--build-resolution",
        "2x2x16x8",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_ok(&o);
    assert!(
        stdout(&o).starts_with(&format!("material {m},")),
        "{}",
        stdout(&o)
    );
    let v = read_json(&json);
    assert_eq!(v["material_spec"], m);
    assert_eq!(v["material"], "gray-plastic");
    let o = acdf(&[
        "bench",
        "--material",
        "nbrdf:unobtainium",
        "--samples",
        "10",
    ]);
    assert!(!o.status.success());
}
