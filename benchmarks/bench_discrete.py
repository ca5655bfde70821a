"""Throughput of `Discrete` sampling: CDF binary search against the alias table.

Run alone: `python benchmarks/bench_discrete.py`. For tables of 10^3 and 10^6 entries (random
weights, 30 % zeros) it times the jitted warp of a fixed batch of float32 uniforms (uniform
generation excluded, so the figure is the selection itself), reports the median of several
repeats after a warm-up call, with `block_until_ready`, in samples per second.
"""

from __future__ import annotations

import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxsample.samplers.discrete import Discrete

BATCH = 1 << 22
REPEATS = 7


def throughput(sampler, u) -> float:
    warp = jax.jit(lambda s, u: s.warp(u))
    warp(sampler, u).block_until_ready()  # compile and warm up
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        warp(sampler, u).block_until_ready()
        times.append(time.perf_counter() - start)
    return u.shape[0] / statistics.median(times)


def main() -> None:
    rng = np.random.default_rng(0)
    u = jax.random.uniform(jax.random.key(0), (BATCH, 1), dtype=jnp.float32)
    print(f"Discrete throughput, {BATCH} samples per call, median of {REPEATS} ({jax.devices()[0].platform})")
    print(f"| {'entries':>9} | {'cdf (M samples/s)':>18} | {'alias (M samples/s)':>20} | {'alias / cdf':>11} |")
    print(f"|{'-' * 11}|{'-' * 20}|{'-' * 22}|{'-' * 13}|")
    for size in (10**3, 10**6):
        weights = rng.random(size)
        weights[rng.random(size) < 0.3] = 0.0
        build = time.perf_counter()
        alias = Discrete(weights, "alias")
        build = time.perf_counter() - build
        cdf_rate = throughput(Discrete(weights, "cdf"), u)
        alias_rate = throughput(alias, u)
        print(f"| {size:>9} | {cdf_rate / 1e6:>18.1f} | {alias_rate / 1e6:>20.1f} | {alias_rate / cdf_rate:>11.2f} |"
              f"  (alias table built in {build * 1e3:.0f} ms)")


if __name__ == "__main__":
    main()
