"""The diagnostics every estimate carries, measured: `python benchmarks/diagnostics.py [--quick]`.

1. Programs whose estimate is confidently wrong: the estimate, the truth, and whether it is flagged.
2. False alarms on honest estimates: 64 oriented lobes over keys, and every sampler of the
   report's table over keys.
3. Coverage of 95 % intervals from R replicates (Sobol', stratified): Student's t against the
   normal quantile.
4. The cost: each program with the diagnostics and without (`run_stream(..., diagnostics=False)`,
   which exists only to measure this), interleaved rounds in one process, medians.
"""

import argparse
import math
import statistics
import sys
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample import edges
from jaxsample.estimators.engine import run_stream
from jaxsample.estimators.plain import packed_values
from jaxsample.report.samplers_table import cases as sampler_cases

warnings.simplefilter("ignore", js.UnreliableEstimateWarning)
NORMALS = js.UniformSphere().warp(jax.random.uniform(jax.random.key(7), (64, 2)))


def lobe_batch(sampler_of, exponent, n, key):
    def one(normal, k):
        f = lambda w: jnp.maximum(w @ normal, 0.0) ** exponent
        return js.estimate(f, sampler_of(normal), k, n)
    return jax.jit(jax.vmap(one))(NORMALS, jax.random.split(key, NORMALS.shape[0]))


def flagged_programs(n):
    print(f"## 1. The confident-wrong programs (n = {n})\n")
    print("| program | estimate | truth | flagged |\n|---|---|---|---|")
    key = iter(jax.random.split(jax.random.key(0), 32))
    for k in (5, 20):
        est = lobe_batch(lambda normal: js.PhongLobe(float(k)), k, n, next(key))
        truth = 2 * np.pi / (k + 1)
        z = np.asarray((est.mean - truth) / est.stderr)
        bad = np.abs(z) > 4
        rel = np.asarray(est.reliable)
        print(f"| ∫max(ω·n,0)^{k} with PhongLobe({k}) not oriented, 64 normals | median z {np.median(z):.3g}, "
              f"{bad.sum()} of 64 beyond 4σ, {int((np.asarray(est.nonzero) == 0).sum())} all-zero | {truth:.4f} | "
              f"{(~rel).sum()} of 64 flagged; {(bad & rel).sum()} wrong and unflagged |")
    for label, f, sampler, truth in (
            ("∫_H² cos θ with PhongLobe(20)", lambda w: w[2], js.PhongLobe(20.0), math.pi),
            ("∫_H² 1/(1 - cos θ), uniform (divergent)", lambda w: 1 / (1 - w[2]), js.UniformHemisphere(), math.inf),
            ("∫_H² cos θ, cosine-weighted (zero variance)", lambda w: w[2], js.CosineHemisphere(), math.pi)):
        est = js.estimate(f, sampler, next(key), n)
        z = "" if not math.isfinite(truth) else f", z {(float(est.mean) - truth) / float(est.stderr):+.2f}"
        print(f"| {label} | {float(est.mean):.5g} ± {float(est.stderr):.2g}{z} | {truth:.5g} | "
              f"{'yes' if not bool(est.reliable) else 'no'} (k-hat {float(est.khat):.2f}) |")
    make = lambda a: (edges.mask(edges.Cap.from_angle(jnp.array([0.0, 0.0, 1.0]), a), lambda w: 1.0),
                      js.UniformSphere())
    g = js.estimate_grad(make, jnp.float32(0.7), next(key), n)
    print(f"| d/dα ∫ 1[ω·a ≥ cos α] dω (edges.mask) | {float(g.mean):.6f} ± {float(g.stderr):.1g} | "
          f"{2 * np.pi * np.sin(0.7):.6f} | {'yes' if not bool(g.reliable) else 'no'} |")
    print()


def false_alarms(n_values, keys):
    print(f"## 2. False alarms on honest estimates ({keys} keys each)\n")
    print("| estimates | n | flagged |\n|---|---|---|")
    total = flagged = 0
    for n in n_values:
        count = 0
        for i in range(keys):
            est = lobe_batch(lambda normal: js.Oriented(js.PhongLobe(5.0), normal), 5, n, jax.random.key(100 + i))
            count += int((~est.reliable).sum())
        print(f"| 64 oriented Phong(5) lobes, ∫max(ω·n,0)^5 | {n} | {count} of {64 * keys} |")
        total += 64 * keys
        flagged += count
        table = sampler_cases()
        table_flagged = 0
        for name, sampler, f, exact, _ in table:
            est = jax.jit(jax.vmap(lambda k: js.estimate(f, sampler, k, n)))(jax.random.split(jax.random.key(5), keys))
            bad = int((~est.reliable).sum())
            table_flagged += bad
            if bad:
                print(f"| {name} (of the report's sampler table) | {n} | {bad} of {keys} "
                      f"(k-hat max {float(jnp.max(est.khat)):.2f}) |")
        print(f"| the {len(table)} samplers of the report's table, each on its integral | {n} | "
              f"{table_flagged} of {len(table) * keys} |")
        total += len(table) * keys
        flagged += table_flagged
    print(f"\nAll honest estimates: {flagged} flagged of {total} ({flagged / total:.2%}).\n")


