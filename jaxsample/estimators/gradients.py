"""Layer 5: gradients of expectations with respect to the parameters of the sampling distribution.

Two different questions share the words "gradient of a Monte Carlo estimate" (Mohamed et al.
2020; Zeltner et al. 2021), and this module keeps them apart:

1. A fixed integral I = ∫ f dμ, estimated as the mean of f(x)/p_θ(x): θ only chooses where the
   samples go, so dI/dθ = 0 unless f itself depends on θ. That is `jaxsample.estimate` with its
   `mode`: "attached" differentiates f(T(u; θ))/p(T(u; θ); θ) through the warp T and the density
   (unbiased, noisy); "detached" holds the sample and its density constant together, so only f
   carries a derivative (every per-sample gradient of a θ-free f is exactly 0). Holding only one
   of them constant is biased (docs/reference.md gives the bias for the Phong lobe), so the choice is
   made in one place (`integrand_values`) and applied to sample, density and MIS weights at once.

2. An expectation E_{p_θ}[g] = ∫ g p_θ dμ, whose value itself moves with θ. That is
   `expectation(g, sampler, key, n, gradient=...)`:

   - "pathwise" (reparameterisation): x = T(u; θ), and the derivative flows through the warp,
     ∇θ E[g] = E[∇x g · ∂θ T]. Low variance; needs g differentiable and T continuous in θ
     wherever the samples land (not true of a `Mixture`'s component choice or a rejection step:
     there the pathwise derivative misses the jumps and is biased; use "score").
   - "score" (likelihood ratio, REINFORCE): ∇θ E[g] = E[(g(x) - b) ∇θ log p_θ(x)] for a sample x
     held constant, with a baseline b that does not depend on x (a constant, or the leave-one-out
     mean of the other samples). Needs only log p differentiable in θ; g may be a black box.

   - "measure_valued" (Mohamed et al. 2020, section 6), for a sampler that defines
     `measure_valued_terms`, such as the Phong lobe's exponent: the
     derivative of the density in n is (1/m)(p_n - q_n), q_n the density of cos θ as the product of
     two draws, so ∇n E[g] = (1/m)(E_{p_n}[g] - E_{q_n}[g]): g need not be differentiable and no
     density is differentiated (`PhongLobe.measure_valued_pair`; unbiased, samples held constant).

   All are written as *surrogates* whose value is the plain Monte Carlo mean of g and whose
   derivative is the chosen estimator, so one `jax.grad` gives the gradient and the returned
   `Estimate` still reports E[g] with its standard error. For the score function the per-sample
   surrogate is g(x̄) + (log p(x̄) - sg(log p(x̄))) · sg(g(x̄) - b), x̄ = sg(T(u; θ)), where sg is
   `stop_gradient`: the second term is exactly 0 in value.

g follows the integrand rule of `integrand.py`: a pytree of real or complex arrays gives the same
pytree of `Estimate`s (each real component's surrogate is the one above, so a complex leaf's real
and imaginary parts get their own gradients: differentiate `est.mean.real`, `est.mean.imag`).

The returned stderr is the standard error of the *value*. For the gradient's own variance, take
per-sample gradients: `jax.vmap(jax.grad(...))` over rows of u of `integrand_values` or
`expectation_values` (below), whose mean is the gradient of the estimate.
"""

from __future__ import annotations

import dataclasses

from typing import Any, Callable

import jax
import jax.numpy as jnp

from .._core.entry import compiled_entry
from ..samplers.base import check_uniforms, checked
from .._core.params import check_choice, resolve_float_dtype
from .engine import run_stream
from .integrand import IntegrandLayout, integrand_layout
from .plain import broadcast_like, integrand_values, over_batch
from .result import Estimate
from .boundary import boundary_dims, boundary_values

__all__ = ["expectation", "expectation_values", "integrand_values"]

_GRADIENTS = ("pathwise", "score", "measure_valued")


def _detached_log_pdf(sampler, x):
    """log p_θ(x̄) at a constant sample, finite everywhere (0 where the density is 0).

    A sample can land a rounding error outside the support (log p = -inf); there the score term
    would be -inf - (-inf) = NaN, so such lanes contribute no score (their derivative is already 0).
    """
    log_p = sampler.log_pdf(x)
    finite = jnp.isfinite(log_p)
    return jnp.where(finite, jnp.where(finite, log_p, 0.0), 0.0)


def score_terms(g, sampler, u):
    """(g(x̄), Δ) for the score function at the samples x̄ = sg(T(u; θ)) of a (count, dims) block:
    Δ = log p(x̄) - sg(log p(x̄)), of value 0 and derivative ∇θ log p(x̄), shaped to scale g's
    values. Every score-function surrogate is g(x̄) + Δ · sg(c) for a coefficient c: (g - b) with a
    constant baseline, n/(n-1) (g - ḡ) with the leave-one-out one."""
    x = jax.lax.stop_gradient(sampler.warp(u))
    gx = jax.vmap(g)(x)
    log_p = _detached_log_pdf(sampler, x)
    return gx, broadcast_like(log_p - jax.lax.stop_gradient(log_p), gx)


