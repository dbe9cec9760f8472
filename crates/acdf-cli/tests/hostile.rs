//! The `acdf` command against hostile input and failing output (issue 29):
//! one test per finding, named `fN_...` after it, and the kill test. Each
//! runs the binary under a 4 GiB address-space limit and a timeout, so that
//! a build that reads without bound fails instead of taking the machine.
//!
//! `ACDF_BIN=/path/to/acdf cargo test -p acdf-cli --test hostile` runs the
//! same tests against another build of the command (an older one fails
//! them).

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

use acdf::materials::merl::{MerlTable, FILE_LEN, PLANE_LEN};
use acdf_core::Brdf;

/// The binary under test.
fn bin() -> PathBuf {
    std::env::var_os("ACDF_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_acdf")))
}

/// `acdf ARGS` run through `sh` with `prelude` (shell commands, e.g. a
/// `ulimit`) and a 4 GiB address-space limit.
fn command(prelude: &str, args: &[&str]) -> Command {
    let mut c = Command::new("sh");
    c.arg("-c")
        .arg(format!("ulimit -v 4194304; {prelude} exec \"$0\" \"$@\""))
        .arg(bin())
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    c
}

/// Wait at most `seconds`, killing the child past that.
fn finish(mut child: Child, seconds: u64) -> Output {
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(seconds) {
            let _ = child.kill();
            panic!("acdf ran longer than {seconds} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn run(args: &[&str]) -> Output {
    finish(command("", args).spawn().unwrap(), 60)
}

fn run_stdin(args: &[&str], input: &[u8]) -> Output {
    let mut child = command("", args).stdin(Stdio::piped()).spawn().unwrap();
    let mut stdin = child.stdin.take().unwrap();
    // A command that stops reading early closes the pipe: not a failure.
    let _ = stdin.write_all(input);
    drop(stdin);
    finish(child, 60)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn signal(status: ExitStatus) -> Option<i32> {
    use std::os::unix::process::ExitStatusExt;
    status.signal()
}

fn assert_ok(o: &Output) {
    assert!(
        o.status.success(),
        "failed ({:?}): {}",
        o.status,
        text(&o.stderr)
    );
}

/// Failed with status 1 (not a signal) and exactly one line on stderr that
/// contains `needle`.
fn assert_one_line_error(o: &Output, needle: &str) {
    let err = text(&o.stderr);
    assert_eq!(
        o.status.code(),
        Some(1),
        "status {:?}, stderr: {err}",
        o.status
    );
    assert_eq!(err.lines().count(), 1, "stderr: {err}");
    assert!(err.contains(needle), "stderr `{err}` lacks `{needle}`");
    assert!(
        !err.contains("panicked") && !err.contains("internal error"),
        "{err}"
    );
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Files in `dir` other than `keep`: what a write left behind.
fn strays(dir: &Path, keep: &[&str]) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !keep.contains(&n.as_str()))
        .collect()
}

/// The bytes of a MERL file of calibrated value `v` everywhere (raw
/// v / scale), and `raw` where `at` says.
fn merl_bytes(raw: impl Fn(usize, usize) -> f64) -> Vec<u8> {
    let mut b: Vec<u8> = [90i32, 90, 180]
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect();
    b.reserve(FILE_LEN as usize);
    for c in 0..3 {
        for n in 0..PLANE_LEN {
            b.extend_from_slice(&raw(c, n).to_le_bytes());
        }
    }
    b
}

/// `acdf build` of a uniform sampler of `material` at `resolution` into
/// `out`.
fn build_args<'a>(material: &'a str, resolution: &'a str, out: &'a Path) -> [&'a str; 9] {
    [
        "build",
        "--material",
        material,
        "--sampler",
        "uniform",
        "--resolution",
        resolution,
        "--out",
        p(out),
    ]
}

fn bake(material: &str, out: &Path) {
    assert_ok(&run(&["bake", "--material", material, "--out", p(out)]));
}

/// A weight file of one network of 675 copies of `w`, with its names file.
fn one_network(dir: &Path, name: &str, w: f32) -> PathBuf {
    let weights = dir.join("merl_nbrdf_weights.f32");
    let bytes: Vec<u8> = (0..675).flat_map(|_| w.to_le_bytes()).collect();
    std::fs::write(&weights, bytes).unwrap();
    std::fs::write(dir.join("merl_nbrdf_materials.txt"), format!("{name}\n")).unwrap();
    weights
}

/// Finding 1: `bake --out F` wrote in place. A write that fails (here a
/// file-size limit, as a full disk does) leaves the old F and no temporary
/// file; two bakes to the same F at once leave one of the two whole.
#[test]
fn f1_bake_is_atomic_under_a_full_disk_and_concurrent_writers() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.binary");
    std::fs::write(&out, b"the previous file").unwrap();
    let full = finish(
        command(
            "trap '' XFSZ; ulimit -f 4096;",
            &["bake", "--material", "builtin:lambert", "--out", p(&out)],
        )
        .spawn()
        .unwrap(),
        60,
    );
    assert_one_line_error(&full, "out.binary");
    assert!(
        text(&full.stderr).contains("cannot write"),
        "{}",
        text(&full.stderr)
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"the previous file");
    assert_eq!(strays(dir.path(), &["out.binary"]), Vec::<String>::new());

    let (lambert, nickel) = (dir.path().join("l.binary"), dir.path().join("n.binary"));
    bake("builtin:lambert", &lambert);
    bake("builtin:nickel", &nickel);
    let (lambert, nickel) = (
        std::fs::read(&lambert).unwrap(),
        std::fs::read(&nickel).unwrap(),
    );
    for round in 0..2 {
        let children: Vec<Child> = ["builtin:lambert", "builtin:nickel"]
            .iter()
            .map(|m| {
                command("", &["bake", "--material", m, "--out", p(&out)])
                    .spawn()
                    .unwrap()
            })
            .collect();
        for c in children {
            assert_ok(&finish(c, 60));
        }
        let got = std::fs::read(&out).unwrap();
        assert!(
            got == lambert || got == nickel,
            "round {round}: the file is neither bake ({} bytes)",
            got.len()
        );
    }
    assert_eq!(
        strays(dir.path(), &["out.binary", "l.binary", "n.binary"]),
        Vec::<String>::new()
    );
}

