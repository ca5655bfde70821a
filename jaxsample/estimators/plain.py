"""Plain Monte Carlo: ∫ f dμ as the mean of Y = f(x)/p(x) over samples x of one sampler.

The streaming, accumulation and standard error are the engine's (`engine.py`); `mode` is the
gradient choice of Zeltner et al. 2021, applied to the sample and its density together; what f
may return (a pytree, complex values) is the integrand rule of `integrand.py`.
"""

from __future__ import annotations

from typing import Callable

import jax
import numpy as np

from .._core.computed_once import stored_once
from .._core.entry import compiled_entry
from ..samplers.base import check_uniforms, checked
from .._core.numerics import safe_div
from .._core.params import check_choice, resolve_float_dtype
from .engine import MANY_OUTPUTS, run_stream
from .integrand import integrand_layout, layout_of
from .result import Estimate
from .boundary import boundary_dims, boundary_values

__all__ = ["estimate", "integrand_values"]


MODES = ("attached", "detached")


def over_batch(one: Callable, sampler, key, owner: str):
    """`one(sampler, key)`, mapped over a batched sampler's members.

    For a sampler with a non-empty `batch_shape`, `one` runs on each member under `jax.vmap` over
    the flattened batch, every member with the same `key` (common random numbers: the differences
    between members carry less noise than the members do), and the result's leaves get the
    leading `batch_shape`: exactly `jax.vmap` over the batch, as a TFP user expects.
    """
    from ..samplers.base import over_members, refuse_unbatchable
    from ..uniforms import as_key

    key = as_key(key, owner)
    if not sampler.batch_shape:
        return one(sampler, key)
    refuse_unbatchable(owner, sampler)
    return over_members(lambda member: one(member, key), sampler)


def check_mode(owner: str, mode: str) -> None:
    """ValueError unless `mode` is "attached" or "detached" (the gradient choice of every estimator)."""
    check_choice(owner, "mode", mode, MODES)


def _detach(mode: str, *arrays):
    """`arrays` (a sample, its density, MIS densities) with their gradient stopped together when
    mode is "detached": stopping some of them and not the others is biased."""
    check_mode("estimate", mode)
    if mode == "detached":
        return jax.lax.stop_gradient(arrays)
    return arrays


def broadcast_like(per_sample, values):
    """A per-sample array (count,) with trailing axes added to divide or scale `values` (count, *out)."""
    return per_sample.reshape(per_sample.shape + (1,) * (values.ndim - per_sample.ndim))


def output_shape(f, sampler, dtype) -> tuple[int, ...]:
    """The shape of the values the engine averages for f (f's own shape for one real array, the
    packed vector's for a pytree or complex values: see `integrand.py`); nothing is computed."""
    return integrand_layout(f, sampler, dtype, "estimate").out_shape


def _values_per_point(f, x) -> int:
    """How many numbers f returns per point (every leaf's elements), from its abstract evaluation."""
    out = jax.eval_shape(jax.vmap(f), x)
    return sum(int(np.prod(leaf.shape[1:], dtype=np.int64)) for leaf in jax.tree_util.tree_leaves(out))


def packed_values(f, sampler, u: jax.Array, mode: str, *, owner: str = "estimate", boundary: bool = True):
    """(Y packed by the integrand rule, its layout): Y_i = f(x_i)/p(x_i) for every component of
    f's value, as one real (count, *out_shape) array (f's own values for one real array).

    An f that declares discontinuities (`jaxsample.edges.mask`) reads its boundary samples from
    the last `boundary_dims(f)` columns of u and adds their boundary terms (value 0;
    `boundary.py`); `boundary=False` (a path that is never differentiated) leaves them out.
    """
    extra = boundary_dims(f) if boundary else 0
    dims = u.shape[-1] - extra
    if extra and dims != sampler.uniform_dims:
        raise ValueError(f"{owner}: the integrand declares discontinuities (jaxsample.edges.mask), whose "
                         "boundary terms this estimator does not add; use estimate or estimate_grad")
    x, pdf = sampler.warp_with_pdf(u[:, :dims] if extra else u)
    x, pdf = _detach(mode, x, pdf)
    if _values_per_point(f, x) > MANY_OUTPUTS:
        # Many outputs: XLA computes each in its own loop; the warped sample is stored once so
        # that none of them re-runs the generator and the warp (`computed_once.stored_once`;
        # measured: 2 outputs 20 -> 11 ns/sample, 3 outputs 33 -> 13, 4 harmonics 65 -> 22).
        x, pdf = stored_once((x, pdf))
    fx = jax.vmap(f)(x)
    layout = layout_of(fx, "integrand_values", lead=1)
    fx = layout.pack(fx, u.dtype)
    values = safe_div(fx, broadcast_like(pdf, fx))
    if extra:
        if not layout.plain:
            raise TypeError(f"{owner}: an integrand with declared discontinuities must return one real array")
        values = values + boundary_values(f, sampler, u[:, dims:], moving=mode == "attached", owner=owner)
    return values, layout


