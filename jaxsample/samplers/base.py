"""The sampler contract shared by every distribution in jaxsample.

A sampler is an immutable pytree whose float parameters are leaves, so it can be built inside
`jit`, `vmap` and `grad`. It is a *warp* from the unit hypercube [0, 1)^uniform_dims onto its
domain, together with the density of the warped points with respect to the domain's measure
(solid angle, area, length or counting, as each class states) and, where the warp is a
bijection, its inverse.
"""

from __future__ import annotations

import functools
import inspect
import operator
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.entry import array_leaves
from .._core.params import resolve_float_dtype
from .._core.pytree import Pytree, declared_ranges_hold, is_checked, mark_checked, parameters, tree_fields
from .._core.numerics import safe_log


def checked(sampler):
    """`sampler` with the invalid-parameter rule applied (`_poisoned`), marked as checked.

    The mark travels with the pytree (`jaxsample._core.pytree.mark_checked`), so the samplers
    nested in it, and the copies JAX rebuilds from it inside a loop, are not checked again: a loop
    (`sample`, the estimators) checks once, outside, by calling `checked` before it. A sampler the
    user holds is never marked (the mark is set on a copy)."""
    return _checked_with_poison(sampler)[0]


def _checked_with_poison(sampler):
    """(`checked(sampler)`, the poison `_poisoned` applied: None when none was needed)."""
    if is_checked(sampler):
        return sampler, None
    result, poison = _poisoned(sampler)
    if result is sampler:
        leaves, treedef = jax.tree_util.tree_flatten(sampler)
        result = jax.tree_util.tree_unflatten(treedef, leaves)
    for s in _samplers_in(result):
        mark_checked(s)
    return result, poison


def _point_argument(method) -> str:
    """The name of a point method's point argument (`u` or `x`), for calls by keyword."""
    return list(inspect.signature(method).parameters)[1]


_CONTRACT_DOCS = {
    "warp": "The point of the domain that the uniforms u (..., uniform_dims) in [0, 1) map to.",
    "warp_with_pdf": "(warp(u), pdf(warp(u))), the density computed from u where that is more exact.",
    "pdf": "The density at x over the sampler's `measure`, 0 outside the support (never NaN).",
    "log_pdf": "log of `pdf`, -inf outside the support (never NaN).",
    "inverse": "The uniforms u with warp(u) = x (the warp is a bijection).",
}


def point_method(method=None, *, batched: bool = True):
    """Decorator of a sampler's per-point method written for ONE distribution (`warp`, `pdf`, ...):
    the decorated method obeys the invalid-parameter rule (`checked`) and, with `batched`, maps over
    a batch of distributions (`apply_point`). Every library sampler decorates its point methods; a
    user's sampler may too (undecorated, its methods run as written, and `sample`, `prob`,
    `log_prob` and the estimators still batch and check them).

    Called eagerly (concrete parameters and points, no extra arguments) a batched method runs as
    one compiled program (cached per class, shapes and dtypes), not op by op.
    """
    if method is None:
        return functools.partial(point_method, batched=batched)
    if not batched:
        @functools.wraps(method)
        def checked_method(self, *args, **kwargs):
            sampler, poison = _checked_with_poison(self)
            return _poison_outputs(method(sampler, *args, **kwargs), poison)

        return checked_method

    name, argument = method.__name__, _point_argument(method)

    @functools.wraps(method)
    def batched_method(self, *args, **kwargs):
        if args:
            point, args = args[0], args[1:]
        elif argument in kwargs:
            point = kwargs.pop(argument)
        else:
            raise TypeError(f"{type(self).__name__}.{name}: missing the point argument '{argument}'")
        return _apply(self, method, argument == "u", point, args, kwargs, compiled)

    compiled = jax.jit(lambda sampler, point: batched_method(sampler, point))
    batched_method.one_distribution = method
    if batched_method.__doc__ is None and name in _CONTRACT_DOCS:
        batched_method.__doc__ = _CONTRACT_DOCS[name]
    return batched_method


def apply_point(sampler, name: str, point):
    """`sampler.<name>(point)` batched over the sampler's batch and checked, whether or not the
    class decorated that method with `point_method`."""
    method = getattr(type(sampler), name)
    if hasattr(method, "one_distribution"):
        return method(sampler, point)
    return _apply(sampler, method, _point_argument(method) == "u", point, (), {}, None)


