"""d/dn of E_{Phong(n)}[cos² θ] with its standard error, for three gradient estimators.

E_{Phong(n)}[cos^m θ] = (n + 1) / (n + m + 1), so its derivative in the exponent is m / (n + m + 1)²:
2 / 64 at n = 5 for m = 2. Each estimator returns an `Estimate` of the gradient, whose stderr comes
from the per-sample gradients, streamed in the same pass.
"""

import jax
import matplotlib.pyplot as plt
import numpy as np

import jaxsample as js

M = 2.0


def make(n):
    return (lambda w: w[2] ** M), js.PhongLobe(n)


def exact(n):
    return M / (n + M + 1.0) ** 2


exponents = np.array([1.0, 2.0, 5.0, 10.0, 20.0, 50.0])
fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
fine = np.geomspace(1, 50, 200)
left.plot(fine, exact(fine), "k-", lw=1, label="closed form m/(n+m+1)²")
right.axhline(0.0, color="k", lw=1)
for shift, gradient in zip((0.96, 1.0, 1.04), ("pathwise", "score", "measure_valued")):
    keys = jax.random.split(jax.random.key(1), len(exponents))
    means, errors = [], []
    for n, key in zip(exponents, keys):
        g = js.expectation_grad(make, float(n), key, 1 << 12, gradient=gradient)
        means.append(float(g.mean))
        errors.append(float(g.stderr))
    means, errors = np.array(means), np.array(errors)
    z = (means - exact(exponents)) / errors
    print(f"{gradient:15s} at n = 5: {means[2]:.5f} ± {errors[2]:.5f} (exact {exact(5.0):.5f});  "
          f"z-scores {np.array2string(z, precision=1, suppress_small=True)}")
    left.errorbar(exponents * shift, means, yerr=1.96 * errors, fmt="o", ms=3, capsize=3, label=gradient)
    right.errorbar(exponents * shift, means / exact(exponents) - 1.0, yerr=1.96 * errors / exact(exponents),
                   fmt="o", ms=3, capsize=3, label=f"{gradient} (95 % interval)")
left.set(xscale="log", yscale="log", xlabel="exponent n", ylabel="d/dn E[cos² θ]",
         title="Gradient estimates, 4096 samples each")
right.set(xscale="log", xlabel="exponent n", ylabel="estimate / exact − 1",
          title="Relative error with 95 % error bars (1.96 stderr)")
for axes in (left, right):
    axes.legend(fontsize=8)
    axes.grid(True, which="both", alpha=0.3)
fig.tight_layout()
