"""The result of every estimator: `Estimate`, a pytree of the mean, its standard error and diagnostics.

`Statistics` holds the seven fields shaped like f's value that every streamed estimate carries;
`Estimate` and `estimate_until`'s `EstimateUntil` add their counts to it. `warn_if_unreliable`,
registered with the compiled entry (`jaxsample._core.entry`), warns about an unreliable one
returned by an eager call.
"""

from __future__ import annotations

import math
import warnings

import jax

from .._core.entry import check_results_with
from .._core.pytree import Pytree, static_field
from .diagnostics import UnreliableEstimateWarning, problems, verdict

_NORMAL_QUANTILE_975 = 1.959963984540054


class Statistics(Pytree):
    """The statistics of a stream of values Y = f/p, each shaped like f's value (`Estimate` says
    what each is); the base of `Estimate` and `EstimateUntil`."""

    mean: jax.Array
    stderr: jax.Array
    variance: jax.Array
    max_abs: jax.Array
    ess: jax.Array
    khat: jax.Array
    nonzero: jax.Array


class Estimate(Statistics):
    """A Monte Carlo estimate; a pytree (mean, stderr and diagnostics are leaves).

    - `mean`: the estimate of the integral (shape of f's value).
    - `stderr`: its standard error (see the module docstring for how replicates are used).
    - `variance`: the sample variance of the per-sample values Y = f/p (for Sobol' and stratified
      points this is *not* the estimator's variance times n; use `stderr`).
    - `max_abs`: the largest |Y| seen, a check for heavy tails (a few samples dominating).
    - `ess`: effective sample size (Σ|Y|)² / Σ Y², n for constant Y; small values warn that the
      variance, and so the stderr, may be unreliable (Kong 1992; Owen 2013, ch. 9).
    - `khat`: the Pareto k-hat of the tail of |Y| (`diagnostics.py`): >= 0.5, infinite variance
      (the stderr means nothing); >= 0.7, the mean itself is unreliable; -inf for a tail with no
      spread, NaN when n is too small to fit one.
    - `nonzero`: the fraction of the n values Y that are nonzero.
    - `n`, `replicates`, `gradient` (True for a gradient estimate): static.

    `reliable` is the verdict (finite, at least M + 1 nonzero Y, k-hat below 0.5; for a gradient, whose
    components are often exactly 0 for a parameter f does not depend on, an all-zero component is
    not a failure) and `diagnostics` the
    numbers behind it. The stderr is never below the float rounding of the values averaged (two
    ulps of mean |Y|), so a zero-variance estimate reports an error bar it can honour.

    If some Y = f/p is not finite (f returned ±inf or NaN, or a float sum overflowed), `mean` is
    what IEEE arithmetic gives for the plain sum (±inf; NaN for a NaN or for infinities of both
    signs), `stderr` and `variance` are inf, `ess` is 0 and `max_abs` is inf or NaN: under jit the
    estimator cannot raise, so test `jnp.isfinite(est.stderr)`.
    """

    n: int = static_field(default=0)
    replicates: int = static_field(default=1)
    gradient: bool = static_field(default=False)

    @property
    def reliable(self) -> jax.Array:
        """Whether mean ± stderr can be trusted: finite, enough nonzero Y, Pareto k-hat below 0.5
        (a boolean array shaped like `mean`; see `jaxsample.estimators.diagnostics`)."""
        return jax.tree_util.tree_map(lambda m, s, k, z: verdict(m, s, k, z, self.n, self.gradient),
                                      self.mean, self.stderr, self.khat, self.nonzero)

    @property
    def diagnostics(self) -> dict:
        """The numbers behind `reliable`: `khat`, `nonzero` (fraction of nonzero Y), `ess_fraction`
        (ess / n) and `reliable` itself."""
        return {"khat": self.khat, "nonzero": self.nonzero,
                "ess_fraction": jax.tree_util.tree_map(lambda e: e / float(self.n), self.ess),
                "reliable": self.reliable}

    def interval(self, level: float = 0.95) -> tuple[jax.Array, jax.Array]:
        """Interval mean ± q stderr: q the normal quantile for independent points (1.96 for 95 %),
        Student's t with R - 1 degrees of freedom for R > 1 replicates (2.36 at R = 8, 2.13 at
        R = 16): the stderr is then the spread of R replicate means."""
        return interval(self.mean, self.stderr, level, self.replicates)

    def per_evaluation(self, n: int) -> "Estimate":
        """This estimate of groups of evaluations (n/2 antithetic pairs, or one BRDF and one light
        sample; n/4 antithetic pairs of those) restated at its cost of n evaluations: `variance` per
        evaluation (stderr² n) and `ess` counted in evaluations, so that strategies compare at equal
        cost by `variance`."""
        return Estimate(mean=self.mean, stderr=self.stderr, variance=self.stderr * self.stderr * n,
                        max_abs=self.max_abs, ess=(n / self.n) * self.ess, khat=self.khat, nonzero=self.nonzero,
                        n=n, replicates=self.replicates, gradient=self.gradient)

    def __repr__(self) -> str:
        return (f"Estimate(mean={self.mean}, stderr={self.stderr}, n={self.n}, replicates={self.replicates}, "
                f"reliable={self.reliable}, khat={self.khat}, nonzero={self.nonzero}, ess={self.ess})")

    def chebyshev_interval(self, level: float = 0.95) -> tuple[jax.Array, jax.Array]:
        """Distribution-free interval mean ± k stderr with k = 1/sqrt(1 - level) (4.47 for 95%).

        By Chebyshev's inequality P(|mean - I| >= k σ) <= 1/k² for *any* distribution with finite
        variance σ² of the mean; it is exact given σ, approximate when σ is the estimated stderr.
        """
        k = 1.0 / math.sqrt(1.0 - level)
        return self.mean - k * self.stderr, self.mean + k * self.stderr


