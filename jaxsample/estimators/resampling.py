"""Resampled importance sampling (RIS; Talbot et al. 2005) and the weighted reservoir behind it.

RIS draws M candidates x_1..x_M from a proposal with density p, weights each by
w_j = p̂(x_j)/p(x_j) for a target p̂ >= 0 known only up to a constant (an unnormalized density
over the proposal's measure), and keeps one, y = x_J, with probability w_J / Σ_j w_j. With the
unbiased contribution weight

    W = (1/p̂(y)) · (1/M) Σ_j w_j          (Bitterli et al. 2020, eq. 6; Talbot 2005, ch. 3),

f(y) W is an unbiased estimate of ∫ f dμ whenever p̂ > 0 wherever f ≠ 0 and p > 0 wherever
p̂ > 0. As M grows, y tends to a sample of p̂ / ∫p̂ and W to ∫p̂ / p̂(y): for p̂ = f >= 0 the
estimate is the mean of the M weights, whose variance is Var_p(f/p)/M exactly.

`Reservoir` is the streaming form (Chao 1982; the reservoirs of ReSTIR, Bitterli et al. 2020;
PBRT-v4's `WeightedReservoirSampler`): candidates are added one at a time, each kept with
probability w / (running Σ w), in constant memory, and two reservoirs of one target merge into the
reservoir of all their candidates. `estimate_resampled` runs RIS on the streaming engine, n
independent outputs of M candidates each, with the standard error and diagnostics of every
estimate.
"""

from __future__ import annotations

from typing import Any, Callable

import jax
import jax.numpy as jnp

from .._core.counts import check_count
from .._core.entry import compiled_entry
from .._core.numerics import safe_div
from .._core.params import resolve_float_dtype
from .._core.pytree import Pytree
from ..samplers.base import check_unbatched, check_uniforms, checked
from .boundary import refuse_edges
from .engine import DEFAULT_CHUNK_SIZE, run_stream
from .integrand import integrand_layout, layout_of
from .plain import broadcast_like
from .result import Estimate

__all__ = ["Reservoir", "estimate_resampled", "resampled_values"]


def _uniform(key, dtype):
    return jax.random.uniform(key, (), dtype)


class Reservoir(Pytree):
    """A weighted reservoir holding one sample: a pytree, usable under `jit`, `vmap` and `lax.scan`.

    - `sample`: the kept candidate (any pytree of arrays).
    - `weight_sum`: Σ w over every candidate seen, w = p̂(x)/p(x).
    - `count`: how many candidates were seen (M).
    - `target`: p̂ at the kept sample.

    `add` and `merge` draw their one uniform from the key they are given. After M additions the
    kept sample is candidate j with probability w_j / Σ w, whatever the order; `merge` of two
    reservoirs resampled toward the same target gives that distribution over their union.
    """

    sample: Any
    weight_sum: jax.Array
    count: jax.Array
    target: jax.Array

    @classmethod
    def empty(cls, like, dtype=jnp.float32) -> "Reservoir":
        """A reservoir that has seen nothing, whose sample has the structure, shapes and dtypes of `like`."""
        zero = jnp.zeros((), dtype)
        return cls(sample=jax.tree_util.tree_map(jnp.zeros_like, like), weight_sum=zero, count=zero, target=zero)

    def add(self, key, sample, target, density) -> "Reservoir":
        """The reservoir after one more candidate `sample`, with p̂ = `target` and proposal density
        `density` (its weight is target/density, 0 where density is 0)."""
        weight = safe_div(jnp.asarray(target, self.weight_sum.dtype), jnp.asarray(density, self.weight_sum.dtype))
        return self._take(key, sample, weight, target, 1.0)

    def merge(self, key, other: "Reservoir") -> "Reservoir":
        """The reservoir of both streams of candidates (both resampled toward the same target)."""
        return self._take(key, other.sample, other.weight_sum, other.target, other.count)

    def _take(self, key, sample, weight, target, count) -> "Reservoir":
        total = self.weight_sum + weight
        keep_new = _uniform(key, total.dtype) * total < weight
        pick = lambda new, old: jnp.where(keep_new, new, old)  # noqa: E731
        return Reservoir(sample=jax.tree_util.tree_map(pick, sample, self.sample), weight_sum=total,
                         count=self.count + count, target=pick(jnp.asarray(target, total.dtype), self.target))

    def contribution_weight(self) -> jax.Array:
        """W = weight_sum / (count · p̂(sample)): f(sample) · W estimates ∫ f dμ; 0 for an empty reservoir
        or a sample with p̂ = 0."""
        return safe_div(self.weight_sum, self.count * self.target)


def _select(weights, u):
    """Index j with probability w_j / Σ w per row of `weights` (count, M), by inversion of the
    cumulative sums with one uniform u < 1 per row (u · Σw < Σw, so a candidate of weight 0 is
    never the one found while some weight is positive), and the row sums."""
    cumulative = jnp.cumsum(weights, axis=1)
    total = cumulative[:, -1]
    index = jnp.sum(cumulative <= (u * total)[:, None], axis=1)
    # M exactly when every weight is 0 (then W = 0 whichever is kept).
    return jnp.minimum(index, weights.shape[1] - 1), total