def _apply(sampler, method, takes_u: bool, point, args, kwargs, compiled):
    """`method` (written for one distribution) at `point`: compiled when eager and concrete, per
    batch member (`jax.vmap` over the flattened batch) when the sampler has a batch."""
    if (compiled is not None and not args and not kwargs and isinstance(point, (jax.Array, np.ndarray, np.generic))
            and array_leaves((sampler, point), concrete=True)):
        return compiled(sampler, point)
    batch = sampler.batch_shape
    if not batch:
        sampler, poison = _checked_with_poison(sampler)
        return _poison_outputs(method(sampler, point, *args, **kwargs), poison)
    refuse_unbatchable("", sampler)
    core = (sampler.uniform_dims,) if takes_u else tuple(sampler.event_shape)
    point = jnp.asarray(point)
    full = tuple(jnp.broadcast_shapes(point.shape, batch + core))
    sample = full[: len(full) - len(batch) - len(core)]
    count = int(np.prod(sample, dtype=np.int64))
    size = int(np.prod(batch, dtype=np.int64))
    points = jnp.broadcast_to(point, full).reshape((count, size) + core)
    one = lambda member, p: _apply(member, method, takes_u, p, args, kwargs, None)
    out = over_members(one, sampler, points, axis=1)
    return jax.tree_util.tree_map(lambda o: o.reshape(sample + o.shape[1:]), out)


def refuse_unbatchable(owner: str, sampler) -> None:
    """ValueError for a batch of a sampler whose tables are built per distribution (`batchable` False)."""
    if sampler.batch_shape and not sampler.batchable:
        raise ValueError(f"{owner + ': ' if owner else ''}{type(sampler).__name__} cannot be batched (its tables are "
                         f"built per distribution); got parameters with batch_shape {sampler.batch_shape}; "
                         "build one per member")


def over_members(one, sampler, *operands, axis: int = 0):
    """`one(member, *operands)` for each member of a batched sampler: the package's one batch map.

    `jax.vmap` over the flattened batch (`flat_batch`: every member's parameters at axis 0), each
    operand split at `axis` (its flat batch there), and every leaf of the result with the flat
    batch at `axis` reshaped to `batch_shape` there. The point methods (`_apply`, and so `sample` of
    a batch) and the estimators (`jaxsample.estimators.plain.over_batch`) map through it."""
    batch = sampler.batch_shape
    in_axes = (0,) + (axis,) * len(operands)
    out = jax.vmap(one, in_axes=in_axes, out_axes=axis)(flat_batch(sampler, batch), *operands)
    return jax.tree_util.tree_map(lambda o: o.reshape(o.shape[:axis] + batch + o.shape[axis + 1:]), out)



