"""Shared fixtures of the Python package's tests: where the repository, the
shared data and the `acdf` command are. Tests that need what is absent skip
with the reason."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[3]


def shared_data() -> Path | None:
    """`$ACDF_SHARED_DATA`, else `../shared/data` beside the repository."""
    env = os.environ.get("ACDF_SHARED_DATA")
    candidates = [Path(env)] if env else []
    candidates.append(REPO.parent / "shared" / "data")
    return next((p for p in candidates if p.is_dir()), None)


def skip_without_data(reason: str) -> None:
    """Skip a test whose shared data is absent, or, where `ACDF_REQUIRE_DATA`
    is set to anything but empty or 0 (as CI sets it: CI always has the
    data), fail it, so that a missing data folder cannot pass."""
    if os.environ.get("ACDF_REQUIRE_DATA", "") not in ("", "0"):
        pytest.fail(f"the shared data this test needs is absent and ACDF_REQUIRE_DATA is set: {reason}")
    pytest.skip(f"skipping: {reason}")


def data_file(folder: str, name: str) -> Path | None:
    """`name` in the shared data's `folder`, if it is there."""
    data = shared_data()
    path = data / folder / name if data else None
    return path if path is not None and path.is_file() else None


def rgl_file(name: str = "ilm_solo_m_68_rgb.bsdf") -> Path | None:
    return data_file("rgl-material-database", name)


@pytest.fixture(scope="session")
def rgl_path() -> Path:
    path = rgl_file()
    if path is None:
        skip_without_data("no RGL material (../shared/data/rgl-material-database absent)")
    return path


def env_file(name: str = "studio_small_03_1k.hdr") -> Path | None:
    return data_file("envmaps", name)


@pytest.fixture(scope="session")
def env_path() -> Path:
    path = env_file()
    if path is None:
        skip_without_data("no environment map (../shared/data/envmaps absent)")
    return path


@pytest.fixture(scope="session")
def acdf_bin() -> Path:
    """The `acdf` command: `$ACDF_BIN`, else target/release/acdf, else on PATH."""
    env = os.environ.get("ACDF_BIN")
    candidates = [Path(env)] if env else []
    candidates.append(REPO / "target" / "release" / "acdf")
    which = shutil.which("acdf")
    if which:
        candidates.append(Path(which))
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    pytest.skip("skipping: no acdf command (cargo build --release -p acdf-cli, or set ACDF_BIN)")


def run(acdf_bin: Path, *args: str, stdin: str | None = None) -> str:
    """The `acdf` command's stdout; it must succeed."""
    done = subprocess.run(
        [str(acdf_bin), *args], input=stdin, capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def csv_rows(text: str, skip_header: bool) -> np.ndarray:
    """The numbers of the command's CSV output, one row a line."""
    lines = [l for l in text.splitlines() if l.strip()]
    if skip_header:
        lines = lines[1:]
    return np.array([[float(x) for x in l.split(",")] for l in lines])
