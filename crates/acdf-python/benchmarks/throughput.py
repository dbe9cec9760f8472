"""Sampling throughput from Python, as `acdf bench` measures it in Rust.

The same workload as `acdf bench`'s `adaptive:chi2` row: built-in nickel at
32x1x256x32, 10^6 uniform pairs from PCG64 seed 1 (`acdf.uniform_2d`, the
stream `acdf bench` draws), outgoing directions cycling through the same 64
(θ_o from 5° to 80°, φ_o spread by the golden ratio), every table built
before timing, the best of `--repeats` runs. What is timed is one Python
call over the whole batch, conversions included:

- `sample(wo, u)` with one outgoing direction per pair (`acdf bench`:
  `sample_each`), and with a single one (`sample_batch`);
- `pdf(wo, wi)` of the successful draws (`pdf_each`).

The calls run on every rayon thread; RAYON_NUM_THREADS=1 runs them on one,
as `acdf bench` does:

    RAYON_NUM_THREADS=1 python crates/acdf-python/benchmarks/throughput.py
    python crates/acdf-python/benchmarks/throughput.py
    target/release/acdf bench --samples 1000000 --repeats 3
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import acdf


def outgoing_directions(count: int) -> np.ndarray:
    t = (np.arange(count, dtype=np.float32) + 0.5) / count
    theta = np.radians(5.0 + 75.0 * t)
    phi = np.float32(2 * np.pi) * np.modf(np.arange(count, dtype=np.float32) * np.float32(0.618034))[0]
    return np.stack(
        [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1
    ).astype(np.float32)


def best(repeats: int, run) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description="Sampling throughput from Python")
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--sampler", default="adaptive:chi2")
    args = parser.parse_args()

    sampler = acdf.Sampler(acdf.Material.load("builtin:nickel"), args.sampler)
    n = args.samples
    u = acdf.uniform_2d(n, seed=1)
    wo = np.tile(outgoing_directions(64), (n // 64 + 1, 1))[:n]
    wi, pdf, valid = sampler.sample(wo, u)
    drawn_wo, drawn_wi = wo[valid], wi[valid]
    one = np.array([np.sin(0.6) * np.cos(1.3), np.sin(0.6) * np.sin(1.3), np.cos(0.6)], np.float32)

    each = best(args.repeats, lambda: sampler.sample(wo, u))
    batch = best(args.repeats, lambda: sampler.sample(one, u))
    dens = best(args.repeats, lambda: sampler.pdf(drawn_wo, drawn_wi))
    threads = os.environ.get("RAYON_NUM_THREADS", f"all ({os.cpu_count()} cores)")
    print(f"{sampler.name} on nickel, {sampler.resolution}, {n} pairs, rayon threads: {threads}")
    print(f"  sample, one wo per pair : {n / each / 1e6:7.2f} M samples/s ({each * 1e3:.1f} ms)")
    print(f"  sample, one wo          : {n / batch / 1e6:7.2f} M samples/s ({batch * 1e3:.1f} ms)")
    print(f"  pdf of the draws        : {len(drawn_wo) / dens / 1e6:7.2f} M pdfs/s ({dens * 1e3:.1f} ms)")


if __name__ == "__main__":
    main()
