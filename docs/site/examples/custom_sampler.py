"""A sampler of one's own: the triangular density on [0, 1] with its peak at c, checked with the
library's chi-square test, and a deliberately wrong twin that the same test rejects.

p(x) = 2x/c on [0, c] and 2(1 - x)/(1 - c) on [c, 1] (length measure). Its CDF is x²/c on [0, c], so
inversion gives x = sqrt(c u) for u < c and x = 1 - sqrt((1 - c)(1 - u)) above it.
"""

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import jaxsample as js
from jaxsample.domains import Interval


class Triangular(js.Sampler):
    """Triangular density on [0, 1] with its peak at `peak` (length measure), by inversion."""

    peak: jax.Array = js.parameter(0.0, 1.0, low_open=True, high_open=True)
    uniform_dims = 1

    def warp(self, u):
        c, u = self.peak, u[..., 0]
        return jnp.where(u < c, jnp.sqrt(c * u), 1.0 - jnp.sqrt((1.0 - c) * (1.0 - u)))

    def pdf(self, x):
        c = self.peak
        rising, falling = 2.0 * x / c, 2.0 * (1.0 - x) / (1.0 - c)
        return jnp.where((x >= 0) & (x <= 1), jnp.where(x < c, rising, falling), 0.0)

    def domain(self):
        return Interval(0.0, 1.0)


class WrongTriangular(Triangular):
    """The same density, with a slip in the warp's rising side: c √u where √(c u) belongs."""

    def warp(self, u):
        c, u = self.peak, u[..., 0]
        return jnp.where(u < c, c * jnp.sqrt(u), 1.0 - jnp.sqrt((1.0 - c) * (1.0 - u)))


right = js.testing.chi2_test(Triangular(0.3), jax.random.key(0), n_samples=200_000)
wrong = js.testing.chi2_test(WrongTriangular(0.3), jax.random.key(0), n_samples=200_000)
print(f"Triangular(0.3):      statistic {right.statistic:9.1f} on {right.dof} dof, p = {right.p_value:.3g}, "
      f"passed: {right.passed}")
print(f"WrongTriangular(0.3): statistic {wrong.statistic:9.1f} on {wrong.dof} dof, p = {wrong.p_value:.3g}, "
      f"passed: {wrong.passed}")
assert right.passed and not wrong.passed
print(f"normalization by quadrature: ∫ p dx = {js.testing.normalization(Triangular(0.3)):.6f}")

try:
    Triangular(1.5)
except ValueError as error:
    print("Triangular(1.5) ->", error)

# The estimators and the gradients come with the base class: E[x] = (1 + c)/3, so dE[x]/dc = 1/3.
mean_x = lambda c: js.expectation(lambda x: x, Triangular(c), jax.random.key(1), 1 << 16).mean
print("E[x] at c = 0.3:", float(mean_x(0.3)), "(exact", (1 + 0.3) / 3, ")")
print("dE[x]/dc at c = 0.3:", float(jax.grad(mean_x)(0.3)), "(exact", 1 / 3, ")")

fig, axes = plt.subplots(figsize=(6, 3.8))
grid = np.linspace(0.0, 1.0, 401)
for sampler, label in ((Triangular(0.3), "Triangular(0.3)"), (WrongTriangular(0.3), "WrongTriangular(0.3)")):
    x = np.asarray(sampler.sample(jax.random.key(2), (100_000,)))
    axes.hist(x, bins=80, density=True, histtype="step", label=f"samples of {label}")
axes.plot(grid, np.asarray(Triangular(0.3).pdf(jnp.asarray(grid))), "k-", lw=1, label="pdf")
axes.set(xlabel="x", ylabel="density", title="Samples against the declared density")
axes.legend(fontsize=8)
fig.tight_layout()
