"""Environment maps and their samplers: every name of the registry, the
batch shapes, the exceptions, and round trips against `acdf env-sample`
and `acdf env-pdf` for the same seed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import acdf
from conftest import csv_rows, run

# Each family once, under its plain name (its default simplifier): derived
# from the registry, so a family added in Rust is tested here too.
FAMILIES = [n for n in acdf.ENV_SAMPLER_NAMES if ":" not in n]
NORMAL = (60.0, 120.0)


@pytest.fixture(scope="module")
def envmap(env_path: Path) -> acdf.EnvMap:
    return acdf.EnvMap.load(env_path)


def test_names_come_from_the_registry() -> None:
    assert {"uniform", "adaptive", "oriented", "uniform-comp", "adaptive-comp"} <= set(FAMILIES)
    for s in acdf.SIMPLIFIER_NAMES:
        assert f"adaptive:{s}" in acdf.ENV_SAMPLER_NAMES
        assert f"oriented:{s}" in acdf.ENV_SAMPLER_NAMES


def test_envmap_load_and_radiance(envmap: acdf.EnvMap) -> None:
    assert envmap.size == (1024, 512) and envmap.repairs == (0, 0)
    dirs = np.array([[0, 0, 1], [1, 0, 0], [0, 0, -2], [0, 0, 0]], dtype=np.float64)
    l = envmap.radiance(dirs)
    assert l.shape == (4, 3) and l.dtype == np.float32
    assert np.all(l[:3] >= 0) and np.all(np.isfinite(l))
    np.testing.assert_array_equal(l[3], 0)
    np.testing.assert_array_equal(envmap.radiance(dirs[1]), l[1])
    # A direction's length does not matter.
    np.testing.assert_array_equal(envmap.radiance(dirs[2] / 2), l[2])
    assert envmap.radiance(dirs, bilinear=True).shape == (4, 3)


@pytest.mark.parametrize("name", FAMILIES)
def test_every_family_samples_with_its_own_pdf(envmap: acdf.EnvMap, name: str) -> None:
    s = acdf.EnvSampler(envmap, name)
    assert s.name.split(":")[0] == name and s.storage_bytes > 0
    assert s.is_compensated == name.endswith("-comp")
    assert (s.cells_built is not None) == name.startswith("oriented")
    n = 4000
    normal = acdf.sphere_direction(*NORMAL)
    dirs, pdf, valid = s.sample(normal, acdf.uniform_2d(n, seed=3))
    assert dirs.shape == (n, 3) and pdf.shape == (n,) and valid.dtype == np.bool_
    assert valid.mean() > 0.99
    np.testing.assert_allclose(np.linalg.norm(dirs[valid], axis=1), 1, atol=1e-5)
    # The density a draw reports is the one pdf gives it, bit for bit.
    np.testing.assert_array_equal(s.pdf(normal, dirs[valid]), pdf[valid])
    # One row per normal gives the same draws as the normal broadcast.
    many = np.tile(normal, (n, 1))
    np.testing.assert_array_equal(s.sample(many, acdf.uniform_2d(n, seed=3))[0], dirs)
    # Single arguments give single results.
    d, p, v = s.sample(normal, acdf.uniform_2d(1, seed=3)[0])
    assert d.shape == (3,) and isinstance(p, float) and isinstance(v, bool)
    assert s.pdf(None, np.zeros(3)) == 0.0


def test_oriented_builds_cells_on_first_use(envmap: acdf.EnvMap) -> None:
    s = acdf.EnvSampler(envmap, "oriented", normal_cells=(2, 4))
    built, total = s.cells_built
    assert total > built
    normals = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, -1, 0]], dtype=np.float32)
    s.sample(np.repeat(normals, 10, axis=0), acdf.uniform_2d(40, seed=1))
    assert s.cells_built[0] > built and s.cells_built[1] == total


def test_env_errors_name_their_cause(tmp_path: Path, envmap: acdf.EnvMap) -> None:
    with pytest.raises(FileNotFoundError) as e:
        acdf.EnvMap.load(tmp_path / "nope.hdr")
    assert isinstance(e.value, acdf.NotFoundError)
    garbage = tmp_path / "garbage.hdr"
    garbage.write_text("not an image")
    with pytest.raises(acdf.EnvMapError, match="cannot decode"):
        acdf.EnvMap.load(garbage)
    with pytest.raises(acdf.UnknownNameError) as e:
        acdf.EnvSampler(envmap, "nope")
    assert all(n in str(e.value) for n in FAMILIES)
    for kwargs in [{"defensive": -0.1}, {"defensive": 1.5}, {"defensive": float("nan")}, {"normal_cells": "0x4"},
                   {"normal_cells": "8by16"}, {"normal_cells": (8,)}, {"tolerance": -1.0}]:
        with pytest.raises(acdf.InvalidArgumentError):
            acdf.EnvSampler(envmap, "oriented", **kwargs)
    s = acdf.EnvSampler(envmap, "uniform")
    with pytest.raises(acdf.ShapeError):
        s.sample(np.zeros(2), acdf.uniform_2d(5))
    with pytest.raises(acdf.ShapeError, match="`normal` has 4 rows but `u` has 5"):
        s.sample(np.zeros((4, 3)), acdf.uniform_2d(5))
    with pytest.raises(acdf.DTypeError):
        s.pdf(None, np.zeros((5, 3), dtype=np.int32))
    with pytest.raises(acdf.InvalidArgumentError):
        acdf.sphere_direction(181, 0)


@pytest.mark.parametrize("name", FAMILIES)
def test_sample_and_pdf_equal_the_command_line(
    acdf_bin: Path, env_path: Path, envmap: acdf.EnvMap, name: str
) -> None:
    n, seed = 2000, 7
    normal = f"{NORMAL[0]:g},{NORMAL[1]:g}"
    common = ["--env", str(env_path), "--sampler", name, "--normal", normal]
    cli = csv_rows(
        run(acdf_bin, "env-sample", *common, "--n", str(n), "--seed", str(seed)), skip_header=True
    ).astype(np.float32)
    s = acdf.EnvSampler(envmap, name)
    dirs, pdf, valid = s.sample(acdf.sphere_direction(*NORMAL), acdf.uniform_2d(n, seed))
    # Every float32 printed in its shortest exact form: equal bit for bit.
    np.testing.assert_array_equal(dirs, cli[:, 0:3])
    np.testing.assert_array_equal(pdf, cli[:, 3])
    np.testing.assert_array_equal(valid, cli[:, 3] > 0)

    stdin = "\n".join(",".join(repr(float(x)) for x in d) for d in dirs[valid])
    cli_pdf = csv_rows(
        run(acdf_bin, "env-pdf", *common, stdin=stdin), skip_header=False
    ).astype(np.float32)[:, 0]
    np.testing.assert_allclose(s.pdf(acdf.sphere_direction(*NORMAL), dirs[valid]), cli_pdf,
                               rtol=1e-5)
