"""Values that XLA's CPU backend must compute in one loop and store once: `computed_once`.

Why. Several values often come from one expensive producer: the g points of one Philox block,
the x, y, z and density of one warped sample. XLA's CPU fusion computes an output element by
element and copies a cheap-looking shared producer into every consumer fusion, so each value (and
each element of an interleaved (count, 3) output) would re-run the generator and the warp: seen in
the optimized HLO as the Philox multiplier emitted once per consumer. `lax.optimization_barrier`
does not prevent it on CPU (it is expanded before fusion).

What works: pack the values pairwise, bit for bit, as the real and imaginary parts of complex
arrays, so that one loop fusion computes both values of a pair together (LLVM shares the common
work inside one loop iteration), and return those arrays from a `lax.cond` branch, a boundary
that fusion cannot cross. Integer values travel as floats of the same width (a same-shape
bitcast), so nothing is rounded: the unpacked values are the computed values exactly. Packing
four 32-bit values into one complex128 through shape-changing bitcasts would share more work,
but it defeats LLVM's vectorizer: the estimator of ∫cos³ runs 2x slower that way
(`benchmarks/bench_estimator.py`). The cond's predicate is
always true but is not a compile-time constant (it reads a traced `token`); were XLA ever to fold
it, only the speed would be lost.

Where. All of this is for XLA's CPU backend, where it was measured: elsewhere, or with the
switch JAXSAMPLE_LANES=0 (`cpu_paths`), `computed_once` returns its values as they are.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

from . import cpu_paths
from .jax_internals import identity_primitive

__all__ = ["computed_once", "stored_once", "stored_once_p"]


def _always(token) -> jax.Array:
    # True for every token (a uint32 shifted right by one is < 2^31), yet not a constant to XLA.
    return (jnp.asarray(token).astype(jnp.uint32) >> 1) != jnp.uint32(0xFFFFFFFF)


def _as_float(value: jax.Array) -> jax.Array:
    """The value's bits as a float of the same width (a same-shape bitcast: no data moves)."""
    target = jnp.float32 if value.dtype.itemsize == 4 else jnp.float64
    return value if value.dtype == target else lax.bitcast_convert_type(value, target)


def computed_once(values, token, *, alone: bool = False):
    """`values` (a sequence of arrays of one shape, 32- or 64-bit dtypes) computed in one loop
    per pair of values.

    Returns the same values, bit for bit; `token` is any traced integer scalar (the estimator's
    chunk offset, a seed word). Values of other widths (bool, int8) pass through unpacked.
    `alone`: a single value also crosses the `lax.cond` boundary (computed in one loop and stored),
    so that no consumer can pull part of its computation into its own fusion (see `engine.chunk_step`).
    """
    values = list(values)
    if not cpu_paths.active():
        return values
    if len(values) == 1 and alone:
        return list(lax.cond(_always(token), lambda: tuple(values), lambda: tuple(jnp.zeros_like(v) for v in values)))
    if len(values) <= 1:
        return values
    shape = values[0].shape
    by_width = {4: [], 8: []}
    for i, v in enumerate(values):
        if v.shape == shape and v.dtype.itemsize in by_width and not jnp.issubdtype(v.dtype, jnp.complexfloating):
            by_width[v.dtype.itemsize].append(i)
    pairs = []
    for members in by_width.values():
        if len(members) % 2:
            members = members + [None]
        pairs.extend(zip(members[::2], members[1::2]))
    if not pairs:
        return values

    def part(i, like):
        return _as_float(values[i]) if i is not None else jnp.zeros_like(_as_float(values[like]))

    packed = tuple(lax.complex(part(a, a), part(b, a)) for a, b in pairs)
    packed = lax.cond(_always(token), lambda: packed, lambda: tuple(jnp.zeros_like(p) for p in packed))
    out = list(values)
    for (a, b), p in zip(pairs, packed):
        for i, half in ((a, jnp.real(p)), (b, jnp.imag(p))):
            if i is not None:
                out[i] = half if half.dtype == values[i].dtype else lax.bitcast_convert_type(half, values[i].dtype)
    return out


# ----------------------------------------------------------------------------------------------
# stored_once: a marker for `lanes.lane_map`, the identity everywhere else
# ----------------------------------------------------------------------------------------------
#
# A per-point function traced by `lane_map` can mark values that many outputs share (the warped
# sample of an integrand with many values per point): `lane_map` passes their lanes through
# `computed_once`, so each output's loop reads them instead of recomputing the generator and the
# warp. Outside `lane_map` (plain JAX, `vmap`, autodiff) the primitive is the identity; its
# derivative passes the tangents through unchanged (the marker is not on the tangent path).

# None where this JAX cannot register a primitive (`jax_internals.MISSING`): `stored_once` is
# then the identity function, and the lanes step aside.
stored_once_p = identity_primitive("jaxsample_stored_once")


def stored_once(tree):
    """`tree` unchanged; inside `lane_map`, its per-point arrays are stored once per block
    (see the note above). Leaves must be arrays."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    if not leaves or stored_once_p is None:
        return tree
    return jax.tree_util.tree_unflatten(treedef, stored_once_p.bind(*[jnp.asarray(x) for x in leaves]))
