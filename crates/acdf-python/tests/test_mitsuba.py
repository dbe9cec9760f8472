"""The Mitsuba 3 plug-in: in `scalar_rgb` and `llvm_ad_rgb`, its eval, pdf,
sample and eval_pdf against the package's own calls and Mitsuba's `measured`
plug-in, and a rendered image against `measured` within the Monte Carlo
error (see render_check.py for how that is judged)."""

from __future__ import annotations

import numpy as np
import pytest

import acdf

from render_check import acdf_bsdf, compare, measured_bsdf, renders, scene

mi = pytest.importorskip("mitsuba", reason="skipping: Mitsuba 3 is not installed")
dr = pytest.importorskip("drjit")


def llvm_reason() -> str | None:
    """Why llvm_ad_rgb cannot run here, or None."""
    if "llvm_ad_rgb" not in mi.variants():
        return "this Mitsuba build has no llvm_ad_rgb variant"
    try:
        mi.set_variant("llvm_ad_rgb")
        dr.eval(mi.Float([1.0, 2.0]) * 2)
    except Exception as e:  # Dr.Jit reports a missing libLLVM as an error
        return f"the LLVM backend does not start ({e}); install libLLVM (e.g. apt-get install libllvm15) or set DRJIT_LIBLLVM_PATH"
    return None


VARIANTS = ["scalar_rgb", "llvm_ad_rgb"]

#: (width, samples per pixel, renders per method) of the image check: the
#: scalar variant calls Python once per ray, so it renders less.
RENDER = {"scalar_rgb": (16, 8, 12), "llvm_ad_rgb": (32, 16, 16)}


@pytest.fixture(params=VARIANTS)
def variant(request) -> str:
    name = request.param
    if name == "llvm_ad_rgb":
        reason = llvm_reason()
        if reason:
            pytest.skip(f"skipping: {reason}")
    mi.set_variant(name)
    acdf.mitsuba.register()
    return name


def outgoing(n: int) -> np.ndarray:
    rng = np.random.default_rng(5)
    t = np.radians(rng.uniform(2, 85, n))
    p = rng.uniform(0, 2 * np.pi, n)
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], 1).astype(np.float32)


def interaction(variant: str, wo: np.ndarray):
    si = dr.zeros(mi.SurfaceInteraction3f)
    if variant == "scalar_rgb":
        si.wi = mi.Vector3f(*map(float, wo))
    else:
        si.wi = mi.Vector3f(wo[:, 0], wo[:, 1], wo[:, 2])
    return si


def test_register_needs_a_variant_and_material(variant: str, rgl_path) -> None:
    with pytest.raises(Exception, match="material"):
        mi.load_dict({"type": "acdf"})
    bsdf = mi.load_dict(acdf_bsdf(rgl_path))
    assert "adaptive:chi2" in str(bsdf)


