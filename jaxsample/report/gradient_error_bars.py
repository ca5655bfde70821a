"""Gradients with error bars and estimates to a requested accuracy, as two report tables.

Run alone: `python -m jaxsample.report.gradient_error_bars [--quick]`.

1. d/dn E_{Phong(n)}[cos^k θ] = k/(n+k+1)² by `jaxsample.expectation_grad` with each estimator
   ("pathwise", "score", "measure_valued"): the gradient ± its reported stderr beside the exact
   value, the per-sample variance n·stderr², the time per sample, and the figure of merit
   1/(variance × time) (higher is better: the gradient accuracy bought per second).
2. Antithetic pairs against independent samples, at equal evaluations: the per-evaluation
   variance of `expectation_grad` / `estimate_grad` with `antithetic="rotate"` (a direction paired
   with the one turned by π about the lobe's axis; Zhang et al. 2021) and `"reflect"` (u, 1 − u),
   on the exponent cases of table 1 and on a rotation of a Phong 50 lobe (the glossy-BRDF
   derivative the pairs are made for: odd about the axis).
3. `jaxsample.estimate_until` at several requested relative accuracies: the achieved stderr
   relative to |mean|, the actual relative error against the exact integral, and the samples used.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample import scene

from .shade_gradients import QUADRATURE
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


def _phong_under_a_sphere(theta):
    """The scene of the shade row: Phong exp(θ), albedo 0.8, under one sphere light."""
    return (jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 1.0]), scene.Phong(jnp.exp(theta), 0.8),
            [scene.SphereLight(jnp.array([0.5, 0.2, 2.0]), 0.4, 5.0)])


def _shade_reference(theta, step=1e-5):
    """d L_o / dθ of that scene by the central difference of the float64 `reference_radiance`."""
    with jax.enable_x64(True):
        def radiance(t):
            return float(scene.reference_radiance(*_phong_under_a_sphere(jnp.asarray(t, jnp.float64)), **QUADRATURE))

        return (radiance(theta + step) - radiance(theta - step)) / (2 * step)


def _rotated_lobe(theta):
    """(f, sampler) of ∫ (1 + ω_x + ω_y²/2) ρ_θ(ω) dω, ρ_θ a Phong 50 lobe about (sin θ, 0, cos θ),
    sampled from the lobe itself; d/dθ = cos θ · 51/52 (the ω_y² term does not change with θ)."""
    axis = jnp.stack([jnp.sin(theta), 0.0, jnp.cos(theta)])
    lobe = js.Oriented(js.PhongLobe(50.0), axis)
    return (lambda w: (1.0 + w[0] + 0.5 * w[1] ** 2) * lobe.pdf(w)), lobe


def antithetic_table(quick: bool = True, progress=print) -> list[dict]:
    """Per-evaluation variance with antithetic pairs against independent samples (same n, same key).
    `quick`: the first exponent case and the detached rotation only (each program compiles anew)."""
    n_samples = 1 << (16 if quick else 20)
    cases = []
    for exponent, power in ((5.0, 2),) if quick else ((5.0, 2), (50.0, 3)):
        make = lambda p, k=power: (lambda w: w[2] ** k, js.PhongLobe(p))  # noqa: E731
        cases.append((f"d/dn E_Phong(n)[cos^k], n={exponent:g} k={power}, pathwise",
                      lambda key, a, make=make, e=exponent: js.expectation_grad(make, e, key, n_samples, antithetic=a),
                      power / (exponent + power + 1.0) ** 2))
    theta = 0.4
    for mode in ("detached",) if quick else ("detached", "attached"):
        cases.append((f"d/dθ ∫ L ρ_θ, Phong 50 lobe rotated by θ = {theta}, {mode}",
                      lambda key, a, m=mode: js.estimate_grad(_rotated_lobe, theta, key, n_samples, mode=m,
                                                              antithetic=a),
                      float(np.cos(theta)) * 51.0 / 52.0))
    # A shading point: d L_o / d log n of Phong 25 under a sphere light by BRDF sampling (the boundary
    # term inside), `scene.shade_grad` at 2^14 evaluations, against the central difference of the
    # float64 quadrature.
    cases.append(("d/d log n of shade, Phong 25 under a sphere light, BRDF sampling",
                  lambda key, a: scene.shade_grad(_phong_under_a_sphere, jnp.float32(np.log(25.0)), key, 1 << 14,
                                                  strategy="brdf", antithetic=a), _shade_reference(np.log(25.0))))
    rows = []
    for name, run, exact in cases:
        plain = None
        for antithetic in (None, "rotate", "reflect"):
            progress(f"[antithetic] {name}, {antithetic or 'independent'}")
            est = jax.jit(lambda key, run=run, a=antithetic: run(key, a))(jax.random.key(11))
            variance = float(est.variance)
            plain = variance if antithetic is None else plain
            rows.append({"case": name, "pairs": antithetic or "none", "n": int(est.n), "gradient": float(est.mean),
                         "stderr": float(est.stderr), "exact": exact, "variance_per_evaluation": variance,
                         "variance_ratio": variance / plain})
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


def markdown(gradient_rows: list[dict], accuracy_rows: list[dict], antithetic_rows=()) -> str:
    out = ["| n, k | estimator | gradient ± stderr | exact | z | per-sample variance | ns/sample "
           "| 1/(variance × time) |",
           "|---|---|---|---|---|---|---|---|"]
    for r in gradient_rows:
        out.append(f"| {r['exponent']:g}, {r['power']} | {r['estimator']} | {r['gradient']:.5g} ± {r['stderr']:.2g} | "
                   f"{r['exact']:.5g} | {r['z']:+.2f} | {r['per_sample_variance']:.3g} | {r['ns_per_sample']:.1f} | "
                   f"{r['merit']:.3g} |")
    if antithetic_rows:
        out += ["", "| gradient | pairs | gradient ± stderr | exact | variance per evaluation | × independent |",
                "|---|---|---|---|---|---|"]
        for r in antithetic_rows:
            out.append(f"| {r['case']} | {r['pairs']} | {r['gradient']:.5g} ± {r['stderr']:.2g} | {r['exact']:.5g} | "
                       f"{r['variance_per_evaluation']:.3g} | {r['variance_ratio']:.3g} |")
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
    print(markdown(gradient_table(quick), accuracy_table(quick), antithetic_table(quick)))
