"""Gradients with error bars and estimates to a requested accuracy, as two report tables.

Run alone: `python -m jaxsample.report.gradient_error_bars [--quick]`.

1. d/dn E_{Phong(n)}[cos^k θ] = k/(n+k+1)² by `jaxsample.expectation_grad` with each estimator
   ("pathwise", "score", "measure_valued"): the gradient ± its reported stderr beside the exact
   value, the per-sample variance n·stderr², the time per sample, and the figure of merit
   1/(variance × time) (higher is better: the gradient accuracy bought per second).
2. `jaxsample.estimate_until` at several requested relative accuracies: the achieved stderr
   relative to |mean|, the actual relative error against the exact integral, and the samples used.
"""

from __future__ import annotations

import argparse

import jax
import numpy as np

import jaxsample as js
from .timing import median_seconds

GRADIENTS = ("pathwise", "score", "measure_valued")


def gradient_table(quick: bool = True, progress=print) -> list[dict]:
    n_samples = 1 << (16 if quick else 20)
    rows = []
    for exponent, power in ((5.0, 2), (50.0, 3)):
        exact = power / (exponent + power + 1.0) ** 2
        for gradient in GRADIENTS:
            progress(f"[gradient error bars] n={exponent:g} k={power} {gradient}")
            make = lambda p, k=power: (lambda w: w[2] ** k, js.PhongLobe(p))  # noqa: E731
            run = jax.jit(lambda key, g=gradient, make=make, e=exponent:
                          js.expectation_grad(make, e, key, n_samples, gradient=g))
            est = run(jax.random.key(7))
            seconds = median_seconds(run, jax.random.key(8))
            variance = float(est.stderr) ** 2 * n_samples
            rows.append({"exponent": exponent, "power": power, "estimator": gradient, "n": n_samples,
                         "gradient": float(est.mean), "stderr": float(est.stderr), "exact": exact,
                         "z": (float(est.mean) - exact) / float(est.stderr), "per_sample_variance": variance,
                         "ns_per_sample": 1e9 * seconds / n_samples,
                         "merit": 1.0 / (variance * seconds / n_samples)})
    return rows


def accuracy_table(quick: bool = True, progress=print) -> list[dict]:
    cases = {"∫cos³ over H², uniform": (lambda w: w[2] ** 3, js.UniformHemisphere(), np.pi / 2, "random"),
             "∫cos³ over H², cosine (inversion) + Sobol'": (lambda w: w[2] ** 3,
                                                             js.CosineHemisphere(method="inversion"), np.pi / 2,
                                                             "sobol")}
    rows = []
    for name, (f, sampler, exact, uniforms) in cases.items():
        for rtol in ((1e-2, 1e-3) if quick else (1e-2, 1e-3, 1e-4)):
            progress(f"[accuracy] {name} rtol={rtol:g}")
            result = jax.jit(lambda key, f=f, s=sampler, r=rtol, u=uniforms: js.estimate_until(
                f, s, key, rtol=r, max_n=1 << 26, chunk_size=1 << 14, uniforms=u))(jax.random.key(9))
            mean = float(result.mean)
            rows.append({"integrand": name, "requested_rtol": rtol,
                         "achieved_stderr_rel": float(result.stderr) / abs(mean),
                         "actual_error_rel": abs(mean - exact) / exact, "n_used": int(result.n_used),
                         "converged": bool(result.converged)})
    return rows


def markdown(gradient_rows: list[dict], accuracy_rows: list[dict]) -> str:
    out = ["| n, k | estimator | gradient ± stderr | exact | z | per-sample variance | ns/sample "
           "| 1/(variance × time) |",
           "|---|---|---|---|---|---|---|---|"]
    for r in gradient_rows:
        out.append(f"| {r['exponent']:g}, {r['power']} | {r['estimator']} | {r['gradient']:.5g} ± {r['stderr']:.2g} | "
                   f"{r['exact']:.5g} | {r['z']:+.2f} | {r['per_sample_variance']:.3g} | {r['ns_per_sample']:.1f} | "
                   f"{r['merit']:.3g} |")
    out += ["", "| integrand | requested relative stderr | achieved | actual relative error | samples used | met |",
            "|---|---|---|---|---|---|"]
    for r in accuracy_rows:
        out.append(f"| {r['integrand']} | {r['requested_rtol']:g} | {r['achieved_stderr_rel']:.3g} | "
                   f"{r['actual_error_rel']:.3g} | {r['n_used']} | {'yes' if r['converged'] else 'no'} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    quick = parser.parse_args().quick
    print(markdown(gradient_table(quick), accuracy_table(quick)))
