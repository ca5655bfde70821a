"""Shared checks for the samplers of issue 3 (flat domains, 1D, discrete, combinators).

Statistical tests here have a stated false-failure rate: each test file runs its chi-square tests
as one family at overall significance 1e-6 (Šidák correction per test, `n_tests`).
"""

from __future__ import annotations

import functools
import itertools
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxsample.samplers.base import Sampler
from jaxsample._core.pytree import pytree_dataclass
from jaxsample.checks.sampler_checks import chi2_test

jax.config.update("jax_debug_key_reuse", True)

FAMILY_SIGNIFICANCE = 1e-6
EDGE_VALUES = (0.0, 0.5, 1.0 - 2.0 ** -24)


def edge_uniforms(dims: int, dtype=jnp.float32) -> jax.Array:
    """All combinations of {0, 0.5, 1 - 2^-24} for up to 2 dims; constant rows beyond that."""
    if dims <= 2:
        rows = list(itertools.product(EDGE_VALUES, repeat=dims))
    else:
        rows = [[v] * dims for v in EDGE_VALUES] + [[EDGE_VALUES[i % 3] for i in range(dims)]]
    return jnp.asarray(np.array(rows, dtype=np.float64), dtype)


def assert_finite(tree, what: str = "") -> None:
    for leaf in jax.tree_util.tree_leaves(tree):
        leaf = np.asarray(leaf)
        if np.issubdtype(leaf.dtype, np.floating):
            assert np.all(np.isfinite(leaf)), f"non-finite {what}: {leaf}"


def _edge_scalar(make, params, u, point):
    s = make(*params)
    x, p = s.warp_with_pdf(u)
    total = jnp.sum(p) + jnp.sum(s.pdf(x))
    if jnp.issubdtype(x.dtype, jnp.floating):
        total = total + jnp.sum(x)
    if point is not None:
        total = total + jnp.sum(s.log_pdf(point))
    return total


@functools.partial(jax.jit, static_argnums=0)
def _edge_everything(make, params, u, point):
    s = make(*params)
    x, p = s.warp_with_pdf(u)
    out = {"x": x, "p": p, "pdf": s.pdf(x), "grad_u": jax.grad(_edge_scalar, argnums=2)(make, params, u, point)}
    if params:
        out["grad_params"] = jax.grad(_edge_scalar, argnums=1)(make, params, u, point)
    if point is not None:
        out["log_pdf"] = s.log_pdf(point)
    if jnp.issubdtype(x.dtype, jnp.floating):
        out["jacrev"] = jax.vmap(jax.jacrev(s.warp))(u)
        out["jacfwd"] = jax.vmap(jax.jacfwd(s.warp))(u)
    return out


def check_finite_at_edges(make, params, dtype, point=None) -> None:
    """Values, densities and their gradients (w.r.t. parameters and u) finite at u in the edge set.

    `make(*params)` builds the sampler inside `jit` (so it must accept traced parameters; pass the
    class itself or a module-level function, so that one compilation serves every value);
    `point` (optional) is a point of the support where log_pdf must be finite too.
    """
    params = tuple(jnp.asarray(p, dtype) for p in params)
    u = edge_uniforms(make(*params).uniform_dims, dtype)
    if point is not None:
        point = jnp.asarray(point, dtype if np.issubdtype(np.asarray(point).dtype, np.floating) else jnp.int32)
    out = _edge_everything(make, params, u, point)
    for name, value in out.items():
        assert_finite(value, name)
    assert np.all(np.asarray(out["p"]) > 0), "a sample has zero density"
    assert np.all(np.asarray(out["pdf"]) > 0), f"pdf(warp(u)) = 0 at some edge u: {out['pdf']}"


def run_chi2(sampler, key, n_tests: int, n_samples: int = 100_000, n_cells: int = 64):
    return chi2_test(sampler, key, n_samples=n_samples, n_cells=n_cells,
                     significance=FAMILY_SIGNIFICANCE, n_tests=n_tests, n_pilot=20_000)


@pytree_dataclass
class WrongWarp(Sampler):
    """Samples from `impostor` but claims the density of `truth`: the chi-square test must fail."""

    truth: Sampler
    impostor: Sampler

    @property
    def uniform_dims(self):
        return self.impostor.uniform_dims

    @property
    def event_shape(self):
        return self.truth.event_shape

    def warp(self, u):
        return self.impostor.warp(u)

    def pdf(self, x):
        return self.truth.pdf(x)

    def domain(self):
        return self.truth.domain()