def resampled_values(f: Callable, proposal, target: Callable, m: int, u: jax.Array):
    """The per-output values f(y) W of RIS from a (count, m · proposal.uniform_dims + 1) block `u`
    of uniforms (each row: M candidates' uniforms, then the selection's), with their layout (the
    integrand rule of `integrand.py`).

    The candidates, their densities, p̂ and the selection carry no derivative; see `estimate_resampled`.
    """
    count, d = u.shape[0], proposal.uniform_dims
    x, density = proposal.warp_with_pdf(u[:, :m * d].reshape(count * m, d))
    x, density = jax.lax.stop_gradient((x, density))
    p_hat = jax.lax.stop_gradient(jax.vmap(target)(x)).astype(density.dtype)
    weights = safe_div(p_hat, density).reshape(count, m)
    index, total = _select(weights, u[:, m * d])
    chosen = lambda a: jnp.take_along_axis(  # noqa: E731
        a.reshape((count, m) + a.shape[1:]), index.reshape((count, 1) + (1,) * (a.ndim - 1)), axis=1)[:, 0]
    y = chosen(x)
    weight = safe_div(total, float(m) * chosen(p_hat))
    fy = jax.vmap(f)(y)
    layout = layout_of(fy, "estimate_resampled", lead=1)
    fy = layout.pack(fy, u.dtype)
    return fy * broadcast_like(weight, fy), layout


def _default_chunk(m: int) -> int:
    """Outputs per streamed chunk: the default chunk's worth of candidates, at least 1024 outputs."""
    return max(1024, DEFAULT_CHUNK_SIZE // (1 << (m - 1).bit_length()))


@compiled_entry("f", "target", "n", "m", "uniforms", "mesh", "chunk_size", "dtype")
def estimate_resampled(f: Callable, proposal, target: Callable, key: jax.Array, n: int, m: int, *,
                       uniforms="random", mesh=None, chunk_size: int | None = None, dtype=None) -> Estimate:
    """∫ f dμ by resampled importance sampling: the mean of f(y) W over n outputs, each y chosen from
    `m` candidates of `proposal` in proportion to target(x)/p(x) (see the module docstring).

    Args:
      f: maps one sample (shape `proposal.event_shape`) to a value (array or pytree, as for `estimate`).
      proposal: any unbatched `jaxsample.Sampler`; μ is its measure.
      target: maps one sample to p̂(x) >= 0, a scalar (unnormalized; a cheap approximation of |f|).
        Unbiased when p̂ > 0 wherever f ≠ 0 (and the proposal covers p̂'s support).
      key, uniforms, mesh, dtype: as for `estimate`; each output uses m · proposal.uniform_dims + 1
        uniforms (the candidates', then the selection's).
      n: number of outputs (at least 2), as `n` of `estimate`: the standard error is over them.
      m: candidates per output, 1 to 2^16 (M = 1 is plain importance sampling from the proposal).
      chunk_size: outputs per streamed chunk (default 2^16 / M rounded, at least 1024): memory
        grows with chunk_size · M.

    Returns an `Estimate` over the n values f(y) W (so `variance` is their per-output variance).

    Gradients: the candidates, their densities, p̂ and the selection are constants (as
    `mode="detached"` of `estimate`), so the derivative is ∂f/∂θ at the kept sample times W: an
    unbiased RIS estimate of ∫ ∂f/∂θ dμ for every parameter θ of f (closed over), when f is
    differentiable in θ at almost every x (no discontinuity that moves with θ; `f` declaring
    edges is refused). The integral does not depend on the proposal's or the target's parameters,
    and the estimator's derivative in them is 0.
    """
    check_unbatched(proposal, "estimate_resampled")
    if not callable(target):
        raise TypeError(f"estimate_resampled: parameter 'target' must be a function of one sample; got "
                        f"{type(target).__name__}")
    m = check_count("estimate_resampled", "m", m, minimum=1, maximum=1 << 16)
    refuse_edges("estimate_resampled", f, target)
    check_uniforms(proposal, uniforms, "estimate_resampled")
    proposal = checked(proposal)
    dtype = resolve_float_dtype("estimate_resampled", dtype)
    layout = integrand_layout(f, proposal, dtype, "estimate_resampled")
    shape = jax.eval_shape(target, jax.ShapeDtypeStruct(proposal.event_shape, dtype)).shape
    if shape != ():
        raise ValueError(f"estimate_resampled: parameter 'target' must return a scalar p̂(x); it returns shape {shape}")

    def values_fn(u):
        return resampled_values(f, proposal, target, m, u)[0]

    est = run_stream(values_fn, m * proposal.uniform_dims + 1, key, n, uniforms=uniforms, mesh=mesh,
                     chunk_size=_default_chunk(m) if chunk_size is None else chunk_size,
                     out_shape=layout.out_shape, dtype=dtype, owner="estimate_resampled")
    return layout.unpack_result(est)
