"""Baselines in one run: jaxsample against vectorized NumPy and against the uniform-generation floor.

Run alone: `python -m jaxsample.report.baselines [--quick]`. Case: ∫ cos³ over the hemisphere with
`CosineHemisphere`, default ("random", Philox4x32-10) uniforms. Ratios are of medians of repeats
after a warm-up, taken in this one run (absolute speeds on a shared machine vary 2–3×).
"""

from __future__ import annotations

import argparse

import jax

import jaxsample as js

from .numpy_baseline import cos3, median_time, numpy_estimate, uniform_floor


def baseline_table(quick: bool = True, progress=print) -> dict:
    n = 1 << (22 if quick else 24)
    progress(f"[baselines] n = 2^{n.bit_length() - 1}")
    keys = iter(jax.random.split(jax.random.key(0), 8))
    t_jax = median_time(jax.jit(lambda k: js.estimate(cos3, js.CosineHemisphere(), k, n).mean), next(keys))
    # The floor: the same engine, source, chunking and accumulation, with the warp and integrand
    # replaced by the plain sum of the two uniforms of each sample.
    t_floor = median_time(uniform_floor(n, full=False), next(keys))
    t_numpy = median_time(numpy_estimate, n, repeats=3)
    return {"n": n, "jaxsample_s": t_jax, "uniform_floor_s": t_floor, "numpy_s": t_numpy,
            "jaxsample_M_per_s": n / t_jax / 1e6, "numpy_M_per_s": n / t_numpy / 1e6,
            "speedup_vs_numpy": t_numpy / t_jax, "time_vs_uniform_floor": t_jax / t_floor}


def markdown_table(b: dict) -> str:
    return ("| n | jaxsample (M samples/s) | NumPy float32 (M samples/s) | speed-up vs NumPy | "
            "time vs generating+summing the uniforms (same engine) |\n|---|---|---|---|---|\n"
            f"| 2^{b['n'].bit_length() - 1} | {b['jaxsample_M_per_s']:.0f} | {b['numpy_M_per_s']:.0f} | "
            f"{b['speedup_vs_numpy']:.2f}× | {b['time_vs_uniform_floor']:.2f}× |\n")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    print(markdown_table(baseline_table(parser.parse_args().quick)))
