"""Gradient estimators for the Phong exponent: variance, bias z-score and cost, against theory.

Two reference problems (docs/reference.md, "Gradients with respect to a sampler parameter"):

- fixed integral ∫_{H²} cos^k dω sampled from Phong(n) (`estimate`, mode "attached" or
  "detached"): the exact gradient is 0; the attached per-sample variance is
  4π²/(n+1)⁴ (2b²/c³ - 2b/c² + 1/c), b = (k+1)/(n+1), c = (2k+1-n)/(n+1), infinite for n >= 2k+1;
  the detached one is exactly 0.
- d/dn E_{Phong(n)}[cos^k] = k/(n+k+1)² (`expectation`, "pathwise", "score", "score" with the
  leave-one-out baseline): exact per-sample variances from E[g²] (docs/literature.md §1.2); for the
  leave-one-out baseline the exact column is the constant baseline b = E[cos^k], which it
  approaches as N grows.

Per row: the gradient (mean of per-sample gradients, which is the gradient of the estimate), the
measured per-sample variance beside the exact one, the bias z-score (mean - exact)/sqrt(var/N)
using the exact variance where it is finite (the measured one otherwise), and the cost in ns per
sample of `jit(grad(estimate or expectation))` (median of repeats, block_until_ready).

Run: `python -m jaxsample.report.bench_gradients [--quick]`; `gradient_table(quick)` returns the rows.
"""

from __future__ import annotations

import argparse
import math
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from ..estimators.gradients import expectation, expectation_values, integrand_values

EXPONENTS = (1.0, 10.0, 50.0)
POWERS = (1, 3, 10, 30)


def _fixed_variance(k, n):
    if n >= 2 * k + 1:
        return math.inf
    b, c = (k + 1) / (n + 1), (2 * k + 1 - n) / (n + 1)
    return 4 * math.pi ** 2 / (n + 1) ** 4 * (2 * b * b / c ** 3 - 2 * b / c ** 2 + 1 / c)


def _f(alpha):
    s = alpha + 1.0
    return 1 / s - 2 / s ** 2 + 2 / s ** 3


def _expectation_variance(estimator, k, n):
    a, grad = k / (n + 1), k / (n + k + 1) ** 2
    if estimator == "pathwise":
        return 2 * k * k / ((n + 1) ** 4 * (2 * a + 1) ** 3) - grad ** 2
    b = 0.0 if estimator == "score" else (n + 1) / (n + k + 1)
    return (_f(2 * a) - 2 * b * _f(a) + b * b) / (n + 1) ** 2 - grad ** 2


def _power(k):
    return lambda x: x[2] ** k


@jax.jit
def _per_sample_gradients(k, n, u):
    """Per-sample gradients d/dn of every estimator at the rows of u (k traced: one compile)."""
    f = _power(k)

    def fixed(mode):
        return jax.vmap(jax.grad(lambda n, row: integrand_values(f, js.PhongLobe(n), row[None], mode=mode)[0]),
                        (None, 0))(n, u)

    def expect(gradient):
        return jax.vmap(jax.grad(lambda n, row: expectation_values(f, js.PhongLobe(n), row[None],
                                                                   gradient=gradient)[0]), (None, 0))(n, u)

    # Leave-one-out per-sample terms (g_i - b_i) ∂ log p_i, b_i the mean of the others: their mean
    # is exactly the leave-one-out gradient (their variance treats them as independent, to O(1/N)).
    x = js.PhongLobe(n).warp(u)
    g = jax.vmap(f)(x)
    score = jax.vmap(jax.grad(lambda n, xi: js.PhongLobe(n).log_pdf(xi)), (None, 0))(n, x)
    count = g.shape[0]
    loo_baseline = (jnp.sum(g) - g) / (count - 1)
    return {"attached": fixed("attached"), "detached": fixed("detached"),
            "pathwise": expect("pathwise"), "score": expect("score"),
            "score+loo": (g - loo_baseline) * score}


