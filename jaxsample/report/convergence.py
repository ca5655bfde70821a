"""Speed against error: RMSE, bias, variance and time per (integrand, strategy).

Run alone: `python benchmarks/convergence.py [--quick]` prints the table; the report
(`python -m jaxsample report`) calls `run_study` and writes tables and plots from it.

Method, for each (integrand, strategy):
- Error: for each of K independent keys, the per-sample values Y_i = f(x_i)/p(x_i) (i < N) are
  computed once and the estimates at n = 2^8, 2^10, ..., N are their prefix means. Prefixes of
  one "random" stream are independent-sample estimates; prefixes of length 2^m of one
  Owen-scrambled Sobol' sequence are randomized (0, m, 2)-nets, so both are valid estimates at
  every n. Jittered ("stratified") points depend on n, so they are drawn anew per n. RMSE and
  bias at each n are taken over the K keys against the exact value; the slope is the least-squares
  fit of log RMSE against log n.
- Time: the library path itself, `jaxsample.estimate` (or `estimate_mis`) under `jit`, at n_time
  samples, median of repeats after a warm-up; ns per sample = time / n_time.
- Bias z-score: mean error over the keys divided by its standard error (the spread of the K
  estimates / sqrt(K), combined with 4 float32 ulps of the exact value).
- Figures of merit (Veach 1997; PBRT): time to unit variance = MSE(N) * N * seconds per sample,
  and efficiency = 1 / that, shown relative to plain uniform sampling of the same integrand.
  Zero-variance strategies are floored at MSE = (2^-23 * exact)^2, the float32 rounding level.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample import uniforms as U
from .timing import median_seconds

COS30 = float(np.cos(np.pi / 6))
CAP_AXIS = np.array([0.5, 0.0, 1.0]) / np.linalg.norm([0.5, 0.0, 1.0])


@dataclasses.dataclass(frozen=True)
class Integrand:
    name: str
    description: str
    f: Callable
    exact: float


@dataclasses.dataclass(frozen=True)
class Strategy:
    integrand: str
    name: str
    sampler: object = None  # a Sampler, or a tuple of two for MIS
    uniforms: str = "random"
    heuristic: str | None = None  # MIS: "balance" | "power"; None otherwise


def _cap(w):
    # A tilted cap of half-angle 30°, wholly above the horizon: an indicator, so discontinuous.
    return jnp.where(w[0] * CAP_AXIS[0] + w[2] * CAP_AXIS[2] > COS30, 1.0, 0.0)


INTEGRANDS = [
    Integrand("hemi_cos1", "cos θ over H²", lambda w: w[2], np.pi),
    Integrand("hemi_cos3", "cos³ θ over H²", lambda w: w[2] ** 3, np.pi / 2),
    Integrand("hemi_cos10", "cos¹⁰ θ over H²", lambda w: w[2] ** 10, 2 * np.pi / 11),
    Integrand("sphere_cos2", "cos² θ over S²", lambda w: w[2] ** 2, 4 * np.pi / 3),
    Integrand("phong100", "sharp lobe cos¹⁰⁰ θ over H²", lambda w: jnp.maximum(w[2], 0.0) ** 100,
              2 * np.pi / 101),
    Integrand("cap", "tilted 30° cap indicator over H²", _cap, 2 * np.pi * (1 - COS30)),
    Integrand("disk_r2", "r² over the unit disk", lambda p: p[0] ** 2 + p[1] ** 2, np.pi / 2),
    Integrand("triangle_x2", "x² over the triangle (0,0),(1,0),(0,1)", lambda p: p[0] ** 2, 1 / 12),
    Integrand("free_flight", "e^{-t} cos t over [0, ∞)", lambda t: jnp.exp(-t) * jnp.cos(t), 0.5),
]


def strategies() -> list[Strategy]:
    S = []
    hemi = js.UniformHemisphere()
    cosine = js.CosineHemisphere()
    for name, phong_n in (("hemi_cos1", 0.5), ("hemi_cos3", 2.0), ("hemi_cos10", 8.0)):
        S += [Strategy(name, "uniform", hemi), Strategy(name, "cosine", cosine),
              Strategy(name, f"phong{phong_n:g}", js.PhongLobe(phong_n)),
              Strategy(name, "cosine+stratified", cosine, "stratified"),
              Strategy(name, "cosine+sobol", cosine, "sobol")]
    S += [Strategy("sphere_cos2", "uniform", js.UniformSphere()),
          Strategy("sphere_cos2", "uniform+sobol", js.UniformSphere(), "sobol"),
          Strategy("sphere_cos2", "vmf1", js.VonMisesFisher(1.0))]
    lobe, vmf = js.PhongLobe(80.0), js.VonMisesFisher(90.0)
    S += [Strategy("phong100", "uniform", hemi), Strategy("phong100", "cosine", cosine),
          Strategy("phong100", "phong80", lobe), Strategy("phong100", "vmf90", vmf),
          Strategy("phong100", "phong80+sobol", lobe, "sobol"),
          Strategy("phong100", "mixture(cosine,phong80)", js.Mixture([cosine, lobe], jnp.array([0.5, 0.5]))),
          Strategy("phong100", "mis-balance(cosine,phong80)", (cosine, lobe), heuristic="balance"),
          Strategy("phong100", "mis-power(cosine,phong80)", (cosine, lobe), heuristic="power")]
    cap_cone = js.Oriented(js.UniformCone(float(np.cos(np.pi / 5))), jnp.asarray(CAP_AXIS, jnp.float32))
    S += [Strategy("cap", "uniform", hemi), Strategy("cap", "cosine", cosine),
          Strategy("cap", "uniform+stratified", hemi, "stratified"),
          Strategy("cap", "uniform+sobol", hemi, "sobol"),
          Strategy("cap", "cone36°", cap_cone)]
    for method in ("concentric", "polar"):
        S += [Strategy("disk_r2", method, js.UniformDisk(method=method)),
              Strategy("disk_r2", f"{method}+sobol", js.UniformDisk(method=method), "sobol")]
    tri = js.UniformTriangle(jnp.array([0.0, 0.0]), jnp.array([1.0, 0.0]), jnp.array([0.0, 1.0]))
    S += [Strategy("triangle_x2", "uniform", tri), Strategy("triangle_x2", "uniform+sobol", tri, "sobol")]
    S += [Strategy("free_flight", "exponential1", js.Exponential(1.0)),
          Strategy("free_flight", "exponential0.5", js.Exponential(0.5)),
          Strategy("free_flight", "exponential1+sobol", js.Exponential(1.0), "sobol")]
    return S


def _values_fn(strategy: Strategy, f):
    """u (count, dims) -> Y (count,), per sample (MIS: per pair of one sample per technique)."""
    if strategy.heuristic is None:
        sampler = strategy.sampler

        def values(u):
            x, p = sampler.warp_with_pdf(u)
            return js.numerics.safe_div(jax.vmap(f)(x), p)

        return values, sampler.uniform_dims
    first, second = strategy.sampler
    d1, d2 = first.uniform_dims, second.uniform_dims
    power = 1.0 if strategy.heuristic == "balance" else 2.0

    def values(u):
        total = 0.0
        for own, other, part in ((first, second, u[:, :d1]), (second, first, u[:, d1:d1 + d2])):
            x, p_own = own.warp_with_pdf(part)
            p_other = other.pdf(x)
            weight = js.numerics.safe_div(p_own**power, p_own**power + p_other**power)
            total = total + js.numerics.safe_div(jax.vmap(f)(x) * weight, p_own)
        return total

    return values, d1 + d2


def _single_replicate_block(name: str, values, dims: int, count: int):
    """jit: seed -> Y over `count` points of ONE replicate of the source (one scramble / jitter).

    The library's Sobol' and stratified sources interleave R >= 2 replicates (global index g
    belongs to replicate g mod R, point g div R); drawing 2 * count points with R = 2 and keeping
    the even ones gives replicate 0 alone: a single scrambled Sobol' sequence in natural order, or
    one jittered pattern of `count` points.
    """
    if name == "random":
        source, stride = U.Random(), 1
    else:
        source, stride = (U.Sobol(replicates=2) if name == "sobol" else U.Stratified(replicates=2)), 2

    def run(seed):
        u = source.block(seed, jnp.uint32(0), count * stride, dims, jnp.float32, total=count * stride)
        return values(u[::stride])

    return jax.jit(run)


def _prefix_means(y: np.ndarray, ns: list[int]) -> np.ndarray:
    csum = np.cumsum(y.astype(np.float64))
    return np.array([csum[n - 1] / n for n in ns])


def _timed_estimate(strategy: Strategy, f, n_time: int) -> float:
    if strategy.heuristic is None:
        run = jax.jit(lambda key: js.estimate(f, strategy.sampler, key, n_time,
                                              uniforms=strategy.uniforms).mean)
    else:
        run = jax.jit(lambda key: js.estimate_mis(f, list(strategy.sampler), key,
                                                  [n_time // 2, n_time // 2],
                                                  heuristic=strategy.heuristic).mean)
    return median_seconds(run, jax.random.key(99), repeats=3) / n_time


def study_one(strategy: Strategy, integrand: Integrand, ns: list[int], n_keys: int, n_time: int,
              seed: int = 0) -> dict:
    values, dims = _values_fn(strategy, integrand.f)
    n_max = ns[-1]
    # An MIS "sample" is a pair (one draw per technique): it costs two evaluations of f.
    evaluations_per_value = 2 if strategy.heuristic else 1
    keys = jax.random.split(jax.random.key(seed), n_keys)
    estimates = np.zeros((n_keys, len(ns)))
    sum_var = 0.0
    if strategy.uniforms in ("random", "sobol"):
        block = _single_replicate_block(strategy.uniforms, values, dims, n_max // evaluations_per_value)
        for i, key in enumerate(keys):
            y = np.asarray(block(U.seed_from_key(key)))
            estimates[i] = _prefix_means(y, [n // evaluations_per_value for n in ns])
            sum_var += float(np.var(y.astype(np.float64)))
    else:
        for j, n in enumerate(ns):
            block = _single_replicate_block(strategy.uniforms, values, dims, n)
            for i, key in enumerate(jax.random.split(jax.random.fold_in(jax.random.key(seed), j), n_keys)):
                y = np.asarray(block(U.seed_from_key(key)))
                estimates[i, j] = float(np.mean(y.astype(np.float64)))
                if j == len(ns) - 1:
                    sum_var += float(np.var(y.astype(np.float64)))
    errors = estimates - integrand.exact
    rmse = np.sqrt(np.mean(errors**2, axis=0))
    bias = np.mean(errors, axis=0)
    floor = (2.0**-23 * abs(integrand.exact)) ** 2
    fit = np.isfinite(np.log(rmse)) & (rmse > 0)
    slope = float(np.polyfit(np.log(np.array(ns)[fit]), np.log(rmse[fit]), 1)[0]) if fit.sum() >= 2 else float("nan")
    seconds_per_sample = _timed_estimate(strategy, integrand.f, n_time)
    mse = max(float(rmse[-1]) ** 2, floor)
    time_to_unit_variance = mse * n_max * seconds_per_sample
    return {
        "integrand": integrand.name, "strategy": strategy.name, "uniforms": strategy.uniforms,
        "exact": integrand.exact, "ns": list(ns), "rmse": rmse.tolist(), "bias": bias.tolist(),
        "rmse_at_max": float(rmse[-1]), "bias_at_max": float(bias[-1]),
        # bias over its standard error (spread across keys, ⊕ 4 float32 ulps of the exact value so
        # that zero-variance strategies are judged on bias, not on rounding)
        "bias_z": float(bias[-1] / math.hypot(float(np.std(estimates[:, -1], ddof=1)) / math.sqrt(n_keys),
                                              4 * 2.0**-23 * abs(integrand.exact))),
        "per_sample_variance": sum_var / n_keys, "ns_per_sample": seconds_per_sample * 1e9,
        "time_to_unit_variance": time_to_unit_variance, "efficiency": 1.0 / time_to_unit_variance,
        "slope": slope, "n_keys": n_keys,
    }


def run_study(quick: bool = True, progress=print, tiny: bool = False) -> list[dict]:
    """Every (integrand, strategy) row; `quick` uses n up to 2^16 and 16 keys, `tiny` 2^10 and 4."""
    if tiny:
        ns, n_keys, n_time = [2**8, 2**10], 4, 2**12
    elif quick:
        ns, n_keys, n_time = [2**k for k in range(8, 17, 2)], 16, 2**18
    else:
        ns, n_keys, n_time = [2**k for k in range(8, 23, 2)], 32, 2**22
    by_name = {i.name: i for i in INTEGRANDS}
    rows = []
    all_strategies = strategies()
    if tiny:  # a smoke test: every integrand, a few strategies, every code path (random, sobol, MIS)
        keep = {("hemi_cos3", "uniform"), ("hemi_cos3", "cosine+sobol"), ("hemi_cos3", "cosine+stratified"),
                ("phong100", "uniform"), ("phong100", "mis-power(cosine,phong80)"), ("cap", "uniform"),
                ("disk_r2", "concentric"), ("triangle_x2", "uniform"), ("free_flight", "exponential1")}
        all_strategies = [s for s in all_strategies if (s.integrand, s.name) in keep]
    for index, strategy in enumerate(all_strategies):
        progress(f"[study {index + 1}/{len(all_strategies)}] {strategy.integrand} / {strategy.name}")
        rows.append(study_one(strategy, by_name[strategy.integrand], ns, n_keys, n_time, seed=index))
    for row in rows:
        base = next(r for r in rows if r["integrand"] == row["integrand"] and r["strategy"] in ("uniform", "exponential1", "concentric"))
        row["relative_efficiency"] = row["efficiency"] / base["efficiency"]
    return rows


def markdown_table(rows: list[dict]) -> str:
    head = ("| integrand | strategy | RMSE @ n_max | bias (z) | per-sample var | ns/sample | "
            "time to unit var (s) | efficiency vs uniform | RMSE slope |\n|---|---|---|---|---|---|---|---|---|\n")
    lines = [f"| {r['integrand']} | {r['strategy']} | {r['rmse_at_max']:.3g} | {r['bias_at_max']:.2g} "
             f"({r['bias_z']:+.1f}) | {r['per_sample_variance']:.3g} | {r['ns_per_sample']:.2f} | "
             f"{r['time_to_unit_variance']:.3g} | {r['relative_efficiency']:.3g}× | {r['slope']:.2f} |"
             for r in rows]
    return head + "\n".join(lines) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    print(markdown_table(run_study(quick=args.quick)))