/// Finding 2: `build --out` replaced FIFOs and symbolic links with regular
/// files and turned a 0600 file into 0644. (A device such as /dev/null is
/// refused by the same check, tested in `acdf_io::fsio` without touching
/// the real one; the interrupted build is the kill test's.)
#[test]
fn f2_build_refuses_special_targets_and_keeps_modes() {
    use std::os::unix::fs::{FileTypeExt, PermissionsExt};
    let dir = tempfile::tempdir().unwrap();
    let build = |out: &Path| run(&build_args("builtin:lambert", "4x1x8x4", out));
    let fifo = dir.path().join("fifo.acdfs");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    assert_one_line_error(&build(&fifo), "a FIFO, not a regular file");
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());

    let target = dir.path().join("target.acdfs");
    std::fs::write(&target, b"kept").unwrap();
    let link = dir.path().join("link.acdfs");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    assert_one_line_error(&build(&link), "a symbolic link, not a regular file");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(&target).unwrap(), b"kept");

    std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o600)).unwrap();
    assert_ok(&build(&target));
    let mode = std::fs::metadata(&target).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    assert_eq!(
        strays(dir.path(), &["fifo.acdfs", "target.acdfs", "link.acdfs"]),
        Vec::<String>::new()
    );
}

/// Finding 3: a saved sampler was matched to `--material` by file stem
/// only, and the options it fixes were silently ignored.
#[test]
fn f3_saved_samplers_match_materials_by_content_and_fix_their_options() {
    let dir = tempfile::tempdir().unwrap();
    for sub in ["a", "b"] {
        std::fs::create_dir(dir.path().join(sub)).unwrap();
    }
    let (nickel, impostor) = (
        dir.path().join("a/nickel.binary"),
        dir.path().join("b/nickel.binary"),
    );
    bake("builtin:nickel", &nickel);
    bake("builtin:lambert", &impostor);
    let file = dir.path().join("nickel.acdfs");
    assert_ok(&run(&build_args(p(&nickel), "4x1x16x8", &file)));
    let sample = |material: &Path, extra: &[&str]| {
        let mut args = vec![
            "sample",
            "--material",
            p(material),
            "--sampler-file",
            p(&file),
            "--wo",
            "30,0",
            "--n",
            "3",
        ];
        args.extend(extra);
        run(&args)
    };
    assert_ok(&sample(&nickel, &[]));
    assert_one_line_error(&sample(&impostor, &[]), "was built for material `nickel`");
    for (option, value) in [
        ("--cosine-mix", Some("0.1")),
        ("--tolerance", Some("0.01")),
        ("--resolution", Some("8x1x16x8")),
        ("--paper", None),
    ] {
        let mut extra = vec![option];
        extra.extend(value);
        let o = sample(&nickel, &extra);
        assert_one_line_error(&o, option);
        assert!(text(&o.stderr).contains("fixes it"), "{}", text(&o.stderr));
    }
}

