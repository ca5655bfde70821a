"""Point sets in many dimensions: `estimate` of sum_j x_j^2 over a d-dim `UniformBox`, ns per point.

    python benchmarks/point_sets_high_dims.py [--dims 8 16 24 28 32 48 56 64] [--log2n 22] [--rounds 3]

Each source at its default settings (Random, Sobol', Lattice, Halton, Latin hypercube), one
compiled `jax.jit` program per (d, source), timed in interleaved rounds (each round calls every
program once, with a new key), median over rounds; ratios against Random of the same d. This is
the path the report's dimensionality study models (`jaxsample.report.point_set_dims`), and the
report's "within 2x of Random" target (`jaxsample.report.paths`) beyond the 8 dimensions it times.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample import uniforms as U

SOURCES = {"random": "random", "sobol": U.Sobol(), "lattice": U.Lattice(), "halton": U.Halton(),
           "lhs": U.LatinHypercube()}


def main(dims_list, log2n: int, rounds: int) -> None:
    n = 1 << log2n
    print(f"n = 2^{log2n}; ns per point (ratio to random), median of {rounds} interleaved rounds")
    print("| d | " + " | ".join(SOURCES) + " |")
    print("|---|" + "---|" * len(SOURCES))
    for d in dims_list:
        box = js.UniformBox(jnp.zeros(d), jnp.ones(d))
        programs = {name: jax.jit(lambda k, s=source: js.estimate(lambda x: jnp.sum(x * x), box, k, n, uniforms=s).mean)
                    for name, source in SOURCES.items()}
        for program in programs.values():
            program(jax.random.key(0)).block_until_ready()
        times = {name: [] for name in programs}
        for r in range(rounds):
            for name, program in programs.items():
                start = time.perf_counter()
                program(jax.random.key(r + 1)).block_until_ready()
                times[name].append(time.perf_counter() - start)
        base = np.median(times["random"])
        cells = [f"{np.median(t) / n * 1e9:.1f} ({np.median(t) / base:.2f}x)" for t in times.values()]
        print(f"| {d} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dims", type=int, nargs="+", default=[8, 16, 24, 28, 32, 48, 56, 64])
    parser.add_argument("--log2n", type=int, default=22)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    main(args.dims, args.log2n, args.rounds)
