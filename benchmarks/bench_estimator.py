"""Speed, memory and efficiency of jaxsample.estimate; run alone: python benchmarks/bench_estimator.py

Every figure is a ratio taken in this one run: medians of repeats after a warm-up, with
block_until_ready. Case: ∫cos³ over the hemisphere with CosineHemisphere, n = 2^24, plus an
integrand that uses every component (max(ω·a, 0)³, tilted a) so nothing is dropped as dead code.

Throughput is reported three ways against NumPy doing the same work: the mean alone (what the
issue's 12x target compares), the mean with its standard error, and the whole Estimate (mean,
stderr, ESS and max |Y|) against NumPy's mean alone. Under jit a user pays only for the fields
they read. The uniform floor is the same engine summing the uniforms (no warp, no integrand).
Sobol' rates are measured for both maps of CosineHemisphere, in float32 and float64.

The throughput figures are taken twice: with XLA's default 256-bit CPU vectors, and (on a CPU with
AVX-512) in a child process with XLA_FLAGS=--xla_cpu_prefer_vector_width=512, a setting a user
chooses for their whole process (the library sets no XLA flags). A breakdown then times the
floor with the warp's arithmetic added, then its square root, then the division f/p.
"""

import json
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample import uniforms as U
from jaxsample.estimators import estimate, run_stream

from jaxsample.report.numpy_baseline import cos3, everything, median_time, numpy_estimate, tilted, uniform_floor
from jaxsample.report.timing import interleaved_medians

N = 1 << 24

