"""acdf against Mitsuba 3 at equal CPU time of one thread, on the scene of
`acdf render`: a sphere of an RGL material under an environment map,
direct light only.

1. `acdf render ... --threads 1 --json FILE` renders the scene with every
   strategy and writes its tables; its equal-CPU-time table gives each
   strategy's RMSE after B CPU seconds of one thread (B: `--seconds`, the
   budget of that table), against a reference of `--ref-spp` samples per
   pixel of mis-power (the EXR the JSON names). With `--acdf-json FILE`
   an existing run is read instead.
2. `acdf render --export-mitsuba DIR` writes the same scene for Mitsuba 3:
   its `measured` BSDF, its `envmap` emitter, its `path` integrator with
   max_depth 2 (direct light, its own MIS of BSDF and emitter sampling).
3. Mitsuba renders it with the `scalar_rgb` variant (no JIT compilation to
   exclude), one thread (`dr.set_thread_count(1)`), timed by the process's
   CPU clock (`time.process_time`, so all of Mitsuba's threads count),
   scene loading excluded as acdf's table building is: a pilot render
   gives the CPU seconds per sample per pixel, up to three renders size
   the samples per pixel that fit in B (within 10%), then `--runs`
   renders with seeds `--seed`, `--seed` + 1, ...; each RMSE is scaled to
   exactly B (RMSE x sqrt(t / B)), and their root mean square is printed
   beside acdf's, against the same reference. RMSE is over all pixels and the three channels, in linear
   radiance; Mitsuba's is also given with the background pixels left out
   of the sum (acdf looks the map up by nearest texel, Mitsuba
   interpolates a resampled copy, a difference that is not noise; the
   ratio uses this, lower, figure).

    /work/main/target/python/venv/bin/python \\
        crates/acdf-python/benchmarks/mitsuba_equal_time.py \\
        --acdf target/release/acdf \\
        --material ../shared/data/rgl-material-database/ilm_solo_m_68_rgb.bsdf \\
        --envmap ../shared/data/envmaps/rooitou_park_1k.hdr \\
        --width 64 --height 48 --seconds 1.5 --out out/mitsuba-rooitou
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time
from pathlib import Path

import numpy as np


def rmse(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """sqrt of the mean over pixels and channels of (a - b)^2; pixels off
    `mask` count as 0 error (the mean is still over all pixels)."""
    d = (a.astype(np.float64) - b.astype(np.float64)) ** 2
    if mask is not None:
        d = np.where(mask[:, :, None], d, 0.0)
    return float(np.sqrt(d.mean()))


def run_acdf(args: argparse.Namespace, out: Path) -> dict:
    json_path = out / "acdf.json"
    cmd = [args.acdf, "render", "--material", args.material, "--envmap", args.envmap,
           "--width", str(args.width), "--height", str(args.height),
           "--spp", str(args.spp), "--ref-spp", str(args.ref_spp),
           "--seconds", str(args.seconds), "--threads", "1",
           # Uniform points in the pixel, as the exported `independent` sampler.
           "--pixel-sampling", "independent",
           "--out", str(out / "acdf"), "--json", str(json_path), *args.acdf_args]
    print("$", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)
    return json.loads(json_path.read_text())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--acdf", default="target/release/acdf", help="the acdf command")
    p.add_argument("--material", help="an RGL .bsdf file (unless --acdf-json)")
    p.add_argument("--envmap", help="the map (unless --acdf-json)")
    p.add_argument("--width", type=int, default=64)
    p.add_argument("--height", type=int, default=48)
    p.add_argument("--spp", type=int, default=64, help="acdf's equal-sample spp")
    p.add_argument("--ref-spp", type=int, default=4096)
    p.add_argument("--seconds", type=float, default=1.5,
                   help="B: CPU seconds of one thread per strategy")
    p.add_argument("--out", default="out/mitsuba-equal-time")
    p.add_argument("--acdf-json", help="read this `acdf render --json` output instead of running acdf")
    p.add_argument("--seed", type=int, default=1, help="Mitsuba's first seed")
    p.add_argument("--runs", type=int, default=4,
                   help="Mitsuba renders at the budget, seeds --seed, --seed + 1, ...")
    p.add_argument("acdf_args", nargs="*", help="more arguments for acdf render (after --)")
    args = p.parse_args()
    if not args.acdf_json and not (args.material and args.envmap):
        p.error("give --material and --envmap, or --acdf-json")

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(1)
    # The measured BSDF's RGB can be slightly negative: Mitsuba warns per
    # sample.
    mi.set_log_level(mi.LogLevel.Error)

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    report = json.loads(Path(args.acdf_json).read_text()) if args.acdf_json else run_acdf(args, out)
    (cpu,) = [t for t in report["tables"] if t["kind"] == "equal_cpu_time"]
    budget = float(cpu["seconds"])
    reference = np.array(mi.Bitmap(report["reference"]), dtype=np.float64)[:, :, :3]
    h, w = reference.shape[:2]

    scene_dir = out / "mitsuba"
    subprocess.run([args.acdf, "render", "--material", report["material"], "--envmap",
                    report["envmap"], "--width", str(w), "--height", str(h),
                    *(["--plane"] if report["plane"] else []),
                    "--export-mitsuba", str(scene_dir)], check=True, capture_output=True)
    scene_file = scene_dir / "scene.xml"

    # The pixels that show a surface: black surfaces under a white sky.
    xml = scene_file.read_text()
    import re
    mask_xml = re.sub(r"<bsdf .*?</bsdf>",
                      '<bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>', xml,
                      flags=re.S)
    mask_xml = re.sub(r'<emitter type="envmap">.*?</emitter>', '<emitter type="constant"/>',
                      mask_xml, flags=re.S)
    mask_file = scene_dir / "mask.xml"
    mask_file.write_text(mask_xml)
    surface = np.array(mi.render(mi.load_file(str(mask_file), spp=16), seed=1))[:, :, :3].max(-1) < 1.0

    def timed(spp: int, seed: int) -> tuple[np.ndarray, float]:
        scene = mi.load_file(str(scene_file), spp=spp)
        start = time.process_time()
        img = np.array(mi.render(scene, seed=seed), dtype=np.float64)[:, :, :3]
        return img, time.process_time() - start

    # A pilot, then up to three renders, each sized by the last one's
    # CPU seconds per sample, until one lands within 10% of the budget.
    _, pilot_t = timed(4, args.seed + 1000)
    spp = max(1, int(budget / max(pilot_t / 4, 1e-9)))
    for attempt in range(3):
        _, t = timed(spp, args.seed + 2000 + attempt)
        if abs(t - budget) < 0.1 * budget:
            break
        spp = max(1, int(spp * budget / max(t, 1e-9)))
    # The runs: each RMSE scaled to exactly the budget; their root mean
    # square (one render's RMSE is dominated by its few brightest outliers
    # and varies from seed to seed).
    runs = []
    for k in range(args.runs):
        img, t = timed(spp, args.seed + k)
        scale = np.sqrt(t / budget)
        runs.append((t, rmse(img, reference) * scale, rmse(img, reference, surface) * scale))
        print(f"mitsuba run {k}: seed {args.seed + k}, {spp} spp, {t:.3f} CPU s, "
              f"RMSE {runs[-1][1]:.6f} (surface pixels {runs[-1][2]:.6f})")
    t = float(np.mean([r[0] for r in runs]))
    m_all = float(np.sqrt(np.mean([r[1] ** 2 for r in runs])))
    m_surface = float(np.sqrt(np.mean([r[2] ** 2 for r in runs])))

    print(f"{Path(report['material']).name} under {Path(report['envmap']).name}, {w}x{h} px, "
          f"budget {budget} CPU s of one thread")
    print("renderer,strategy,spp,cpu_seconds,rmse_at_budget,rmse_vs_mitsuba")
    best = min(r["rmse"] for r in cpu["rows"])
    for r in cpu["rows"]:
        print(f"acdf,{r['strategy']},{r['spp']:.1f},{budget:.3f},{r['rmse']:.6f},"
              f"{r['rmse'] / m_surface:.3f}")
    print(f"mitsuba scalar_rgb,path max_depth 2 (all pixels; rms of {args.runs} runs),"
          f"{spp},{t:.3f},{m_all:.6f},")
    print(f"mitsuba scalar_rgb,path max_depth 2 (surface pixels; rms of {args.runs} runs),"
          f"{spp},{t:.3f},{m_surface:.6f},")
    print(f"acdf best / mitsuba (surface pixels): {best / m_surface:.3f}")


if __name__ == "__main__":
    main()
