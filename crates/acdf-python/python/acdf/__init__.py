"""acdf: importance sampling measured BRDFs with adaptive numerical CDFs.

The materials and samplers of the ``acdf`` command, vectorised over NumPy
arrays::

    import acdf
    m = acdf.Material.load("builtin:nickel")
    s = acdf.Sampler(m, "adaptive:chi2")
    wo = acdf.direction(30, 45)                 # theta, phi in degrees
    wi, pdf, valid = s.sample(wo, acdf.uniform_2d(100_000, seed=1))
    f = m.eval(wo, wi)                          # (N, 3) f_r in 1/sr

Directions are in the local shading frame (z along the normal, both
pointing away from the surface); ``wo`` is given and ``wi`` sampled; pdfs
are per unit solid angle. ``acdf.EnvMap`` and ``acdf.EnvSampler`` do the
same for environment maps (directions over the sphere, in the map's frame).
Large batches run on every core with the interpreter released, and Ctrl-C
interrupts every long call. ``acdf.mitsuba.register()`` adds the BSDF
plug-in ``acdf`` to Mitsuba 3. Failures raise subclasses of
:class:`acdf.Error`.
"""

from __future__ import annotations

from ._acdf import (
    BUILTIN_MATERIALS,
    ENV_SAMPLER_NAMES,
    PARALLEL_MIN,
    SAMPLER_NAMES,
    SIMPLIFIER_NAMES,
    EnvMap,
    EnvSampler,
    Material,
    Sampler,
    __version__,
    direction,
    report,
    sphere_direction,
    sweep,
    uniform_2d,
)
from . import errors
from .errors import *  # noqa: F403 (the exception classes)

__all__ = [
    "BUILTIN_MATERIALS",
    "ENV_SAMPLER_NAMES",
    "PARALLEL_MIN",
    "SAMPLER_NAMES",
    "SIMPLIFIER_NAMES",
    "EnvMap",
    "EnvSampler",
    "Material",
    "Sampler",
    "direction",
    "report",
    "sphere_direction",
    "sweep",
    "uniform_2d",
    "__version__",
    *errors.__all__,
]


def __getattr__(name: str) -> object:
    # `acdf.mitsuba` is imported on first use, so that `import acdf` does
    # not need Mitsuba.
    if name == "mitsuba":
        import importlib

        return importlib.import_module(".mitsuba", __name__)
    raise AttributeError(f"module 'acdf' has no attribute {name!r}")