class Sampler(Pytree):
    """Base class: `sample`, `sample_with_pdf`, `prob`, `log_prob`, `log_pdf` and `warp_with_pdf`
    from `warp` and `pdf`.

    Subclasses define `uniform_dims`, `warp(u)`, `pdf(x)` and `domain()` (which also gives
    `event_shape` and `measure`, unless the class states them); they may override `warp_with_pdf`
    when the density is more accurate from u than from x (sharp lobes), and `inverse` where the
    warp is a bijection. A subclass is a `Pytree` (`jaxsample._core.pytree`): a frozen
    dataclass-style pytree whose annotated fields are leaves, traceable under `jit`, `vmap` and
    `grad`, unless declared `static_field()`.

    Parameters are declared once, as fields: `exponent: jax.Array = parameter(0.0, 1e7)`. The
    declaration states the range and the parameter's own rank (0 for a scalar such as an exponent,
    1 for a vector such as a vertex).

    Batches (as in TFP and distrax): a declared parameter with leading dimensions beyond its rank
    makes a batch of distributions, and `batch_shape` is the broadcast of those leading shapes;
    undeclared fields (a user's own arrays) are taken whole, never as a batch, and nested samplers
    declare their own. A per-point method written for one distribution and decorated with
    `point_method` (every library sampler's `warp`, `warp_with_pdf`, `pdf`, `log_pdf`, `inverse`)
    takes points of shape `sample_shape + batch_shape + core` (or broadcastable to it) and evaluates
    each batch member at its own points (`jax.vmap` over the flattened batch); `prob`, `log_prob`,
    `sample` and the estimators do the same for undecorated methods (`apply_point`).
    `sample(key, sample_shape)` returns `sample_shape + batch_shape + event_shape`. A sampler whose
    tables cannot be batched sets `batchable = False` and refuses batched parameters.

    Invalid parameters (the one rule, docs/design.md "Invalid input"): a concrete parameter outside
    its declared range raises `ValueError` naming it and the range when it is assigned, in the
    constructor (a non-number raises `TypeError`); a traced one cannot raise, so
    `_parameters_valid()` (the declared ranges, and any rule a class adds) poisons the parameters
    with NaN before a point method runs: float values, densities and gradients are then NaN (integer
    outputs, such as `Discrete`'s indices, cannot be; their densities are), and estimators report a
    NaN mean with an infinite stderr, never a finite number. The same holds for concrete parameters
    that never met a constructor (a sampler rebuilt by `jax.tree_util.tree_map`, an optimizer's
    step). Loops check once, outside (`checked`).
    """

    uniform_dims: ClassVar[int]
    # Uniform coordinates that are periodic (an azimuth 2πu): u and u ± 1 give the same point, so
    # round-trip checks compare them modulo 1.
    periodic_dims: ClassVar[tuple[int, ...]] = ()
    batchable: ClassVar[bool] = True
    # Whether `warp` is a deterministic map of its uniforms (every library sampler). A sampler that
    # only uses its uniforms to make a key and draws with it (`jaxsample.adapters.from_distribution`)
    # sets False: antithetic pairs, stratified and QMC points are then refused (`check_uniforms`).
    transports_uniforms: ClassVar[bool] = True

    def _parameters_valid(self):
        """A boolean (scalar) array: whether the parameters are in range; None if always valid.

        The declared ranges (`parameter(low, high)` fields) are tested here; a class with a rule
        no range states (weights that sum to more than 0) extends this with `super()`."""
        return declared_ranges_hold(self)

    @property
    def event_shape(self) -> tuple[int, ...]:
        """The shape of one sample: the domain's (`domain().event_shape`) unless the class states it."""
        return tuple(self.domain().event_shape)

    @property
    def measure(self) -> str | None:
        """The measure the density is over ("solid angle", "area", "length", "counting", ...): the
        domain's unless the class states it. MIS refuses to combine samplers whose densities are
        over different measures."""
        return getattr(self.domain(), "measure", None)

    @property
    def batch_shape(self) -> tuple[int, ...]:
        """The broadcast of the parameters' leading (batch) dimensions; () for one distribution."""
        return _batch_shape(self)

    def warp(self, u: jax.Array) -> jax.Array:
        """The point of the domain that the uniforms u (..., uniform_dims) in [0, 1) map to."""
        raise NotImplementedError(f"{type(self).__name__} does not define warp(u)")

    def pdf(self, x: jax.Array) -> jax.Array:
        """The density at x over the sampler's `measure`, 0 outside the support (never NaN)."""
        raise NotImplementedError(f"{type(self).__name__} does not define pdf(x)")

    @point_method
    def log_pdf(self, x: jax.Array) -> jax.Array:
        """log of `pdf`, -inf outside the support (never NaN)."""
        return safe_log(self.pdf(x))

    @point_method
    def warp_with_pdf(self, u: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(warp(u), pdf(warp(u))); subclasses compute the density from u where that is more exact."""
        x = self.warp(u)
        return x, self.pdf(x)

    def inverse(self, x: jax.Array) -> jax.Array:
        """The uniforms u with warp(u) = x, where the warp is a bijection."""
        raise NotImplementedError(_no_inverse(type(self)))

    def flow(self, x: jax.Array) -> jax.Array:
        """The sample through x moving with the parameters: warp(inverse(x)) with x and the uniforms
        held, so that its derivative is the sample flow V = ∂T(u; θ)/∂θ at u = T⁻¹(x) (what the
        boundary terms subtract, `jaxsample.estimators.boundary`). A class overrides it where u cannot
        carry what the derivative needs (`PhongLobe`: the lobe's tail, where u₀ rounds to 1)."""
        return self.warp(jax.lax.stop_gradient(self.inverse(jax.lax.stop_gradient(x))))

    def measure_valued_terms(self, u: jax.Array):
        """(θ, x, x', c) for `gradient="measure_valued"` (`jaxsample.expectation`), from uniforms u of
        shape (..., uniform_dims + 1): the derivative in the parameter θ as a scaled difference of
        two expectations, d/dθ E_{p_θ}[g] = c (E[g(x)] - E[g(x')]), x ~ p_θ and x' drawn from the
        second density of the decomposition (Mohamed et al. 2020, section 6). A class with such a
        decomposition overrides this (`PhongLobe`: its exponent); the default has none and raises
        ValueError."""
        raise ValueError(f"{type(self).__name__} has no measure-valued decomposition (gradient='measure_valued' "
                         "needs a sampler that defines measure_valued_terms, as PhongLobe does for its exponent): "
                         "use 'pathwise' or 'score'")

    def prob(self, x: jax.Array) -> jax.Array:
        """The density at `x` (the name TFP, distrax and NumPyro use): `pdf`, batched and checked."""
        return apply_point(self, "pdf", x)

    def log_prob(self, x: jax.Array) -> jax.Array:
        """The log density at `x` (TFP's, distrax's and NumPyro's name): `log_pdf`, batched and checked."""
        return apply_point(self, "log_pdf", x)

    @property
    def has_inverse(self) -> bool:
        return type(self).inverse is not Sampler.inverse

    def domain(self):
        """The `jaxsample.domains` object the checks integrate over and bin on."""
        raise NotImplementedError

    def sample(self, key=None, sample_shape=(), dtype=None, *, seed=None, shape=None) -> jax.Array:
        """Samples of shape `sample_shape + batch_shape + event_shape` drawn with `key`.

        `key` (or `seed=`, the keyword TFP and distrax use) is a JAX key: `jax.random.key(s)` or a
        legacy `jax.random.PRNGKey(s)`, which draws the same stream (`uniforms.as_key`).
        `shape=` is the former name of `sample_shape`. The i-th sample (in C order over
        `sample_shape + batch_shape`) is `warp` of the i-th point of the estimators'
        counter-based Philox stream (`jaxsample.uniforms`, several times faster than threefry on
        CPU, strictly inside (0, 1)): batch members draw independent points. One distribution
        is computed in one compiled loop (see `_draw`).
        """
        return draw(self, *key_and_shape(key, sample_shape, seed, shape, "sample"), dtype, "warp")

    def sample_with_pdf(self, key=None, sample_shape=(), dtype=None, *, seed=None, shape=None):
        """(samples, their densities); the density is the one `pdf` states, computed alongside."""
        return draw(self, *key_and_shape(key, sample_shape, seed, shape, "sample_with_pdf"), dtype,
                    "warp_with_pdf")

    def sample_and_log_prob(self, key=None, sample_shape=(), dtype=None, *, seed=None, shape=None):
        """(samples, their log densities), the pair distrax and TFP name `sample_and_log_prob`: the
        samples of `sample` for the same key and the log of the density `sample_with_pdf` computes
        alongside them (from u where the class does so), -inf where that density is 0."""
        x, density = draw(self, *key_and_shape(key, sample_shape, seed, shape, "sample_and_log_prob"), dtype,
                          "warp_with_pdf")
        return x, safe_log(density)




def _no_inverse(cls) -> str:
    """Why `cls` has no inverse: a library sampler's warp is not a bijection (a mixture, a
    rejection loop, a discrete choice); a user's class has simply not written one."""
    library = [c for c in cls.__mro__ if issubclass(c, Sampler) and c not in (Sampler, WrapsSampler)
               and c.__module__.startswith("jaxsample.")]
    if library:
        return f"{cls.__name__} has no inverse: its warp is not a bijection"
    return (f"{cls.__name__} does not define inverse(x); write one (the u in [0, 1)^uniform_dims with "
            f"warp(u) = x) to use inverse and what needs it (jaxsample.testing.inverse_error, the "
            f"boundary terms of jaxsample.edges)")


def _is_shape(value) -> bool:
    """Whether `value` is a sample shape as written by hand: an int or a tuple or list of ints."""
    def is_int(v):
        return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))
    return is_int(value) or (isinstance(value, (tuple, list)) and all(is_int(v) for v in value))


