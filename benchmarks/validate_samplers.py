"""Normalization error and chi-square p-values of every sampler (directional, flat, 1D, discrete, mixture).

Run alone: `python benchmarks/validate_samplers.py` (about a minute on 2 cores). Normalization is
∫ pdf by deterministic float64 quadrature; chi-square uses 2·10^5 samples (10^6 for the 10^6-entry
tables) in 128 cells. Sharp cases that float32 cannot resolve (Power 1e6, thin triangles) run in
float64.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js

from jaxsample.samplers.box import UniformBox
from jaxsample.samplers.discrete import Discrete
from jaxsample.samplers.disk import UniformDisk
from jaxsample.samplers.exponential import Exponential, TruncatedExponential
from jaxsample.samplers.mixture import Mixture
from jaxsample.samplers.piecewise import PiecewiseConstant1D, PiecewiseConstant2D
from jaxsample.samplers.power import Power
from jaxsample.testing.sampler_checks import chi2_test, normalization
from jaxsample.samplers.triangle import UniformTriangle


def report(name, sampler, key, n_samples=200_000):
    r = chi2_test(sampler, key, n_samples=n_samples)
    print(f"| {name:28s} | {normalization(sampler) - 1:+.1e} | {r.p_value:7.3f} | {r.dof:3d} |")


def main():
    rng = np.random.default_rng(0)
    w = rng.random(1000)
    w[::7] = 0
    big = rng.random(10**6)
    big[rng.random(10**6) < 0.3] = 0
    keys = iter(jax.random.split(jax.random.key(0), 64))
    print("| sampler | ∫pdf - 1 | chi2 p | dof |\n|---|---|---|---|")
    f32 = {
        "UniformSphere": js.UniformSphere(), "UniformSphere rejection": js.UniformSphere(method="rejection"),
        "UniformHemisphere": js.UniformHemisphere(), "CosineHemisphere malley": js.CosineHemisphere(),
        "CosineHemisphere inversion": js.CosineHemisphere(method="inversion"),
        "PhongLobe 0": js.PhongLobe(0.0), "PhongLobe 100": js.PhongLobe(100.0), "PhongLobe 1e7": js.PhongLobe(1e7),
        "UniformCone cos 0.5": js.UniformCone(0.5), "UniformCone 1e-8 sr": js.UniformCone.from_solid_angle(1e-8),
        "VonMisesFisher 1e-6": js.VonMisesFisher(1e-6), "VonMisesFisher 89": js.VonMisesFisher(89.0),
        "VonMisesFisher 1e7": js.VonMisesFisher(1e7),
        "Oriented Phong 30 (normal -z+)": js.Oriented(js.PhongLobe(30.0), jnp.array([0.3, -0.5, -0.8])),
        "UniformDisk concentric": UniformDisk(), "UniformDisk polar": UniformDisk("polar"),
        "UniformDisk rejection": UniformDisk("rejection"),
        "UniformTriangle R²": UniformTriangle(jnp.array([0., 0.]), jnp.array([1., .2]), jnp.array([.3, 1.])),
        "UniformTriangle R³": UniformTriangle(jnp.array([0., 0., 1]), jnp.array([1., .2, 0]), jnp.array([.3, 1., 2])),
        "UniformBox": UniformBox(jnp.array([-1., 0]), jnp.array([1., 3])),
        "Exponential 1e-6": Exponential(1e-6), "Exponential 1": Exponential(1.0), "Exponential 1e6": Exponential(1e6),
        "TruncatedExp 1e-6, T=3": TruncatedExponential(1e-6, 3.0),
        "TruncatedExp 2, T=1.5": TruncatedExponential(2.0, 1.5),
        "Power 0": Power(0.0), "Power 3": Power(3.0), "Power 4 (max)": Power(4, "max"),
        "Discrete cdf 1e3 zeros": Discrete(w), "Discrete alias 1e3 zeros": Discrete(w, "alias"),
        "PiecewiseConstant1D 1e3": PiecewiseConstant1D(w),
        "PiecewiseConstant2D 32x30": PiecewiseConstant2D(w[:960].reshape(32, 30)),
        "Mixture exp(1)+exp(30)": Mixture((Exponential(1.0), Exponential(30.0)), [0.3, 0.7]),
    }
    for name, s in f32.items():
        report(name, s, next(keys))
    for name, s in {"Discrete cdf 1e6 zeros": Discrete(big), "Discrete alias 1e6 zeros": Discrete(big, "alias"),
                    "PiecewiseConstant1D 1e6": PiecewiseConstant1D(big),
                    "PiecewiseConstant2D 1000²": PiecewiseConstant2D(big.reshape(1000, 1000))}.items():
        report(name, s, next(keys), n_samples=1_000_000)
    with jax.enable_x64(True):
        f64 = {"Power 1e6 (f64)": Power(1e6),
               "thin triangle R² 1e-12 (f64)": UniformTriangle(jnp.array([0., 0.]), jnp.array([1., 1.]),
                                                              jnp.array([.5, .5 + 2e-12])),
               "thin triangle R³ 1e-12 (f64)": UniformTriangle(jnp.array([0., 0., 0.]), jnp.array([1., 1., 1.]),
                                                              jnp.array([.5, .5 + 2e-12, .5])),
               "TruncatedExp 1e6, T=2 (f64)": TruncatedExponential(1e6, 2.0)}
        for name, s in f64.items():
            report(name, s, next(keys))


if __name__ == "__main__":
    main()
