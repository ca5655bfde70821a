"""The one pytree idiom of jaxsample: subclass `Pytree`, declare fields by annotation.

Every sampler, light, BRDF, region, source and result is a `Pytree` (after equinox's `Module`):

    class PhongLobe(Sampler):
        exponent: jax.Array = parameter(0.0, 1e7)   # a leaf, checked, with a declared range
        method: str = static_field(default="x")     # metadata: hashed by `jit`, a change recompiles

- Each subclass is a dataclass of its annotated fields (`ClassVar`s excepted) and is registered with
  JAX when it is defined. A class that writes its own `__init__` keeps it (its fields are then set
  there); otherwise the dataclass `__init__` is generated. Subclasses inherit the fields and add theirs.
- Which attributes are leaves: every annotated field, unless declared `static_field()` (or a
  `parameter(..., static=True)`). An attribute set in a user's `__init__` without an annotation is
  classified by its value: arrays, floats and complex numbers, `Pytree`s and containers made only of
  them are leaves; str, int, bool, None and functions are static (an int is static: pass a float to
  make it traceable).
- Immutable: once the constructor returns, assigning an attribute raises
  `dataclasses.FrozenInstanceError`; make a new object (the constructor, or `dataclasses.replace`
  for a class with the generated `__init__`).
- `parameter(low, high, ...)` declares a parameter's range once: assigning a concrete value outside
  it raises `ValueError` naming the parameter and the range; `declared_ranges_hold` gives the traced
  test the samplers use (an invalid traced parameter makes every output NaN, see `Sampler`); the
  class docstring lists the ranges; the contract tests take their hard cases from it.

Unflattening bypasses `__init__`: JAX rebuilds objects from leaves that may be tracers or
placeholders, and the constructor's checks and tables were done when the object was first made.
The leaf/static split travels with the tree, so a rebuilt object flattens the same way whatever its
leaves hold.
"""

from __future__ import annotations

import dataclasses
import inspect

import jax
import jax.numpy as jnp
import numpy as np

from .params import as_parameter, check_number, check_parameter, in_range, interval_text

_FIELDS = "_pytree_fields_"  # an unflattened object remembers its split here
_FROZEN = "_pytree_frozen_"  # set once the constructor has returned
_CHECKED = "_pytree_checked_"  # parameters checked (`Sampler`'s invalid-parameter rule)
_MARKERS = (_FIELDS, _FROZEN, _CHECKED)
_PARAMETER = "jaxsample.parameter"
_STATIC = "jaxsample.static"


@dataclasses.dataclass(frozen=True)
class Parameter:
    """A parameter's declaration: its closed or open range, its own rank (0 for a scalar, 1 for a
    vector: leading dimensions beyond it make a batch of distributions), whether it is static."""

    low: float = -np.inf
    high: float = np.inf
    low_open: bool = False
    high_open: bool = False
    rank: int = 0
    static: bool = False
    doc: str = ""
    optional: bool = False  # None is allowed (declared with default=None)
    hard_cases: tuple = ()  # values the contract suite checks instead of the bounds' neighbours

    @property
    def bounded(self) -> bool:
        return bool(np.isfinite(self.low) or np.isfinite(self.high))

    def check(self, owner: str, name: str, value) -> None:
        """`TypeError` unless `value` is a number (or an array of them); `ValueError` naming `owner`'s
        parameter `name` and the range for a concrete value outside it, NaN included, when bounded."""
        if not self.bounded:
            check_number(owner, name, value)
            return
        check_parameter(owner, name, value, self.low, self.high, low_open=self.low_open, high_open=self.high_open)

    def contains(self, value):
        """Whether every entry of `value` is in range: a NumPy bool when concrete, a JAX one when traced."""
        return in_range(value, self.low, self.high, low_open=self.low_open, high_open=self.high_open)

    def describe(self) -> str:
        return interval_text(self.low, self.high, self.low_open, self.high_open)

    def edge_values(self, dtype=np.float32) -> list[tuple[float, float]]:
        """(inside, outside) at each finite bound, one normal `dtype` step apart: the hard cases
        the contract suite checks (valid and finite inside; refused, or NaN when traced, outside).
        `hard_cases`, when declared, replace the inside values (a rate of 1e-38 is in range but
        its samples overflow float32: the class says which values it is tested at)."""
        info = np.finfo(dtype)

        def step(bound, direction):
            return float(bound + direction * max(float(info.tiny), abs(bound) * float(info.eps)))

        pairs = []
        if np.isfinite(self.low):
            low = float(dtype(self.low))
            pairs.append((step(low, 1) if self.low_open else low, low if self.low_open else step(low, -1)))
        if np.isfinite(self.high):
            high = float(dtype(self.high))
            pairs.append((step(high, -1) if self.high_open else high, high if self.high_open else step(high, 1)))
        if self.hard_cases:
            outside = [o for _, o in pairs]
            inside = list(self.hard_cases)
            pairs = list(zip(inside, outside + outside[-1:] * (len(inside) - len(outside)))) if outside else []
        return pairs


