"""The Mitsuba check: a sphere under a constant emitter, shaded by an RGL
material through the `acdf` plug-in and through Mitsuba's own `measured`
plug-in, rendered K times each with independent seeds. Both estimate the
same image, so the difference of the two means is zero up to Monte Carlo
error, which the K renders measure.

How it is judged (`compare`): over the pixels where both renders vary (the
sphere), each render is reduced to its mean (the pooled value) and to the
means of a 4 x 4 grid of blocks. For the pooled value and for every block,
Welch's t = (mean_acdf - mean_measured) / sqrt(s²_acdf / K + s²_measured / K)
with s² the sample variance over the K renders. The check passes when
|t_pooled| < 4.5 and max |t_block| < 5.5 (with K = 12 to 16, about 3e-4 and,
Bonferroni over 16 blocks, 5e-4 two-sided significance). The variance of
each method is the per-pixel variance over the K renders times the sample
count per pixel (the variance of one sample), averaged over the sphere.

Run as a script for the figures of the documentation:

    python crates/acdf-python/tests/render_check.py [--variant llvm_ad_rgb]
        [--width 64] [--spp 16] [--renders 32] [--material PATH]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

POOLED_T = 4.5
BLOCK_T = 5.5
BLOCKS = 4


def scene(mi: Any, bsdf: dict, width: int, spp: int, integrator: dict | None = None) -> Any:
    """A unit sphere seen from above at 45°, under a constant emitter of
    radiance 1, so that its pixels cover outgoing angles from 0 to 90°."""
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": integrator or {"type": "path", "max_depth": 2},
            "sensor": {
                "type": "perspective",
                "fov": 40,
                "to_world": mi.ScalarTransform4f().look_at(
                    origin=[0, 3, 3], target=[0, 0, 0], up=[0, 1, 0]
                ),
                "film": {
                    "type": "hdrfilm",
                    "width": width,
                    "height": width,
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
                "sampler": {"type": "independent", "sample_count": spp},
            },
            "sphere": {"type": "sphere", "bsdf": bsdf},
            "light": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
        }
    )


def renders(mi: Any, sc: Any, count: int, first_seed: int) -> np.ndarray:
    """`count` renders of `sc` with seeds first_seed, first_seed + 1, ...:
    float64 (count, height, width, 3)."""
    return np.stack(
        [np.array(mi.render(sc, seed=first_seed + k), dtype=np.float64) for k in range(count)]
    )


def welch_t(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Welch's t over the first axis (the renders)."""
    k_a, k_b = a.shape[0], b.shape[0]
    se = np.sqrt(a.var(0, ddof=1) / k_a + b.var(0, ddof=1) / k_b)
    return (a.mean(0) - b.mean(0)) / np.where(se > 0, se, np.inf)


@dataclass
class Comparison:
    pixels: int
    mean_a: float
    mean_b: float
    pooled_t: float
    max_block_t: float
    variance_a: float
    variance_b: float

    @property
    def agree(self) -> bool:
        return abs(self.pooled_t) < POOLED_T and self.max_block_t < BLOCK_T

    def __str__(self) -> str:
        return (
            f"{self.pixels} sphere pixels: means {self.mean_a:.5f} / {self.mean_b:.5f}, "
            f"pooled t {self.pooled_t:+.2f} (limit {POOLED_T}), max block |t| "
            f"{self.max_block_t:.2f} (limit {BLOCK_T}); variance of one sample per pixel "
            f"{self.variance_a:.5f} / {self.variance_b:.5f}"
        )


def compare(a: np.ndarray, b: np.ndarray, spp: int) -> Comparison:
    """Compare two stacks of renders (K, H, W, 3) as described above."""
    va, vb = a.var(0, ddof=1), b.var(0, ddof=1)
    sphere = (va.sum(-1) > 0) & (vb.sum(-1) > 0)
    pooled = welch_t(a[:, sphere].mean(axis=(1, 2)), b[:, sphere].mean(axis=(1, 2)))
    h, w = sphere.shape
    block_t = []
    for i in range(BLOCKS):
        for j in range(BLOCKS):
            rows = slice(i * h // BLOCKS, (i + 1) * h // BLOCKS)
            cols = slice(j * w // BLOCKS, (j + 1) * w // BLOCKS)
            m = sphere[rows, cols]
            if m.sum() < 4:
                continue
            block_t.append(
                welch_t(a[:, rows, cols][:, m].mean(axis=(1, 2)), b[:, rows, cols][:, m].mean(axis=(1, 2)))
            )
    return Comparison(
        pixels=int(sphere.sum()),
        mean_a=float(a.mean(0)[sphere].mean()),
        mean_b=float(b.mean(0)[sphere].mean()),
        pooled_t=float(pooled),
        max_block_t=float(np.max(np.abs(block_t))),
        variance_a=float(va[sphere].mean() * spp),
        variance_b=float(vb[sphere].mean() * spp),
    )


def acdf_bsdf(material: Path, sampler: str = "adaptive:chi2") -> dict:
    return {"type": "acdf", "material": str(material), "sampler": sampler}


def measured_bsdf(material: Path) -> dict:
    return {"type": "measured", "filename": str(material)}


def main() -> None:
    import time

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--variant", default="llvm_ad_rgb")
    parser.add_argument("--width", type=int, default=64)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--renders", type=int, default=32)
    default_material = (
        Path(__file__).resolve().parents[3].parent
        / "shared/data/rgl-material-database/ilm_solo_m_68_rgb.bsdf"
    )
    parser.add_argument("--material", type=Path, default=default_material)
    args = parser.parse_args()

    import mitsuba as mi

    mi.set_variant(args.variant)
    import acdf.mitsuba

    acdf.mitsuba.register()
    k, spp = args.renders, args.spp
    print(f"{args.variant}, {args.material.name}, {args.width}x{args.width}, {spp} spp, {k} renders each")
    integrators = {
        "path (MIS)": {"type": "path", "max_depth": 2},
        "BSDF sampling only": {"type": "direct", "emitter_samples": 0, "bsdf_samples": 1},
    }
    methods = {
        "acdf adaptive:chi2": acdf_bsdf(args.material),
        "acdf rgl": acdf_bsdf(args.material, "rgl"),
        "acdf uniform": acdf_bsdf(args.material, "uniform"),
        "mitsuba measured": measured_bsdf(args.material),
    }
    for integrator_name, integrator in integrators.items():
        stacks = {}
        for n, (name, bsdf) in enumerate(methods.items()):
            start = time.perf_counter()
            stacks[name] = renders(mi, scene(mi, bsdf, args.width, spp, integrator), k, n * k)
            seconds = (time.perf_counter() - start) / k
            print(f"  {integrator_name:20s} {name:20s} {seconds:6.3f} s per render")
        ref = stacks["mitsuba measured"]
        for name in methods:
            if name != "mitsuba measured":
                c = compare(stacks[name], ref, spp)
                print(f"  {integrator_name}: {name} vs measured: {c}; agree: {c.agree}")


if __name__ == "__main__":
    main()