def coverage(keys):
    print(f"## 3. Coverage of 95 % intervals from replicates ({keys} keys, ∫cos³ cosine-weighted)\n")
    print("| source | R | points per replicate | t interval | normal interval |\n|---|---|---|---|---|")
    for source_of in (js.uniforms.Sobol, js.uniforms.Stratified):
        for r in (8, 16):
            for per in (64, 1024):
                est = jax.jit(jax.vmap(lambda k: js.estimate(lambda w: w[2] ** 3, js.CosineHemisphere(), k, r * per,
                                                             uniforms=source_of(r))))(
                    jax.random.split(jax.random.key(r + per), keys))
                lo, hi = est.interval(0.95)
                t = float(jnp.mean((lo <= np.pi / 2) & (np.pi / 2 <= hi)))
                normal = float(jnp.mean(jnp.abs(est.mean - np.pi / 2) <= 1.959964 * est.stderr))
                print(f"| {source_of.__name__} | {r} | {per} | {t:.2%} | {normal:.2%} |")
    print()


def program(f, sampler, n, diagnostics):
    def values_fn(u):
        return packed_values(f, sampler, u, "attached")[0]
    out = jax.eval_shape(lambda: f(jnp.zeros(sampler.event_shape))).shape
    return jax.jit(lambda key: run_stream(values_fn, sampler.uniform_dims, key, n, out_shape=out,
                                          diagnostics=diagnostics).mean)


def harmonics(w):
    """16 products of the direction's coordinates up to degree 3 (a projection's many outputs)."""
    x, y, z = w[0], w[1], w[2]
    return jnp.stack([jnp.ones_like(x), x, y, z, x * y, y * z, x * z, x * x - y * y, 3 * z * z - 1,
                      x * (x * x - 3 * y * y), y * (3 * x * x - y * y), z * (x * x - y * y), x * y * z,
                      x * (5 * z * z - 1), y * (5 * z * z - 1), z * (5 * z * z - 3)])


COST_CASES = {
    "∫cos³, cosine-weighted": (lambda w: w[2] ** 3, js.CosineHemisphere()),
    "∫max(ω·a, 0)³, Phong 20 tilted": (lambda w: jnp.maximum(w @ jnp.array([0.6, 0.0, 0.8]), 0.0) ** 3,
                                       js.Oriented(js.PhongLobe(20.0), jnp.array([0.0, 0.6, 0.8]))),
    "16 outputs per direction, uniform sphere": (harmonics, js.UniformSphere()),
}


def cost(log2n, rounds):
    n = 1 << log2n
    key = jax.random.key(0)
    print(f"## 4. Cost (n = 2^{log2n}, {rounds} interleaved rounds, medians; {jax.devices()[0].platform})\n")
    print("| program | with diagnostics, ns/sample | without | ratio |\n|---|---|---|---|")
    for name, (f, sampler) in COST_CASES.items():
        fns = {flag: program(f, sampler, n, flag) for flag in (True, False)}
        for fn in fns.values():
            jax.block_until_ready(fn(key))
        times = {True: [], False: []}
        for _ in range(rounds):
            for flag, fn in fns.items():
                start = time.perf_counter()
                jax.block_until_ready(fn(key))
                times[flag].append(time.perf_counter() - start)
        ratio = statistics.median(a / b for a, b in zip(times[True], times[False]))
        on, off = (1e9 * statistics.median(times[flag]) / n for flag in (True, False))
        print(f"| {name} | {on:.2f} | {off:.2f} | {ratio:.3f}x |")
    print()


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--only", choices=["table", "alarms", "coverage", "cost"])
    args = parser.parse_args(argv)
    steps = {"table": lambda: flagged_programs(1 << 14),
             "alarms": lambda: false_alarms((1 << 12, 1 << 16), 4 if args.quick else 16),
             "coverage": lambda: coverage(2000 if args.quick else 4000),
             "cost": lambda: cost(22 if args.quick else 24, 5 if args.quick else 9)}
    for name, step in steps.items():
        if args.only in (None, name):
            step()
            sys.stdout.flush()


if __name__ == "__main__":
    main()