def _timers(n_samples):
    """jit(grad(...)) of each estimator over n_samples; k, n traced so each compiles once."""

    def fixed(mode):
        return jax.jit(jax.grad(lambda n, k, key: js.estimate(_power(k), js.PhongLobe(n), key, n_samples,
                                                              mode=mode).mean))

    def expect(gradient, baseline=None):
        return jax.jit(jax.grad(lambda n, k, key: expectation(_power(k), js.PhongLobe(n), key, n_samples,
                                                              gradient=gradient, baseline=baseline).mean))

    return {"attached": fixed("attached"), "detached": fixed("detached"), "pathwise": expect("pathwise"),
            "score": expect("score"), "score+loo": expect("score", "leave_one_out")}


def _time(fn, n, k, key, n_samples, repeats):
    keys = jax.random.split(key, repeats + 1)
    jax.block_until_ready(fn(n, k, keys[0]))  # compile
    times = []
    for i in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(n, k, keys[i + 1]))
        times.append(time.perf_counter() - start)
    return float(np.median(times)) / n_samples * 1e9


def gradient_table(quick: bool = True) -> list[dict]:
    """Rows of {problem, estimator, k, n, samples, gradient, exact_gradient, variance,
    exact_variance, z, note, ns_per_sample}."""
    samples = 1 << (16 if quick else 20)
    timed_samples = 1 << (16 if quick else 20)
    repeats = 3 if quick else 7
    exponents = EXPONENTS
    powers = POWERS
    timers = _timers(timed_samples)
    key = jax.random.key(2024)
    rows = []
    for n in exponents:
        for k in powers:
            key, u_key, t_key = jax.random.split(key, 3)
            u = jax.random.uniform(u_key, (samples, 2))
            grads = _per_sample_gradients(jnp.float32(k), jnp.float32(n), u)
            t_keys = jax.random.split(t_key, len(grads))
            for (name, per_sample), tk in zip(grads.items(), t_keys):
                per_sample = np.asarray(per_sample, np.float64)
                if name in ("attached", "detached"):
                    problem, exact = "fixed ∫cos^k, Phong(n)", 0.0
                    exact_var = _fixed_variance(k, n) if name == "attached" else 0.0
                else:
                    problem, exact = "d/dn E[cos^k]", k / (n + k + 1) ** 2
                    exact_var = _expectation_variance(name if name != "score+loo" else "baseline", k, n)
                mean, var = float(per_sample.mean()), float(per_sample.var())
                note = ""
                if not math.isfinite(exact_var):
                    # n >= 2k + 1: finite mean, infinite variance; no z-score is meaningful.
                    z, note = math.nan, "infinite variance (n >= 2k+1)"
                elif exact_var == 0:
                    z = 0.0 if mean == exact else math.inf
                else:
                    z = (mean - exact) / math.sqrt(exact_var / samples)
                    if problem.startswith("fixed") and 3 * n > 4 * k + 1:
                        note = "infinite 4th moment: sample variance unreliable"
                rows.append({
                    "problem": problem, "estimator": name, "k": k, "n": n, "samples": samples,
                    "gradient": mean, "exact_gradient": exact, "variance": var,
                    "exact_variance": exact_var, "z": z, "note": note,
                    "ns_per_sample": _time(timers[name], jnp.float32(n), jnp.float32(k), tk,
                                           timed_samples, repeats),
                })
    return rows


def markdown(rows: list[dict]) -> str:
    head = ("| problem | estimator | k | n | gradient | exact | variance | exact variance | z | ns/sample | note |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        lines.append(f"| {r['problem']} | {r['estimator']} | {r['k']} | {r['n']:g} | {r['gradient']:.4g} | "
                     f"{r['exact_gradient']:.4g} | {r['variance']:.3g} | {r['exact_variance']:.3g} | "
                     f"{r['z']:+.2f} | {r['ns_per_sample']:.1f} | {r['note']} |")
    return "\n".join(lines)


markdown_table = markdown  # the name the report calls


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2^16 samples, 3 timing repeats")
    args = parser.parse_args()
    print(markdown(gradient_table(quick=args.quick)))


if __name__ == "__main__":
    main()

