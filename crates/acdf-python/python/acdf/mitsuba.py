"""acdf's samplers as a Mitsuba 3 BSDF.

::

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")      # or "scalar_rgb"
    import acdf.mitsuba
    acdf.mitsuba.register()
    bsdf = {"type": "acdf", "material": "path/to/material_rgb.bsdf",
            "sampler": "adaptive:chi2"}

The plug-in is a one-sided reflection BSDF: f_r comes from
:meth:`acdf.Material.eval` and directions are drawn by an
:class:`acdf.Sampler`, so any material spec and sampler name of the
``acdf`` command can shade a Mitsuba scene. Its properties:

``material`` (string, required)
    A material spec: ``builtin:NAME``, a MERL ``.binary`` or RGL ``.bsdf``
    path, ``nbrdf:NAME``.
``sampler`` (string, default ``"adaptive:chi2"``)
    A name of :data:`acdf.SAMPLER_NAMES`.
``sampler_file`` (string)
    A sampler file (``acdf build``, :meth:`acdf.Sampler.save`) to load
    instead of building ``sampler``.
``resolution`` (string), ``tolerance`` (float), ``cosine_mix`` (float),
``nbrdf_weights`` (string)
    As for :class:`acdf.Sampler` and :meth:`acdf.Material.load`.

Mitsuba's names are the other way round from acdf's: Mitsuba's ``si.wi``
(towards the viewer) is acdf's ``wo``, and the direction a Mitsuba BSDF
samples (towards the light) is acdf's ``wi``.

In the JIT variants (``llvm_ad_rgb``, ``cuda_ad_rgb``), a BSDF written in
Python receives whole arrays of shading points and must read them as NumPy
arrays, which Dr.Jit allows only when the calls, loops and conditionals
around it are evaluated rather than recorded symbolically. :func:`register`
therefore sets ``dr.JitFlag.SymbolicCalls``, ``dr.JitFlag.SymbolicLoops``
and ``dr.JitFlag.SymbolicConditionals`` to False (Mitsuba then runs its
integrators in wavefront mode). The scalar variants call the BSDF once per
ray, which is simpler but much slower.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from . import Material, Sampler
from .errors import Error

__all__ = ["register", "JIT_FLAGS"]

#: The Dr.Jit flags :func:`register` turns off in JIT variants.
JIT_FLAGS = ("SymbolicCalls", "SymbolicLoops", "SymbolicConditionals")


@functools.lru_cache(maxsize=16)
def _material(spec: str, nbrdf_weights: str | None) -> Material:
    return Material.load(spec, nbrdf_weights)


@functools.lru_cache(maxsize=16)
def _sampler(
    spec: str,
    nbrdf_weights: str | None,
    name: str,
    sampler_file: str | None,
    resolution: str | None,
    tolerance: float | None,
    cosine_mix: float,
) -> Sampler:
    material = _material(spec, nbrdf_weights)
    if sampler_file is not None:
        return Sampler.load(sampler_file, material)
    return Sampler(
        material, name, resolution=resolution, tolerance=tolerance, cosine_mix=cosine_mix
    )


def _rows(*vectors: Any) -> list[np.ndarray]:
    """Mitsuba vectors as acdf's rows: (K,) in scalar variants; in JIT ones
    (N, K), a transposed view (which acdf reads without a copy), with
    arrays of width 1 broadcast to the widest."""
    arrays = [np.asarray(v, dtype=np.float32) for v in vectors]
    if arrays[0].ndim == 1:
        return arrays
    n = max(a.shape[1] for a in arrays)
    return [np.broadcast_to(a.T, (n, a.shape[0])) for a in arrays]


def register(name: str = "acdf", jit_flags: bool = True) -> None:
    """Register the BSDF plug-in ``name`` with Mitsuba for the current
    variant (call ``mi.set_variant`` first, and again after changing it).

    In JIT variants, ``jit_flags`` turns off the Dr.Jit flags of
    :data:`JIT_FLAGS`, without which the plug-in cannot read its arguments.
    """
    import drjit as dr
    import mitsuba as mi

    if mi.variant() is None:
        raise Error("acdf.mitsuba.register(): set a Mitsuba variant first (mi.set_variant)")
    jit = dr.is_jit_v(mi.Float)
    if jit and jit_flags:
        for flag in JIT_FLAGS:
            dr.set_flag(getattr(dr.JitFlag, flag), False)

    flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide

    def triple(kind: Any, a: np.ndarray) -> Any:
        """Rows of three (a (3,) or (N, 3) array) as a Mitsuba `kind`."""
        if a.ndim == 1:
            return kind(float(a[0]), float(a[1]), float(a[2]))
        return kind(*(np.ascontiguousarray(a[:, c]) for c in range(3)))

    def vector3(a: np.ndarray) -> Any:
        return triple(mi.Vector3f, a)

    def color(a: np.ndarray) -> Any:
        return triple(mi.Color3f, a)

    float_type: Any = mi.Float

    def scalar(a: Any) -> Any:
        if np.ndim(a) == 0:
            return float_type(float(a))
        return float_type(np.ascontiguousarray(a))

    class AcdfBSDF(mi.BSDF):
        """f_r of an acdf material, sampled by an acdf sampler."""

        def __init__(self, props: Any) -> None:
            super().__init__(props)
            if not props.has_property("material"):
                raise Error("the acdf BSDF needs a `material` property (a material spec)")
            get = props.get
            spec = str(get("material"))
            weights = get("nbrdf_weights", None)
            resolution = get("resolution", None)
            tolerance = get("tolerance", None)
            self.sampler = _sampler(
                spec,
                None if weights is None else str(weights),
                str(get("sampler", "adaptive:chi2")),
                None if not props.has_property("sampler_file") else str(get("sampler_file")),
                None if resolution is None else str(resolution),
                None if tolerance is None else float(tolerance),
                float(get("cosine_mix", 0.0)),
            )
            self.material = self.sampler.material
            self.m_flags = flags
            self.m_components = [flags]

        # acdf's wo is Mitsuba's si.wi; acdf's wi is Mitsuba's wo.

        def _f_cos(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
            f = self.material.eval(wo, wi)
            cos = np.maximum(wi[..., 2], 0.0)
            return f * cos[..., None]

        def _enabled(self, ctx: Any) -> bool:
            return bool(ctx.is_enabled(mi.BSDFFlags.GlossyReflection, 0))

        def sample(self, ctx, si, sample1, sample2, active=True):  # noqa: ANN001
            bs = dr.zeros(mi.BSDFSample3f)
            if not self._enabled(ctx):
                return bs, mi.Color3f(0.0)
            wo, u = _rows(si.wi, sample2)
            wi, pdf, valid = self.sampler.sample(wo, u)
            weight = np.where(
                np.asarray(valid)[..., None],
                self._f_cos(wo, wi) / np.where(pdf > 0, pdf, 1.0)[..., None],
                0.0,
            ).astype(np.float32)
            bs.wo = vector3(wi)
            bs.pdf = scalar(pdf)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            return bs, dr.select(active, color(weight), 0.0)

        def eval(self, ctx, si, wo, active=True):  # noqa: ANN001
            if not self._enabled(ctx):
                return mi.Color3f(0.0)
            value = self._f_cos(*_rows(si.wi, wo)).astype(np.float32)
            return dr.select(active, color(value), 0.0)

        def pdf(self, ctx, si, wo, active=True):  # noqa: ANN001
            if not self._enabled(ctx):
                return mi.Float(0.0)
            return dr.select(active, scalar(self.sampler.pdf(*_rows(si.wi, wo))), 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):  # noqa: ANN001
            if not self._enabled(ctx):
                return mi.Color3f(0.0), mi.Float(0.0)
            a, b = _rows(si.wi, wo)
            value = color(self._f_cos(a, b).astype(np.float32))
            pdf = scalar(self.sampler.pdf(a, b))
            return dr.select(active, value, 0.0), dr.select(active, pdf, 0.0)

        def traverse(self, callback) -> None:  # noqa: ANN001
            pass

        def to_string(self) -> str:
            return f"AcdfBSDF[material={self.material.spec!r}, sampler={self.sampler.name!r}]"

    mi.register_bsdf(name, lambda props: AcdfBSDF(props))