def score_surrogate(gx, score, coefficient):
    """g(x̄) + Δ · sg(coefficient): the value g(x̄), the derivative ∇g(x̄) + coefficient ∇ log p(x̄)
    (`score_terms` gives g(x̄) and Δ)."""
    return gx + score * jax.lax.stop_gradient(coefficient)


def uniform_dims(sampler, gradient: str) -> int:
    """Uniforms per sample for `gradient`: the sampler's, one more for "measure_valued"."""
    return sampler.uniform_dims + (1 if gradient == "measure_valued" else 0)


def _measure_valued_values(g, sampler, u):
    """Surrogate g(x̄) + (θ - sg(θ)) · sg(c (g(x̄) - g(x̄'))): its value is g(x̄), its derivative
    in the sampler's parameter θ the measure-valued estimator, and g's own parameters differentiate
    through g(x̄) (samples x̄, x̄' held constant). θ, x̄, x̄' and c are the sampler's
    (`Sampler.measure_valued_terms`; a sampler without a decomposition raises there)."""
    parameter, x, x_product, c = sampler.measure_valued_terms(u)
    x, x_product = jax.lax.stop_gradient((x, x_product))
    gx, gx_product = jax.vmap(g)(x), jax.vmap(g)(x_product)
    parameter = jnp.asarray(parameter, gx.dtype)
    tangent = parameter - jax.lax.stop_gradient(parameter)
    return gx + tangent * jax.lax.stop_gradient(jnp.asarray(c, gx.dtype) * (gx - gx_product))


class _Plain:
    """g without its declared discontinuities (the interior part of an estimator)."""

    def __init__(self, g):
        self.g = g

    def __call__(self, x):
        return self.g(x)


def _packed(g, layout: IntegrandLayout, dtype):
    """g with its value packed by the integrand rule: one real vector per sample (g itself for one
    real array)."""
    if layout.plain:
        return g
    if boundary_dims(g):
        raise TypeError("expectation: an integrand with declared discontinuities (jaxsample.edges.mask) "
                        "must return one real array")
    return lambda x: layout.pack(jax.tree_util.tree_map(lambda v: jnp.asarray(v)[None], g(x)), dtype)[0]


def expectation_values(g: Callable[[jax.Array], jax.Array], sampler, u: jax.Array, *,
                       gradient: str = "pathwise", baseline: Any = None):
    """Per-sample surrogate values for E_{p_θ}[g] from a (count, uniform_dims) block of uniforms.

    The value of each row is g(x_i); its derivative is the chosen per-sample gradient estimator:
    ∇(g ∘ T) for "pathwise", ∇g(x̄) + (g(x̄) - b) ∇ log p(x̄) for "score" with a constant
    baseline b (`baseline`, default 0, broadcast against g's value and held constant; for a
    pytree-valued g, a matching pytree or one array broadcast to every leaf). The leave-one-out
    baseline couples samples, so it exists only in `expectation`. A pytree-valued g gives the
    same pytree of (count, *leaf shape) arrays.
    """
    check_choice("expectation", "gradient", gradient, _GRADIENTS)
    if gradient != "score" and baseline is not None:
        raise ValueError("expectation: parameter 'baseline' applies to gradient='score' only")
    if isinstance(baseline, str):
        raise ValueError("expectation_values: a string 'baseline' (leave_one_out) needs the whole "
                         "sample; use expectation")
    layout = integrand_layout(g, sampler, u.dtype, "expectation_values")
    if baseline is not None:
        baseline = layout.pack_constant(baseline, u.dtype)
    values = _surrogate_values(_packed(g, layout, u.dtype), sampler, u, gradient, baseline)
    return layout.unpack(values)


def _surrogate_values(g, sampler, u, gradient, baseline):
    """`expectation_values` for a g whose value is one real array (packed).

    A g with declared discontinuities (`jaxsample.edges.mask`) reads boundary uniforms from the
    last `boundary_dims(g)` columns and adds the boundary term of ∫ g p dμ (`boundary.py`): the
    pathwise samples move with θ, the score and measure-valued ones are held constant.
    """
    extra = boundary_dims(g)
    if extra:
        interior = _surrogate_values(_Plain(g), sampler, u[:, :-extra], gradient, baseline)
        edge = boundary_values(g, sampler, u[:, -extra:], moving=gradient == "pathwise", weight_by_density=True,
                               owner="expectation", remedy="use gradient='score'")
        return interior + edge
    if gradient == "pathwise":
        return jax.vmap(g)(sampler.warp(u))
    if gradient == "measure_valued":
        return _measure_valued_values(g, sampler, u)
    gx, score = score_terms(g, sampler, u)
    return score_surrogate(gx, score, gx if baseline is None else gx - baseline)


