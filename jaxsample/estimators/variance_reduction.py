"""Variance reduction beyond the plain mean (multiple importance sampling is in `mis.py`).

All of them run on the streaming engine (`engine.py`) (constant memory, the same
counter-based uniform sources, chunking-invariant) and return an `Estimate`.

- `estimate_ratio`: the self-normalized (ratio) estimator ∫f / ∫h; biased, bias O(1/n).
- `estimate_antithetic`: antithetic pairs u, 1 - u (Hammersley & Morton 1956).
- `estimate_control_variate`: f - c (g - G) with ∫g = G known and c estimated from the same
  samples (Owen 2013, ch. 8.9); the fitted coefficient makes it biased by O(1/n).

Integrands follow the rule of `integrand.py`: f may return a pytree of real or complex arrays, and
the result is the same pytree of `Estimate`s. For the ratio and the control variate each real
component of f (a complex leaf's real and imaginary parts separately) gets its own ratio or its
own coefficient, against one real scalar h or g (a normalizer, a control with a known integral:
a pytree or complex h or g is a TypeError).
"""

from __future__ import annotations

import dataclasses

from typing import Callable

import jax
import jax.numpy as jnp

from .._core.entry import compiled_entry
from .._core.counts import check_count
from ..samplers.base import check_unbatched, check_uniforms, checked
from .._core.params import resolve_float_dtype
from .engine import run_stream, stderr_floor
from .integrand import integrand_layout, require_real_scalar
from .plain import _detach, broadcast_like, check_mode, packed_values
from .result import Estimate
from .boundary import refuse_edges
from .._core.numerics import safe_div, safe_sqrt

__all__ = ["estimate_ratio", "estimate_antithetic", "estimate_control_variate"]


def _paired_moments(f, h, sampler, key, n, mode, uniforms, chunk_size, dtype, mesh, owner, h_name, why):
    """Estimate of (Y, Z, Y + Z) stacked on a new axis 0 of the value, Y = f/p packed by the
    integrand rule, Z = h/p (a real scalar, broadcast to Y's shape): the diagonal variances give
    Cov(Y_k, Z) for every component k; returns (est, var_y, var_z, cov, f's layout)."""
    check_mode(owner, mode)
    check_unbatched(sampler, owner)
    sampler = checked(sampler)
    check_uniforms(sampler, uniforms, owner)
    dtype = resolve_float_dtype(owner, dtype)
    layout = integrand_layout(f, sampler, dtype, owner)
    require_real_scalar(integrand_layout(h, sampler, dtype, owner), owner, h_name, why)

    def values_fn(u):
        x, pdf = sampler.warp_with_pdf(u)
        x, pdf = _detach(mode, x, pdf)
        y = layout.pack(jax.vmap(f)(x), u.dtype)
        y = safe_div(y, broadcast_like(pdf, y))
        z = safe_div(jax.vmap(h)(x), pdf)
        z = jnp.broadcast_to(broadcast_like(z, y), y.shape)
        return jnp.stack([y, z, y + z], axis=1)

    est = run_stream(values_fn, sampler.uniform_dims, key, n, uniforms=uniforms, mesh=mesh,
                     chunk_size=chunk_size, out_shape=(3,) + layout.out_shape, dtype=dtype, owner=owner)
    var_y, var_z, var_sum = est.variance[0], est.variance[1], est.variance[2]
    return est, var_y, var_z, 0.5 * (var_sum - var_y - var_z), layout


@compiled_entry("f", "h", "n", "mode", "uniforms", "chunk_size", "dtype", "mesh")
def estimate_ratio(f: Callable, h: Callable, sampler, key: jax.Array, n: int, *,
                   mode: str = "attached", uniforms="random", chunk_size=None, dtype=None,
                   mesh=None) -> Estimate:
    """Self-normalized estimate of ∫f / ∫h: (Σ f/p) / (Σ h/p) over the same n samples.

    With h = π̃ an unnormalized density and f = φ π̃ this is self-normalized importance sampling
    of E_π[φ] (Owen 2013, ch. 9.2). It is biased, with bias
    (R Var Z - Cov(Y, Z)) / (n E[Z]²) + O(n^-2) (delta method; Owen 2013, ch. 9.2), and
    consistent. stderr is the delta-method one, sqrt(Var(Y - R Z) / n) / |mean Z|. f may return a
    pytree of real or complex arrays (a ratio per real component: E_π of several quantities at
    once); h returns a real scalar. Use the "random" source (the delta-method variance assumes
    independent points). `mode`, `uniforms`, `chunk_size`, `dtype`, `mesh`: as in `jaxsample.estimate`.
    """
    refuse_edges("estimate_ratio", f, h)
    est, var_y, var_z, cov, layout = _paired_moments(
        f, h, sampler, key, n, mode, uniforms, chunk_size, dtype, mesh, "estimate_ratio", "h",
        "the denominator ∫h is one number")
    mean_y, mean_z = est.mean[0], est.mean[1]
    ratio = safe_div(mean_y, mean_z)
    linear_var = jnp.maximum(var_y - 2.0 * ratio * cov + ratio * ratio * var_z, 0.0)
    variance = safe_div(linear_var, mean_z * mean_z)
    return layout.unpack_result(dataclasses.replace(
        jax.tree_util.tree_map(lambda leaf: leaf[0], est), mean=ratio, variance=variance, khat=_worst_tail(est),
        stderr=jnp.maximum(safe_sqrt(variance / float(est.n)), stderr_floor(jnp.abs(ratio), 1.0))))