MEMORY_CHILD = """
import resource, sys, jax, jaxsample as js
from jaxsample.estimators import estimate, run_stream
n = int(sys.argv[1])
f = jax.jit(lambda k: estimate(lambda w: w[2] ** 3, js.CosineHemisphere(), k, n).mean)
print(float(f(jax.random.key(0))), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def peak_rss_mib(n):
    out = subprocess.run([sys.executable, "-c", MEMORY_CHILD, str(n)], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1]) / 1024.0


WIDE_VECTORS = "--xla_cpu_prefer_vector_width=512"


def throughput(keys, cosine):
    """Seconds for the estimator and its uniform floor, and the ratios the issue's targets name.

    Medians of 7, the five variants interleaved so that a burst of load on this shared machine
    hits them alike; NumPy (about 10x slower) gets 3.
    """
    variants = {
        "mean": jax.jit(lambda k: estimate(cos3, cosine, k, N).mean),
        "full": jax.jit(lambda k: everything(estimate(cos3, cosine, k, N))),
        "mean_stderr": jax.jit(lambda k: (lambda e: (e.mean, e.stderr))(estimate(cos3, cosine, k, N))),
        "floor_mean": uniform_floor(N, full=False),
        "floor_full": uniform_floor(N, full=True),
    }
    t = interleaved_medians(variants, keys)
    t_np = median_time(numpy_estimate, N, repeats=3)
    t_np_stderr = median_time(lambda: numpy_estimate(N, with_stderr=True), repeats=3)
    return {
        "jax_mean_stderr_s": t["mean_stderr"], "numpy_mean_stderr_s": t_np_stderr,
        "speedup_vs_numpy_mean_and_stderr": t_np_stderr / t["mean_stderr"],
        "jax_mean_only_s": t["mean"], "jax_full_estimate_s": t["full"], "numpy_s": t_np,
        "uniforms_only_mean_s": t["floor_mean"], "uniforms_only_full_s": t["floor_full"],
        "speedup_vs_numpy": t_np / t["mean"],
        "speedup_vs_numpy_full_estimate": t_np / t["full"],
        "time_vs_uniforms_only": t["mean"] / t["floor_mean"],
        "time_vs_uniforms_only_full_estimate": t["full"] / t["floor_full"],
        "jax_Msamples_per_s": N / t["mean"] / 1e6, "numpy_Msamples_per_s": N / t_np / 1e6}


def _disk_radius_term(u):
    """1 - r² of the concentric map's radius r = max(|2u₀ - 1|, |2u₁ - 1|): Malley's z² for ∫cos³."""
    r = jnp.maximum(jnp.abs(2.0 * u[:, 0] - 1.0), jnp.abs(2.0 * u[:, 1] - 1.0))
    return (1.0 - r) * (1.0 + r)


def breakdown(keys):
    """Where the time above the uniform floor goes: the same engine and uniforms with the warp's
    arithmetic but neither square root nor division (π z²), then with the square root
    (π z, z = sqrt(z²)), then with both, as ∫cos³ needs them (z³ / (z/π)). Medians of 7, interleaved."""
    pi = np.float32(np.pi)
    stages = {
        "floor": lambda u: u[:, 0] + u[:, 1],
        "warp_arithmetic": lambda u: pi * _disk_radius_term(u),
        "plus_sqrt": lambda u: pi * jnp.sqrt(_disk_radius_term(u)),
        "plus_sqrt_and_divide": lambda u: (lambda z: z * z * z / (z / pi))(jnp.sqrt(_disk_radius_term(u))),
    }
    fns = {name: jax.jit(lambda k, f=f: run_stream(f, 2, k, N).mean) for name, f in stages.items()}
    t = interleaved_medians(fns, keys)
    return {f"{name}_vs_floor": t[name] / t["floor"] for name in fns if name != "floor"} | {"floor_s": t["floor"]}


def has_avx512() -> bool:
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            return " avx512f" in cpuinfo.read()
    except OSError:
        return False


def wide_vector_throughput():
    """`throughput` again in a child process whose XLA emits 512-bit vectors (a flag a user sets;
    XLA's CPU default is 256). None where the CPU has no AVX-512."""
    if not has_avx512():
        return None
    env = dict(os.environ, XLA_FLAGS=(os.environ.get("XLA_FLAGS", "") + " " + WIDE_VECTORS).strip())
    out = subprocess.run([sys.executable, __file__, "--throughput-only"], env=env, capture_output=True,
                         text=True, check=True)
    return dict(json.loads(out.stdout), xla_flags=env["XLA_FLAGS"])


def main():
    if "--throughput-only" in sys.argv:
        keys = iter(jax.random.split(jax.random.key(0), 64))
        print(json.dumps(throughput(keys, js.CosineHemisphere())))
        return
    keys = iter(jax.random.split(jax.random.key(0), 256))
    results = {"n": N, "devices": jax.device_count()}
    cosine = js.CosineHemisphere()
    inversion = js.CosineHemisphere(method="inversion")
    results["cos3"] = throughput(keys, cosine)
    results["cos3_512bit_vectors"] = wide_vector_throughput()
    results["cos3_time_above_floor"] = breakdown(keys)
    t_gen = results["cos3"]["uniforms_only_mean_s"]
    t_tilt_malley = median_time(jax.jit(lambda k: estimate(tilted, cosine, k, N).mean), next(keys))
    t_tilt_inv = median_time(jax.jit(lambda k: estimate(tilted, inversion, k, N).mean), next(keys))
    t_np_tilt = median_time(lambda: numpy_estimate(N, all_components=True), repeats=3)
    results["all_components"] = {
        "jax_malley_s": t_tilt_malley, "jax_inversion_sincos_poly_s": t_tilt_inv, "numpy_s": t_np_tilt,
        "speedup_malley_vs_numpy": t_np_tilt / t_tilt_malley,
        "speedup_inversion_vs_numpy": t_np_tilt / t_tilt_inv,
        "inversion_time_vs_uniforms_only": t_tilt_inv / t_gen}

    # Sobol': RMSE of one n-point scrambled estimate, from the spread of 64 independent scrambles
    # (stderr of their mean times sqrt(64)), for both of CosineHemisphere's maps, in float32 (the
    # default) and float64. The concentric map behind Malley's method has kinks along the square's
    # diagonals, and ∫cos³ is π(1 - r²) = π(1 - max(a², b²)) in its coordinates: a kinked
    # integrand, which caps scrambled Sobol' near n^-1.2. Under the inversion map the same
    # integrand is π(1 - u₀), smooth, and the points reach their n^-1.5 rate.
    logs = np.arange(10, 21, 2)
    n_eff = 1 << 20
    var_random = np.pi ** 2 / 12 / n_eff             # exact (docs/reference.md), either map
    sobol = {}
    for name, sampler in (("malley", cosine), ("inversion", inversion)):
        for dtype in ("float32", "float64"):
            with jax.enable_x64(dtype == "float64"):
                rmse = {}
                for log_n in logs:
                    n = 1 << int(log_n)
                    run = jax.jit(lambda k, n=n, s=sampler: estimate(cos3, s, k, 64 * n, uniforms=U.Sobol(64)))
                    rmse[int(log_n)] = float(run(next(keys)).stderr) * 8.0
            slope = np.polyfit(logs * np.log(2), np.log([rmse[k] for k in logs]), 1)[0]
            sobol[f"{name}_{dtype}"] = {"rmse_slope": slope, "rmse": rmse}
        t_sobol = median_time(jax.jit(lambda k, s=sampler: estimate(cos3, s, k, n_eff, uniforms="sobol").mean),
                              next(keys))
        t_random = median_time(jax.jit(lambda k, s=sampler: estimate(cos3, s, k, n_eff).mean), next(keys))
        var_sobol = sobol[f"{name}_float32"]["rmse"][16] ** 2 / 16  # 16 replicates of 2^16 points
        sobol[f"{name}_float32"].update(
            t_sobol_s=t_sobol, t_random_s=t_random,
            efficiency_ratio_vs_random=(var_random * t_random) / (var_sobol * t_sobol))
    results["sobol"] = sobol

    small, large = peak_rss_mib(1 << 20), peak_rss_mib(1 << 30)
    results["memory"] = {"peak_rss_mib_2^20": small, "peak_rss_mib_2^30": large, "growth_mib": large - small}
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
