"""Round trips against the `acdf` command: the same material, sampler and
seed give the same numbers from Python as on the command line, and sampler
files pass between the two."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import acdf
from conftest import csv_rows, run

MATERIAL = "builtin:nickel"
WO = (30.0, 45.0)


@pytest.mark.parametrize("sampler", ["adaptive:chi2", "uniform", "cosine"])
def test_sample_pdf_eval_equal_the_command_line(acdf_bin: Path, sampler: str) -> None:
    n, seed = 3000, 7
    wo_arg = f"{WO[0]:g},{WO[1]:g}"
    cli = csv_rows(
        run(acdf_bin, "sample", "--material", MATERIAL, "--sampler", sampler,
            "--wo", wo_arg, "--n", str(n), "--seed", str(seed)),
        skip_header=True,
    ).astype(np.float32)
    m = acdf.Material.load(MATERIAL)
    s = acdf.Sampler(m, sampler)
    wo = acdf.direction(*WO)
    wi, pdf, valid = s.sample(wo, acdf.uniform_2d(n, seed))
    # The command prints each float32 in its shortest exact form: equal bit
    # for bit.
    np.testing.assert_array_equal(wi, cli[:, 0:3])
    np.testing.assert_array_equal(pdf, cli[:, 3])
    np.testing.assert_array_equal(valid, cli[:, 4] == 1)

    # `acdf pdf` and `acdf eval` normalise every direction they read, while
    # Python uses a unit vector as given: the two differ by one float32
    # rounding of the direction, which moves f and pdf on nickel's sharp
    # lobe (exponent ~10^3) by up to 1e-4 relative.
    dirs = "\n".join(",".join(repr(float(x)) for x in w) for w in wi[valid])
    cli_pdf = csv_rows(
        run(acdf_bin, "pdf", "--material", MATERIAL, "--sampler", sampler, "--wo", wo_arg, stdin=dirs),
        skip_header=False,
    ).astype(np.float32)[:, 0]
    np.testing.assert_allclose(s.pdf(wo, wi[valid]), cli_pdf, rtol=2e-4)
    cli_f = csv_rows(
        run(acdf_bin, "eval", "--material", MATERIAL, "--wo", wo_arg, stdin=dirs), skip_header=False
    ).astype(np.float32)
    np.testing.assert_allclose(m.eval(wo, wi[valid]), cli_f, rtol=2e-4)


def test_sampler_files_pass_both_ways(acdf_bin: Path, tmp_path: Path) -> None:
    m = acdf.Material.load(MATERIAL)
    from_cli = tmp_path / "cli.acdfs"
    run(acdf_bin, "build", "--material", MATERIAL, "--sampler", "adaptive:chi2",
        "--resolution", "8x1x32x8", "--out", str(from_cli))
    built = acdf.Sampler(m, "adaptive:chi2", resolution="8x1x32x8")
    loaded = acdf.Sampler.load(from_cli, m)
    assert loaded.storage_bytes == built.storage_bytes
    u = acdf.uniform_2d(500, seed=3)
    wo = acdf.direction(*WO)
    np.testing.assert_array_equal(loaded.sample(wo, u)[0], built.sample(wo, u)[0])

    from_python = tmp_path / "python.acdfs"
    built.save(from_python)
    cli = csv_rows(
        run(acdf_bin, "sample", "--material", MATERIAL, "--sampler-file", str(from_python),
            "--wo", "30,45", "--n", "500", "--seed", "3"),
        skip_header=True,
    ).astype(np.float32)
    np.testing.assert_array_equal(built.sample(wo, u)[0], cli[:, 0:3])


def test_report_equals_the_command_line(acdf_bin: Path, tmp_path: Path) -> None:
    quick = ["--samples", "512", "--timing-samples", "16", "--timing-repeats", "1",
             "--resolution", "8x1x32x8"]
    out = tmp_path / "report.json"
    run(acdf_bin, "report", "--material", MATERIAL, "--sampler", "uniform",
        "--sampler", "adaptive:chi2", *quick, "--json", str(out))
    cli = json.loads(out.read_text())
    py = acdf.report([MATERIAL], ["uniform", "adaptive:chi2"], resolution="8x1x32x8",
                     samples=512, timing_samples=16, timing_repeats=1)
    assert [r["sampler"] for r in py] == [r["sampler"] for r in cli]
    assert list(py[0]) == list(cli[0])
    # Everything but the clock: storage, estimate, variance, missed share.
    for a, b in zip(py, cli):
        for key in ("storage_bytes", "resolution", "estimate", "relative_variance", "samples",
                    "missed_share", "compression_ratio"):
            assert a[key] == b[key], key


def test_sweep_equals_the_command_line(acdf_bin: Path, tmp_path: Path) -> None:
    run(acdf_bin, "sweep", "--material", MATERIAL, "--simplifiers", "chi2", "--tolerances",
        "0.001,0.01", "--samples", "256", "--timing-samples", "16", "--timing-repeats", "1",
        "--resolution", "8x1x32x8", "--out", str(tmp_path))
    cli = json.loads((tmp_path / "sweep-nickel.json").read_text())
    py = acdf.sweep(MATERIAL, ["chi2"], [0.001, 0.01], resolution="8x1x32x8", samples=256,
                    timing_samples=16, timing_repeats=1)
    assert list(py[0]) == list(cli[0])
    for a, b in zip(py, cli, strict=True):
        for key in ("sampler", "tolerance", "storage_bytes", "relative_variance", "mean_marginal_vertices"):
            assert a[key] == b[key], key


def test_target_efficiency_builds_what_the_command_builds(acdf_bin: Path, tmp_path: Path) -> None:
    # A target every candidate meets (the least efficient of the search is
    # ~0.15 of the reference), so the choice depends on storage only, not
    # on the clock: the search steps the tolerance up until the storage
    # stops shrinking and keeps the smallest such tolerance.
    args = {"resolution": "8x1x32x8", "reference": "uniform@8x1x32x8"}
    out = tmp_path / "target.acdfs"
    text = run(acdf_bin, "build", "--material", MATERIAL, "--sampler", "adaptive:chi2",
               "--resolution", args["resolution"], "--reference", args["reference"],
               "--target-efficiency", "0.01", "--out", str(out))
    m = acdf.Material.load(MATERIAL)
    s = acdf.Sampler(m, "adaptive:chi2", target_efficiency=0.01, **args)
    search = s.target_search
    assert search["reached"] and search["target"] == 0.01
    chosen = search["chosen"]
    assert chosen["storage_bytes"] == s.storage_bytes
    assert chosen["storage_bytes"] == min(c["storage_bytes"] for c in search["tried"])
    # The command's line: "adaptive:chi2: tolerance 6.144e0 meets ..." (Rust's
    # `{:.3e}`: no sign or leading zeros in the exponent).
    mantissa, exponent = f"{chosen['tolerance']:.3e}".split("e")
    assert f"tolerance {mantissa}e{int(exponent)} meets" in text, text
    loaded = acdf.Sampler.load(out, m)
    assert loaded.storage_bytes == s.storage_bytes
    u = acdf.uniform_2d(500, seed=3)
    wo = acdf.direction(*WO)
    np.testing.assert_array_equal(loaded.sample(wo, u)[0], s.sample(wo, u)[0])


def test_a_bad_target_fails_as_on_the_command_line(acdf_bin: Path, tmp_path: Path) -> None:
    done = subprocess.run(
        [str(acdf_bin), "build", "--material", MATERIAL, "--sampler", "adaptive:chi2",
         "--target-efficiency=-2", "--out", str(tmp_path / "x.acdfs")],
        capture_output=True, text=True, check=False,
    )
    assert done.returncode != 0
    with pytest.raises(acdf.InvalidArgumentError) as e:
        acdf.Sampler(acdf.Material.load(MATERIAL), "adaptive:chi2", target_efficiency=-2)
    assert str(e.value) in done.stderr
    assert not (tmp_path / "x.acdfs").exists()
