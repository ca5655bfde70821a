"""The result of every estimator: `Estimate`, a pytree of the mean, its standard error and diagnostics."""

from __future__ import annotations

import math

import jax

from .._core.pytree import pytree_dataclass

_NORMAL_QUANTILE_975 = 1.959963984540054


@pytree_dataclass(static=("n", "replicates"))
class Estimate:
    """A Monte Carlo estimate; a pytree (mean, stderr and diagnostics are leaves).

    - `mean`: the estimate of the integral (shape of f's value).
    - `stderr`: its standard error (see the module docstring for how replicates are used).
    - `variance`: the sample variance of the per-sample values Y = f/p (for Sobol' and stratified
      points this is *not* the estimator's variance times n; use `stderr`).
    - `max_abs`: the largest |Y| seen, a check for heavy tails (a few samples dominating).
    - `ess`: effective sample size (Σ|Y|)² / Σ Y², n for constant Y; small values warn that the
      variance, and so the stderr, may be unreliable (Kong 1992; Owen 2013, ch. 9).
    - `n`, `replicates`: static.

    If some Y = f/p is not finite (f returned ±inf or NaN, or a float sum overflowed), `mean` is
    what IEEE arithmetic gives for the plain sum (±inf; NaN for a NaN or for infinities of both
    signs), `stderr` and `variance` are inf, `ess` is 0 and `max_abs` is inf or NaN: under jit the
    estimator cannot raise, so test `jnp.isfinite(est.stderr)`.
    """

    mean: jax.Array
    stderr: jax.Array
    variance: jax.Array
    max_abs: jax.Array
    ess: jax.Array
    n: int = 0
    replicates: int = 1

    def interval(self, level: float = 0.95) -> tuple[jax.Array, jax.Array]:
        """Normal-approximation interval mean ± z stderr (z = 1.96 for 95%)."""
        return normal_interval(self.mean, self.stderr, level)

    def per_evaluation(self, n: int) -> "Estimate":
        """This estimate of n/2 pairs (antithetic pairs, one BRDF and one light sample) restated at
        its cost of n evaluations: `variance` per evaluation (stderr² n) and `ess` counted in
        evaluations, so that strategies compare at equal cost by `variance`."""
        return Estimate(mean=self.mean, stderr=self.stderr, variance=self.stderr * self.stderr * n,
                        max_abs=self.max_abs, ess=2.0 * self.ess, n=n, replicates=self.replicates)

    def chebyshev_interval(self, level: float = 0.95) -> tuple[jax.Array, jax.Array]:
        """Distribution-free interval mean ± k stderr with k = 1/sqrt(1 - level) (4.47 for 95%).

        By Chebyshev's inequality P(|mean - I| >= k σ) <= 1/k² for *any* distribution with finite
        variance σ² of the mean; it is exact given σ, approximate when σ is the estimated stderr.
        """
        k = 1.0 / math.sqrt(1.0 - level)
        return self.mean - k * self.stderr, self.mean + k * self.stderr


def normal_interval(mean, stderr, level: float = 0.95):
    """mean ± z stderr with z the normal quantile of (1 + level)/2 (1.96 for 95 %)."""
    z = _normal_quantile(0.5 + 0.5 * level)
    return mean - z * stderr, mean + z * stderr


def _normal_quantile(p: float) -> float:
    if abs(p - 0.975) < 1e-12:
        return _NORMAL_QUANTILE_975
    # Acklam-free: bisection on erf, only at trace time (p is a Python float).
    lo, hi = -10.0, 10.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if 0.5 * (1.0 + math.erf(mid / math.sqrt(2.0))) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
