"""The sampler contract shared by every distribution in jaxsample.

A sampler is an immutable pytree whose float parameters are leaves, so it can be built inside
`jit`, `vmap` and `grad`. It is a *warp* from the unit hypercube [0, 1)^uniform_dims onto its
domain, together with the density of the warped points with respect to the domain's measure
(solid angle, area, length or counting, as each class states) and, where the warp is a
bijection, its inverse.
"""

from __future__ import annotations

import functools
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.params import default_float_dtype
from .._core.pytree import Pytree
from .._core.numerics import safe_log


class Sampler(Pytree):
    """Base class: `sample`, `sample_with_pdf`, `log_pdf` and `warp_with_pdf` from `warp` and `pdf`.

    Subclasses define `uniform_dims`, `event_shape`, `warp(u)`, `pdf(x)` and `domain()`; they may
    override `warp_with_pdf` when the density is more accurate from u than from x (sharp lobes),
    and `inverse` where the warp is a bijection. Every subclass is a pytree with no registration
    (`jaxsample._core.pytree.Pytree`): attributes holding arrays or floats are its leaves (traceable
    under `jit`, `vmap` and `grad`), the others (strings, ints) static metadata.
    """

    uniform_dims: ClassVar[int]
    event_shape: ClassVar[tuple[int, ...]] = ()
    # Uniform coordinates that are periodic (an azimuth 2πu): u and u ± 1 give the same point, so
    # round-trip checks compare them modulo 1.
    periodic_dims: ClassVar[tuple[int, ...]] = ()

    def warp(self, u: jax.Array) -> jax.Array:
        raise NotImplementedError

    def pdf(self, x: jax.Array) -> jax.Array:
        raise NotImplementedError

    def log_pdf(self, x: jax.Array) -> jax.Array:
        """log of `pdf`, -inf outside the support (never NaN)."""
        return safe_log(self.pdf(x))

    def warp_with_pdf(self, u: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(warp(u), pdf(warp(u))); subclasses compute the density from u where that is more exact."""
        x = self.warp(u)
        return x, self.pdf(x)

    def inverse(self, x: jax.Array) -> jax.Array:
        raise NotImplementedError(f"{type(self).__name__} has no inverse: its warp is not a bijection")

    @property
    def has_inverse(self) -> bool:
        return type(self).inverse is not Sampler.inverse

    def domain(self):
        """The `jaxsample.domains` object the checks integrate over and bin on."""
        raise NotImplementedError

    def sample(self, key: jax.Array, shape=(), dtype=None) -> jax.Array:
        """Samples of shape `shape + event_shape` from uniforms drawn with `key`.

        The i-th sample (in C order over `shape`) is `warp` of the i-th point of the estimators'
        counter-based Philox stream (`jaxsample.uniforms`, several times faster than threefry on
        CPU, strictly inside (0, 1)), computed in one compiled loop (see `_draw`).
        """
        return _draw(self, key, _as_shape(shape), _as_dtype(dtype), "warp")

    def sample_with_pdf(self, key: jax.Array, shape=(), dtype=None) -> tuple[jax.Array, jax.Array]:
        """(samples, their densities); the density is the one `pdf` states, computed alongside."""
        return _draw(self, key, _as_shape(shape), _as_dtype(dtype), "warp_with_pdf")


def draw(sampler: Sampler, key, shape, dtype, method: str):
    """`sampler.<method>` applied to the sampling stream's first prod(shape) points (see `_draw`)."""
    return _draw(sampler, key, _as_shape(shape), _as_dtype(dtype), method)


def _as_shape(shape) -> tuple[int, ...]:
    return (int(shape),) if isinstance(shape, (int, np.integer)) else tuple(int(s) for s in shape)


def _as_dtype(dtype):
    return default_float_dtype() if dtype is None else jnp.dtype(dtype)


_DRAW_CHUNK = 1 << 16


@functools.partial(jax.jit, static_argnums=(2, 3, 4))
def _draw(sampler: Sampler, key, shape: tuple[int, ...], dtype, method: str):
    """`sampler.<method>` (warp, warp_with_pdf, ...) of the stream's first points, shaped
    `shape + event`: `sample` and `sample_with_pdf` as one compiled program, whatever the sampler.

    The uniforms come as the generator makes them (`Source.lanes`: g = 4 // d points per Philox
    block, one array per coordinate), the warp runs on coordinate lanes (`jaxsample.lanes`), and
    every output coordinate of every group is computed in one loop and stored once
    (`jaxsample.computed_once`) before the groups are interleaved into the (count, *event) result.
    Written as `warp(u)` on a (count, d) block, XLA recomputed the generator and the warp for each
    output coordinate (the HLO shows Philox once per consumer) and ran below NumPy's speed.
    """
    from .._core.computed_once import computed_once
    from .._core.lanes import lane_map
    from ..uniforms import Random, seed_from_key
    from ..uniforms.index import NARROW_LIMIT, offset_at, token

    seed = key if (isinstance(key, jax.Array) and key.dtype == jnp.uint32) else seed_from_key(key)
    count = int(np.prod(shape, dtype=np.int64))
    dims = sampler.uniform_dims
    g = 4 // dims if dims <= 4 else 1
    # Chunks of at most _DRAW_CHUNK points, a multiple of g each, as even as possible: the packed
    # values of a chunk stay in cache, and only the interleaved result goes to memory.
    steps = max(1, -(-count // _DRAW_CHUNK))
    chunk = max(g, -(-(-(-count // steps)) // g) * g)
    fn = getattr(sampler, method)

    def one_chunk(offset):
        groups = Random().lanes(seed, offset, chunk, dims, dtype, aligned=chunk)
        per_group = chunk // len(groups)
        outputs = [lane_map(fn, per_group)(lanes) for lanes in groups]
        leaves = [jax.tree_util.tree_leaves(o) for o in outputs]
        columns, layout = [], []
        for group in leaves:
            layout.append([])
            for leaf in group:
                flat = leaf.reshape(per_group, -1)
                layout[-1].append((len(columns), flat.shape[1], leaf.shape[1:]))
                columns.extend(flat[:, c] for c in range(flat.shape[1]))
        columns = computed_once(columns, token(offset))
        results = []
        for k in range(len(leaves[0])):
            parts = [jnp.stack(columns[start:start + width], axis=-1).reshape((per_group,) + event)
                     for start, width, event in (group_layout[k] for group_layout in layout)]
            results.append(jnp.stack(parts, axis=1).reshape((chunk,) + layout[0][k][2]))
        return tuple(results)

    treedef = jax.tree_util.tree_structure(jax.eval_shape(fn, jnp.zeros((dims,), dtype)))
    if steps == 1:
        results = one_chunk(jnp.uint32(0))
    else:
        offsets = jnp.arange(steps, dtype=jnp.uint32) * jnp.uint32(chunk)
        if count > NARROW_LIMIT:  # past 2^32 points the offsets are 64-bit (two-word) indices
            offsets = offset_at(0, jnp.arange(steps, dtype=jnp.uint32), chunk, wide=True)
        results = jax.lax.map(one_chunk, offsets)
        results = tuple(r.reshape((steps * chunk,) + r.shape[2:]) for r in results)
    results = [r[:count].reshape(shape + r.shape[1:]) for r in results]
    return jax.tree_util.tree_unflatten(treedef, results)


class WrapsSampler(Sampler):
    """A sampler built on `self.base` (a rotation, a change of variables): it draws the base's
    uniforms, so it has the base's uniform dimensions, periodic dimensions and invertibility."""

    @property
    def uniform_dims(self):
        return self.base.uniform_dims

    @property
    def periodic_dims(self):
        return self.base.periodic_dims

    @property
    def has_inverse(self):
        return self.base.has_inverse
