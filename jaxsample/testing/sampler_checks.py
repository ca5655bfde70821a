"""Public checks that prove a sampler against its own density; users can run them on theirs.

- `normalization(sampler)`: ∫ pdf dμ over the sampler's domain by deterministic float64 quadrature
  (panels graded toward lobes and jumps, see `jaxsample.domains`).
- `chi2_test(sampler, key)`: Pearson's chi-square goodness of fit of samples against the density.
- `inverse_error(sampler, u)` and `jacobian_error(sampler, u)`: the warp's inverse and its
  Jacobian, computed by autodiff, checked against the stated density: p(T(u)) · J(u) = 1 where
  J = sqrt(det(JᵀJ)) is the surface Jacobian of the warp.
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import gammaincc

from .._core.pytree import to_float64
from ..samplers.base import check_sampler
from .. import domains

__all__ = ["Chi2Result", "chi2_test", "normalization", "inverse_error", "jacobian_error", "pdf_float64", "to_float64"]


@functools.partial(jax.jit, static_argnums=2)
def _sample_jit(sampler, key, n):
    return sampler.sample(key, (n,))


@jax.jit
def _pdf_jit(sampler, points):
    return sampler.pdf(points)


def pdf_float64(sampler, points: np.ndarray, chunk: int = 1 << 16) -> np.ndarray:
    """The sampler's density at `points`, evaluated with every parameter promoted to float64.

    Points go through in chunks of one fixed size (the last is padded), so a check run over many
    parameter values compiles the density once.
    """
    points = np.asarray(points)
    if np.issubdtype(points.dtype, np.floating):
        points = points.astype(np.float64)
    n = len(points)
    padded = -(-n // chunk) * chunk
    if padded > n:
        points = np.concatenate([points, np.repeat(points[:1], padded - n, axis=0)])
    with jax.enable_x64(True):
        sampler64 = to_float64(sampler)
        out = [np.asarray(_pdf_jit(sampler64, jnp.asarray(points[i:i + chunk])))
               for i in range(0, padded, chunk)]
    return np.concatenate(out)[:n] if out else np.zeros(0)


def normalization(sampler) -> float:
    """∫ pdf dμ over the sampler's domain, by deterministic float64 quadrature (1 if normalised)."""
    points, weights = domains.quadrature(sampler.domain())
    return float(np.sum(weights * pdf_float64(sampler, points)))


@dataclasses.dataclass(frozen=True)
class Chi2Result:
    statistic: float
    dof: int
    p_value: float
    passed: bool
    threshold: float
    n_samples: int
    n_outside: int  # samples outside the domain or in cells of zero probability


def _pool(expected: np.ndarray, observed: np.ndarray, minimum: float = 5.0):
    """Merge cells whose expected count is below `minimum` into one pooled cell (ascending order)."""
    small = expected < minimum
    if not np.any(small):
        return expected, observed
    e_pool, o_pool = expected[small].sum(), observed[small].sum()
    e_big, o_big = expected[~small], observed[~small]
    if e_pool < minimum and len(e_big):
        # Fold the pooled remainder into the smallest regular cell.
        j = int(np.argmin(e_big))
        e_big, o_big = e_big.copy(), o_big.copy()
        e_big[j] += e_pool
        o_big[j] += o_pool
        return e_big, o_big
    return np.append(e_big, e_pool), np.append(o_big, o_pool)


def chi2_test(sampler, key, n_samples: int = 1_000_000, n_cells: int = 128, significance: float = 1e-6,
              n_tests: int = 1, n_pilot: int = 65_536) -> Chi2Result:
    """Pearson chi-square test of `sampler.sample` against `sampler.pdf`.

    Cells of roughly equal probability are placed at the quantiles of `n_pilot` pilot samples
    independent of the tested ones (so cell placement does not depend on the tested samples and the
    statistic keeps its chi-square law); expected counts are n · ∫_cell pdf by float64 quadrature
    — never by low-order rules, which reject sharp lobes wrongly. Cells expecting fewer than 5 are
    pooled. Any sample in a cell of zero probability (or outside the domain) fails the test.

    `significance` is the false-failure probability of the whole family of `n_tests` tests; each
    test uses the Šidák level 1 - (1 - significance)^(1/n_tests).
    """
    check_sampler("chi2_test", "sampler", sampler)
    # Pilot and tested samples are disjoint index ranges of one draw: `sample` is counter-based
    # (sample i depends only on the key and i), so they are independent, and one compiled program
    # draws both.
    drawn = np.asarray(_sample_jit(sampler, key, n_pilot + n_samples))
    pilot, samples = drawn[:n_pilot], drawn[n_pilot:]
    domain = sampler.domain()
    cells = domains.cells(domain, pilot, n_cells)
    mass = np.bincount(cells.cell_of_point, weights=cells.weights * pdf_float64(sampler, cells.points),
                       minlength=cells.n_cells)
    index = np.asarray(cells.assign(samples))
    inside = index >= 0
    observed = np.bincount(index[inside], minlength=cells.n_cells).astype(np.float64)
    # A cell whose probability is below 1e-12 is a region of zero density (quadrature nodes a few
    # ulps inside a support edge can pick up a sliver of mass).
    mass = np.where(mass < 1e-12, 0.0, mass)
    expected = n_samples * mass
    n_outside = int(np.sum(~inside) + observed[expected <= 0].sum())
    threshold = 1.0 - (1.0 - significance) ** (1.0 / n_tests)
    if n_outside:
        return Chi2Result(float("inf"), 0, 0.0, False, threshold, n_samples, n_outside)
    e, o = _pool(expected[expected > 0], observed[expected > 0])
    statistic = float(np.sum((o - e) ** 2 / e))
    dof = max(len(e) - 1, 1)
    with jax.enable_x64(True):
        p_value = float(gammaincc(0.5 * dof, 0.5 * statistic))
    return Chi2Result(statistic, dof, p_value, bool(p_value >= threshold), threshold, n_samples, 0)


def inverse_error(sampler, u: jax.Array) -> jax.Array:
    """max_j |inverse(warp(u))_j - u_j| per point; periodic coordinates are compared modulo 1."""
    difference = sampler.inverse(sampler.warp(u)) - u
    periodic = jnp.zeros(u.shape[-1], bool).at[jnp.asarray(sampler.periodic_dims, int)].set(True) \
        if sampler.periodic_dims else jnp.zeros(u.shape[-1], bool)
    difference = jnp.where(periodic, difference - jnp.round(difference), difference)
    return jnp.max(jnp.abs(difference), axis=-1)


def surface_jacobian(sampler, u: jax.Array) -> jax.Array:
    """sqrt(det(JᵀJ)) of the warp at each u (batch shape (N, uniform_dims)), J by `jax.jacfwd`."""

    def flat_warp(point):
        return jnp.reshape(sampler.warp(point), (-1,))

    jac = jax.vmap(jax.jacfwd(flat_warp))(u)  # (N, event_size, uniform_dims)
    gram = jnp.einsum("nij,nik->njk", jac, jac)
    return jnp.sqrt(jnp.abs(jnp.linalg.det(gram)))


def jacobian_error(sampler, u: jax.Array) -> jax.Array:
    """|pdf(warp(u)) · sqrt(det(JᵀJ)) - 1| per point: the density checked against its own warp."""
    density = sampler.pdf(sampler.warp(u))
    return jnp.abs(density * surface_jacobian(sampler, u) - 1.0)