def parameter(low: float = -np.inf, high: float = np.inf, *, low_open: bool = False, high_open: bool = False,
              rank: int = 0, static: bool = False, doc: str = "", hard_cases: tuple = (), **field_options):
    """Declare a parameter field with its range (see the module docstring); `hard_cases` are the
    values it is tested at when the range's own ends are not representable in float32 arithmetic
    (`Parameter.edge_values`); `field_options` go to `dataclasses.field` (a `default`, say)."""
    spec = Parameter(float(low), float(high), low_open, high_open, rank, static, doc,
                     optional=field_options.get("default", dataclasses.MISSING) is None,
                     hard_cases=tuple(float(v) for v in hard_cases))
    return dataclasses.field(metadata={_PARAMETER: spec}, **field_options)


def static_field(**field_options):
    """Declare a field that is static metadata (a method name, a table size, a function)."""
    return dataclasses.field(metadata={_STATIC: True}, **field_options)


def parameters(cls_or_obj) -> dict[str, Parameter]:
    """The declared parameters of a `Pytree` class (or of an object's class), by name."""
    cls = cls_or_obj if isinstance(cls_or_obj, type) else type(cls_or_obj)
    return dict(getattr(cls, "_parameters_", {}))


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
    """(leaf attribute names, static attribute names) of `obj`: its declared split, then its
    undeclared attributes by value."""
    state = vars(obj)
    recorded = state.get(_FIELDS)
    if recorded is not None:
        return recorded
    cls = type(obj)
    leaves, static = cls._field_leaves_, cls._field_static_
    declared = cls._field_names_
    extra = [name for name in state if name not in declared and name not in _MARKERS]
    if extra:
        leaves = leaves + tuple(n for n in extra if _holds_arrays(state[n]))
        static = static + tuple(n for n in extra if not _holds_arrays(state[n]))
    return leaves, static


def _aux(obj, fields):
    return fields, tuple(getattr(obj, name) for name in fields[1]), vars(obj).get(_CHECKED, False)


def _flatten_with_keys(obj):
    fields = tree_fields(obj)
    children = tuple((jax.tree_util.GetAttrKey(name), getattr(obj, name)) for name in fields[0])
    return children, _aux(obj, fields)


def _flatten(obj):
    fields = tree_fields(obj)
    return tuple(getattr(obj, name) for name in fields[0]), _aux(obj, fields)


def _unflattener(cls):
    def unflatten(aux, children):
        (leaves, static), values, checked = aux
        obj = object.__new__(cls)
        for name, value in zip(leaves + static, tuple(children) + values):
            object.__setattr__(obj, name, value)
        object.__setattr__(obj, _FIELDS, (leaves, static))
        object.__setattr__(obj, _FROZEN, True)
        if checked:
            object.__setattr__(obj, _CHECKED, True)
        return obj

    return unflatten


def register_foreign_base(cls, flatten, unflatten) -> None:
    """Register as a pytree a class whose base another library owns, so that it cannot be a `Pytree`
    (the adapters' TFP distribution subclasses `tfp.distributions.Distribution`): `flatten(obj)` ->
    (children, aux), `unflatten(aux, children)` -> obj. The one exception to the idiom, kept here
    so that every registration of the package is in this module."""
    jax.tree_util.register_pytree_node(cls, flatten, unflatten)


def mark_checked(obj) -> None:
    """Mark `obj` (a copy the library made, never a user's object) as having had its parameters
    checked; the mark is part of the tree structure, so JAX's rebuilt copies carry it."""
    object.__setattr__(obj, _CHECKED, True)


def is_checked(obj) -> bool:
    return bool(vars(obj).get(_CHECKED, False))


