"""The report's reference case, ∫cos³ over H² with CosineHemisphere: the same estimate written in
vectorized NumPy (the baseline every speed ratio is taken against), the integrands, and the
uniform-generation floor (the engine summing its uniforms, no warp, no integrand)."""

import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

from ..estimators.engine import run_stream

AXIS = np.array([0.3, 0.2, 0.9327379], np.float32)


def median_time(fn, *args, repeats=5):
    jax.block_until_ready(fn(*args))
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def numpy_estimate(n, seed=0, chunk=1 << 20, all_components=False, with_stderr=False):
    """Straightforward vectorized NumPy float32: concentric map, Malley lift, f/p, summed in chunks
    of `chunk` samples (the last one shorter when n is not a multiple), and, with_stderr, the sum of
    squares for the standard error."""
    rng = np.random.default_rng(seed)
    total = squares = 0.0
    for start in range(0, n, chunk):
        size = min(chunk, n - start)
        u = rng.random((size, 2), dtype=np.float32)
        a, b = 2 * u[:, 0] - 1, 2 * u[:, 1] - 1
        a_wins = np.abs(a) > np.abs(b)
        r = np.where(a_wins, a, b)
        z = np.sqrt(np.maximum((1 - r) * (1 + r), 0))
        if all_components:
            with np.errstate(divide="ignore", invalid="ignore"):
                phi = np.where(a_wins, np.float32(np.pi / 4) * (b / a),
                               np.float32(np.pi / 2) - np.float32(np.pi / 4) * (a / b))
            phi = np.nan_to_num(phi)
            x, y = r * np.cos(phi), r * np.sin(phi)
            f = np.maximum(x * AXIS[0] + y * AXIS[1] + z * AXIS[2], 0) ** 3
        else:
            f = z ** 3
        p = z / np.float32(np.pi)
        y = np.where(p > 0, f / np.where(p > 0, p, 1), 0)
        total += float(np.sum(y, dtype=np.float32))
        if with_stderr:
            squares += float(np.dot(y, y))
    mean = total / n
    if with_stderr:
        return mean, np.sqrt(max(squares / n - mean * mean, 0.0) / (n - 1))
    return mean


def cos3(w):
    return w[2] ** 3


def tilted(w):
    # Written out: jnp.dot of one sample under vmap becomes an unfused XLA dot on CPU, ~10x slower
    # (the "x @ a" rows of `benchmarks/paths.py`); the products fuse with the warp.
    return jnp.maximum(w[0] * AXIS[0] + w[1] * AXIS[1] + w[2] * AXIS[2], 0.0) ** 3


def uniform_floor(n, full: bool):
    """Generating and summing the same uniforms with the same source, through the same engine
    (chunking, materialization, accumulation): the warp and integrand replaced by u0 + u1."""
    def run(key):
        est = run_stream(lambda u: u[:, 0] + u[:, 1], 2, key, n)
        return everything(est) if full else est.mean

    return jax.jit(run)


def everything(est):
    """What a user of the whole Estimate pays for: mean, standard error and both diagnostics."""
    return est.mean, est.stderr, est.ess, est.max_abs