def key_and_shape(key, sample_shape, seed, shape, owner):
    """(key, sample shape) of a `sample`-like call: `sample(key, sample_shape)`, with `seed=` for
    the key and `shape=` for the sample shape as aliases.

    TFP's spelling `sample((5,), seed=key)` is accepted: the key is given by name, and what stands
    in the key's place is an int or a tuple or list of ints, which no key is, so it can only be the
    sample shape. Both positionally in TFP's order, `sample((5,), key)`, is refused with the
    library's own call (a TypeError, as for every other key mistake).
    """
    if seed is not None and _is_shape(key) and sample_shape in ((), None) and shape is None:
        key, sample_shape = None, key
    elif seed is None and _is_shape(key) and isinstance(sample_shape, (jax.Array, np.ndarray)):
        shown = tuple(key) if isinstance(key, (tuple, list)) else (key,)
        raise TypeError(f"{owner}: the key comes first: {owner}(key, {shown}), "
                        f"or with the key by name as in TFP, {owner}({key!r}, seed=key)")
    return _one_key(key, seed, owner), _one_shape(sample_shape, shape)


def _one_key(key, seed, owner):
    if key is not None and seed is not None:
        raise TypeError(f"{owner}: give the key once, as 'key' or as its alias 'seed'")
    if key is None and seed is None:
        raise TypeError(f"{owner}: missing the key: pass jax.random.key(...) as 'key' (or 'seed')")
    return seed if key is None else key


