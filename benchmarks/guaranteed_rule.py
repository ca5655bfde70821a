"""The guaranteed stopping rule (`estimate_guaranteed`) measured: does the bound cover, at what cost.

    python benchmarks/guaranteed_rule.py [--keys 16]

For each integrand with a known integral, each point set (the default `Lattice(replicates=2)` and
`Sobol(replicates=2, scramble="lms")`) and each absolute tolerance, over `--keys` keys: the
fraction of keys whose error |mean - I| is within `error_bound` (over all keys, and over those
with `in_cone` True), the largest error / bound, the fraction flagged out of the cone, the
fraction converged, the median points and the median wall time per call (after one warm-up call:
compile excluded). Beside it, the statistical rule it replaces: `estimate_until` with the lattice's
16 replicates, atol = tol / 1.96 (so its 95 % t interval is about +- tol), chunk 2^12: the
fraction of keys its 95 % interval covers and its median points.
"""

from __future__ import annotations

import argparse
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js


def cases():
    box = lambda d: js.UniformBox(jnp.zeros(d), jnp.ones(d))
    j8 = jnp.arange(1, 9, dtype=jnp.float32)
    return [
        ("3-d exp: prod e^x_j", box(3), lambda x: jnp.prod(jnp.exp(x)), (np.e - 1) ** 3),
        ("8-d decaying product", box(8), lambda x: jnp.prod(1 + (jnp.exp(x) - (np.e - 1)) / j8 ** 2), 1.0),
        ("sphere: e^z", js.UniformSphere(), lambda x: jnp.exp(x[2]), 2 * np.pi * (np.e - 1 / np.e)),
        ("hemisphere: cos^3 (uniform)", js.UniformHemisphere(), lambda w: w[2] ** 3, np.pi / 2),
        ("2-d spike, width 0.01", box(2), lambda x: jnp.exp(-jnp.sum((x - 0.3) ** 2) / (2 * 0.01 ** 2)),
         2 * np.pi * 0.01 ** 2),
        ("1-d step at 0.3", box(1), lambda x: (x[0] < 0.3).astype(jnp.float32), 0.3),
    ]


def main(keys: int):
    print(f"estimate_guaranteed, {keys} keys per row; float32; max_n = 2^21 per source (R = 2)")
    print("| integrand | points | atol | covered (all / in cone) | max err/bound | in cone | converged | "
          "median n | median s | estimate_until: covered, median n |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, sampler, f, exact in cases():
        for uniforms in ("lattice", "sobol"):
            for tol in (1e-3, 1e-5):
                rows = []
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    js.estimate_guaranteed(f, sampler, jax.random.key(10_000), max_n=1 << 21, atol=tol,
                                           uniforms=uniforms)
                    for k in range(keys):
                        start = time.perf_counter()
                        est = js.estimate_guaranteed(f, sampler, jax.random.key(k), max_n=1 << 21, atol=tol,
                                                     uniforms=uniforms)
                        seconds = time.perf_counter() - start
                        err = abs(float(est.mean) - exact)
                        rows.append((err, float(est.error_bound), bool(est.in_cone), bool(est.converged),
                                     int(est.n_used), seconds))
                err, bound, cone, conv, used, secs = (np.array(c) for c in zip(*rows))
                covered = err <= bound
                in_cone = f"{covered[cone].mean():.2f}" if cone.any() else "-"
                until = ""
                if uniforms == "lattice":
                    hits, ns = [], []
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        for k in range(keys):
                            r = js.estimate_until(f, sampler, jax.random.key(k), atol=tol / 1.96, max_n=1 << 22,
                                                  uniforms="lattice", chunk_size=1 << 12)
                            low, high = r.interval()
                            hits.append(float(low) <= exact <= float(high))
                            ns.append(int(r.n_used))
                    until = f"{np.mean(hits):.2f}, {int(np.median(ns))}"
                print(f"| {name} | {uniforms} | {tol:.0e} | {covered.mean():.2f} / {in_cone} | "
                      f"{np.max(err / bound):.3g} | {cone.mean():.2f} | {conv.mean():.2f} | {int(np.median(used))} | "
                      f"{np.median(secs):.3f} | {until} |", flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keys", type=int, default=16)
    main(parser.parse_args().keys)