@compiled_entry("g", "n", "gradient", "uniforms", "mesh", "chunk_size", "dtype")
def expectation(g: Callable[[jax.Array], jax.Array], sampler, key: jax.Array, n: int, *,
                gradient: str = "pathwise", baseline: Any = None, uniforms="random", mesh=None,
                chunk_size: int | None = None, dtype=None) -> Estimate:
    """E_{p_θ}[g] = ∫ g p_θ dμ as the mean of g(x_i), x_i ~ sampler, with a chosen gradient.

    Args:
      g: maps ONE sample (shape `sampler.event_shape`) to a value: an array of any fixed shape or
        a pytree of real or complex arrays (the integrand rule of `integrand.py`); vmapped. It may
        close over θ too: both estimators then add its explicit derivative.
      sampler: any `jaxsample.Sampler`; its parameters are the θ that `jax.grad` sees.
      key, n, uniforms, mesh, chunk_size, dtype: as in `jaxsample.estimate`.
      gradient: "pathwise" (default; through the warp), "score" (through log p of a detached
        sample) or "measure_valued" (samplers that define `measure_valued_terms`, PhongLobe's
        exponent among them: the derivative as a scaled difference of two densities; one more
        uniform per sample).
        All have the value mean(g); see the module docstring for when each is unbiased.
      baseline: score only. None (no baseline), a constant (array broadcastable to g's value, or
        for a pytree-valued g a matching pytree; held constant: a baseline that depends on θ is
        stopped) or "leave_one_out": sample i uses
        the mean of the other n - 1 samples, b_i = (S - g_i)/(n - 1), independent of x_i, so the
        gradient stays unbiased. Its gradient is n/(n-1) (mean(g ∇log p) - mean(g) mean(∇log p)),
        computed in the same single streaming pass.

    Returns: `Estimate` of E[g] (mean, stderr of the value; see the module docstring for the
    gradient's variance), or for a pytree-valued g the same pytree of them. Under `jax.grad`, its
    `mean` differentiates to the chosen estimator. For a sampler with a `batch_shape`, a batched
    `Estimate` (as `jaxsample.estimate`).
    """
    check_choice("expectation", "gradient", gradient, _GRADIENTS)
    if sampler.batch_shape:
        return over_batch(lambda member, k: expectation(g, member, k, n, gradient=gradient, baseline=baseline,
                                                        uniforms=uniforms, mesh=mesh, chunk_size=chunk_size,
                                                        dtype=dtype),
                          sampler, key, "expectation")
    leave_one_out = isinstance(baseline, str)
    if leave_one_out:
        check_choice("expectation", "baseline", baseline, ("leave_one_out",))
        if gradient != "score":
            raise ValueError("expectation: parameter 'baseline' applies to gradient='score' only")
    sampler = checked(sampler)  # the invalid-parameter rule, once, outside the loop
    check_uniforms(sampler, uniforms, "expectation")
    dims = uniform_dims(sampler, gradient) + boundary_dims(g)
    if leave_one_out and boundary_dims(g):
        raise ValueError("expectation: baseline='leave_one_out' does not add the boundary terms of an integrand "
                         "with declared discontinuities; use a constant baseline")
    dtype = resolve_float_dtype("expectation", dtype)
    layout = integrand_layout(g, sampler, dtype, "expectation")
    if baseline is not None and not leave_one_out:
        if gradient != "score":
            raise ValueError("expectation: parameter 'baseline' applies to gradient='score' only")
        baseline = jax.lax.stop_gradient(layout.pack_constant(baseline, dtype))
    out_shape = layout.out_shape
    g = _packed(g, layout, dtype)
    common = dict(uniforms=uniforms, mesh=mesh, chunk_size=chunk_size, dtype=dtype,
                  owner="expectation")

    if not leave_one_out:
        def values_fn(u):
            return _surrogate_values(g, sampler, u, gradient, baseline)

        return layout.unpack_result(run_stream(values_fn, dims, key, n, out_shape=out_shape, **common))

    # Leave-one-out: stream the three means (g, Δ·sg(g), Δ), Δ = log p - sg(log p) (value 0), and
    # combine; the value is mean(g) exactly, the gradient the leave-one-out estimator.
    def stacked_fn(u):
        gx, score = score_terms(g, sampler, u)
        return jnp.stack([gx, score * jax.lax.stop_gradient(gx), score * jnp.ones_like(gx)], axis=1)

    est = run_stream(stacked_fn, dims, key, n, out_shape=(3,) + out_shape, **common)
    mean_g, mean_g_score, mean_score = est.mean[0], est.mean[1], est.mean[2]
    count = float(est.n)
    correction = (count / (count - 1.0)) * (mean_g_score - jax.lax.stop_gradient(mean_g) * mean_score)
    return layout.unpack_result(dataclasses.replace(jax.tree_util.tree_map(lambda leaf: leaf[0], est),
                                                    mean=mean_g + correction))