def _one_shape(sample_shape, shape):
    if shape is not None and sample_shape not in ((), None):
        raise TypeError("sample: give the shape once, as 'sample_shape' or as its former name 'shape'")
    return sample_shape if shape is None else shape


def _leaf_ranks(obj) -> list[int | None]:
    """The own rank of each leaf of `obj`, in `jax.tree_util.tree_leaves` order (None: the whole
    leaf is its own shape, as for every attribute not declared a `parameter`)."""
    names, _ = tree_fields(obj)
    declared = {name: spec.rank for name, spec in parameters(obj).items()}
    ranks = []
    for name in names:
        for item in jax.tree_util.tree_leaves(getattr(obj, name), is_leaf=lambda v: isinstance(v, Pytree)):
            ranks.extend(_leaf_ranks(item) if isinstance(item, Pytree) else [declared.get(name)])
    return ranks


def _batch_shape(sampler) -> tuple[int, ...]:
    shapes = []
    for leaf, rank in zip(jax.tree_util.tree_leaves(sampler), _leaf_ranks(sampler)):
        shape = np.shape(leaf)
        if rank is not None:
            shapes.append(tuple(shape[: max(len(shape) - rank, 0)]))
    try:
        return tuple(jnp.broadcast_shapes(*shapes)) if shapes else ()
    except ValueError:
        raise ValueError(f"{type(sampler).__name__}: the batch shapes of its parameters must broadcast "
                         f"(equal, or 1 or missing where they differ); got {_batch_shapes_named(sampler)}") from None


def _batch_shapes_named(sampler) -> str:
    """'path (batch shape)' for each batchable parameter of `sampler`: for the message of `_batch_shape`."""
    paths = [jax.tree_util.keystr(path) for path, _ in jax.tree_util.tree_flatten_with_path(sampler)[0]]
    named = []
    for path, leaf, rank in zip(paths, jax.tree_util.tree_leaves(sampler), _leaf_ranks(sampler)):
        shape = np.shape(leaf)
        if rank is not None:
            named.append(f"{path.lstrip('.')} {tuple(shape[: max(len(shape) - rank, 0)])}")
    return ", ".join(named)


def flat_batch(sampler, batch: tuple[int, ...]):
    """`sampler` with every parameter broadcast to `batch` and the batch flattened to one leading
    axis: a pytree that `jax.vmap(..., in_axes=0)` splits into its batch members."""
    refuse_class("", "sampler", sampler)
    size = int(np.prod(batch, dtype=np.int64))
    leaves, treedef = jax.tree_util.tree_flatten(sampler)
    flat = []
    for leaf, rank in zip(leaves, _leaf_ranks(sampler)):
        leaf = jnp.asarray(leaf)
        own = leaf.shape if rank is None else leaf.shape[leaf.ndim - rank:] if rank else ()
        flat.append(jnp.broadcast_to(leaf, batch + own).reshape((size,) + own))
    return jax.tree_util.tree_unflatten(treedef, flat)


