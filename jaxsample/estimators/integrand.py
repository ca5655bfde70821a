"""The integrand rule of every estimator: what f may return, and how its value is averaged.

f maps ONE sample to a pytree of arrays: one array of any fixed shape, or a tuple, a
dict, a registered dataclass ... of them. Every estimator that takes an integrand follows this
rule (`estimate`, `estimate_mis`, `estimate_antithetic`, `estimate_until`, `expectation`, `f` of
`estimate_ratio` and `estimate_control_variate`, and the per-sample `integrand_values` and
`expectation_values`):

- Each leaf is averaged on its own, and the result has f's structure with an `Estimate` (for
  `estimate_until` an `EstimateUntil`) at every leaf: `est["a"].mean`, `est[0].stderr`. A single
  array gives a single `Estimate`. All leaves are averaged over the same samples
  in one pass (one stream, one program), so they are as correlated as the samples make them.
- Integer and bool leaves are averaged as floats of the estimator's `dtype` (the mean of an
  indicator is a probability); leaves of a pytree are averaged in that dtype.
- Complex leaves: the real and imaginary parts are averaged as two real integrands, and every
  statistic of the leaf's `Estimate` is the complex number (statistic of the real parts) +
  i (statistic of the imaginary parts): `mean` is the complex mean, `stderr.real` and
  `stderr.imag` are the standard errors of its two parts, and so for `variance`, `max_abs` and
  `ess`. `interval()` is then the box mean ± z stderr, part by part, and `abs(stderr)` =
  sqrt(se_re² + se_im²) is the root-mean-square distance of the complex mean from the integral.
- Leaves of any other type (PRNG keys, float0, strings) are a `TypeError`, raised when the
  estimator is called, before anything runs.

Where a rule does not apply the estimator says so with a `TypeError`: `h` of `estimate_ratio` and
`g` of `estimate_control_variate` must be real scalars (a normalizer, a control with a known
integral), and `estimate_grad`/`expectation_grad` differentiate a real scalar (the gradient of a
pytree or of a complex value would be a Jacobian: differentiate one real component per call).

How. The leaves of each sample are packed into one real vector (a complex leaf as its real parts
then its imaginary parts), the engine streams that vector as one integrand, and the result is
unpacked leaf by leaf. A single real array is not packed at all: its program is unchanged.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import jax
import jax.numpy as jnp

from .._core.params import check_float64_enabled

__all__ = ["IntegrandLayout", "integrand_layout", "layout_of", "require_real", "require_real_scalar",
           "STATISTICS"]

# The fields of `Estimate` and `EstimateUntil` that have the shape of f's value.
STATISTICS = ("mean", "stderr", "variance", "max_abs", "ess", "khat", "nonzero")


@dataclasses.dataclass(frozen=True)
class _Leaf:
    shape: tuple[int, ...]
    size: int
    is_complex: bool
    start: int          # where its values begin in the packed vector (width size, twice if complex)


@dataclasses.dataclass(frozen=True)
class IntegrandLayout:
    """Where each leaf of f's value sits in the packed real vector the engine averages."""

    treedef: Any
    leaves: tuple[_Leaf, ...]
    width: int
    plain: bool         # one real array: no packing, the values keep f's shape

    @property
    def out_shape(self) -> tuple[int, ...]:
        """The shape of one sample's value as the engine sees it."""
        return self.leaves[0].shape if self.plain else (self.width,)

    def pack(self, values, dtype, lead: int = 1) -> jax.Array:
        """A pytree of arrays (*lead, *leaf shape) -> one real array (*lead, *out_shape)."""
        if self.plain:
            return values
        arrays = self.treedef.flatten_up_to(values)
        parts = []
        for leaf, value in zip(self.leaves, arrays):
            value = jnp.asarray(value)
            value = value.reshape(value.shape[:lead] + (leaf.size,))
            parts.extend([jnp.real(value), jnp.imag(value)] if leaf.is_complex else [value])
        return jnp.concatenate([p.astype(dtype) for p in parts], axis=-1)

    def unpack(self, packed: jax.Array, lead: int = 1):
        """The inverse of `pack`: (*lead, *out_shape) -> f's pytree of (*lead, *leaf shape)."""
        if self.plain:
            return packed
        lead_shape = packed.shape[:lead]
        arrays = []
        for leaf in self.leaves:
            part = packed[..., leaf.start:leaf.start + leaf.size]
            if leaf.is_complex:
                imaginary = packed[..., leaf.start + leaf.size:leaf.start + 2 * leaf.size]
                part = jax.lax.complex(part, imaginary)
            arrays.append(part.reshape(lead_shape + leaf.shape))
        return jax.tree_util.tree_unflatten(self.treedef, arrays)

    def unpack_result(self, result, fields=STATISTICS):
        """An `Estimate` (or `EstimateUntil`) of the packed vector -> f's pytree of them, one per
        leaf; the other fields (n, n_used, converged ...) are shared by every leaf."""
        if self.plain:
            return result
        per_field = {name: self.treedef.flatten_up_to(self.unpack(getattr(result, name), lead=0))
                     for name in fields}
        parts = [dataclasses.replace(result, **{name: per_field[name][i] for name in fields})
                 for i in range(len(self.leaves))]
        return jax.tree_util.tree_unflatten(self.treedef, parts)

    def pack_constant(self, value, dtype) -> jax.Array:
        """A constant shaped like one value of f (a matching pytree, or one array broadcast to
        every leaf, such as a baseline), packed like f's values."""
        if self.plain:
            return jnp.asarray(value)
        if jax.tree_util.tree_structure(value) != self.treedef:
            value = jax.tree_util.tree_unflatten(self.treedef, [value] * len(self.leaves))
        arrays = self.treedef.flatten_up_to(value)
        shaped = [jnp.broadcast_to(jnp.asarray(v), leaf.shape)[None] for v, leaf in zip(arrays, self.leaves)]
        return self.pack(jax.tree_util.tree_unflatten(self.treedef, shaped), dtype)[0]

    def magnitudes(self, packed: jax.Array) -> jax.Array:
        """|component| of a packed vector, except that both parts of a complex leaf get the modulus
        of the pair: the size a tolerance is compared with (the modulus of a complex stderr is the
        rms error of the complex mean; that of its mean, the mean's size)."""
        if self.plain:
            return jnp.abs(packed)
        pieces = []
        for leaf in self.leaves:
            part = packed[..., leaf.start:leaf.start + leaf.size]
            if leaf.is_complex:
                imaginary = packed[..., leaf.start + leaf.size:leaf.start + 2 * leaf.size]
                modulus = jnp.abs(jax.lax.complex(part, imaginary))
                pieces.extend([modulus, modulus])
            else:
                pieces.append(jnp.abs(part))
        return jnp.concatenate(pieces, axis=-1)


