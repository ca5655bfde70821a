"""The boundary term of a gradient: what every interior estimator misses when θ moves an edge.

For an integrand f that jumps by Δf across the boundary of a region Ω(θ) (`jaxsample.edges`),
d/dθ ∫ f dμ = ∫ ∂f/∂θ dμ + ∫_{∂Ω} Δf (v·n) dl (Reynolds transport; Li et al. 2018). An estimator
whose samples x = T(u; θ) move with θ (mode "attached", gradient "pathwise") already has part of
that term: in u-space the jump sits where T maps it to the boundary, and what the per-sample
derivative misses is the *relative* motion of boundary and samples. Written out (change of
variables from u to ω: du = p dω on each side, the sample flow V = ∂T/∂θ at the point),

    missing = ∫_{∂Ω} Δf(y) ((v(y) − V(y)) · n(y)) dl(y),

so a detached estimator (V = 0) misses all of it and a sampler that carries its samples along the
boundary (light sampling of the light whose rim it is) misses none. The flow at a boundary point
is V(y) = ∂T(u*; θ)/∂θ with u* = T⁻¹(y) held constant, so the attached correction needs the
sampler's `inverse` (`Sampler.flow`, or a class's own form of the same flow where u* cannot carry
it). For an expectation E_p[g] = ∫ g p dμ the jump is Δg · p(y).

The term is estimated by edge sampling: each interior sample i gets a boundary point y_i, drawn
uniformly by arc length from its own uniforms (the last `boundary_dims` coordinates of its row),
and adds the surrogate

    sg(Δf(y)/q(y)) · sg(n) · ((y − sg(y)) − (y_T − sg(y_T))),    y_T = T(sg(T⁻¹(sg y)); θ),

where sg is stop_gradient and q the boundary density: its value is exactly 0, so estimates are
unchanged, and its derivative is the missing term's unbiased estimate. Because it rides on the same
row as the interior sample, the per-sample gradients of `estimate_grad` include it and their
spread is the standard error of the whole gradient, boundary term included.

Assumed, not checked: the sampler's density is continuous across the region's boundary (a sampler
whose own support ends exactly on the region's rim, e.g. a `UniformCone` on the same cap, makes the
support factor p(y) > 0 a matter of rounding, and for an expectation the jump would be
g_in p_in − g_out p_out rather than Δg · p), and the warp is continuous where the samples cross
the boundary (not a `Mixture`'s component choice or a rejection step).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..edges.masked import boundary_dims, discontinuities
from .._core.numerics import safe_div

__all__ = ["boundary_values", "boundary_dims", "relative_motion", "refuse_edges", "sample_flow"]


def refuse_edges(owner: str, *functions) -> None:
    """ValueError for an estimator that does not add boundary terms, given an integrand that
    declares discontinuities: its gradient would silently miss them."""
    if any(boundary_dims(f) for f in functions):
        raise ValueError(f"{owner}: the integrand declares discontinuities (jaxsample.edges.mask), whose "
                         "boundary terms this estimator does not add; use estimate or estimate_grad (or, for a "
                         "value only, pass the plain function f.__call__)")


def _has_parameters(sampler) -> bool:
    return bool(jax.tree_util.tree_leaves(sampler))


def relative_motion(y, flows=()):
    """(y − sg y) minus the motion of each flow's sample through sg(y): value 0, the derivative
    the velocity of the boundary point relative to the samples (one flow per sampler piece)."""
    move = y - jax.lax.stop_gradient(y)
    for flow in flows:
        moved = flow(jax.lax.stop_gradient(y))
        move = move - (moved - jax.lax.stop_gradient(moved))
    return move


def sampler_flow(sampler, owner: str, remedy: str):
    """y ↦ T(sg(T⁻¹(y)); θ): the sample of `sampler` through y, moving with its parameters.

    A sampler without parameters does not move (no flow); one with parameters and no inverse
    cannot say how its samples move at the boundary: ValueError with the remedy."""
    if not _has_parameters(sampler):
        return None
    try:
        jax.eval_shape(sampler.inverse, jax.ShapeDtypeStruct((1,) + tuple(sampler.event_shape), jnp.float32))
    except NotImplementedError:
        raise ValueError(f"{owner}: the integrand declares a discontinuity ('jaxsample.edges.mask') and "
                         f"{type(sampler).__name__} has no inverse, so the motion of its samples across "
                         f"the boundary is unknown; {remedy}") from None

    return lambda y: sample_flow(sampler, y)


def sample_flow(sampler, y):
    """T(sg(T⁻¹(y)); θ), y held: `sampler.flow(y)` (`Sampler.flow`, which a class computes without
    the round trip through u where u loses the tail), the round trip itself for an object without
    `flow` (a sampler written without the `Sampler` base)."""
    if hasattr(sampler, "flow"):
        return sampler.flow(y)
    return sampler.warp(jax.lax.stop_gradient(sampler.inverse(jax.lax.stop_gradient(y))))


def boundary_values(f, sampler, t: jax.Array, *, moving: bool, weight_by_density: bool = False,
                    owner: str = "estimate", remedy: str = "use mode='detached'"):
    """Per-sample boundary surrogates (value 0) for the declared discontinuities of f.

    t: (count, boundary_dims(f)) uniforms. `moving`: the samples move with θ (attached /
    pathwise), so the sampler's flow is subtracted. `weight_by_density`: the integral is
    E_p[f] = ∫ f p dμ, whose jump is Δf · p(y). Returns (count, *f's shape) values, all 0.
    """
    terms = discontinuities(f)
    flows = ()
    if moving:
        flow = sampler_flow(sampler, owner, remedy)
        flows = () if flow is None else (flow,)
    total = 0.0
    offset = 0
    for region, jump in terms:
        dims = int(region.boundary_dims)
        y, normal, pdf = region.boundary_sample(t[:, offset:offset + dims])
        offset += dims
        fixed = jax.lax.stop_gradient(y)
        delta = jax.vmap(jump)(fixed)
        density = sampler.pdf(fixed)
        # ∫ f dμ is estimated over the sampler's support only (f/p is 0 where p is 0), so a
        # boundary point outside it bounds nothing the estimate sees.
        inside = (density > 0).astype(delta.dtype) if not weight_by_density else density
        delta = delta * inside.reshape(inside.shape + (1,) * (delta.ndim - 1))
        weight = jax.lax.stop_gradient(safe_div(delta, pdf))
        speed = jnp.sum(jax.lax.stop_gradient(normal) * relative_motion(y, flows), axis=-1)
        total = total + weight * speed.reshape(speed.shape + (1,) * (weight.ndim - 1))
    return total
