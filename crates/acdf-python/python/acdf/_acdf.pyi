"""Type stubs of the native module `acdf._acdf` (re-exported by `acdf`)."""

from __future__ import annotations

import os
import pathlib
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

__version__: str

#: Every sampler name `Sampler` accepts (from the registry of the Rust crate:
#: a sampler added there appears here).
SAMPLER_NAMES: tuple[str, ...]
#: Every environment sampler name `EnvSampler` accepts (from the registry of
#: the Rust crate, `ENV_SAMPLERS`).
ENV_SAMPLER_NAMES: tuple[str, ...]
#: The simplifiers of the adaptive sampler (`adaptive:NAME`).
SIMPLIFIER_NAMES: tuple[str, ...]
#: The built-in materials (`builtin:NAME`).
BUILTIN_MATERIALS: tuple[str, ...]
#: Batches of at least this many rows run on every core.
PARALLEL_MIN: int

#: A float32 or float64 array (or a nested sequence of floats).
Floats = npt.ArrayLike
Resolution = str | tuple[int, int, int, int]
PathLike = str | os.PathLike[str]

class Material:
    """A measured or analytic BRDF, loaded from a spec the `acdf` command
    accepts: `builtin:NAME`, a MERL `.binary` path, an RGL `.bsdf` path, or
    `nbrdf:NAME`."""

    @staticmethod
    def load(spec: PathLike, nbrdf_weights: PathLike | None = None) -> Material:
        """Load the material `spec` names. A missing file raises
        `acdf.NotFoundError` (a `FileNotFoundError`), an unknown name
        `acdf.UnknownNameError`, a malformed file `acdf.MaterialError`."""
    @property
    def spec(self) -> str:
        """The spec it was loaded from."""
    @property
    def name(self) -> str:
        """The BRDF's own name (recorded in sampler files)."""
    @property
    def label(self) -> str:
        """A short label: the built-in or network name, or the file stem."""
    @property
    def is_isotropic(self) -> bool:
        """Whether f_r depends on the azimuths only through their difference."""
    def eval(self, wo: Floats, wi: Floats) -> npt.NDArray[np.float32]:
        """f_r(wo, wi) per RGB channel in 1/sr, without the cosine factor.

        `wo`, `wi`: shape (3,) or (N, 3), local frame (z along the normal,
        both pointing away from the surface); a single row is broadcast.
        Returns float32 (N, 3), or (3,) when both are single; 0 at or below
        the horizon."""

class Sampler:
    """An importance sampler of incident directions for one material."""

    def __init__(
        self,
        material: Material,
        name: str,
        *,
        resolution: Resolution | None = None,
        tolerance: float | None = None,
        cosine_mix: float = 0.0,
        target_efficiency: float | None = None,
        reference: str | None = None,
        lazy: bool = False,
    ) -> None:
        """Build the sampler `name` (one of `SAMPLER_NAMES`) for `material`.

        `resolution`: `"32x1x256x32"` (default), `"paper"` or four counts.
        `tolerance`: the simplifier's (default: its own). `cosine_mix`: the
        probability of drawing from a cosine lobe. `target_efficiency`: for
        an adaptive sampler, search the tolerance (from `tolerance` or the
        default) for the least storage whose efficiency is at least this
        fraction of `reference`'s (`NAME` or `NAME@RES`, default
        `uniform@32x16x256x32`), as `acdf build --target-efficiency` does;
        `acdf.TargetNotReachedError` when no tolerance reaches it. `lazy`:
        build each table on first use instead of all now. Ctrl-C interrupts
        the build."""
    @staticmethod
    def load(path: PathLike, material: Material) -> Sampler:
        """Read a sampler file (`Sampler.save`, `acdf build`) built for
        `material`."""
    def save(self, path: PathLike) -> None:
        """Write the sampler file (atomically); `acdf.IncompatibleError` for
        samplers without tables."""
    @property
    def name(self) -> str:
        """The sampler's name, e.g. `adaptive:chi2`."""
    @property
    def material(self) -> Material:
        """The material it samples."""
    @property
    def storage_bytes(self) -> int:
        """Bytes held by the tables built so far."""
    @property
    def resolution(self) -> str:
        """θ_o×φ_o×θ_h×φ_h, or θ_o×φ_o× mean kept vertices; `-` without tables."""
    @property
    def mean_vertices(self) -> tuple[float, float] | None:
        """Mean kept marginal and conditional vertices of an adaptive sampler."""
    @property
    def target_search(self) -> dict[str, Any] | None:
        """What the `target_efficiency` search found: `sampler`, `target`,
        `reached`, `chosen` (the candidate built: `tolerance`,
        `storage_bytes`, `relative_variance`, `relative_efficiency`, ...),
        `tried` (every candidate); None without a target."""
    def sample(
        self, wo: Floats, u: Floats
    ) -> tuple[npt.NDArray[np.float32], Any, Any]:
        """Draw incident directions: `(wi, pdf, valid)`.

        `wo`: (3,) or (N, 3); `u`: uniform numbers, (2,) or (N, 2); a single
        row is broadcast. `wi` float32 (N, 3), `pdf` float32 (N,) per unit
        solid angle, `valid` bool (N,); a failed draw is wi = 0, pdf = 0,
        valid = False. Both single: `(wi (3,), float, bool)`."""
    def pdf(self, wo: Floats, wi: Floats) -> Any:
        """The solid-angle density of `wi` given `wo`: float32 (N,), or a
        float when both are single."""

