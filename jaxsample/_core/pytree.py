"""The pytree machinery: how jaxsample's immutable objects become JAX pytrees."""

from __future__ import annotations

import dataclasses

import jax


def pytree_dataclass(cls=None, *, static: tuple[str, ...] = ()):
    """Freeze `cls` as a dataclass and register it as a pytree.

    Fields named in `static` (methods, table sizes) are metadata and trigger recompilation when
    they change; every other field is a leaf and may be a tracer.
    """

    def wrap(cls):
        cls = dataclasses.dataclass(frozen=True)(cls)
        names = [f.name for f in dataclasses.fields(cls)]
        data = [n for n in names if n not in static]
        meta = [n for n in names if n in static]
        return jax.tree_util.register_dataclass(cls, data_fields=data, meta_fields=meta)

    return wrap if cls is None else wrap(cls)


def pytree_attributes(leaves: tuple[str, ...], static: tuple[str, ...] = ()):
    """Register a class with its own `__init__` as a pytree: the attributes named in `leaves` are
    its leaves, those in `static` its metadata (hashable; a change recompiles).

    For samplers whose constructor checks its arguments and builds tables, which a dataclass
    cannot express. Unflattening bypasses `__init__`: JAX rebuilds the object from leaves that
    may be tracers or placeholders, and the checks and tables were done when it was first made.
    """

    def wrap(cls):
        def flatten(obj):
            return tuple(getattr(obj, n) for n in leaves), tuple(getattr(obj, n) for n in static)

        def unflatten(aux, children):
            obj = object.__new__(cls)
            for name, value in zip(leaves + static, tuple(children) + tuple(aux)):
                object.__setattr__(obj, name, value)
            return obj

        jax.tree_util.register_pytree_node(cls, flatten, unflatten)
        return cls

    return wrap