def _worst_tail(est):
    """The heavier of the two streams' tails (Y = f/p and Z): either makes the combination unreliable."""
    return jnp.fmax(est.khat[0], est.khat[1])


@compiled_entry("f", "n", "mode", "uniforms", "chunk_size", "dtype", "mesh")
def estimate_antithetic(f: Callable, sampler, key: jax.Array, n: int, *, mode: str = "attached",
                        uniforms="random", chunk_size=None, dtype=None, mesh=None) -> Estimate:
    """∫ f dμ from n/2 antithetic pairs: Y(u) and Y(1 - u) averaged per pair (n evaluations of f).

    Unbiased (1 - u is uniform too; the sources' grids are symmetric, so 1 - u stays in (0, 1)).
    It reduces variance when Y is monotone in u along the reflection: Var = (σ²/n)(1 + ρ) with ρ
    the correlation of Y(u) and Y(1 - u). It can also raise it (ρ > 0): e.g. the concentric-map
    CosineHemisphere maps 1 - u to the reflected point, so a rotationally symmetric f gets ρ = 1.
    The stderr comes from the pair means (independent); `n` must be even (any concrete integer).
    f may return a pytree of real or complex arrays (the same pytree of `Estimate`s comes back).
    `mode`, `uniforms`, `chunk_size`, `dtype`, `mesh`: as in `jaxsample.estimate`.
    """
    check_mode("estimate_antithetic", mode)
    check_unbatched(sampler, "estimate_antithetic")
    sampler = checked(sampler)
    check_uniforms(sampler, uniforms, "estimate_antithetic", antithetic=True)
    n = check_count("estimate_antithetic", "n", n, minimum=2)
    if n % 2:
        raise ValueError(f"estimate_antithetic: parameter 'n' must be even (n/2 antithetic pairs); got {n}")
    dtype = resolve_float_dtype("estimate_antithetic", dtype)
    layout = integrand_layout(f, sampler, dtype, "estimate_antithetic")
    return layout.unpack_result(_antithetic(f, sampler, key, n, mode, uniforms, chunk_size, dtype, mesh, layout))


def _antithetic(f, sampler, key, n, mode, uniforms, chunk_size, dtype, mesh, layout) -> Estimate:
    """`estimate_antithetic` on f's packed values."""

    def one(u):
        return packed_values(f, sampler, u, mode)[0]

    est = run_stream(lambda u: 0.5 * (one(u) + one(1.0 - u)), sampler.uniform_dims, key, n // 2,
                     uniforms=uniforms, chunk_size=chunk_size, dtype=dtype, mesh=mesh,
                     out_shape=layout.out_shape, owner="estimate_antithetic")
    return est.per_evaluation(n)


@compiled_entry("f", "g", "n", "mode", "uniforms", "chunk_size", "dtype", "mesh")
def estimate_control_variate(f: Callable, g: Callable, g_integral, sampler, key: jax.Array, n: int,
                             *, mode: str = "attached", uniforms="random", chunk_size=None,
                             dtype=None, mesh=None) -> Estimate:
    """∫ f dμ as mean(Y) - c (mean(Z) - G), Y = f/p, Z = g/p, G = ∫ g dμ known exactly.

    c = Cov(Y, Z) / Var(Z) is the variance-minimizing coefficient, estimated from the same samples
    (so the estimate carries an O(1/n) bias); the residual variance is Var(Y)(1 - ρ²), and the
    stderr is sqrt((Var Y - Cov²/Var Z) / n). f may return a pytree of real or complex arrays (a
    coefficient per real component); g returns a real scalar, with the real `g_integral`. Use the
    "random" source. `mode`, `uniforms`, `chunk_size`, `dtype`, `mesh`: as in `jaxsample.estimate`.
    """
    refuse_edges("estimate_control_variate", f, g)
    est, var_y, var_z, cov, layout = _paired_moments(
        f, g, sampler, key, n, mode, uniforms, chunk_size, dtype, mesh, "estimate_control_variate", "g",
        "a control variate is one real function with a known integral")
    coefficient = safe_div(cov, var_z)
    mean = est.mean[0] - coefficient * (est.mean[1] - g_integral)
    variance = jnp.maximum(var_y - coefficient * cov, 0.0)
    return layout.unpack_result(dataclasses.replace(
        jax.tree_util.tree_map(lambda leaf: leaf[0], est), mean=mean, variance=variance, khat=_worst_tail(est),
        stderr=jnp.maximum(safe_sqrt(variance / float(est.n)), stderr_floor(jnp.abs(mean), 1.0))))
