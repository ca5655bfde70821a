"""Time per point of the replicated point sets against `Random`, through `jaxsample.estimate`.

    python benchmarks/point_sets.py [--n 1048576] [--repeats 5]

Path: `jaxsample.estimate` of w_x^2 + w_z over `UniformSphere` (2 uniform dimensions), n points
under `jit`, with each source. Prints the median ns/point over `repeats` runs after one compile
and the ratio to `Random` in the same run (shared 2-core machine: ratios are the figure to read).
The same sets against `Random` through the report's 2-, 3- and 8-d estimates are measured in
`benchmarks/results/point-sets-paths-cpu-2core-2026-12-05.md`.
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

import jaxsample as js
from jaxsample import uniforms as U


def time_source(source, n, repeats):
    sampler = js.UniformSphere()
    f = lambda w: w[0] * w[0] + w[2]
    run = jax.jit(lambda k: js.estimate(f, sampler, k, n, uniforms=source).mean)
    run(jax.random.key(0)).block_until_ready()
    times = []
    for r in range(repeats):
        start = time.perf_counter()
        run(jax.random.key(r + 1)).block_until_ready()
        times.append(time.perf_counter() - start)
    return float(np.median(times)) / n * 1e9


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=1 << 20)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    sources = [("random", U.Random()), ("sobol", U.Sobol()), ("sobol-lms", U.Sobol(scramble="lms")),
               ("sobol-padded", U.Sobol(padding=True)), ("sobol-lms-padded", U.Sobol(scramble="lms", padding=True)),
               ("lattice", U.Lattice()),
               ("halton", U.Halton()), ("halton-owen", U.Halton(scramble="owen")), ("lhs", U.LatinHypercube())]
    base = None
    print("| source | ns/point (2 dims, median) | ratio to random |\n|---|---|---|")
    for name, source in sources:
        ns = time_source(source, args.n, args.repeats)
        base = base or ns
        print(f"| {name} | {ns:.2f} | {ns / base:.2f} |")


if __name__ == "__main__":
    main()