/// Finding 4: a material path that is a link to /dev/zero or /dev/urandom
/// was read whole before its header was checked.
#[test]
fn f4_material_paths_to_endless_devices_are_refused_after_the_header() {
    let dir = tempfile::tempdir().unwrap();
    let link = |name: &str, device: &str| {
        let path = dir.path().join(name);
        std::os::unix::fs::symlink(device, &path).unwrap();
        path
    };
    let eval = |material: &Path| {
        run_stdin(
            &["eval", "--material", p(material), "--wo", "30,0"],
            b"0,0,1\n",
        )
    };
    let start = Instant::now();
    assert_one_line_error(&eval(&link("zero.binary", "/dev/zero")), "header");
    assert_one_line_error(&eval(&link("random.bsdf", "/dev/urandom")), "random.bsdf");
    assert_one_line_error(&eval(&link("zero.bsdf", "/dev/zero")), "zero.bsdf");
    let sampler = link("zero.acdfs", "/dev/zero");
    assert_one_line_error(
        &run_stdin(
            &[
                "pdf",
                "--material",
                "builtin:nickel",
                "--sampler-file",
                p(&sampler),
                "--wo",
                "30,0",
            ],
            b"0,0,1\n",
        ),
        "zero.acdfs",
    );
    let nets = dir.path().join("nets");
    std::fs::create_dir(&nets).unwrap();
    std::fs::write(nets.join("merl_nbrdf_materials.txt"), "a\n").unwrap();
    std::os::unix::fs::symlink("/dev/zero", nets.join("w.f32")).unwrap();
    let weights = nets.join("w.f32");
    assert_one_line_error(
        &run_stdin(
            &[
                "eval",
                "--material",
                "nbrdf:a",
                "--nbrdf-weights",
                p(&weights),
                "--wo",
                "30,0",
            ],
            b"0,0,1\n",
        ),
        "w.f32",
    );
    assert!(start.elapsed() < Duration::from_secs(30));
}

/// Finding 5: a line with no end grew without bound, and a huge token was
/// echoed whole in the error.
#[test]
fn f5_stdin_lines_are_bounded_and_not_echoed_whole() {
    let args = [
        "pdf",
        "--material",
        "builtin:lambert",
        "--sampler",
        "cosine",
        "--wo",
        "30,0",
    ];
    let zero = std::fs::File::open("/dev/zero").unwrap();
    let o = finish(command("", &args).stdin(zero).spawn().unwrap(), 30);
    assert_one_line_error(&o, "line 1");
    assert!(
        text(&o.stderr).contains("longer than"),
        "{}",
        text(&o.stderr)
    );
    let mut token = "7".repeat(10 << 20);
    token.push_str(",0\n");
    let o = run_stdin(&args, token.as_bytes());
    assert_one_line_error(&o, "line 1");
    assert!(o.stderr.len() < 300, "{} bytes of error", o.stderr.len());
}

/// Finding 6: sizes that pass every per-axis check but not the memory
/// (2.7e11 cells; a 100000-pixel-wide render) aborted out of memory.
#[test]
fn f6_sizes_beyond_the_memory_limit_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("huge.acdfs");
    let o = run(&build_args("builtin:nickel", "65536x1x2048x2048", &out));
    assert_one_line_error(&o, "memory limit");
    assert!(text(&o.stderr).contains("65536x1x2048x2048"));
    let render = run(&[
        "render",
        "--material",
        "builtin:nickel",
        "--width",
        "100000",
        "--out",
        p(dir.path()),
    ]);
    assert_one_line_error(&render, "memory limit");
    // The flag moves the limit both ways.
    let sample = |limit: &str| {
        run(&[
            "sample",
            "--material",
            "builtin:nickel",
            "--sampler",
            "uniform",
            "--wo",
            "30,0",
            "--n",
            "2",
            "--memory-limit",
            limit,
        ])
    };
    assert_one_line_error(&sample("1M"), "memory limit of 1.0 MiB");
    assert_ok(&sample("64M"));
    assert_ok(&sample("unlimited"));
    assert!(!out.exists());
}