class _FrozenAfterInit(type):
    """Metaclass of `Pytree`: an instance is frozen once its constructor (and `__post_init__`) returns."""

    def __call__(cls, *args, **kwargs):
        obj = super().__call__(*args, **kwargs)
        object.__setattr__(obj, _FROZEN, True)
        return obj


class Pytree(metaclass=_FrozenAfterInit):
    """Base class of every jaxsample object: a frozen dataclass-style JAX pytree (module docstring)."""

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        own_init = "__init__" in cls.__dict__
        cls._custom_init_ = own_init or any(getattr(base, "_custom_init_", False) for base in cls.__mro__[1:])
        dataclasses.dataclass(init=not cls._custom_init_, repr=False, eq=False)(cls)
        fields = dataclasses.fields(cls)
        cls._parameters_ = {f.name: f.metadata[_PARAMETER] for f in fields if _PARAMETER in f.metadata}
        is_static = lambda f: f.metadata.get(_STATIC, False) or getattr(f.metadata.get(_PARAMETER), "static", False)
        cls._field_names_ = frozenset(f.name for f in fields)
        cls._field_leaves_ = tuple(f.name for f in fields if not is_static(f))
        cls._field_static_ = tuple(f.name for f in fields if is_static(f))
        _document_parameters(cls)
        # The metaclass's __call__ would otherwise be the signature `help` and `inspect` show.
        init = inspect.signature(cls.__init__)
        cls.__signature__ = init.replace(parameters=list(init.parameters.values())[1:])
        jax.tree_util.register_pytree_with_keys(cls, _flatten_with_keys, _unflattener(cls), flatten_func=_flatten)

    def __setattr__(self, name, value):
        if vars(self).get(_FROZEN):
            raise dataclasses.FrozenInstanceError(
                f"{type(self).__name__} is immutable: cannot assign '{name}' after construction; build a new one")
        spec = type(self)._parameters_.get(name)
        if spec is not None and not (value is None and spec.optional):
            value = as_parameter(value)
            spec.check(type(self).__name__, name, value)
        object.__setattr__(self, name, value)

    def __delattr__(self, name):
        raise dataclasses.FrozenInstanceError(f"{type(self).__name__} is immutable: cannot delete '{name}'")

    def __repr__(self):
        leaves, static = tree_fields(self)
        shown = ", ".join(f"{name}={getattr(self, name)!r}" for name in leaves + static)
        return f"{type(self).__name__}({shown})"


def declared_ranges_hold(obj):
    """Whether every declared, non-static parameter of `obj` is in its range (a NumPy bool when all
    are concrete, else a JAX bool), or None when `obj` declares no bounded parameter."""
    checks = [spec.contains(getattr(obj, name)) for name, spec in parameters(obj).items()
              if spec.bounded and not spec.static and getattr(obj, name, None) is not None]
    if not checks:
        return None
    if all(isinstance(c, (bool, np.bool_)) for c in checks):
        return np.bool_(all(bool(c) for c in checks))
    out = checks[0]
    for c in checks[1:]:
        out = jnp.logical_and(out, c)
    return out


def _document_parameters(cls) -> None:
    """Append the declared ranges to the class docstring (what `help()` shows)."""
    own = {name: spec for name, spec in cls._parameters_.items() if spec.bounded or spec.doc}
    if not own or cls.__doc__ is None:
        return
    lines = [f"        {name}: {spec.describe()}{' — ' + spec.doc if spec.doc else ''}"
             + (f" (tested at {', '.join(f'{v:g}' for v in spec.hard_cases)})" if spec.hard_cases else "")
             for name, spec in own.items()]
    marker = "    Declared parameter ranges"
    doc = cls.__doc__.split("\n\n" + marker)[0].rstrip()
    cls.__doc__ = (doc + "\n\n" + marker + " (checked when concrete; NaN outputs when traced):\n"
                   + "\n".join(lines) + "\n")


def to_float64(tree):
    """`tree` with every floating leaf cast to float64 (call under `jax.enable_x64(True)`): a sampler,
    light or BRDF evaluated in double precision, for the checks and the quadrature references."""

    def cast(leaf):
        if isinstance(leaf, (jax.Array, np.ndarray, float)) and jnp.issubdtype(jnp.result_type(leaf), jnp.floating):
            return jnp.asarray(leaf, jnp.float64)
        return leaf

    return jax.tree_util.tree_map(cast, tree)

