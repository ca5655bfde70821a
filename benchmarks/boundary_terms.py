"""The boundary-term checks of the test suite, printed with their numbers: `python benchmarks/boundary_terms.py`.

Each line: the gradient, its standard error, the reference (exact, or central differences of a
float64 quadrature written in `tests/estimators/test_boundary.py`), and z. Checkout only: it reuses
the tests' reference quadratures.
"""

import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "estimators"))
import test_boundary as t  # noqa: E402

import jaxsample as js  # noqa: E402
from jaxsample import edges  # noqa: E402


def line(name, mean, stderr, reference):
    mean, stderr, reference = (np.atleast_1d(np.asarray(v, float)) for v in (mean, stderr, reference))
    for i in range(mean.size):
        label = name if mean.size == 1 else f"{name}[{i}]"
        if stderr[i] <= 1e-6 * max(abs(reference[i]), 1e-30):
            # A zero-variance estimate (a constant jump on a circle): its stderr is float rounding.
            rel = abs(mean[i] - reference[i]) / max(abs(reference[i]), 1e-30)
            verdict = f"exact to float32 rounding (relative error {rel:.1e})"
        else:
            verdict = f"z {(mean[i] - reference[i]) / stderr[i]:+.2f}"
        print(f"{label:<58} {mean[i]:+.6f} ± {stderr[i]:.2e}   reference {reference[i]:+.6f}   {verdict}")


def main():
    g = t._cap_grad(js.UniformSphere(), lambda w: 1.0, jax.random.key(0), 1 << 12)
    line("cap, g = 1, uniform sphere, d/dalpha (2 pi sin a)", g.mean["alpha"], g.stderr["alpha"],
         t.TWO_PI * np.sin(0.7))
    line("cap, g = 1, uniform sphere, d/dbeta (0)", g.mean["beta"], g.stderr["beta"], 0.0)
    alpha, beta = 0.7, 1.2
    g = t._cap_grad(js.CosineHemisphere(), lambda w: 1.0, jax.random.key(1), 1 << 16, alpha, beta)
    exact = np.sin(alpha) * 2.0 * np.arccos(np.clip(-1.0 / (np.tan(alpha) * np.tan(beta)), -1, 1))
    fd = t._central(lambda b: t._cap_quadrature(alpha, b, lambda w: np.ones(w.shape[:-1]), hemisphere=True,
                                                nodes=64), beta)
    line("cap cut by the horizon, cosine, d/dalpha (exact)", g.mean["alpha"], g.stderr["alpha"], exact)
    line("cap cut by the horizon, cosine, d/dbeta (quadrature FD)", g.mean["beta"], g.stderr["beta"], fd)
    smooth = lambda w: 1.0 + w[..., 0] ** 2 + w[..., 2]
    cases = (("uniform", js.UniformSphere(), 0.5, 0.6, False),
             ("cosine, cut by the horizon", js.CosineHemisphere(), 0.5, 1.3, True))
    for label, sampler, alpha, beta, hemisphere in cases:
        quadrature = lambda a, b: t._cap_quadrature(a, b, smooth, hemisphere=hemisphere, nodes=64)
        references = {"alpha": t._central(lambda a: quadrature(a, beta), alpha),
                      "beta": t._central(lambda b: quadrature(alpha, b), beta)}
        keys = jax.random.split(jax.random.key(2), 2000)
        est = jax.jit(jax.vmap(lambda k: t._cap_grad(sampler, smooth, k, 1024, alpha, beta)))(keys)
        for name, reference in references.items():
            mean, err = est.mean[name], est.stderr[name]
            cover = float(jnp.mean((mean - 1.96 * err <= reference) & (reference <= mean + 1.96 * err)))
            pooled = float(jnp.mean(mean)), float(jnp.std(mean) / np.sqrt(mean.size))
            line(f"cap, smooth g, {label}, d/d{name}, 2000 keys pooled", pooled[0], pooled[1], reference)
            print(f"{'':<58} one key's stderr {float(jnp.mean(err)):.2e}; "
                  f"95 % intervals cover {cover:.2%} of 2000 keys")
    a0, b0, c0 = np.array([0.2, 0.1, 1.0]), np.array([1.0, 0.2, 0.6]), np.array([0.3, 1.0, 0.5])
    g = js.estimate_grad(
        lambda a: (edges.mask(edges.SphericalTriangle(a, b0, c0), lambda w: 1.0), js.UniformSphere()),
        jnp.asarray(a0, jnp.float32), jax.random.key(3), 1 << 16)
    reference = [t._central(lambda s: t._solid_angle(a0 + s * e, b0, c0), 0.0) for e in np.eye(3)]
    line("spherical triangle, d solid angle / d vertex a", g.mean, g.stderr, reference)
    box = js.UniformBox(jnp.array([-1.0, -1.0]), jnp.array([1.5, 1.0]))
    g = js.estimate_grad(lambda p: (edges.mask(edges.Disk(p["centre"], p["radius"]), lambda x: 1.0 + x[0]), box),
                         {"centre": jnp.array([0.3, -0.2]), "radius": jnp.float32(0.6)}, jax.random.key(5), 1 << 15)
    line("disk, d/dradius of int (1 + x) dA", g.mean["radius"], g.stderr["radius"], 2 * np.pi * 0.6 * 1.3)
    line("disk, d/dcentre", g.mean["centre"], g.stderr["centre"], [np.pi * 0.36, 0.0])
    params = {"alpha": jnp.float32(0.5), "n": jnp.float32(4.0)}
    make = lambda p: (edges.mask(edges.Cap.from_angle(jnp.array([0.2, 0.0, 1.0]), p["alpha"]), lambda w: 1.0),
                      js.PhongLobe(p["n"]))
    for mode in ("attached", "detached"):
        g = js.estimate_grad(make, params, jax.random.key(6), 1 << 16, mode=mode)
        line(f"Phong-sampled cap, {mode}, d/dn (0)", g.mean["n"], g.stderr["n"], 0.0)
        line(f"Phong-sampled cap, {mode}, d/dalpha", g.mean["alpha"], g.stderr["alpha"], t.TWO_PI * np.sin(0.5))


if __name__ == "__main__":
    main()