/// Finding 7: a full stdout panicked and a full stderr aborted; a closed
/// pipe must end the command as it ends any Unix tool.
#[test]
fn f7_output_failures_end_cleanly_and_sigpipe_kills_as_in_unix_tools() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.acdfs");
    let full = || {
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    let build = build_args("builtin:lambert", "4x1x8x4", &out);
    let o = finish(command("", &build).stdout(full()).spawn().unwrap(), 60);
    assert_one_line_error(&o, "cannot write to standard output");
    assert!(out.exists(), "the sampler is saved before the summary");

    let baked = dir.path().join("l.binary");
    let o = finish(
        command(
            "",
            &["bake", "--material", "builtin:lambert", "--out", p(&baked)],
        )
        .stderr(full())
        .spawn()
        .unwrap(),
        60,
    );
    assert!(
        o.status.success(),
        "bake with a full stderr: {:?}",
        o.status
    );
    let o = finish(
        command(
            "",
            &["sample", "--material", "builtin:lambert", "--wo", "95,0"],
        )
        .stderr(full())
        .spawn()
        .unwrap(),
        60,
    );
    assert_eq!(o.status.code(), Some(1), "{:?}", o.status);

    let mut child = command(
        "",
        &[
            "sample",
            "--material",
            "builtin:lambert",
            "--sampler",
            "cosine",
            "--wo",
            "30,0",
            "--n",
            "10000000",
        ],
    )
    .spawn()
    .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert_eq!(first.trim(), "wi_x,wi_y,wi_z,pdf,valid");
    let o = finish(child, 60);
    assert_eq!(signal(o.status), Some(13), "{:?}", o.status);
    assert!(o.stderr.is_empty(), "{}", text(&o.stderr));
}

/// A render of 8 × 8 pixels at 1 sample per pixel into `out`, with
/// `extra` arguments.
fn small_render(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "render",
        "--material",
        "builtin:lambert",
        "--width",
        "8",
        "--spp",
        "1",
        "--ref-spp",
        "1",
        "--out",
        p(out),
    ];
    args.extend(extra);
    run(&args)
}

/// Finding 8: `--seconds=1e30` panicked converting to a Duration.
#[test]
fn f8_equal_time_seconds_beyond_a_year_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for seconds in ["1e30", "inf", "-1", "0"] {
        let o = small_render(dir.path(), &[&format!("--seconds={seconds}")]);
        assert_one_line_error(&o, "seconds");
    }
}

/// Finding 9: directions were parsed as f32 (`1e-30,0,1e-30` gave pdf 0)
/// and extra columns were dropped.
#[test]
fn f9_directions_are_read_in_f64_with_exact_field_counts() {
    let pdf = |input: &str| {
        run_stdin(
            &[
                "pdf",
                "--material",
                "builtin:lambert",
                "--sampler",
                "cosine",
                "--wo",
                "30,0",
            ],
            input.as_bytes(),
        )
    };
    let o = pdf("1e-30,0,1e-30\n1e150,0,1e150\n1,0,1\n");
    assert_ok(&o);
    let values: Vec<f64> = text(&o.stdout)
        .lines()
        .map(|l| l.parse().unwrap())
        .collect();
    let expected = std::f64::consts::FRAC_1_SQRT_2 / std::f64::consts::PI;
    assert_eq!(values.len(), 3);
    for v in values {
        assert!((v - expected).abs() < 1e-6, "{v}");
    }
    let o = run_stdin(
        &["eval", "--material", "builtin:lambert", "--wo", "30,0"],
        b"1e-30,0,1e-30\n",
    );
    assert_ok(&o);
    assert!(text(&o.stdout)
        .split(',')
        .all(|c| c.trim().parse::<f64>().unwrap() > 0.0));
    assert_one_line_error(&pdf("0,0,1\n0,0,1,5\n"), "line 2");
    assert_one_line_error(&pdf("0,0,1,abc\n"), "line 1");
    let grazing = run(&[
        "sample",
        "--material",
        "builtin:lambert",
        "--sampler",
        "cosine",
        "--wo",
        "89.99999999,0",
        "--n",
        "1",
    ]);
    assert_ok(&grazing);
}