def _describe(tree) -> str:
    return str(jax.tree_util.tree_map(lambda leaf: f"{getattr(leaf, 'dtype', type(leaf).__name__)}"
                                                   f"{list(getattr(leaf, 'shape', ()))}", tree))


def layout_of(tree, owner: str, lead: int = 0) -> IntegrandLayout:
    """The layout of f's value `tree` (arrays or ShapeDtypeStructs with `lead` leading axes)."""
    arrays, treedef = jax.tree_util.tree_flatten(tree)
    if not arrays:
        raise TypeError(f"{owner}: the integrand must return an array or a pytree of arrays; got {tree!r}")
    leaves, start = [], 0
    for array in arrays:
        dtype = getattr(array, "dtype", None)
        if dtype is None or not (jnp.issubdtype(dtype, jnp.number) or jnp.issubdtype(dtype, jnp.bool_)):
            raise TypeError(f"{owner}: every value of the integrand must be a number (float, int, bool or "
                            f"complex); got {dtype or type(array).__name__} in {_describe(tree)}")
        shape = tuple(array.shape)[lead:]
        size = math.prod(shape)
        is_complex = bool(jnp.issubdtype(dtype, jnp.complexfloating))
        leaves.append(_Leaf(shape, size, is_complex, start))
        start += 2 * size if is_complex else size
    plain = treedef == jax.tree_util.tree_structure(0) and not leaves[0].is_complex
    return IntegrandLayout(treedef, tuple(leaves), start, plain)


def integrand_layout(f: Callable, sampler, dtype, owner: str) -> IntegrandLayout:
    """The layout of f's value at one sample of `sampler` (traced abstractly: nothing runs).

    Checks what every estimator averaging f needs before anything runs: a float64 `dtype` has
    jax_enable_x64 on (`check_float64_enabled`; without it JAX would compute in float32), and f
    returns at least one number per sample (an empty array has no mean to estimate).
    """
    check_float64_enabled(owner, dtype)
    u = jax.ShapeDtypeStruct((sampler.uniform_dims,), dtype)
    x = jax.eval_shape(sampler.warp, u)
    try:
        value = jax.eval_shape(f, x)
    except IndexError as error:
        shape = jax.tree.map(lambda a: tuple(a.shape), x)
        raise IndexError(f"{owner}: the integrand receives one sample x of shape {shape}, not a batch (the "
                         "estimator maps it over the samples): index its coordinates as x[k] or x[..., k], not "
                         f"x[:, k]; JAX said: {error}") from error
    layout = layout_of(value, owner)
    if layout.width == 0:
        raise ValueError(f"{owner}: the integrand must return at least one number per sample; it returns "
                         f"{_describe(value)}")
    return layout


def require_real(layout: IntegrandLayout, owner: str, name: str, why: str) -> None:
    """TypeError unless `name` returns one real array per sample (`why` says why the estimator
    needs that)."""
    if not layout.plain:
        kind = "a complex value" if layout.treedef == jax.tree_util.tree_structure(0) else "a pytree"
        raise TypeError(f"{owner}: '{name}' must return one real array per sample ({why}); it returns {kind}")


def require_real_scalar(layout: IntegrandLayout, owner: str, name: str, why: str) -> None:
    """`require_real`, and a ValueError unless that array is a scalar."""
    require_real(layout, owner, name, why)
    if layout.leaves[0].shape != ():
        raise ValueError(f"{owner}: '{name}' must return a scalar per sample ({why}); got shape "
                         f"{layout.leaves[0].shape}")