def refuse_class(owner: str, name: str, value) -> None:
    """ValueError for a sampler class given where an instance is needed (`UniformSphere` for
    `UniformSphere()`), naming `owner`'s parameter `name`: read from a class, `batch_shape` and
    the other properties are property objects, which fail far from the argument."""
    if isinstance(value, type) and issubclass(value, Sampler):
        try:
            needs = any(p.default is inspect.Parameter.empty and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
                        for p in inspect.signature(value).parameters.values())
        except (TypeError, ValueError):
            needs = True
        call = f"{value.__name__}(...)" if needs else f"{value.__name__}()"
        raise ValueError(f"{owner + ': ' if owner else ''}parameter '{name}' must be a sampler instance; "
                         f"got the class {value.__name__}: call it, {call}")


def check_sampler(owner: str, name: str, value) -> None:
    """Raise unless `value` is a sampler instance: `ValueError` for a sampler class (naming the
    call that makes an instance), `TypeError` for anything else that is not a `Sampler`."""
    refuse_class(owner, name, value)
    if not isinstance(value, Sampler):
        raise TypeError(f"{owner}: parameter '{name}' must be a jaxsample.Sampler instance; "
                        f"got {type(value).__name__} {value!r}")


def check_uniforms(sampler, uniforms, owner: str, *, antithetic: bool = False) -> None:
    """Raise where the estimator relies on the structure of the uniforms (stratified or QMC points;
    with `antithetic`, the pair u, 1 - u) and a sampler in `sampler` does not warp them but draws
    from a key made of them (`transports_uniforms` False: a distribution of NumPyro, distrax or TFP
    through `jaxsample.adapters.from_distribution`). There the points' structure is lost in the key
    hash: the estimate would stay unbiased but gain nothing, so the caller is told instead."""
    from ..uniforms import as_source

    keyed = [type(s).__name__ for s in _samplers_in(sampler) if not s.transports_uniforms]
    if not keyed:
        return
    if antithetic:
        raise ValueError(f"{owner}: needs a sampler whose warp maps u and 1 - u to paired points; {keyed[0]} draws "
                         "from a key (jaxsample.adapters.from_distribution), so antithetic pairs are unrelated: "
                         "use estimate")
    source = as_source(uniforms)
    if source.name != "random":
        raise ValueError(f"{owner}: parameter 'uniforms' must be 'random' for {keyed[0]}, which draws from a key "
                         f"(jaxsample.adapters.from_distribution): the structure of {source.name!r} points does "
                         "not survive the key hash; got " + repr(uniforms))


def check_unbatched(sampler, owner: str) -> None:
    """Raise for anything but a sampler instance (`check_sampler`), and for a batched sampler
    where an entry point takes one distribution."""
    check_sampler(owner, "sampler", sampler)
    if sampler.batch_shape:
        raise ValueError(f"{owner}: takes one distribution; the sampler has batch_shape {sampler.batch_shape} "
                         "(jax.vmap over the batch, or use `estimate`, which maps over it)")


def _samplers_in(obj) -> list:
    """`obj` and every sampler nested in its attributes (an Oriented's base, a Mixture's components)."""
    found = [obj] if isinstance(obj, Sampler) else []
    names, _ = tree_fields(obj)
    for name in names:
        for item in jax.tree_util.tree_leaves(getattr(obj, name), is_leaf=lambda v: isinstance(v, Pytree)):
            if isinstance(item, Pytree):
                found.extend(_samplers_in(item))
    return found


def _poisoned(sampler):
    """(`sampler` with every float parameter made NaN where it, or a sampler nested in it, has
    invalid parameters (`_parameters_valid()` False), the poison e: 0.0, NaN, or None when the
    parameters are known valid).

    Each parameter becomes θ·(1 + e) with e = 0 (valid: θ exactly, derivative 1) or NaN (invalid):
    the values are NaN, and so is the derivative of every entry of θ, also of the entries a
    gather never reads (their cotangent 0 times NaN), so no gradient comes out finite. Concrete
    parameters are checked too (a sampler rebuilt by `tree_map` never ran its constructor's check).
    """
    checks = [v for s in _samplers_in(sampler) if (v := s._parameters_valid()) is not None]
    traced = [v for v in checks if isinstance(v, jax.core.Tracer)]
    if all(bool(np.all(np.asarray(v))) for v in checks if not isinstance(v, jax.core.Tracer)):
        if not traced:
            return sampler, None
        valid = functools.reduce(jnp.logical_and, [jnp.all(v) for v in traced])
    else:
        valid = False
    poison = jnp.where(valid, 0.0, jnp.nan)

    def add(leaf):
        leaf_dtype = jnp.result_type(leaf)
        if jnp.issubdtype(leaf_dtype, jnp.inexact):
            return leaf * (1 + poison.astype(leaf_dtype))
        return leaf

    return jax.tree_util.tree_map(add, sampler), poison


