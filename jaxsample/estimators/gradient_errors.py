"""Gradients with error bars: `estimate_grad` and `expectation_grad`.

`jax.grad` of an estimate returns a bare number. Its noise is the spread of the per-sample
gradients whose mean it is: with Y_i(θ) the per-sample value (`integrand_values` for ∫ f dμ,
`expectation_values` for E_{p_θ}[g]), the gradient of the estimate is (1/n) Σ_i ∇θ Y_i(θ), an
average of n per-sample gradients, so it has a standard error like any Monte Carlo mean. These
functions stream the per-sample gradients through the same engine as the value (constant memory,
the same uniforms: sample i depends only on the key and i; under `jit` and `vmap`; `mesh=`
shards them), and return an `Estimate` whose `mean`, `stderr`, `variance`, `max_abs` and `ess`
have the structure of `params`. With independent points the stderr is sqrt(s²/n) per parameter;
with Sobol' or stratified points it is the spread of the replicate means, as for values.

`make(params)` returns `(f, sampler)` (or `(g, sampler)`) built from a pytree of float
parameters, so that a parameter may live in the integrand, the sampler or both. The integrand
must return one real scalar per sample (the gradient of a vector, a pytree or a complex value
would be a Jacobian): a pytree or complex integrand is a TypeError, a non-scalar array a
ValueError; differentiate one real component per call (`f(w)["a"]`, `f(w).real`).
"""

from __future__ import annotations

import dataclasses

from typing import Any, Callable

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from .._core.entry import compiled_entry
from ..samplers.base import check_unbatched, checked
from .._core.params import check_choice
from .engine import run_stream
from .integrand import integrand_layout, require_real
from .plain import integrand_values
from .result import Estimate
from .boundary import boundary_dims
from .gradients import _GRADIENTS, expectation, expectation_values, score_surrogate, score_terms, uniform_dims

__all__ = ["estimate_grad", "expectation_grad"]


ANTITHETIC = ("rotate", "reflect")


def antithetic_partner(u, sampler, antithetic: str):
    """The partner of each row of uniforms `u` in an antithetic pair: "reflect", 1 − u in every
    coordinate; "rotate", the sampler's periodic coordinates (an azimuth) moved by 1/2 modulo 1 and
    the others kept, so that a direction is paired with the one turned by π about the lobe's axis."""
    if antithetic == "reflect":
        return 1.0 - u
    shifted = u[:, list(sampler.periodic_dims)] + 0.5
    return u.at[:, list(sampler.periodic_dims)].set(jnp.where(shifted >= 1.0, shifted - 1.0, shifted))


def _check_antithetic(owner, antithetic, sampler, n):
    check_choice(owner, "antithetic", antithetic, ANTITHETIC)
    if antithetic == "rotate" and not sampler.periodic_dims:
        raise ValueError(f"{owner}: antithetic='rotate' turns a sampler's azimuth by π, and "
                         f"{type(sampler).__name__} has no periodic coordinate; use antithetic='reflect'")
    if n % 2:
        raise ValueError(f"{owner}: parameter 'n' must be even with antithetic pairs (n/2 pairs); got {n}")