def integrand_values(f: Callable[[jax.Array], jax.Array], sampler, u: jax.Array, *,
                     mode: str = "attached"):
    """The per-sample values Y_i = f(x_i)/p(x_i), x_i = sampler.warp(u_i), that `estimate` averages.

    `u` is a (count, uniform_dims) block (plus `jaxsample.edges.boundary_dims(f)` columns of
    boundary uniforms for an f with declared discontinuities); the result is (count, *f's output shape), 0 where p = 0;
    for a pytree-valued f, the same pytree of such arrays (complex leaves stay complex: their real
    and imaginary parts are divided by p). `mode` is applied to the sample and its density
    together (see `estimate`). Differentiating this function per sample (e.g.
    `jax.vmap(jax.grad(...))` over rows of u) gives the per-sample gradients whose mean is the
    gradient of `estimate`, and whose spread is its variance.
    """
    values, layout = packed_values(f, sampler, u, mode)
    return layout.unpack(values)


@compiled_entry("f", "n", "uniforms", "mode", "mesh", "chunk_size", "dtype")
def estimate(f: Callable[[jax.Array], jax.Array], sampler, key: jax.Array, n: int, *,
             uniforms="random", mode: str = "attached", mesh=None, chunk_size: int | None = None,
             dtype=None) -> Estimate:
    """∫ f dμ as the mean of f(x)/p(x) over n samples of `sampler` (μ is the sampler's measure).

    Args:
      f: maps ONE sample (shape `sampler.event_shape`) to a value: an array of any fixed shape, or
        a pytree of arrays (tuple, dict, dataclass ...), real or complex (see below); vmapped.
      sampler: any `jaxsample.Sampler` (a pytree: its parameters may be traced).
      key: a JAX key (`jax.random.key`, or a legacy `jax.random.PRNGKey`: the same stream); consumed
        once (turned into the source's seed words).
      n: number of samples: any concrete integer (Python, NumPy, a concrete JAX integer of shape
        (), an integral float), at least 2, a multiple of the source's replicates x devices; up to
        2^31 chunks (2^47 with the default chunk size; sample indices have 64 bits). Not a traced
        value: under `jax.jit` pass it with `static_argnums`/`static_argnames`.
      uniforms: "random" (default, Philox4x32-10), "stratified", "sobol" or a `uniforms.Source`.
      mode: "attached" (pathwise: sample and pdf move with the parameters) or "detached"
        (sample and pdf are constants together; only f carries derivatives).
      mesh: a `jax.sharding.Mesh`; the n samples are split evenly over all its devices, each
        drawing its own index range of the same stream, and combined with `psum`.
      chunk_size: samples per streamed chunk (default 2^16; a multiple of 4 and of replicates).
      dtype: float dtype of the uniforms (default float32, float64 under jax_enable_x64).

    Returns: `Estimate`, or for a pytree-valued f the same pytree with an `Estimate` at every
    leaf (`est["a"].mean`). A complex leaf's statistics are complex: real part from the real parts,
    imaginary part from the imaginary parts (`stderr.real`, `stderr.imag`; see `integrand.py`).
    Y = f/p is 0 where p = 0, with finite gradients there. For a sampler with a `batch_shape`, an
    `Estimate` whose fields have that leading shape: `jax.vmap` over the members, all drawing
    with the same key.
    """
    check_mode("estimate", mode)
    if sampler.batch_shape:
        return over_batch(lambda member, k: estimate(f, member, k, n, uniforms=uniforms, mode=mode, mesh=mesh,
                                                     chunk_size=chunk_size, dtype=dtype),
                          sampler, key, "estimate")
    sampler = checked(sampler)  # the invalid-parameter rule, once, outside the loop
    check_uniforms(sampler, uniforms, "estimate")
    dims = sampler.uniform_dims + boundary_dims(f)
    dtype = resolve_float_dtype("estimate", dtype)
    layout = integrand_layout(f, sampler, dtype, "estimate")

    def values_fn(u):
        return packed_values(f, sampler, u, mode)[0]

    est = run_stream(values_fn, dims, key, n, uniforms=uniforms, mesh=mesh, chunk_size=chunk_size,
                     out_shape=layout.out_shape, dtype=dtype)
    return layout.unpack_result(est)