def _poison_outputs(out, poison):
    """Float outputs of a point method times (1 + e): NaN where the parameters are invalid. A
    density written as `where(x inside, ..., 0)` would otherwise report 0 for a NaN parameter
    (the comparison with NaN is False), a finite number where the rule promises NaN."""
    if poison is None:
        return out

    def add(leaf):
        leaf_dtype = jnp.result_type(leaf)
        return leaf * (1 + poison.astype(leaf_dtype)) if jnp.issubdtype(leaf_dtype, jnp.inexact) else leaf

    return jax.tree_util.tree_map(add, out)


def draw(sampler: Sampler, key, shape, dtype, method: str):
    """`sampler.<method>` applied to the sampling stream's first points, shaped
    `shape + batch_shape + event` (see `_draw`; a batch goes through `_draw_batch`)."""
    from ..uniforms import as_key

    key = as_key(key, "sample")
    shape, dtype = _as_shape(shape), _as_dtype(dtype)
    if sampler.batch_shape:
        return _draw_batch(sampler, key, shape, dtype, method)
    return _draw(sampler, key, shape, dtype, method)


def _as_shape(shape) -> tuple[int, ...]:
    if isinstance(shape, (int, np.integer)) and not isinstance(shape, bool):
        shape = (shape,)
    try:
        shape = tuple(operator.index(s) for s in shape)
    except TypeError:
        raise TypeError(f"sample: parameter 'sample_shape' must be an int or a tuple of ints; got {shape!r}") from None
    if any(s < 0 for s in shape):
        raise ValueError(f"sample: parameter 'sample_shape' must have entries >= 0; got {shape}")
    return shape


@functools.partial(jax.jit, static_argnums=(2, 3, 4))
def _draw_batch(sampler: Sampler, key, shape: tuple[int, ...], dtype, method: str):
    """A batch of distributions: the stream's first prod(shape + batch) points, shaped
    `shape + batch + (d,)`, through the batched point method (one vmap over the flat batch)."""
    from ..uniforms import Random, seed_from_key

    full = shape + sampler.batch_shape
    count = int(np.prod(full, dtype=np.int64))
    u = Random().block(seed_from_key(key), jnp.uint32(0), count, sampler.uniform_dims, dtype)
    return apply_point(sampler, method, u.reshape(full + (sampler.uniform_dims,)))


def _as_dtype(dtype):
    return resolve_float_dtype("sample", dtype)


_DRAW_CHUNK = 1 << 16


@functools.partial(jax.jit, static_argnums=(2, 3, 4))
def _draw(sampler: Sampler, key, shape: tuple[int, ...], dtype, method: str):
    """`_draw_unchecked` with the sampler's parameters checked once, outside the chunk loop."""
    return _draw_unchecked(checked(sampler), key, shape, dtype, method)


def _draw_unchecked(sampler: Sampler, key, shape: tuple[int, ...], dtype, method: str):
    """`sampler.<method>` (warp, warp_with_pdf, ...) of the stream's first points, shaped
    `shape + event`: `sample` and `sample_with_pdf` as one compiled program, whatever the sampler.

    The uniforms come as the generator makes them (`Source.lanes`: g = 4 // d points per Philox
    block, one array per coordinate), the warp runs on coordinate lanes (`jaxsample._core.lanes`),
    and every output coordinate of every group is computed in one loop and stored once
    (`jaxsample._core.computed_once`) before the groups are interleaved into the (count, *event)
    result: written as `warp(u)` on a (count, d) block, XLA recomputes the generator and the warp
    for each output coordinate (the optimized HLO shows Philox once per consumer).
    """
    from .._core.computed_once import computed_once
    from .._core.lanes import lane_map
    from ..uniforms import Random, seed_from_key
    from ..uniforms.index import NARROW_LIMIT, offset_at, token

    seed = seed_from_key(key, "sample")
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
    def measure(self):
        return self.base.measure

    @property
    def has_inverse(self):
        return self.base.has_inverse