/// Finding 10 through the command: an RGL file whose `rgb` field points
/// into the header, or whose `theta_i` holds hundreds of radians, loaded.
/// (Zero tables and the synthetic cases are tested in
/// `acdf-materials`' rgl tests.)
#[test]
fn f10_rgl_files_with_overlapping_fields_or_wild_angles_are_refused() {
    let Some(data) = acdf::materials::rgl::shared_dir() else {
        acdf::materials::testing::skip_without_data("no shared RGL data (set ACDF_SHARED_DATA)");
        return;
    };
    let good = std::fs::read(data.join("paper_white_rgb.bsdf")).unwrap();
    let file = acdf::materials::rgl::TensorFile::from_bytes(&good).unwrap();
    let descriptor = |name: &str| {
        let mut needle = (name.len() as u16).to_le_bytes().to_vec();
        needle.extend_from_slice(name.as_bytes());
        let at = good
            .windows(needle.len())
            .position(|w| w == needle)
            .unwrap();
        at + needle.len() + 2 + 1
    };
    let dir = tempfile::tempdir().unwrap();
    let eval = |bytes: &[u8], name: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        run_stdin(
            &["eval", "--material", p(&path), "--wo", "30,0"],
            b"0,0,1\n",
        )
    };
    let mut into_header = good.clone();
    let at = descriptor("rgb");
    into_header[at..at + 8].copy_from_slice(&0u64.to_le_bytes());
    assert_one_line_error(&eval(&into_header, "header.bsdf"), "overlaps the header");
    let mut wild = good.clone();
    let theta = file.field("theta_i").unwrap();
    let last = theta.offset as usize + theta.bytes().len() - 4;
    wild[last..last + 4].copy_from_slice(&300f32.to_le_bytes());
    assert_one_line_error(&eval(&wild, "theta.bsdf"), "theta_i");
}

/// Finding 11: a Neural-BRDF network of large weights printed f32::MAX and
/// baked -1 everywhere; a MERL table of zeros sampled with pdf > 0.
#[test]
fn f11_overflowing_networks_and_zero_tables_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let weights = one_network(dir.path(), "huge", 30.0);
    let eval = run_stdin(
        &[
            "eval",
            "--material",
            "nbrdf:huge",
            "--nbrdf-weights",
            p(&weights),
            "--wo",
            "30,0",
        ],
        b"0,0,1\n",
    );
    assert_one_line_error(&eval, "`huge`");
    assert!(text(&eval.stderr).contains("f32"), "{}", text(&eval.stderr));
    let out = dir.path().join("huge.binary");
    let bake = run(&[
        "bake",
        "--material",
        "nbrdf:huge",
        "--nbrdf-weights",
        p(&weights),
        "--out",
        p(&out),
    ]);
    assert_one_line_error(&bake, "`huge`");
    assert!(!out.exists());

    let zeros = dir.path().join("zeros.binary");
    std::fs::write(&zeros, merl_bytes(|_, _| 0.0)).unwrap();
    let o = run_stdin(
        &["eval", "--material", p(&zeros), "--wo", "30,0"],
        b"0,0,1\n",
    );
    assert_ok(&o);
    assert_eq!(text(&o.stdout).trim(), "0,0,0");
    for sampler in ["uniform", "adaptive:chi2"] {
        let o = run(&[
            "sample",
            "--material",
            p(&zeros),
            "--sampler",
            sampler,
            "--wo",
            "30,0",
            "--n",
            "5",
        ]);
        assert_one_line_error(&o, "zero everywhere");
    }
}

/// Finding 12: baking a MERL material changed 3.47 M of its 4.37 M values.
/// A table acdf wrote comes back byte for byte; a table with more precision
/// than acdf keeps (f32) comes back value for value, unmeasured entries
/// included.
#[test]
fn f12_baking_a_merl_material_reproduces_its_table() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.binary"), dir.path().join("b.binary"));
    bake("builtin:nickel", &a);
    bake(p(&a), &b);
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap());

    let mut precise = std::fs::read(&a).unwrap();
    for (k, raw) in precise[12..].chunks_exact_mut(8).enumerate().step_by(7) {
        let v = f64::from_le_bytes(raw.try_into().unwrap());
        let v = if v > 0.0 {
            f64::from_bits(v.to_bits() + (k as u64 % 1000))
        } else {
            -(k as f64) - 1.0
        };
        raw.copy_from_slice(&v.to_le_bytes());
    }
    let (c, d) = (dir.path().join("c.binary"), dir.path().join("d.binary"));
    std::fs::write(&c, &precise).unwrap();
    bake(p(&c), &d);
    let (tc, td) = (MerlTable::read(&c).unwrap(), MerlTable::read(&d).unwrap());
    assert!(tc.unmeasured_count() > 0);
    assert_eq!(tc.unmeasured_count(), td.unmeasured_count());
    assert_eq!(
        tc.fingerprint(),
        td.fingerprint(),
        "values differ after baking"
    );
}