def _per_sample_gradients(make, params, key, n, point_value, owner, extra_dims=0, antithetic=None,
                          **kw) -> Estimate:
    """Stream ∇θ of point_value(f_or_g, sampler, u_row) over n points (n/2 antithetic pairs, each
    pair's mean one value, when `antithetic` names a pairing); Estimate shaped like params."""
    flat, unravel = ravel_pytree(params)
    if not jnp.issubdtype(flat.dtype, jnp.floating):
        raise TypeError(f"{owner}: parameter 'params' must be a pytree of floats; got dtype {flat.dtype}")
    fn, sampler = make(params)
    check_unbatched(sampler, owner)
    sampler = checked(sampler)
    dims = sampler.uniform_dims + extra_dims + boundary_dims(fn)
    require_real(integrand_layout(fn, sampler, flat.dtype, owner), owner, "make(params)[0]",
                 "its gradient is an Estimate shaped like params; differentiate one real component per "
                 "call, e.g. lambda w: f(w)['a'] or lambda w: f(w).real")
    out = jax.eval_shape(lambda u: point_value(fn, sampler, u), jax.ShapeDtypeStruct((dims,), flat.dtype))
    if out.shape != ():
        raise ValueError(f"{owner}: the integrand must return a scalar (one value per sample); got shape "
                         f"{out.shape}. For a vector-valued integrand, take one component per call.")

    def gradients(u):
        def one(row):
            def value(theta):
                f, s = make(unravel(theta))
                return point_value(f, s, row)
            return jax.grad(value)(flat)
        return jax.vmap(one)(u)

    if antithetic is None:
        est = run_stream(gradients, dims, key, n, out_shape=flat.shape, owner=owner, **kw)
    else:
        _check_antithetic(owner, antithetic, sampler, n)
        est = run_stream(lambda u: 0.5 * (gradients(u) + gradients(antithetic_partner(u, sampler, antithetic))),
                         dims, key, n // 2, out_shape=flat.shape, owner=owner, **kw).per_evaluation(n)
    return dataclasses.replace(jax.tree_util.tree_map(unravel, est), gradient=True)


@compiled_entry("make", "n", "mode", "antithetic", "uniforms", "mesh", "chunk_size", "dtype")
def estimate_grad(make: Callable[[Any], tuple[Callable, Any]], params, key: jax.Array, n: int, *,
                  mode: str = "attached", antithetic: str | None = None, uniforms="random", mesh=None,
                  chunk_size: int | None = None, dtype=None) -> Estimate:
    """∇θ of ∫ f dμ as estimated by `jaxsample.estimate(f, sampler, key, n, mode=mode)`, with its
    standard error; `(f, sampler) = make(θ)`, θ = `params` (a pytree of floats).

    The mean is the gradient that `jax.grad` of that estimate's mean gives (same samples, to float
    rounding); `stderr` has the structure of `params`. `mode`, `uniforms`, `mesh`, `chunk_size`,
    `dtype`: as in `estimate` (`mode` decides whether samples and densities move with θ).

    `antithetic`: None (independent samples), or n/2 pairs whose per-sample gradients are averaged
    (unbiased: each member of a pair is a uniform point; the stderr is over the pairs, `variance`
    restated per evaluation; n even). "rotate" pairs a direction with the one turned by π about
    the lobe's axis (the sampler's periodic coordinate moved by 1/2): the antithetic sampling of
    glossy BRDF derivatives of Zhang et al. 2021, whose derivative in a rotation of the lobe is odd
    about the axis, so that the pair cancels it where the rest of the integrand is smooth. "reflect"
    pairs u with 1 − u, as `estimate_antithetic`.
    """
    check_choice("estimate_grad", "mode", mode, ("attached", "detached"))

    def point_value(f, sampler, row):
        return integrand_values(f, sampler, row[None], mode=mode)[0]

    return _per_sample_gradients(make, params, key, n, point_value, "estimate_grad", antithetic=antithetic,
                                 uniforms=uniforms, mesh=mesh, chunk_size=chunk_size, dtype=dtype)


@compiled_entry("make", "n", "gradient", "antithetic", "uniforms", "mesh", "chunk_size", "dtype")
def expectation_grad(make: Callable[[Any], tuple[Callable, Any]], params, key: jax.Array, n: int, *,
                     gradient: str = "pathwise", baseline: Any = None, antithetic: str | None = None,
                     uniforms="random", mesh=None, chunk_size: int | None = None, dtype=None) -> Estimate:
    """∇θ E_{p_θ}[g] by the chosen per-sample estimator, with its standard error; `(g, sampler) =
    make(θ)`, θ = `params` (a pytree of floats).

    `gradient`: "pathwise", "score" or "measure_valued" (PhongLobe's exponent; as in
    `jaxsample.expectation`). `baseline`, score only: a constant (held constant), or
    "leave_one_out", whose gradient is that of `expectation(..., baseline="leave_one_out")`: one
    pass over the samples gives the mean ḡ of g, a second streams the per-sample terms
    ∇g_i + n/(n-1) (g_i - ḡ) ∇log p_i on the same samples (their stderr is the large-n one: the
    terms share ḡ). `antithetic`: None, "rotate" or "reflect", as in `estimate_grad` (not with the
    leave-one-out baseline). `uniforms`, `mesh`, `chunk_size`, `dtype`: as in `estimate`.
    """
    check_choice("expectation_grad", "gradient", gradient, _GRADIENTS)
    if baseline is not None and gradient != "score":
        raise ValueError("expectation_grad: parameter 'baseline' applies to gradient='score' only")
    common = dict(uniforms=uniforms, mesh=mesh, chunk_size=chunk_size, dtype=dtype)
    if isinstance(baseline, str):
        check_choice("expectation_grad", "baseline", baseline, ("leave_one_out",))
        if antithetic is not None:
            raise ValueError("expectation_grad: parameter 'antithetic' does not combine with baseline='leave_one_out'")
        return _leave_one_out(make, params, key, n, common)

    def point_value(g, sampler, row):
        return expectation_values(g, sampler, row[None], gradient=gradient, baseline=baseline)[0]

    extra = uniform_dims(make(params)[1], gradient) - make(params)[1].uniform_dims
    return _per_sample_gradients(make, params, key, n, point_value, "expectation_grad", extra_dims=extra,
                                 antithetic=antithetic, **common)


def _leave_one_out(make, params, key, n, common) -> Estimate:
    """The score function with the leave-one-out baseline, as a mean of per-sample terms.

    `expectation`'s gradient is mean(∇g) + n/(n-1) (mean(g ∇log p) - ḡ mean(∇log p)), ḡ the mean
    of g over all n samples, which is exactly the mean of h_i = ∇g_i + n/(n-1) (g_i - ḡ) ∇log p_i.
    So a first pass over the samples gives ḡ, a second streams the h_i on the same samples. The
    h_i share ḡ, so they are not quite independent: the stderr from their spread is the usual
    large-n (delta-method) standard error, off by O(1/n).
    """
    g, sampler = make(params)
    if boundary_dims(g):
        raise ValueError("expectation_grad: baseline='leave_one_out' does not add the boundary terms of an "
                         "integrand with declared discontinuities; use a constant baseline")
    mean_g = jax.lax.stop_gradient(expectation(g, sampler, jax.random.clone(key), n, **common).mean)
    scale = n / (n - 1.0)

    def point_value(g, sampler, row):
        gx, score = score_terms(g, sampler, row[None])
        return score_surrogate(gx, score, scale * (gx - mean_g))[0]

    return _per_sample_gradients(make, params, key, n, point_value, "expectation_grad", **common)
