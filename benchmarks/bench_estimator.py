"""Speed, memory and efficiency of jaxsample.estimate; run alone: python benchmarks/bench_estimator.py

Every figure is a ratio taken in this one run: medians of repeats after a warm-up, with
block_until_ready. Case: ∫cos³ over the hemisphere with CosineHemisphere, n = 2^24, plus an
integrand that uses every component (max(ω·a, 0)³, tilted a) so nothing is dropped as dead code.
"""

import json
import resource
import statistics
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample import uniforms as U
from jaxsample.estimate import estimate

N = 1 << 24
AXIS = np.array([0.3, 0.2, 0.9327379], np.float32)


def median_time(fn, *args, repeats=5):
    jax.block_until_ready(fn(*args))
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def numpy_estimate(n, seed=0, chunk=1 << 20, all_components=False):
    """Straightforward vectorized NumPy float32: concentric map, Malley lift, f/p, chunked sum."""
    rng = np.random.default_rng(seed)
    total = 0.0
    for _ in range(n // chunk):
        u = rng.random((chunk, 2), dtype=np.float32)
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
        total += float(np.sum(np.where(p > 0, f / np.where(p > 0, p, 1), 0), dtype=np.float32))
    return total / n


def cos3(w):
    return w[2] ** 3


def tilted(w):
    # Written out: jnp.dot of one sample under vmap becomes an unfused XLA dot on CPU, measured
    # ~10x slower here; the products fuse with the warp.
    return jnp.maximum(w[0] * AXIS[0] + w[1] * AXIS[1] + w[2] * AXIS[2], 0.0) ** 3


def generate_and_sum(n, chunk=1 << 16):
    def run(key):
        seed = U.seed_from_key(key)

        def body(total, step):
            groups = U.Random().groups(seed, step * chunk, chunk, 2, aligned=True)
            return total + sum(jnp.sum(g) for g in groups), None

        return jax.lax.scan(body, jnp.float32(0), jnp.arange(n // chunk, dtype=jnp.uint32))[0]

    return jax.jit(run)


MEMORY_CHILD = """
import resource, sys, jax, jaxsample as js
from jaxsample.estimate import estimate
n = int(sys.argv[1])
f = jax.jit(lambda k: estimate(lambda w: w[2] ** 3, js.CosineHemisphere(), k, n).mean)
print(float(f(jax.random.key(0))), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def peak_rss_mib(n):
    out = subprocess.run([sys.executable, "-c", MEMORY_CHILD, str(n)], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1]) / 1024.0


def main():
    keys = iter(jax.random.split(jax.random.key(0), 64))
    results = {"n": N, "devices": jax.device_count()}
    cosine = js.CosineHemisphere()
    inversion = js.CosineHemisphere(method="inversion")
    jax_cos3 = jax.jit(lambda k: estimate(cos3, cosine, k, N).mean)
    t_jax = median_time(jax_cos3, next(keys))
    t_gen = median_time(generate_and_sum(N), next(keys))
    t_np = median_time(numpy_estimate, N, repeats=3)
    results["cos3"] = {"jax_s": t_jax, "numpy_s": t_np, "uniforms_only_s": t_gen,
                       "speedup_vs_numpy": t_np / t_jax, "time_vs_uniforms_only": t_jax / t_gen,
                       "jax_Msamples_per_s": N / t_jax / 1e6, "numpy_Msamples_per_s": N / t_np / 1e6}
    t_tilt_malley = median_time(jax.jit(lambda k: estimate(tilted, cosine, k, N).mean), next(keys))
    t_tilt_inv = median_time(jax.jit(lambda k: estimate(tilted, inversion, k, N).mean), next(keys))
    t_np_tilt = median_time(lambda: numpy_estimate(N, all_components=True), repeats=3)
    results["all_components"] = {
        "jax_malley_s": t_tilt_malley, "jax_inversion_sincos_poly_s": t_tilt_inv, "numpy_s": t_np_tilt,
        "speedup_malley_vs_numpy": t_np_tilt / t_tilt_malley,
        "speedup_inversion_vs_numpy": t_np_tilt / t_tilt_inv,
        "inversion_time_vs_uniforms_only": t_tilt_inv / t_gen}

    # Sobol': RMSE of one n-point scrambled estimate from 64 independent scrambles.
    rmse = {}
    for log_n in range(10, 21, 2):
        n = 1 << log_n
        est = jax.jit(lambda k, n=n: estimate(cos3, cosine, k, 64 * n, uniforms=U.Sobol(64)))(next(keys))
        rmse[log_n] = float(est.stderr) * 8.0  # stderr of the 64-mean, times sqrt(64)
    logs = np.array(sorted(rmse))
    slope = np.polyfit(logs * np.log(2), np.log([rmse[k] for k in logs]), 1)[0]
    n_eff = 1 << 20
    t_sobol = median_time(jax.jit(lambda k: estimate(cos3, cosine, k, n_eff, uniforms="sobol").mean), next(keys))
    t_random = median_time(jax.jit(lambda k: estimate(cos3, cosine, k, n_eff).mean), next(keys))
    var_random = np.pi ** 2 / 12 / n_eff             # exact (reference.md)
    var_sobol = rmse[16] ** 2 / 16                   # 16 replicates of 2^16 points
    results["sobol"] = {"rmse": rmse, "rmse_slope": slope, "t_sobol_s": t_sobol, "t_random_s": t_random,
                        "efficiency_ratio_vs_random": (var_random * t_random) / (var_sobol * t_sobol)}

    # The same slope in float64: a float32 mean of ~π/2 cannot resolve errors below ~1e-7, which
    # flattens the float32 curve from n = 2^16 on; float64 shows the points' own rate.
    with jax.enable_x64(True):
        for name, sampler in (("malley", cosine), ("inversion", inversion)):
            rmse64 = {}
            for log_n in range(10, 21, 2):
                n = 1 << log_n
                est = jax.jit(lambda k, n=n: estimate(cos3, sampler, k, 64 * n, uniforms=U.Sobol(64)))(next(keys))
                rmse64[log_n] = float(est.stderr) * 8.0
            slope64 = np.polyfit(logs * np.log(2), np.log([rmse64[k] for k in logs]), 1)[0]
            results["sobol"][f"rmse_slope_float64_{name}"] = slope64
            results["sobol"][f"rmse_float64_{name}"] = rmse64

    small, large = peak_rss_mib(1 << 20), peak_rss_mib(1 << 30)
    results["memory"] = {"peak_rss_mib_2^20": small, "peak_rss_mib_2^30": large, "growth_mib": large - small}
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