/// Finding 13: `--exposure nan` was accepted.
#[test]
fn f13_nan_exposure_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for exposure in ["nan", "inf", "-1"] {
        let o = small_render(dir.path(), &[&format!("--exposure={exposure}")]);
        assert_one_line_error(&o, "exposure");
    }
}

/// The messages the issue lists, each now naming its real cause.
#[test]
fn error_messages_name_their_cause() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "build",
        "--material",
        "builtin:nickel",
        "--sampler",
        "cosine",
        "--out",
        p(&dir.path().join("c.acdfs")),
    ]);
    assert_one_line_error(&o, "`cosine` has no tables to save");
    assert!(!text(&o.stderr).contains("`-`"));

    let o = run(&[
        "bake",
        "--material",
        "builtin:lambert",
        "--out",
        p(&dir.path().join("no/such/folder/x.binary")),
    ]);
    assert_one_line_error(&o, "cannot write");
    assert!(!text(&o.stderr).contains("material"), "{}", text(&o.stderr));

    let weights = one_network(dir.path(), "broken", f32::NAN);
    let o = run_stdin(
        &[
            "eval",
            "--material",
            "nbrdf:broken",
            "--nbrdf-weights",
            p(&weights),
            "--wo",
            "30,0",
        ],
        b"0,0,1\n",
    );
    assert_one_line_error(&o, "not finite");
    assert!(
        !text(&o.stderr).contains("unknown material"),
        "{}",
        text(&o.stderr)
    );

    let big = dir.path().join("big.binary");
    std::fs::write(
        &big,
        merl_bytes(|c, n| if (c, n) == (0, 99) { 1e308 } else { 1.0 }),
    )
    .unwrap();
    let o = run_stdin(&["eval", "--material", p(&big), "--wo", "30,0"], b"0,0,1\n");
    assert_one_line_error(&o, "1e308");
    assert!(o.stderr.len() < 300, "{}", text(&o.stderr));

    let adaptive = acdf::make_sampler(
        "adaptive:dp",
        &acdf::load_material(&"builtin:lambert".parse().unwrap(), None).unwrap(),
        &acdf::SamplerOptions {
            resolution: "2x1x8x4".parse().unwrap(),
            ..Default::default()
        },
    )
    .unwrap();
    let file = dir.path().join("a.acdfs");
    acdf::registry::save_sampler(&adaptive, &file).unwrap();
    let err = acdf::uniform::UniformBrdfSampler::load(&file)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("\"adaptive\"") && err.contains("\"uniform\""),
        "{err}"
    );
}

