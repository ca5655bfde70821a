"""Per sampler: normalization, a Monte Carlo estimate of a known integral, and time per million.

Run alone: `python -m jaxsample.report.samplers_table`. Normalization is ∫ pdf dμ by deterministic
float64 quadrature (`jaxsample.testing.normalization`); the estimate is `jaxsample.estimate` with
n = 2^20 default ("random") uniforms; time per million samples is `sample_with_pdf` under jit at
n = 2^20, median of 5 after a warm-up.
"""

from __future__ import annotations


import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from .. import testing
from .timing import median_seconds

TRI = (jnp.array([0.0, 0.0]), jnp.array([1.0, 0.0]), jnp.array([0.0, 1.0]))


def cases():
    """(name, sampler, integrand f, exact ∫ f dμ, what the integral is)."""
    z3 = lambda w: jnp.maximum(w[2], 0.0) ** 3
    return [
        ("UniformSphere", js.UniformSphere(), lambda w: w[2] ** 2, 4 * np.pi / 3, "∫_S² cos²"),
        ("UniformSphere(rejection)", js.UniformSphere(method="rejection"), lambda w: w[2] ** 2, 4 * np.pi / 3,
         "∫_S² cos²"),
        ("UniformHemisphere", js.UniformHemisphere(), z3, np.pi / 2, "∫_H² cos³"),
        ("CosineHemisphere(malley)", js.CosineHemisphere(), z3, np.pi / 2, "∫_H² cos³"),
        ("CosineHemisphere(inversion)", js.CosineHemisphere(method="inversion"), z3, np.pi / 2, "∫_H² cos³"),
        ("PhongLobe(20)", js.PhongLobe(20.0), lambda w: jnp.maximum(w[2], 0.0) ** 20, 2 * np.pi / 21, "∫_H² cos²⁰"),
        ("PhongLobe(1e7)", js.PhongLobe(1e7),
         lambda w: jnp.exp(1e7 * jnp.log1p(-js.numerics.one_minus_cos_theta(w))), 2 * np.pi / (1e7 + 1),
         "∫_H² cos^1e7 (zero variance)"),
        ("UniformCone(0.5)", js.UniformCone(0.5), lambda w: jnp.ones(()), np.pi, "cap area 2π(1-cos θ)"),
        ("UniformCone(1e-8 sr)", js.UniformCone.from_solid_angle(1e-8), lambda w: jnp.ones(()), 1e-8, "cap area"),
        ("VonMisesFisher(1e-6)", js.VonMisesFisher(1e-6), lambda w: w[2] ** 2, 4 * np.pi / 3, "∫_S² cos²"),
        ("VonMisesFisher(10)", js.VonMisesFisher(10.0), lambda w: jnp.exp(10.0 * w[2]),
         4 * np.pi * np.sinh(10.0) / 10.0, "∫ e^{κ cos θ}"),
        ("UniformDisk(concentric)", js.UniformDisk(), lambda p: p[0] ** 2 + p[1] ** 2, np.pi / 2, "∫_disk r²"),
        ("UniformDisk(polar)", js.UniformDisk(method="polar"), lambda p: p[0] ** 2 + p[1] ** 2, np.pi / 2, "∫_disk r²"),
        ("UniformTriangle", js.UniformTriangle(*TRI), lambda p: p[0] ** 2, 1 / 12, "∫_T x²"),
        ("Exponential(2)", js.Exponential(2.0), lambda t: jnp.exp(-2.0 * t), 0.5, "∫ e^{-2t}"),
        ("TruncatedExponential(1, 2)", js.TruncatedExponential(1.0, 2.0), lambda t: jnp.ones(()), 2.0, "∫_0^2 1"),
        ("Power(3)", js.Power(3.0), lambda x: x**2, 1 / 3, "∫_0^1 x²"),
        ("Discrete(1,2,3,4)", js.Discrete(jnp.array([1.0, 2.0, 3.0, 4.0])), lambda i: (i + 1.0) ** 2,
         30.0, "Σ (i+1)²"),
        ("PiecewiseConstant1D", js.PiecewiseConstant1D(jnp.array([1.0, 3.0, 0.0, 2.0])), lambda x: x, 0.34375,
         "∫ x over the support [0, ½] ∪ [¾, 1]"),
        ("Mixture(cosine, Phong 20)", js.Mixture([js.CosineHemisphere(), js.PhongLobe(20.0)], jnp.array([0.5, 0.5])),
         z3, np.pi / 2, "∫_H² cos³"),
    ]


def time_per_million(sampler, n=1 << 20, repeats=5) -> float:
    run = jax.jit(lambda key: sampler.sample_with_pdf(key, (n,)))
    return median_seconds(run, jax.random.key(1), repeats) * 1e6 / n


def _z(mean, stderr, exact) -> float:
    # Zero-variance estimators have a stderr of ~0; the float32 rounding of the mean (a few ulps)
    # is added in quadrature so that z measures bias, not rounding.
    scale = float(np.hypot(stderr, 4 * np.finfo(np.float32).eps * abs(exact)))
    return float((mean - exact) / scale) if scale > 0 else 0.0


def sampler_table(n: int = 1 << 20, progress=print, timing_n: int = 1 << 20, only=None) -> list[dict]:
    """Rows for every case, or for the names in `only`."""
    rows = []
    chosen = [c for c in cases() if only is None or c[0] in only]
    keys = jax.random.split(jax.random.key(0), len(chosen))
    for key, (name, sampler, f, exact, what) in zip(keys, chosen):
        progress(f"[samplers] {name}")
        est = jax.jit(lambda k: js.estimate(f, sampler, k, n))(key)
        rows.append({"sampler": name, "normalization_error": testing.normalization(sampler) - 1.0,
                     "integral": what, "estimate": float(est.mean), "stderr": float(est.stderr),
                     "exact": float(exact), "z": _z(float(est.mean), float(est.stderr), float(exact)),
                     "seconds_per_million": time_per_million(sampler, n=timing_n)})
    return rows


def markdown_table(rows) -> str:
    out = ["| sampler | ∫pdf − 1 | integral | estimate ± stderr | exact | z (bias / stderr ⊕ 4 ulp) "
           "| ms per 10⁶ samples |",
           "|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['sampler']} | {r['normalization_error']:+.1e} | {r['integral']} | "
                   f"{r['estimate']:.6g} ± {r['stderr']:.2g} | {r['exact']:.6g} | {r['z']:+.2f} | "
                   f"{r['seconds_per_million'] * 1e3:.2f} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    print(markdown_table(sampler_table()))
