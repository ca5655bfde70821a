"""Time per point of the replicated point sets against `Random`, through `jaxsample.estimate`.

    python benchmarks/point_sets.py [--n 1048576] [--repeats 5]

Path: `jaxsample.estimate` of w_x^2 + w_z over `UniformSphere` (2 uniform dimensions), n points
under `jit`, with each source. Prints the median ns/point over `repeats` runs after one compile
and the ratio to `Random` in the same run (shared 2-core machine: ratios are the figure to read).
Measured 2026-12-03, n = 2^20: random 3.3, sobol 8.9, lattice 7.4, halton 85, halton-owen 140,
lhs 14.6 ns/point (ratios 1, 2.7, 2.2, 25, 42, 4.4).
Measured 2026-12-03 after the lattice table path (b90aad4) and Sobol' LMS / padding (67f6bc3), with
a CI run sharing both cores (so every ratio is noisy): random 3.4, sobol 10.9, sobol-lms 17.7,
sobol-padded 10.5, sobol-lms-padded 29.3, lattice 10.0, halton 128, halton-owen 172, lhs 16.1
ns/point (ratios 1, 3.2, 5.2, 3.1, 8.6, 2.9, 38, 50, 4.7). On a quieter machine the same day
(an ad hoc script, random first and last): random 2.8-3.2, lattice 6.3 before the table path
and 5.5 after (1.8x).
Measured 2026-12-03 after Halton's uint32 digits (a second session sharing the machine): random 4.4,
sobol 11.7, sobol-lms 17.2, sobol-padded 8.5, sobol-lms-padded 15.4, lattice 8.6, halton 11.2,
halton-owen 36.1, lhs 18.5 ns/point (ratios 1, 2.6, 3.9, 1.9, 3.5, 2.0, 2.5, 8.2, 4.2); halton was
38x and halton-owen 50x before.
Measured 2026-12-03 after Halton's one-hash Owen digits and uint32 t mod b, and LHS's hashed jitter
with two bijection rounds (94466d8, e335088, 9057091; loaded shared machine): random 3.8, sobol
10.9, sobol-lms 13.7, sobol-padded 8.8, sobol-lms-padded 14.6, lattice 8.0, halton 12.0,
halton-owen 26.1, lhs 19.2 ns/point (ratios 1, 2.9, 3.6, 2.3, 3.9, 2.1, 3.2, 6.9, 5.1; lhs here
was noisy: through `estimate` of sum x^2 over `UniformBox` the same hour it was 2.7x at 3 dims and
1.9x at 8 dims, from 2.6x and 3.3x).
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
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
