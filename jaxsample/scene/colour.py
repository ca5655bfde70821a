"""Colour in the scene layer: reflectances and radiances with a trailing channel axis.

A colour quantity (a BRDF's albedo, a conductor's η and k, a light's radiance, an environment map's
texels) is either a scalar, one grey channel, or a vector of C channels on its last axis: RGB, or
any number of them (spectral samples, or a batch of independent channels). Everything the shading
integral multiplies per sample, f_r(ω_o, ω_i) L_i(ω_i) cos θ_i / p(ω_i), is then per channel, while
the directions, their densities and the MIS weights are shared by every channel: one proposal for
all of them, so each channel's estimate comes from the same samples (as PBRT-v4 and Mitsuba 3 shade
RGB). The channel counts of the BRDF and of every light must agree, or be 1 (`scene_channels`).

Per-sample arrays have the shape of the batch of samples, `batch`; colour values have `batch` or
`batch + (C,)`. `lift` gives a per-sample array the channel axis so that the two broadcast.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

__all__ = ["lift", "product", "with_channel_axis", "channel_shape", "scene_channels"]


def with_channel_axis(values, batch_ndim: int, coloured: bool):
    """`values` (per sample: `batch_ndim` axes, or already `batch + (C,)`) with a trailing axis of
    length 1 where `coloured` and it has none, so that it broadcasts against `batch + (C,)` colour.
    Python numbers, and everything where nothing is coloured, are returned as they are. The one
    rule that `lift`, `product` and the shading integrand's per-sample factors share."""
    if coloured and not isinstance(values, (int, float)) and jnp.ndim(values) == batch_ndim:
        return jnp.expand_dims(values, -1)
    return values


def lift(values, colour):
    """`values` (per sample, shape `batch`) with a trailing axis of length 1 when `colour` (an
    object's parameter, scalar or (C,)) has a channel axis; unchanged otherwise."""
    return with_channel_axis(values, jnp.ndim(values), jnp.ndim(colour) == 1)


def product(batch_ndim: int, *factors):
    """The product of per-sample factors of shape `batch` (`batch_ndim` axes) or `batch + (C,)`:
    where any factor has the channel axis, the others are given one. Python numbers pass through."""
    coloured = any(jnp.ndim(f) > batch_ndim for f in factors)
    result = None
    for f in factors:
        f = with_channel_axis(f, batch_ndim, coloured)
        result = f if result is None else result * f
    return result


def channel_shape(owner: str, name: str, shape) -> tuple:
    """`shape` of one sample's colour, () or (C,): anything of higher rank is a ValueError."""
    shape = tuple(shape)
    if len(shape) > 1:
        raise ValueError(f"{owner}: {name} must be a scalar or one value per channel (shape (C,)); it gives "
                         f"shape {shape} per sample (a batch of scenes is jax.vmap over shade)")
    return shape


def _shape_of(owner: str, label: str, fn, obj, dtype) -> tuple:
    """The shape `fn(obj, point_or_wo, wi)` gives for one pair of 3-vectors, by `jax.eval_shape`."""
    direction = jax.ShapeDtypeStruct((3,), dtype)
    try:
        shape = jax.eval_shape(fn, obj, direction, direction).shape
    except (TypeError, ValueError) as error:
        raise ValueError(f"{owner}: {label} fails for one direction; its colour parameters must be scalars or one "
                         f"value per channel, shape (C,), of one count ({error})") from error
    return channel_shape(owner, label, shape)


def scene_channels(owner: str, brdf, lights, dtype=jnp.float32) -> tuple:
    """The channel shape of L_o at a shading point, () or (C,), read from the shapes of f_r and of
    each light's radiance for one direction (nothing is computed: `jax.eval_shape`). C is the
    common count of every coloured factor; a factor with another count is a ValueError naming it.
    The answer depends only on the scene's structure and its leaves' shapes and dtypes, and is
    cached on them: a call with a scene already seen costs a flatten, not a trace."""
    lights = tuple(lights)
    leaves, treedef = jax.tree_util.tree_flatten((brdf, lights))
    try:
        signature = (owner, treedef, tuple((jnp.shape(v), jnp.result_type(v)) for v in leaves), jnp.dtype(dtype))
        hash(signature)
    except TypeError:  # a leaf or static field that cannot be hashed: no cache
        return _scene_channels(owner, brdf, lights, dtype)
    return _cached_channels(signature)


@functools.lru_cache(maxsize=256)
def _cached_channels(signature) -> tuple:
    owner, treedef, specs, dtype = signature
    brdf, lights = jax.tree_util.tree_unflatten(treedef, [jax.ShapeDtypeStruct(s, d) for s, d in specs])
    return _scene_channels(owner, brdf, lights, dtype)


def _scene_channels(owner, brdf, lights, dtype) -> tuple:
    found = [("the BRDF's eval", _shape_of(owner, f"the BRDF's eval ({type(brdf).__name__})",
                                           lambda b, wo, wi: b.eval(wo, wi), brdf, dtype))]
    for k, light in enumerate(lights):
        label = f"light {k}'s radiance ({type(light).__name__})" if len(lights) > 1 else \
            f"the light's radiance ({type(light).__name__})"
        found.append((label, _shape_of(owner, label, lambda l, p, wi: l.radiance_from(p, wi), light, dtype)))
    counts = {shape[0] for _, shape in found if shape and shape[0] != 1}
    if len(counts) > 1:
        listed = ", ".join(f"{label}: {shape[0] if shape else 1}" for label, shape in found)
        raise ValueError(f"{owner}: the scene's channel counts do not broadcast ({listed}); give every colour "
                         "the same number of channels, or a scalar")
    if counts:
        return (counts.pop(),)
    return (1,) if any(shape for _, shape in found) else ()
