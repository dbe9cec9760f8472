"""`acdf render` against Mitsuba 3 on the scene `acdf render --export-mitsuba`
writes: a sphere of an RGL material (Mitsuba's `measured`) and of
`builtin:lambert` (`diffuse`, albedo 0.8) under one shared environment map,
and the lambert sphere on the ground plane (its shadow, and the plane hiding
the lower sky), 64 x 64 pixels, direct light only.

The map is a real one (studio_small_03) box-filtered to 64 x 32 texels, so
that the exported copy (resampled 8x for Mitsuba's interpolated lookup,
see crates/acdf/src/mitsuba.rs) stays small. acdf renders with MIS (power
heuristic) of its adaptive BRDF sampler and the compensated adaptive
environment sampler; Mitsuba with its `path` integrator to depth 2 (its own
MIS of BSDF and emitter sampling).

Agreement (render_check.compare): K renders per renderer with independent
seeds; over the pixels that show only the sphere or the plane (found by a
Mitsuba render of the scene with black surfaces under a constant sky),
Welch's t of the image mean and of
the means of 4 x 4 blocks; pass when |t_pooled| < 4.5 and max |t_block| <
5.5 (about 3e-4 and, Bonferroni over 16 blocks, 5e-4 two-sided). The same
check must reject Mitsuba's render with the rotation that brings Mitsuba's
pole to `+z` without the reflection acdf's azimuth needs (x, y, z) -> (z, x,
y), instead of (-z, x, y): a map mirrored left to right, the easy mistake.

Skips with the reason when Mitsuba, the `acdf` command or the shared data
is absent. About 25 s on 2 cores.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from conftest import rgl_file, shared_data, skip_without_data
from render_check import compare

mi = pytest.importorskip("mitsuba", reason="skipping: Mitsuba 3 is not installed")

WIDTH = 64
SPP = 16
#: Renders per renderer and material.
RUNS = 12
MAP = "studio_small_03_1k.hdr"
RGL = "ilm_l3_37_matte_rgb.bsdf"
#: The box filter's side, in texels of the 1k map.
DOWNSAMPLE = 16


@pytest.fixture(scope="module")
def small_map(tmp_path_factory) -> Path:
    data = shared_data()
    src = data / "envmaps" / MAP if data else None
    if src is None or not src.is_file():
        skip_without_data(f"no environment map ../shared/data/envmaps/{MAP}")
    mi.set_variant("scalar_rgb")
    full = np.array(
        mi.Bitmap(str(src)).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False)
    )
    h, w, _ = full.shape
    f = DOWNSAMPLE
    small = full.reshape(h // f, f, w // f, f, 3).mean(axis=(1, 3)).astype(np.float32)
    path = tmp_path_factory.mktemp("map") / "small.exr"
    mi.Bitmap(small).write(str(path))
    return path


def acdf_renders(acdf_bin: Path, material: str, envmap: Path, out: Path,
                 extra: tuple[str, ...] = ()) -> np.ndarray:
    """RUNS renders by `acdf render` (mis-power), seeds 100, 101, ...:
    float64 (RUNS, H, W, 3)."""
    images = []
    for k in range(RUNS):
        d = out / f"run{k}"
        subprocess.run(
            [str(acdf_bin), "render", "--material", material, "--envmap", str(envmap), *extra,
             "--width", str(WIDTH), "--spp", str(SPP), "--ref-spp", "1",
             # Uniform points in the pixel, as Mitsuba's `independent` sampler.
             "--pixel-sampling", "independent",
             "--strategies", "mis-power", "--seed", str(100 + k), "--out", str(d)],
            check=True, capture_output=True, text=True,
        )
        (exr,) = d.glob("*-mis-power.exr")
        images.append(np.array(mi.Bitmap(str(exr)), dtype=np.float64))
    return np.stack(images)


def mitsuba_renders(scene_file: Path) -> np.ndarray:
    sc = mi.load_file(str(scene_file), spp=SPP)
    return np.stack([np.array(mi.render(sc, seed=100 + k), dtype=np.float64) for k in range(RUNS)])


def export(acdf_bin: Path, material: str, envmap: Path, out: Path,
           extra: tuple[str, ...] = ()) -> Path:
    subprocess.run(
        [str(acdf_bin), "render", "--material", material, "--envmap", str(envmap), *extra,
         "--width", str(WIDTH), "--spp", str(SPP), "--export-mitsuba", str(out)],
        check=True, capture_output=True, text=True,
    )
    return out / "scene.xml"


def sphere_mask(scene_file: Path) -> np.ndarray:
    """(H, W) booleans: the pixels whose every sample meets the sphere, from
    64 spp of the scene with the sphere black and a constant white sky.
    The background is left out of the comparison: there acdf looks the map
    up by nearest texel and Mitsuba interpolates, which differ pixel by
    pixel (by 0.3% on the mean) with almost no noise to hide it."""
    xml = scene_file.read_text()
    xml = re.sub(r"<bsdf .*?</bsdf>", '<bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>', xml)
    xml = re.sub(r'<emitter type="envmap">.*?</emitter>', '<emitter type="constant"/>', xml)
    path = scene_file.with_name("mask.xml")
    path.write_text(xml)
    img = np.array(mi.render(mi.load_file(str(path), spp=64), seed=1))
    return img.max(-1) == 0


def on_sphere(images: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The images with every pixel off the mask set to 0 (so that
    render_check.compare, which keeps the pixels where both vary, drops
    them)."""
    return np.where(mask[None, :, :, None], images, 0.0)


def cases() -> list[tuple[str, tuple[str, ...]]]:
    rgl = rgl_file(RGL)
    return [("builtin:lambert", ()), (str(rgl) if rgl else "missing-rgl", ()),
            ("builtin:lambert", ("--plane",))]


@pytest.mark.parametrize("material,extra", cases(), ids=["lambert", "rgl", "lambert-plane"])
def test_acdf_render_agrees_with_mitsuba(acdf_bin: Path, small_map: Path, tmp_path: Path,
                                         material: str, extra: tuple[str, ...]) -> None:
    if material == "missing-rgl":
        skip_without_data(f"no RGL material ../shared/data/rgl-material-database/{RGL}")
    mi.set_variant("scalar_rgb")
    scene = export(acdf_bin, material, small_map, tmp_path / "mitsuba", extra)
    mask = sphere_mask(scene)
    assert mask.sum() > 1000
    a = on_sphere(acdf_renders(acdf_bin, material, small_map, tmp_path, extra), mask)
    m = on_sphere(mitsuba_renders(scene), mask)
    c = compare(a, m, SPP)
    print(f"{Path(material).name} {' '.join(extra)}: acdf / Mitsuba, {RUNS} renders of {SPP} spp each: {c}")
    assert c.agree, str(c)

    if material == "builtin:lambert" and not extra:
        # The mutant: the azimuth mirrored.
        xml = scene.read_text()
        wrong = xml.replace('<matrix value="0 0 -1 0 ', '<matrix value="0 0 1 0 ')
        assert wrong != xml
        wrong_file = scene.with_name("wrong.xml")
        wrong_file.write_text(wrong)
        c = compare(a, on_sphere(mitsuba_renders(wrong_file), mask), SPP)
        print(f"mutant (azimuth mirrored): {c}")
        assert not c.agree, str(c)