/// The kill test: bakes and builds killed at seeded random points (SIGKILL,
/// SIGTERM, SIGINT, SIGQUIT, SIGUSR1, SIGALRM, SIGXFSZ, SIGABRT, SIGHUP in
/// turn; SIGXFSZ is caught and changes nothing) leave the old file or the
/// new one, never a cut or mixed one; after any signal but SIGKILL no
/// temporary file is left (only SIGKILL can leave
/// one, beside the target, under a name ending
/// `.acdf-tmp`). Every other round waits for the write to begin (a new
/// file in the folder, or the target changing) and kills within 20 ms of
/// it, since a uniformly random time rarely lands in the write itself.
#[test]
fn kill_at_random_points_leaves_the_old_or_the_new_file() {
    const SIGNALS: [&str; 9] = [
        "KILL", "TERM", "INT", "QUIT", "USR1", "ALRM", "XFSZ", "ABRT", "HUP",
    ];
    use rand::{Rng, SeedableRng};
    let dir = tempfile::tempdir().unwrap();
    let (old_path, new_path) = (dir.path().join("old"), dir.path().join("new"));
    let cases: [(&str, Vec<&str>, Vec<&str>, f64); 2] = [
        (
            "out.binary",
            vec!["bake", "--material", "builtin:nickel"],
            vec!["bake", "--material", "builtin:lambert"],
            0.8,
        ),
        (
            "out.acdfs",
            vec![
                "build",
                "--material",
                "builtin:lambert",
                "--sampler",
                "uniform",
            ],
            vec![
                "build",
                "--material",
                "builtin:nickel",
                "--sampler",
                "adaptive:chi2",
            ],
            1.5,
        ),
    ];
    let mut rng = rand_pcg::Pcg64::seed_from_u64(29);
    let mut cut_while_writing = 0;
    for (name, old_args, new_args, span) in cases {
        let target = dir.path().join(name);
        for (args, path) in [(&old_args, &old_path), (&new_args, &new_path)] {
            let mut a = args.clone();
            a.extend(["--out", p(path)]);
            assert_ok(&run(&a));
        }
        let (old, new) = (
            std::fs::read(&old_path).unwrap(),
            std::fs::read(&new_path).unwrap(),
        );
        let keep = [name, "old", "new"];
        for (round, sig) in SIGNALS.into_iter().enumerate() {
            std::fs::write(&target, &old).unwrap();
            let before = std::fs::metadata(&target).unwrap().modified().unwrap();
            let mut a = new_args.clone();
            a.extend(["--out", p(&target)]);
            let mut child = Command::new(bin())
                .args(&a)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap();
            if round % 2 == 0 {
                std::thread::sleep(Duration::from_secs_f64(rng.random::<f64>() * span));
            } else {
                let start = Instant::now();
                while start.elapsed() < Duration::from_secs(30)
                    && child.try_wait().unwrap().is_none()
                    && strays(dir.path(), &keep).is_empty()
                    && std::fs::metadata(&target).is_ok_and(|m| {
                        m.len() == old.len() as u64 && m.modified().unwrap() == before
                    })
                {
                    std::thread::sleep(Duration::from_micros(300));
                }
                std::thread::sleep(Duration::from_secs_f64(rng.random::<f64>() * 0.02));
            }
            let _ = Command::new("kill")
                .args([format!("-{sig}"), child.id().to_string()])
                .status();
            let status = child.wait().unwrap();
            let got = std::fs::read(&target).unwrap();
            assert!(
                got == old || got == new,
                "{name} round {round} ({sig}, {status:?}): {} bytes, neither file",
                got.len()
            );
            let left = strays(dir.path(), &keep);
            if sig == "KILL" {
                assert!(left.iter().all(|n| n.ends_with(".acdf-tmp")), "{left:?}");
                cut_while_writing += left.len();
                for n in left {
                    std::fs::remove_file(dir.path().join(n)).unwrap();
                }
            } else {
                assert_eq!(left, Vec::<String>::new(), "{name} round {round} ({sig})");
            }
        }
        std::fs::remove_file(&target).unwrap();
    }
    println!("{cut_while_writing} SIGKILLs landed while a temporary file existed");
}

/// Help and version written to a full disk are a failure, like any other
/// output (they exited 0 silently), and still succeed on a working stdout.
#[test]
fn help_and_version_to_a_full_disk_fail() {
    for flag in ["--help", "--version", "-h", "-V"] {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let o = finish(command("", &[flag]).stdout(full).spawn().unwrap(), 60);
        assert_one_line_error(&o, "cannot write to standard output");
        let o = run(&[flag]);
        assert_ok(&o);
        assert!(!o.stdout.is_empty(), "{flag}");
    }
    // A usage error is still clap's, on stderr, with its status.
    let o = run(&["no-such-command"]);
    assert_eq!(o.status.code(), Some(2), "{:?}", o.status);
    assert!(text(&o.stderr).contains("no-such-command"));
}

/// Every count option is checked against --memory-limit before its draws
/// are allocated: 2^32 draws aborted the process ("memory allocation of
/// 34359738368 bytes failed").
#[test]
fn draw_counts_are_checked_against_the_memory_limit() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("sky.hdr");
    let img = image::Rgb32FImage::from_pixel(16, 8, image::Rgb([1.0, 0.5, 0.25]));
    image::DynamicImage::ImageRgb32F(img).save(&map).unwrap();
    let huge = "4294967296";
    let cases: [Vec<&str>; 4] = [
        vec![
            "env-report",
            "--env",
            p(&map),
            "--sampler",
            "uniform",
            "--mc-samples",
            "64",
            "--timing-samples",
            huge,
            "--timing-passes",
            "1",
        ],
        vec!["report", "--material", "builtin:lambert", "--samples", huge],
        vec![
            "report",
            "--material",
            "builtin:lambert",
            "--samples",
            "0",
            "--timing-samples",
            huge,
        ],
        vec!["bench", "--samples", huge],
    ];
    for args in cases {
        let o = run(&args);
        assert_eq!(signal(o.status), None, "{args:?} died of a signal");
        assert_one_line_error(&o, "memory limit");
    }
}