def test_plugin_calls_match_the_package_and_measured(variant: str, rgl_path) -> None:
    bsdf = mi.load_dict(acdf_bsdf(rgl_path))
    measured = mi.load_dict(measured_bsdf(rgl_path))
    material = acdf.Material.load(str(rgl_path))
    sampler = acdf.Sampler(material, "adaptive:chi2")
    ctx = mi.BSDFContext()
    n = 32 if variant == "scalar_rgb" else 2000
    wo = outgoing(n)
    u = acdf.uniform_2d(n, seed=4)
    wi, pdf, valid = sampler.sample(wo, u)
    f_cos = material.eval(wo, wi) * wi[:, 2:3]
    if variant == "scalar_rgb":
        rows = []
        for k in range(n):
            si = interaction(variant, wo[k])
            bs, weight = bsdf.sample(ctx, si, 0.5, mi.Point2f(*map(float, u[k])))
            w = mi.Vector3f(*map(float, wi[k]))
            rows.append(
                (np.array(bs.wo), bs.pdf, np.array(weight), np.array(bsdf.eval(ctx, si, w)),
                 bsdf.pdf(ctx, si, w), np.array(measured.eval(ctx, si, w)),
                 np.array(bsdf.eval_pdf(ctx, si, w)[0]), bsdf.eval_pdf(ctx, si, w)[1])
            )
        got = [np.array([r[i] for r in rows], dtype=np.float32) for i in range(8)]
    else:
        si = interaction(variant, wo)
        bs, weight = bsdf.sample(ctx, si, mi.Float(np.zeros(n, np.float32)), mi.Point2f(u[:, 0], u[:, 1]))
        w = mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2])
        ev, pd = bsdf.eval_pdf(ctx, si, w)
        got = [np.array(x, dtype=np.float32) for x in (
            bs.wo, bs.pdf, weight, bsdf.eval(ctx, si, w), bsdf.pdf(ctx, si, w),
            measured.eval(ctx, si, w), ev, pd)]
        got = [g.T if g.ndim == 2 else g for g in got]
    bs_wo, bs_pdf, weight, ev, pd, meas, ev2, pd2 = got
    # sample: the package's draws, weight f cos / pdf.
    np.testing.assert_array_equal(bs_wo, wi)
    np.testing.assert_array_equal(bs_pdf, pdf)
    expected_weight = np.where(valid[:, None], f_cos / np.where(valid, pdf, 1)[:, None], 0)
    np.testing.assert_allclose(weight, expected_weight, rtol=1e-5, atol=1e-7)
    # eval is f cos, pdf the sampler's, eval_pdf both.
    np.testing.assert_allclose(ev, f_cos, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(pd, sampler.pdf(wo, wi), rtol=1e-6)
    np.testing.assert_array_equal(ev2, ev)
    np.testing.assert_array_equal(pd2, pd)
    # And f cos is Mitsuba's own reading of the file (README: to 1.3e-4),
    # where acdf clips the interpolation's rare negative values to 0.
    np.testing.assert_allclose(ev, np.maximum(meas, 0), rtol=1e-3, atol=1e-6)


def test_render_agrees_with_measured(variant: str, rgl_path) -> None:
    width, spp, k = RENDER[variant]
    a = renders(mi, scene(mi, acdf_bsdf(rgl_path), width, spp), k, 0)
    b = renders(mi, scene(mi, measured_bsdf(rgl_path), width, spp), k, k)
    c = compare(a, b, spp)
    print(f"{variant}: acdf adaptive:chi2 / measured: {c}")
    assert c.pixels > width * width // 4
    assert c.agree, str(c)


class ScaledPdf:
    """A broken sampler: draws as the real one but reports pdf x 1.15 from
    `sample` (its `pdf` stays right), as a sampler whose two halves
    disagree would."""

    def __init__(self, inner: acdf.Sampler) -> None:
        self.inner, self.material, self.name = inner, inner.material, inner.name

    def sample(self, wo, u):
        wi, pdf, valid = self.inner.sample(wo, u)
        return wi, pdf * np.float32(1.15), valid

    def pdf(self, wo, wi):
        return self.inner.pdf(wo, wi)


def test_render_check_rejects_a_broken_sampler(rgl_path, monkeypatch) -> None:
    reason = llvm_reason()
    if reason:
        pytest.skip(f"skipping: {reason}")
    mi.set_variant("llvm_ad_rgb")
    acdf.mitsuba.register()
    real = acdf.mitsuba._sampler
    monkeypatch.setattr(acdf.mitsuba, "_sampler", lambda *a: ScaledPdf(real(*a)))
    width, spp, k = RENDER["llvm_ad_rgb"]
    a = renders(mi, scene(mi, acdf_bsdf(rgl_path), width, spp), k, 0)
    b = renders(mi, scene(mi, measured_bsdf(rgl_path), width, spp), k, k)
    c = compare(a, b, spp)
    print(f"mutant (pdf x 1.15 in sample): {c}")
    assert not c.agree
