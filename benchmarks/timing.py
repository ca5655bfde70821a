"""Shared timing for the benchmarks: median wall time of a jitted function of a key."""

from __future__ import annotations

import statistics
import time

import jax


def median_seconds(run, key, repeats: int = 3) -> float:
    """Median seconds of `run(k)` over `repeats` fresh keys split from `key`, after one warm-up call
    (which compiles); each call is waited for with `block_until_ready`."""
    keys = jax.random.split(key, repeats + 1)
    jax.block_until_ready(run(keys[0]))
    times = []
    for k in keys[1:]:
        start = time.perf_counter()
        jax.block_until_ready(run(k))
        times.append(time.perf_counter() - start)
    return statistics.median(times)