@check_results_with
def warn_if_unreliable(result, owner: str) -> None:
    """Emit one `UnreliableEstimateWarning` per unreliable estimate in `result` (an estimate or a
    pytree of them), when its values are concrete (an eager call); nothing under a transformation."""
    found = [leaf for leaf in jax.tree_util.tree_leaves(result, is_leaf=lambda x: isinstance(x, Statistics))
             if isinstance(leaf, Statistics)]
    for est in found:
        if any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(est)):
            return
        reasons = problems(est.mean, est.stderr, est.khat, est.nonzero, est.n, getattr(est, "gradient", False))
        if reasons:
            warnings.warn(f"{owner}: unreliable estimate: " + "; ".join(reasons) + " (see est.diagnostics)",
                          UnreliableEstimateWarning, stacklevel=3)


def normal_interval(mean, stderr, level: float = 0.95):
    """mean ± z stderr with z the normal quantile of (1 + level)/2 (1.96 for 95 %)."""
    z = _normal_quantile(0.5 + 0.5 * level)
    return mean - z * stderr, mean + z * stderr


def interval(mean, stderr, level: float = 0.95, replicates: int = 1):
    """mean ± q stderr: q the normal quantile of (1 + level)/2 for replicates = 1, Student's t
    quantile with replicates - 1 degrees of freedom otherwise."""
    q = interval_quantile(level, replicates)
    return mean - q * stderr, mean + q * stderr


def interval_quantile(level: float, replicates: int = 1) -> float:
    """The two-sided multiplier of the stderr for `level`: normal for one replicate, t_{R-1} for R."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"interval: parameter 'level' must be in (0, 1); got {level!r}")
    if replicates <= 1:
        return _normal_quantile(0.5 + 0.5 * level)
    return student_t_quantile(0.5 + 0.5 * level, replicates - 1)


def _t_central(t: float, dof: int) -> float:
    """P(|T| < t) for Student's t with an integer number of degrees of freedom, in closed form
    (Abramowitz and Stegun 26.7.3 and 26.7.4): with θ = atan(t / √ν), c = cos θ,
    ν odd: (2/π)(θ + sin θ (c + (2/3) c³ + ... + (2·4···(ν-3))/(1·3···(ν-2)) c^(ν-2))),
    ν even: sin θ (1 + (1/2) c² + (1·3)/(2·4) c⁴ + ... + (1·3···(ν-3))/(2·4···(ν-2)) c^(ν-2))."""
    theta = math.atan(t / math.sqrt(dof))
    s, c = math.sin(theta), math.cos(theta)
    if dof % 2:
        if dof == 1:
            return 2.0 * theta / math.pi
        term, total = c, c
        for k in range(3, dof - 1, 2):    # term_k = term_{k-2} (k - 1)/k c²
            term *= (k - 1) / k * c * c
            total += term
        return 2.0 / math.pi * (theta + s * total)
    term, total = 1.0, 1.0
    for k in range(2, dof - 1, 2):        # term_k = term_{k-2} (k - 1)/k c²
        term *= (k - 1) / k * c * c
        total += term
    return s * total


def student_t_quantile(p: float, dof: int) -> float:
    """The p-quantile (p > 1/2) of Student's t with `dof` degrees of freedom, by bisection on the
    closed-form CDF at trace time (a Python float)."""
    target = 2.0 * p - 1.0
    lo, hi = 0.0, 1.0
    while _t_central(hi, dof) < target:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if _t_central(mid, dof) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


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