/// `render`'s reference and its cache: a reference of another size is
/// refused from its header, before its pixels are read (even past the
/// memory limit); a cache key that is a FIFO (which hung the command) or a
/// link to an endless device is noted, and the reference is rendered again
/// and not cached.
#[test]
fn render_reads_its_reference_and_cache_with_bounds() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render",
            "--material",
            "builtin:lambert",
            "--strategies",
            "brdf",
            "--width",
            "8",
            "--spp",
            "1",
            "--ref-spp",
            "2",
            "--timing-repeats",
            "1",
            "--out",
            p(&out),
        ];
        args.extend(extra);
        finish(command("", &args).spawn().unwrap(), 120)
    };

    let big = dir.path().join("big.exr");
    // Noise, so that the file cannot compress below the memory limit.
    let img = image::Rgb32FImage::from_fn(1024, 512, |x, y| {
        let h =
            (x.wrapping_mul(0x9E37_79B9) ^ y.wrapping_mul(0x85EB_CA6B)).wrapping_mul(0xC2B2_AE35);
        image::Rgb([h as f32 / u32::MAX as f32, 0.5, 0.25])
    });
    image::DynamicImage::ImageRgb32F(img).save(&big).unwrap();
    assert!(std::fs::metadata(&big).unwrap().len() > 4 << 20);
    let o = render(&["--reference", p(&big), "--memory-limit", "4M"]);
    assert_one_line_error(&o, "the reference is 1024x512 pixels");

    assert_ok(&render(&[]));
    let key = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().ends_with("-reference.key"))
        .expect("the cached reference's key");
    std::fs::remove_file(&key).unwrap();
    assert!(Command::new("mkfifo").arg(&key).status().unwrap().success());
    let o = render(&[]);
    assert_ok(&o);
    assert!(
        text(&o.stderr).contains("not a regular file"),
        "{}",
        text(&o.stderr)
    );

    std::fs::remove_file(&key).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &key).unwrap();
    let o = render(&[]);
    assert_ok(&o);
    assert!(
        text(&o.stderr).contains("not a regular file"),
        "{}",
        text(&o.stderr)
    );
}

/// The remaining inconsistencies, each decided one way: an output folder
/// taken by something else says what is there (not "File exists"); an
/// infinite tolerance is refused by every command, naming the tolerance;
/// `bench --repeats 0` and `build --reference` without a target are
/// refused; control characters of a user's string are escaped, so that an
/// error stays one line.
#[test]
fn remaining_inconsistencies_are_decided() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let fifo = dir.path().join("a-fifo");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let dangling = dir.path().join("dangling");
    std::os::unix::fs::symlink(dir.path().join("nothing"), &dangling).unwrap();
    for (out, kind) in [
        (&file, "a regular file"),
        (&fifo, "a FIFO"),
        (&dangling, "a symbolic link to nothing"),
    ] {
        let o = run(&[
            "sweep",
            "--material",
            "builtin:lambert",
            "--simplifiers",
            "dp",
            "--tolerances",
            "1e-3",
            "--samples",
            "0",
            "--timing-repeats",
            "1",
            "--out",
            p(out),
        ]);
        assert_one_line_error(
            &o,
            &format!("cannot use {} as a folder: it is {kind}", p(out)),
        );
    }
    let o = run(&[
        "sweep",
        "--material",
        "builtin:lambert",
        "--tolerances",
        "inf",
    ]);
    assert_one_line_error(&o, "invalid tolerance `inf`");
    let o = run(&[
        "sample",
        "--material",
        "builtin:nickel",
        "--tolerance",
        "inf",
        "--wo",
        "30,0",
    ]);
    assert_one_line_error(&o, "invalid tolerance `inf`");
    let o = run(&["bench", "--repeats", "0"]);
    assert_one_line_error(&o, "invalid repeats `0`");
    let out = dir.path().join("s.acdfs");
    for reference in ["bogus", "uniform"] {
        let o = run(&[
            "build",
            "--material",
            "builtin:lambert",
            "--sampler",
            "uniform",
            "--reference",
            reference,
            "--out",
            p(&out),
        ]);
        assert_one_line_error(&o, reference);
        assert!(!out.exists());
    }
    let o = run(&[
        "sample",
        "--material",
        "builtin:a\nb\u{1b}[31m",
        "--wo",
        "30,0",
    ]);
    assert_one_line_error(&o, "builtin:a\\nb\\u{1b}[31m");
}