class EnvMap:
    """A latitude-longitude environment map (`.hdr` or `.exr`, +z up, row 0
    at the zenith, φ = 0 along +x at the left edge)."""

    @staticmethod
    def load(path: PathLike, *, repair: bool = False) -> EnvMap:
        """Read the map. `acdf.NotFoundError` for a missing file,
        `acdf.EnvMapError` for one that cannot be decoded, is not twice as
        wide as high, or has NaN, infinite or negative texels (unless
        `repair`, which sets them to 0 with a warning);
        `acdf.InvalidArgumentError` for a black map."""
    @property
    def path(self) -> pathlib.Path:
        """The file it was read from."""
    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in texels."""
    @property
    def repairs(self) -> tuple[int, int]:
        """(non-finite, negative) channel values `repair=True` set to 0."""
    def radiance(self, dirs: Floats, *, bilinear: bool = False) -> npt.NDArray[np.float32]:
        """RGB radiance towards `dirs` ((3,) or (N, 3), the map's frame):
        float32 (N, 3) or (3,); the texel's value, or bilinear between texel
        centres. 0 for a zero or non-finite direction."""

class EnvSampler:
    """An importance sampler of directions towards an environment map."""

    def __init__(
        self,
        envmap: EnvMap,
        name: str,
        *,
        tolerance: float | None = None,
        normal_cells: str | tuple[int, int] | None = None,
        defensive: float | None = None,
    ) -> None:
        """Build the sampler `name` (one of `ENV_SAMPLER_NAMES`) for `envmap`.

        `tolerance`: the simplifier's (default: its own; 0.005 for chi2).
        `normal_cells` (`"16x32"` default) and `defensive` (in [0, 1],
        default 0): the oriented sampler's, whose tables are built on
        first use per region of normals. Ctrl-C interrupts the build."""
    @property
    def name(self) -> str:
        """The sampler's name, e.g. `adaptive:chi2`."""
    @property
    def envmap(self) -> EnvMap:
        """The map it samples."""
    @property
    def storage_bytes(self) -> int:
        """Bytes held by the tables built so far."""
    @property
    def cells_built(self) -> tuple[int, int] | None:
        """For `oriented`: (cells of normals built so far, all cells)."""
    @property
    def tables(self) -> str:
        """The tables as `acdf env-report` labels them."""
    @property
    def is_compensated(self) -> bool:
        """Whether it draws the compensated density (`*-comp`, for MIS)."""
    def sample(
        self, normal: Floats | None, u: Floats
    ) -> tuple[npt.NDArray[np.float32], Any, Any]:
        """Draw directions: `(dirs, pdf, valid)`.

        `normal`: None, (3,) or (N, 3), the shading normal in the map's
        frame (used by `oriented`; zero or non-finite counts as none); `u`:
        (2,) or (N, 2). `dirs` float32 (N, 3), `pdf` float32 (N,) per unit
        solid angle, `valid` bool (N,); a failed draw is dirs = 0, pdf = 0,
        valid = False. Both single: `(dirs (3,), float, bool)`."""
    def pdf(self, normal: Floats | None, dirs: Floats) -> Any:
        """The solid-angle density of `dirs` for `normal`: float32 (N,), or a
        float when both are single; 0 for a zero or non-finite direction."""

def sphere_direction(theta_deg: float, phi_deg: float) -> npt.NDArray[np.float32]:
    """The unit direction at polar angle `theta_deg` from +z in [0, 180] and
    azimuth `phi_deg`, as `acdf env-sample --normal THETA,PHI` computes it."""

def uniform_2d(n: int, seed: int = 1) -> npt.NDArray[np.float32]:
    """`n` uniform pairs in [0, 1), float32 (n, 2): the stream of
    `acdf sample --seed SEED`."""

def direction(theta_deg: float, phi_deg: float) -> npt.NDArray[np.float32]:
    """The unit direction at polar angle `theta_deg` in [0, 90) and azimuth
    `phi_deg`, as `--wo THETA,PHI` computes it."""

def report(
    materials: Sequence[Material | str] | None = None,
    samplers: Sequence[str] | None = None,
    *,
    resolution: Resolution | None = None,
    tolerance: float | None = None,
    cosine_mix: float = 0.0,
    samples: int | None = None,
    timing_samples: int | None = None,
    timing_repeats: int | None = None,
    seed: int | None = None,
    target_efficiency: float | None = None,
    reference: str | None = None,
) -> list[dict[str, Any]]:
    """The results table of `acdf report`: one dict per material and
    sampler, with the keys of `acdf report --json`. `reference`: the
    reference of the relative columns (`NAME` or `NAME@RES`);
    `target_efficiency`: search each adaptive sampler's tolerance first, as
    `acdf report --target-efficiency`. Ctrl-C interrupts it."""

def sweep(
    material: Material | str,
    simplifiers: Sequence[str] | None = None,
    tolerances: Sequence[float] | None = None,
    *,
    resolution: Resolution | None = None,
    samples: int | None = None,
    timing_samples: int | None = None,
    timing_repeats: int | None = None,
    seed: int | None = None,
    target_efficiency: float | None = None,
    reference: str | None = None,
) -> list[dict[str, Any]]:
    """The tolerance sweep of `acdf sweep`: one dict per point, with the
    keys of its JSON output; `target_efficiency` adds each simplifier's
    searched point, `reference` as for `report`. Ctrl-C interrupts it."""
