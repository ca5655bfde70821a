"""The pytree machinery: one mechanism by which every jaxsample object becomes a JAX pytree.

`Pytree` is the base class (after distrax's `Jittable`): every subclass is registered with JAX when
it is defined, so a user's `class MySampler(jaxsample.Sampler)` can be passed through `jit`, `vmap`
and `grad` with no registration. Which attributes are leaves:

- declared: `pytree_dataclass(static=...)` (a frozen dataclass; every field not named static is a
  leaf) and `pytree_attributes(leaves, static)` (a class with its own `__init__`) state the split
  for the library's classes, and a subclass inherits it;
- inferred, for a class that declares nothing: an attribute holding a JAX or NumPy array, a Python
  float, a `Pytree`, or a container whose leaves are all arrays and floats is a leaf; everything else
  (str, int, bool, None, functions, tuples of those) is static metadata, hashed and compared by
  `jit` (a change recompiles). An int parameter is static: pass a float to make it traceable.

Unflattening bypasses `__init__`: JAX rebuilds objects from leaves that may be tracers or
placeholders, and the constructor's checks and tables were done when the object was first made.
The leaf/static split travels with the tree, so a rebuilt object flattens the same way whatever
its leaves hold.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

_FIELDS = "_pytree_fields_"  # an unflattened object remembers its split here (inferred classes)


def _holds_arrays(value) -> bool:
    """Whether an undeclared attribute is a leaf: arrays, floats, or pytrees made only of them."""
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, (jax.Array, np.ndarray, float, np.floating, complex, Pytree)):
        return True
    if value is None or isinstance(value, (str, bytes, int, np.integer)):
        return False
    leaves = jax.tree_util.tree_leaves(value)
    return bool(leaves) and all(_holds_arrays(leaf) for leaf in leaves)


def tree_fields(obj) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(leaf attribute names, static attribute names) of `obj`."""
    recorded = vars(obj).get(_FIELDS)
    if recorded is not None:
        return recorded
    split = getattr(obj, "_tree_fields", None)
    if split is not None:
        return split()
    cls = type(obj)
    if getattr(cls, "_pytree_leaves", None) is not None:
        return cls._pytree_leaves, cls._pytree_static
    names = [name for name in vars(obj) if name != _FIELDS]
    leaves = tuple(name for name in names if _holds_arrays(getattr(obj, name)))
    return leaves, tuple(name for name in names if name not in leaves)


def _flatten_with_keys(obj):
    leaves, static = fields = tree_fields(obj)
    children = tuple((jax.tree_util.GetAttrKey(name), getattr(obj, name)) for name in leaves)
    return children, (fields, tuple(getattr(obj, name) for name in static))


def _flatten(obj):
    leaves, static = fields = tree_fields(obj)
    return tuple(getattr(obj, name) for name in leaves), (fields, tuple(getattr(obj, name) for name in static))


def _unflattener(cls):
    declared = cls

    def unflatten(aux, children):
        (leaves, static), values = aux
        obj = object.__new__(declared)
        for name, value in zip(leaves + static, tuple(children) + values):
            object.__setattr__(obj, name, value)
        if getattr(declared, "_pytree_leaves", None) is None and not hasattr(declared, "_tree_fields"):
            object.__setattr__(obj, _FIELDS, (leaves, static))
        return obj

    return unflatten


def register(cls) -> type:
    """Register `cls` as a pytree with the mechanism described above (done for `Pytree` subclasses)."""
    jax.tree_util.register_pytree_with_keys(cls, _flatten_with_keys, _unflattener(cls), flatten_func=_flatten)
    return cls


class Pytree:
    """Base class: every subclass is a JAX pytree, with no registration (see the module docstring)."""

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        register(cls)


def _declare(cls, leaves: tuple[str, ...], static: tuple[str, ...]):
    cls._pytree_leaves = tuple(leaves)
    cls._pytree_static = tuple(static)
    if not issubclass(cls, Pytree):
        register(cls)
    return cls


def pytree_dataclass(cls=None, *, static: tuple[str, ...] = ()):
    """Freeze `cls` as a dataclass and make it a pytree.

    Fields named in `static` (methods, table sizes) are metadata and trigger recompilation when
    they change; every other field is a leaf and may be a tracer.
    """

    def wrap(cls):
        cls = dataclasses.dataclass(frozen=True)(cls)
        names = [f.name for f in dataclasses.fields(cls)]
        return _declare(cls, tuple(n for n in names if n not in static), tuple(n for n in names if n in static))

    return wrap if cls is None else wrap(cls)


def pytree_attributes(leaves: tuple[str, ...], static: tuple[str, ...] = ()):
    """Make a class with its own `__init__` a pytree: the attributes named in `leaves` are its
    leaves, those in `static` its metadata (hashable; a change recompiles).

    For samplers whose constructor checks its arguments and builds tables, which a dataclass
    cannot express.
    """
    return lambda cls: _declare(cls, leaves, static)


def to_float64(tree):
    """`tree` with every floating leaf cast to float64 (call under `jax.enable_x64(True)`): a sampler,
    light or BRDF evaluated in double precision, for the checks and the quadrature references."""

    def cast(leaf):
        if isinstance(leaf, (jax.Array, np.ndarray, float)) and jnp.issubdtype(jnp.result_type(leaf), jnp.floating):
            return jnp.asarray(leaf, jnp.float64)
        return leaf

    return jax.tree_util.tree_map(cast, tree)
