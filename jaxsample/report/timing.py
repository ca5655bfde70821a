"""Shared timing for the benchmarks: median wall time of a jitted function of a key."""

from __future__ import annotations

import statistics
import time

import jax
import numpy as np


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


def interleaved_medians(fns: dict, keys, repeats: int = 7) -> dict:
    """Median seconds of each `fns[name](k)`, the functions called in turn `repeats` times (after
    one warm-up call each) so that a burst of load on a shared machine hits them alike; `keys` is
    an iterator of fresh keys, one per call. Each round calls them in a new (seeded) random
    order, so that no function always follows the same one: a JAX program called right after the
    NumPy baseline can run slower, and a fixed order would give that to one row."""
    for fn in fns.values():
        jax.block_until_ready(fn(next(keys)))
    times = {name: [] for name in fns}
    names = list(fns)
    order = np.random.default_rng(0)
    for _ in range(repeats):
        for index in order.permutation(len(names)):
            name = names[index]
            fn = fns[name]
            start = time.perf_counter()
            jax.block_until_ready(fn(next(keys)))
            times[name].append(time.perf_counter() - start)
    return {name: statistics.median(v) for name, v in times.items()}
