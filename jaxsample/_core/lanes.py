"""Per-point functions evaluated on a block of points, one array per coordinate ("lanes").

Why this exists. The estimators apply a per-sample function (warp, density, the user's f) to
blocks of tens of thousands of points. The obvious way, `jax.vmap(fn)` on a (count, d) block,
puts the small event axes (the 3 of a direction) minor-most, and XLA's CPU backend handles the
operations that mix them badly: a batched `x @ a` stays a separate (count, 3) x (3,) `dot` op fed
by a materialised (count, 3) stack, `jnp.sum(x * a)` reduces over a length-3 minor axis after
materialising the product, and the generator and the warp are fused twice, once into each
consumer (seen in the optimized HLO; `docs/xla-cpu-paths.md`). Written with explicit
components (`x[0] * a[0] + ...`) the same integrand is one loop fusion, 10-30x faster (the path
table of `benchmarks/paths.py` times each way of writing it).

`lane_map(fn)` gets that fusion for every way of writing the integrand. It traces `fn` on ONE
point and evaluates the resulting jaxpr with a small interpreter in which a per-point value of
shape S is a NumPy object array of shape S whose elements are arrays over the points (one per
element, the lanes): reshapes, slices, stacks, broadcasts and transposes only rearrange those arrays; `dot_general`
and the reductions become sums of elementwise products written out in order; elementwise
primitives apply lane by lane. XLA then sees only elementwise arithmetic on (count,) vectors,
which it fuses into a single loop. Nothing is approximated: every lane computes the same
operations as the vmapped program (sums of a dot product in index order), so values and
gradients agree to float rounding, and autodiff, `jit` and `vmap` see ordinary JAX operations.

Anything else (gathers, loops, sorts, custom derivative rules, an operation with an operand or
result of more than `MAX_LANES` elements per point, a dot_general of more than `_MAX_TERMS`
multiply-adds, elementwise work on values already stacked) is evaluated by `jax.vmap` of that one
primitive on the stacked (points, *S) arrays, so every program works and only the small-vector
part is rewritten. That fallback is a decision taken before a rule runs: the primitive has no rule,
its values are too wide, or the rule's own checks decline the case (it returns `NotImplemented`);
an exception raised inside a rule is a bug and propagates. `lane_map(..., strict=True)` raises
`LaneFallback` instead of falling back, which is how the tests pin the programs that must stay
on the lanes. Calls of `jax.jit`-ed functions (`jnp.clip`, `jnp.where`, `jnp.linalg.norm`, ...)
are inlined. Tuple inputs are coordinate columns of one dtype (the first column's).

The tables below are keyed on primitive objects, looked up once at import
(`jax_internals.primitive`). A few primitives are newer than the oldest supported JAX; each is
required from the version that introduced it and skipped before (those versions express the same
operation with primitives that have rules).

Where it runs. The interpreter is an optimization for XLA's CPU backend, where it was measured,
and it can only fail soft: where it does not run, `lane_map(fn)` is `jax.vmap(fn)` on the points
(the same values to float rounding, and the same derivatives), as it is on every other platform.
It runs when (1) the program being traced targets the CPU (`cpu_paths.active`), (2) every
primitive its tables name exists in the installed JAX and so do the JAX internals it reads
(`jax_internals.MISSING`), and (3) that JAX is one it was tested with (`jax_internals.TESTED_JAX`).
A failure of (2) or (3) is one `LanesUnavailableWarning` per process, when a program first would
have used the interpreter, never an ImportError: a JAX release that renames a primitive costs
speed, not the package. The environment variable JAXSAMPLE_LANES, read when jaxsample is
imported, overrides: `JAXSAMPLE_LANES=0` turns the interpreter off (and `computed_once`'s
packing with it: the CPU then runs the program the other platforms run), `JAXSAMPLE_LANES=1`
runs it on every platform and on an untested JAX (`cpu_paths` has the details).

`reduce_max`/`reduce_min` follow JAX's derivative at ties (the tangent is split evenly among the
elements equal to the result), which a chain of pairwise `max` would not (it halves per step).
"""

from __future__ import annotations

import warnings
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from . import cpu_paths, jax_internals
from .computed_once import computed_once, stored_once_p as _core_stored_once_p
from .jax_internals import Literal, bind as _bind

__all__ = ["lane_map", "LaneFallback", "LanesUnavailableWarning", "MAX_LANES"]

# Per-point values with more elements than this stay stacked (count, *S) arrays: unrolling a
# (1000,) per-point vector into 1000 lanes would trade a tight loop for a huge program.
MAX_LANES = 64
# ... and a dot_general with more multiply-adds than this stays a dot (64x64 weights: 4096).
_MAX_TERMS = 4 * MAX_LANES


class LaneFallback(RuntimeError):
    """Raised by `lane_map(..., strict=True)` where a primitive would be evaluated by vmap, or
    where the interpreter cannot run at all (a primitive missing from this JAX)."""


class LanesUnavailableWarning(RuntimeWarning):
    """The lane interpreter steps aside for `jax.vmap` on this JAX (see the module docstring)."""


# -- the primitives, as objects --------------------------------------------------------------------

# The primitive names the tables need that this JAX does not have: while any is missing, the
# interpreter does not run (`_unavailable`).
_MISSING: list[str] = []


def _jax_version() -> tuple[int, ...]:
    return jax_internals.jax_version()


def _keyed(entries: dict, since: tuple[int, ...] | None = None) -> dict:
    """{primitive object: value} for `entries` {primitive name: value}. A name this JAX has no
    primitive for is recorded in `_MISSING` (which turns the interpreter off), except under `since`
    (the first JAX version that has them) on an older JAX, where the missing ones are left out."""
    found = {name: jax_internals.primitive(name) for name in entries}
    missing = [name for name, prim in found.items() if prim is None]
    if missing and (since is None or _jax_version() >= since):
        _MISSING.extend(name for name in missing if name not in _MISSING)
    return {prim: entries[name] for name, prim in found.items() if prim is not None}


_ELEMENTWISE_NAMES = """
    neg sign floor ceil round is_finite exp exp2 log expm1 log1p tanh logistic sin cos tan asin
    acos atan sinh cosh asinh acosh atanh lgamma digamma erf erfc erf_inv real imag complex conj
    abs sqrt rsqrt cbrt not population_count clz integer_pow square convert_element_type
    reduce_precision add sub mul div rem pow max min nextafter atan2 and or xor shift_left
    shift_right_arithmetic shift_right_logical eq ne ge gt le lt select_n clamp copy
    igamma igammac igamma_grad_a bessel_i0e bessel_i1e polygamma zeta regularized_incomplete_beta
    eq_to le_to lt_to stop_gradient add_jaxvals
""".split()
# `add_jaxvals` is autodiff's `add_any`, the sum of two tangents: every JVP that reads a value twice
# has one (the engine's per-point sensitivities do), so it must stay on the lanes.

# Calls of a jaxpr, evaluated inline: the primitive and the parameter that holds its jaxpr
# (a ClosedJaxpr, or an open Jaxpr for `call`).
_INLINED = _keyed({"jit": "jaxpr", "closed_call": "call_jaxpr", "call": "call_jaxpr"})


class _Lanes:
    """A per-point value of shape `shape`: an object array of arrays over the points (lanes)."""

    __slots__ = ("cells", "dtype")

    def __init__(self, cells: np.ndarray, dtype):
        self.cells = cells
        self.dtype = dtype

    @property
    def shape(self):
        return self.cells.shape


class _Stacked:
    """A per-point value of shape S held as one (*lane_shape, *S) array (the vmap layout)."""

    __slots__ = ("array",)

    def __init__(self, array):
        self.array = array


def _size(var) -> int:
    shape = getattr(var.aval, "shape", ())
    return int(np.prod(shape, dtype=np.int64))


def _object_array(items, shape) -> np.ndarray:
    cells = np.empty(len(items), dtype=object)
    for i, item in enumerate(items):
        cells[i] = item
    return cells.reshape(shape)


class _Evaluator:
    def __init__(self, lane_shape: tuple[int, ...], strict: bool = False, token=None):
        self.lane_shape = lane_shape
        self.strict = strict
        self.token = token

    # -- conversions --------------------------------------------------------------------------

    def lane(self, value):
        """One element's array over the points: lanes as they are, constants broadcast."""
        value = jnp.asarray(value)
        if value.shape == self.lane_shape:
            return value
        return lax.broadcast_in_dim(value, self.lane_shape, ())

    def as_lanes(self, value) -> _Lanes | None:
        if isinstance(value, _Lanes):
            return value
        if isinstance(value, _Stacked):
            array = value.array
            shape = array.shape[len(self.lane_shape):]
            size = int(np.prod(shape, dtype=np.int64))
            if size > MAX_LANES:
                return None
            flat = array.reshape(self.lane_shape + (size,))
            return _Lanes(_object_array([flat[..., i] for i in range(size)], shape), array.dtype)
        return None

    def as_stacked(self, value) -> _Stacked:
        if isinstance(value, _Stacked):
            return value
        cells = value.cells
        if cells.size == 0:
            return _Stacked(jnp.zeros(self.lane_shape + cells.shape, value.dtype))
        if cells.ndim == 0:
            return _Stacked(self.lane(cells[()]))
        flat = jnp.stack([self.lane(c) for c in cells.ravel()], axis=-1)
        return _Stacked(flat.reshape(self.lane_shape + cells.shape))

    @staticmethod
    def batched(value) -> bool:
        return isinstance(value, (_Lanes, _Stacked))

    # -- the interpreter ----------------------------------------------------------------------

    def run(self, jaxpr, consts, args):
        env = {}

        def read(v):
            if isinstance(v, Literal):
                return v.val
            return env[v]

        for var, value in zip(jaxpr.constvars, consts):
            env[var] = value
        for var, value in zip(jaxpr.invars, args):
            env[var] = value
        for eqn in jaxpr.eqns:
            inputs = [read(v) for v in eqn.invars]
            outputs = self.apply(eqn, inputs)
            if not eqn.primitive.multiple_results:
                outputs = [outputs]
            for var, value in zip(eqn.outvars, outputs):
                env[var] = value
        return [read(v) for v in jaxpr.outvars]

    def apply(self, eqn, inputs):
        prim, params = eqn.primitive, eqn.params
        if not any(self.batched(x) for x in inputs):
            # Shared by every point (parameters, constants): evaluate once, as JAX would.
            return _bind(prim, params, inputs)
        if prim in _INLINED:
            closed = params[_INLINED[prim]]
            inner = closed.jaxpr if hasattr(closed, "jaxpr") else closed
            consts = closed.consts if hasattr(closed, "consts") else ()
            return self.run(inner, consts, inputs)
        rule = _RULES.get(prim)
        if rule is None:
            return self.fallback(eqn, inputs, "no lane rule for this primitive")
        if any(_size(v) > MAX_LANES for v in list(eqn.outvars) + list(eqn.invars)):
            return self.fallback(eqn, inputs, f"a value of more than MAX_LANES = {MAX_LANES} elements")
        if rule is _elementwise and all(isinstance(x, _Stacked) for x in inputs if self.batched(x)):
            # Values the fallback already stacked stay stacked through elementwise work among
            # themselves: XLA is fast on elementwise (points, *S) arrays. Mixed with lanes, the
            # stacked operand is split into lanes instead (slices of an array already computed):
            # stacking the lanes would put everything they are computed from into one concatenate
            # fusion, evaluated element by element. A layout choice, not a missing rule.
            return self.fallback(eqn, inputs, None)
        lanes = [self.as_lanes(x) if self.batched(x) else x for x in inputs]
        if any(x is None for x in lanes):
            return self.fallback(eqn, inputs, "an operand stacked wider than MAX_LANES")
        result = rule(self, eqn, lanes)
        if result is NotImplemented:
            return self.fallback(eqn, inputs, "its rule declines these parameters or dtypes")
        return result

    def stored_for_stacking(self, inputs):
        """The lanes among a fallback's operands, stored once (`computed_once`) where there are
        several: stacked straight from the lanes (or combined by vmap's batching rule, as the
        indices of a vmapped `dynamic_slice`), they are one concatenate fusion that computes
        everything upstream element by element (an environment map's texel index (i, j)).
        Stored, the stack reads computed arrays."""
        lanes = [x for x in inputs if isinstance(x, _Lanes)]
        if sum(x.cells.size for x in lanes) < 2 or self.token is None:
            return inputs
        stored = iter(computed_once([self.lane(c) for x in lanes for c in x.cells.ravel()], self.token))
        return [_Lanes(_object_array([next(stored) for _ in range(x.cells.size)], x.cells.shape), x.dtype)
                if isinstance(x, _Lanes) else x for x in inputs]

    def fallback(self, eqn, inputs, reason):
        """vmap of this one primitive over the stacked (points, *S) operands. `reason`: why the
        lanes cannot take it (None for elementwise work kept stacked), raised in strict mode."""
        prim = eqn.primitive
        if self.strict and reason is not None:
            raise LaneFallback(f"lane_map(strict=True): `{prim.name}` would be evaluated by vmap: {reason} "
                               f"(per-point operands {[v.aval.str_short() for v in eqn.invars]})")
        lanes = self.lane_shape
        points = int(np.prod(lanes, dtype=np.int64))
        axes = [0 if self.batched(x) else None for x in inputs]
        inputs = self.stored_for_stacking(inputs)
        operands = [self.as_stacked(x).array for x in inputs if self.batched(x)]
        operands = iter([a.reshape((points,) + a.shape[len(lanes):]) for a in operands])
        operands = [next(operands) if self.batched(x) else x for x in inputs]

        def one(*xs):
            return _bind(prim, eqn.params, xs)

        out = jax.vmap(one, in_axes=axes, out_axes=0)(*operands)
        unflat = lambda o: _Stacked(o.reshape(lanes + o.shape[1:]))
        if prim.multiple_results:
            return [unflat(o) for o in out]
        return unflat(out)


# ----------------------------------------------------------------------------------------------
# Rules: each gets the evaluator, the equation and its inputs (per-point values as _Lanes,
# shared values as arrays) and returns the output(s), or NotImplemented to fall back to vmap.
# ----------------------------------------------------------------------------------------------


def _cells_of(ev: _Evaluator, x, shape, dtype):
    """An object array of shape `shape` for operand x: its lanes, or a shared array's elements
    (cast to the operand's dtype: a literal's Python scalar must not widen under x64)."""
    if isinstance(x, _Lanes):
        return x.cells
    # A 64-bit operand (a program that switched x64 on inside, as Philox and the double-float sums
    # of a nested estimate do) keeps its width when the caller runs with x64 off.
    with jax.enable_x64(jnp.dtype(dtype).itemsize == 8 or jax.config.jax_enable_x64):
        x = jnp.asarray(x, dtype=dtype)
    if x.shape == ():
        return _object_array([x] * int(np.prod(shape, dtype=np.int64)), shape)
    flat = x.reshape(-1)
    return _object_array([flat[i] for i in range(flat.shape[0])], x.shape)


def _elementwise(ev, eqn, inputs):
    shape = eqn.outvars[0].aval.shape
    prim = eqn.primitive
    cells = [_cells_of(ev, x, shape, v.aval.dtype) for x, v in zip(inputs, eqn.invars)]
    # Size-1 axes broadcast: lax accepts (1,) against (3,) (equal ranks; a scalar is filled).
    cells = [c if c.shape == shape else np.broadcast_to(c, shape) for c in cells]
    outs = [prim.bind(*[ev.lane(c[idx]) for c in cells], **eqn.params) for idx in np.ndindex(shape)]
    return _Lanes(_object_array(outs, shape), eqn.outvars[0].aval.dtype)


def _rearranged(eqn, cells):
    return _Lanes(cells, eqn.outvars[0].aval.dtype)


def _broadcast_in_dim(ev, eqn, inputs):
    (x,) = inputs[:1]
    if len(inputs) > 1:
        return NotImplemented  # dynamic shapes
    shape = eqn.params["shape"]
    dims = eqn.params["broadcast_dimensions"]
    cells = x.cells
    expanded = [1] * len(shape)
    for i, d in enumerate(dims):
        expanded[d] = cells.shape[i]
    return _rearranged(eqn, np.broadcast_to(cells.reshape(expanded), shape))


def _reshape(ev, eqn, inputs):
    if len(inputs) > 1:
        return NotImplemented
    dims = eqn.params.get("dimensions")
    cells = inputs[0].cells
    if dims is not None:
        cells = cells.transpose(dims)
    return _rearranged(eqn, cells.reshape(eqn.params["new_sizes"]))


def _squeeze(ev, eqn, inputs):
    return _rearranged(eqn, inputs[0].cells.reshape(eqn.outvars[0].aval.shape))


def _transpose(ev, eqn, inputs):
    return _rearranged(eqn, inputs[0].cells.transpose(eqn.params["permutation"]))


def _rev(ev, eqn, inputs):
    cells = inputs[0].cells
    for d in eqn.params["dimensions"]:
        cells = np.flip(cells, d)
    return _rearranged(eqn, cells)


def _slice(ev, eqn, inputs):
    starts, limits = eqn.params["start_indices"], eqn.params["limit_indices"]
    strides = eqn.params["strides"] or (1,) * len(starts)
    index = tuple(slice(s, l, st) for s, l, st in zip(starts, limits, strides))
    return _rearranged(eqn, inputs[0].cells[index])


def _concatenate(ev, eqn, inputs):
    cells = [_cells_of(ev, x, v.aval.shape, v.aval.dtype) for x, v in zip(inputs, eqn.invars)]
    return _rearranged(eqn, np.concatenate(cells, axis=eqn.params["dimension"]))


def _stack(ev, eqn, inputs):
    cells = [_cells_of(ev, x, v.aval.shape, v.aval.dtype) for x, v in zip(inputs, eqn.invars)]
    return _rearranged(eqn, np.stack(cells, axis=eqn.params["axis"]))


def _unstack(ev, eqn, inputs):
    cells = inputs[0].cells
    axis = eqn.params["axis"]
    # Unstacking a vector gives scalars: np.take returns the element itself there, not a 0-d array.
    parts = [np.take(cells, i, axis=axis) for i in range(len(eqn.outvars))]
    parts = [p if isinstance(p, np.ndarray) else _object_array([p], ()) for p in parts]
    return [_Lanes(p, v.aval.dtype) for p, v in zip(parts, eqn.outvars)]


def _tile(ev, eqn, inputs):
    return _rearranged(eqn, np.tile(inputs[0].cells, eqn.params["reps"]))


def _bitcast_convert_type(ev, eqn, inputs):
    if eqn.outvars[0].aval.shape != eqn.invars[0].aval.shape:
        return NotImplemented  # a change of width reshapes the value
    return _elementwise(ev, eqn, inputs)


def _split(ev, eqn, inputs):
    cells = inputs[0].cells
    axis = eqn.params["axis"]
    bounds = np.cumsum(eqn.params["sizes"])[:-1]
    return [_Lanes(part, v.aval.dtype) for part, v in zip(np.split(cells, bounds, axis=axis), eqn.outvars)]


def _pad(ev, eqn, inputs):
    x, padding_value = inputs
    if isinstance(padding_value, _Lanes) or any(i != 0 for _, _, i in eqn.params["padding_config"]):
        return NotImplemented
    if any(lo < 0 or hi < 0 for lo, hi, _ in eqn.params["padding_config"]):
        return NotImplemented
    fill = jnp.asarray(padding_value, eqn.invars[1].aval.dtype)
    cells = x.cells
    pad = [(lo, hi) for lo, hi, _ in eqn.params["padding_config"]]
    out = np.empty(eqn.outvars[0].aval.shape, dtype=object)
    out[...] = None
    index = tuple(slice(lo, lo + n) for (lo, _), n in zip(pad, cells.shape))
    out[index] = cells
    for idx in np.ndindex(out.shape):
        if out[idx] is None:
            out[idx] = fill
    return _rearranged(eqn, out)


def _chained(combine, terms):
    total = terms[0]
    for t in terms[1:]:
        total = combine(total, t)
    return total


def _chooser(combine):
    """`combine` (lax.max or lax.min) chained over the terms, with the derivative of JAX's
    reduce_max/reduce_min: the tangent is the mean of the tangents of the terms equal to the
    result. Differentiating the chain itself would split 0.5/0.5 at each tied pair, weighting the
    first of three tied terms 1/4, not 1/3. The primal is the chain, so values are unchanged."""

    @jax.custom_jvp
    def choose(*terms):
        return _chained(combine, terms)

    @choose.defjvp
    def choose_jvp(primals, tangents):
        ans = choose(*primals)
        hits = [lax.convert_element_type(lax.eq(t, ans), ans.dtype) for t in primals]
        counts = _chained(lax.add, hits)
        picked = _chained(lax.add, [lax.mul(dt, h) for dt, h in zip(tangents, hits)])
        return ans, lax.div(picked, counts)

    return choose


_MAX_OF, _MIN_OF = _chooser(lax.max), _chooser(lax.min)


def _reduce(ev, eqn, inputs):
    combine, chooser = _REDUCERS[eqn.primitive]
    inexact = jnp.issubdtype(eqn.outvars[0].aval.dtype, jnp.inexact)
    cells = inputs[0].cells
    axes = tuple(eqn.params["axes"])
    keep = [d for d in range(cells.ndim) if d not in axes]
    moved = cells.transpose(keep + list(axes))
    out_shape = moved.shape[: len(keep)]
    flat = moved.reshape(out_shape + (-1,))
    if flat.shape[-1] == 0:
        return NotImplemented  # a reduction over no elements is its identity; vmap knows it
    outs = []
    for idx in np.ndindex(out_shape):
        terms = [ev.lane(t) for t in flat[idx]]
        # Only a max/min of floats has a derivative to get right; integers take the plain chain.
        outs.append(chooser(*terms) if chooser is not None and inexact else _chained(combine, terms))
    return _rearranged(eqn, _object_array(outs, out_shape))


def _dot_general(ev, eqn, inputs):
    (lhs_contract, rhs_contract), (lhs_batch, rhs_batch) = eqn.params["dimension_numbers"]
    out_dtype = eqn.outvars[0].aval.dtype
    lhs, rhs = (_cells_of(ev, x, v.aval.shape, v.aval.dtype) for x, v in zip(inputs, eqn.invars))
    lhs_free = [d for d in range(lhs.ndim) if d not in lhs_contract and d not in lhs_batch]
    rhs_free = [d for d in range(rhs.ndim) if d not in rhs_contract and d not in rhs_batch]
    # (batch, free, contract) on each side; the output is (batch, lhs free, rhs free).
    lhs_t = lhs.transpose(list(lhs_batch) + lhs_free + list(lhs_contract))
    rhs_t = rhs.transpose(list(rhs_batch) + rhs_free + list(rhs_contract))
    nb = len(lhs_batch)
    batch_shape = lhs_t.shape[:nb]
    lf_shape = lhs_t.shape[nb: nb + len(lhs_free)]
    rf_shape = rhs_t.shape[nb: nb + len(rhs_free)]
    k = int(np.prod(lhs_t.shape[nb + len(lhs_free):], dtype=np.int64))
    lhs_m = lhs_t.reshape(batch_shape + lf_shape + (k,))
    rhs_m = rhs_t.reshape(batch_shape + rf_shape + (k,))
    terms = int(np.prod(batch_shape + lf_shape + rf_shape, dtype=np.int64)) * k
    if k == 0 or terms > _MAX_TERMS or jnp.bool_ in (eqn.invars[0].aval.dtype, out_dtype):
        return NotImplemented  # a matrix product (a small network's layer) stays one XLA dot

    def term(a, b):
        a, b = ev.lane(a), ev.lane(b)
        return lax.mul(a.astype(out_dtype), b.astype(out_dtype))

    outs = []
    for b in np.ndindex(batch_shape):
        for i in np.ndindex(lf_shape):
            for j in np.ndindex(rf_shape):
                total = term(lhs_m[b + i + (0,)], rhs_m[b + j + (0,)])
                for c in range(1, k):
                    total = lax.add(total, term(lhs_m[b + i + (c,)], rhs_m[b + j + (c,)]))
                outs.append(total)
    return _rearranged(eqn, _object_array(outs, eqn.outvars[0].aval.shape))


# Reductions: the pairwise combine, and for max/min the chooser with JAX's derivative at ties.
_REDUCERS = _keyed({"reduce_sum": (lax.add, None), "reduce_max": (lax.max, _MAX_OF),
                    "reduce_min": (lax.min, _MIN_OF), "reduce_prod": (lax.mul, None),
                    "reduce_and": (lax.bitwise_and, None), "reduce_or": (lax.bitwise_or, None),
                    "reduce_xor": (lax.bitwise_xor, None)})

def _stored_once(ev, eqn, inputs):
    """`computed_once.stored_once`: the lanes of every marked per-point value stored once."""
    lanes = [x for x in inputs if isinstance(x, _Lanes)]
    flat = [ev.lane(c) for x in lanes for c in x.cells.reshape(-1)]
    if not flat:
        return list(inputs)
    tok = ev.token
    if tok is None:
        # A token from the values themselves: cheap, but it reads one element of each, which gives
        # their producers a second consumer (see `lane_map`'s `token`).
        first = flat[0].reshape(-1)[0]
        tok = lax.bitcast_convert_type(first, jnp.uint32 if first.dtype.itemsize == 4 else jnp.uint64)
    stored = iter(computed_once(flat, tok))
    out = []
    for x in inputs:
        if isinstance(x, _Lanes):
            cells = _object_array([next(stored) for _ in range(x.cells.size)], x.cells.shape)
            out.append(_Lanes(cells, x.dtype))
        else:
            out.append(x)
    return out


_RULES = {
    **({} if _core_stored_once_p is None else {_core_stored_once_p: _stored_once}),
    **_keyed(dict.fromkeys(_ELEMENTWISE_NAMES, _elementwise)),
    **_keyed({"mulhi": _elementwise}, since=(0, 10, 2)),
    **_keyed({"broadcast_in_dim": _broadcast_in_dim, "reshape": _reshape, "squeeze": _squeeze,
              "transpose": _transpose, "rev": _rev, "slice": _slice, "concatenate": _concatenate,
              "split": _split, "bitcast_convert_type": _bitcast_convert_type, "pad": _pad,
              "dot_general": _dot_general}),
    **_keyed({"tile": _tile}, since=(0, 9, 0)),
    **_keyed({"stack": _stack, "unstack": _unstack}, since=(0, 10, 1)),
    **{prim: _reduce for prim in _REDUCERS},
}


# ----------------------------------------------------------------------------------------------
# Where the interpreter runs, and plain vmap where it does not
# ----------------------------------------------------------------------------------------------

_warned = False


def _missing() -> str | None:
    """What this JAX lacks of what the interpreter reads (None: nothing)."""
    if not (_MISSING or jax_internals.MISSING):
        return None
    parts = ([f"no primitive(s) {_MISSING}"] if _MISSING else []) + list(jax_internals.MISSING)
    return f"JAX {jax.__version__} has {'; '.join(parts)}"


def _unavailable() -> str | None:
    """Why the interpreter does not run on this JAX (None: it does)."""
    reason = _missing()
    if reason is None and not jax_internals.version_tested() and cpu_paths.setting() != "on":
        low, high = (".".join(map(str, v)) for v in jax_internals.TESTED_JAX)
        reason = (f"JAX {jax.__version__} is not a version it was tested with ({low} to {high}); "
                  f"{cpu_paths.ENV}=1 runs it anyway")
    return reason


def _interpreting(strict: bool) -> bool:
    """Whether `lane_map` evaluates the program being traced on the lanes. Where it cannot on this
    JAX, the first program that would have is a `LanesUnavailableWarning` (once per process)."""
    global _warned
    if strict:  # a question about the interpreter itself: asked whatever the switch says
        reason = _missing()
        if reason is not None:
            raise LaneFallback(f"lane_map(strict=True): the lane interpreter cannot run: {reason}")
        return True
    if not cpu_paths.active():
        return False
    reason = _unavailable()
    if reason is None:
        return True
    if not _warned:
        _warned = True
        warnings.warn(f"jaxsample: the per-coordinate lane interpreter steps aside for plain jax.vmap "
                      f"(the same values to float rounding; on the CPU some integrands run several times "
                      f"slower): {reason}. {cpu_paths.ENV}=0 (set before jaxsample is imported) chooses vmap "
                      "without this warning.",
                      LanesUnavailableWarning, stacklevel=2)
    return False


def _by_vmap(fn: Callable, lane_shape: tuple[int, ...]) -> Callable:
    """`lane_map`'s contract by `jax.vmap(fn)` over the points, flattened from `lane_shape`."""
    points = int(np.prod(lane_shape, dtype=np.int64))

    def mapped(*args):
        flat = []
        for a in args:
            if isinstance(a, (tuple, list)):  # coordinate columns, of the first column's dtype
                dtype = jnp.asarray(a[0]).dtype
                a = jnp.stack([jnp.broadcast_to(jnp.asarray(c).astype(dtype), lane_shape) for c in a], axis=-1)
            else:
                a = jnp.asarray(a)
            flat.append(a.reshape((points,) + a.shape[len(lane_shape):]))
        out = jax.vmap(fn)(*flat)
        return jax.tree_util.tree_map(lambda o: o.reshape(lane_shape + o.shape[1:]), out)

    return mapped


def _as_columns(array, lane_shape: tuple[int, ...]) -> tuple:
    """A (*lane_shape, *S) array as its per-point elements in C order, one lane array each."""
    size = int(np.prod(array.shape[len(lane_shape):], dtype=np.int64))
    flat = array.reshape(lane_shape + (size,))
    return tuple(flat[..., i] for i in range(size))


def lane_map(fn: Callable, lane_shape, *, strict: bool = False, token=None, columns: bool = False) -> Callable:
    """`fn` maps ONE point (arrays of any shape, a pytree) to a pytree of arrays; the result maps
    per-coordinate lanes to the same outputs over all the points, like `jax.vmap(fn)`.

    The points are laid out in an array of shape `lane_shape` (an int for a flat block). The
    returned function takes, for each argument of `fn`, either a tuple of d arrays of shape
    `lane_shape` (the coordinates of a flat (d,) argument: lanes as the sources make them) or one
    array of shape lane_shape + S (the vmap layout). It returns outputs of shape lane_shape + out.

    `strict=True` raises `LaneFallback` (naming the primitive and why) where a primitive would be
    evaluated by vmap instead of on the lanes; elementwise work on a value given or kept in the
    stacked layout is not a fallback. For tests and for checking that an integrand stays fast:
    it runs the interpreter wherever it can run, whatever JAXSAMPLE_LANES and the platform say.

    Where the interpreter does not run (see the module docstring), the result is `jax.vmap(fn)`
    on the points, and `token` is not used.

    `columns=True`: each output leaf comes back as a tuple of its per-point elements in C order, one
    array of shape `lane_shape` each, never stacked. Stacking the lanes of a (C,) output interleaves
    them in a (points, C) array, which XLA's CPU backend computes in one concatenate fusion that
    evaluates the whole per-point program element by element without vectorizing
    (`docs/xla-cpu-paths.md`); kept apart, each element is a lane of its own.

    `token`: a traced integer scalar for the values `stored_once` marks (`computed_once`'s token),
    e.g. the streaming engine's chunk offset. Without one, the token is read from the stored values,
    and the single element read is a second consumer of everything they are computed from, which
    XLA's CPU fusion then materializes array by array (a gradient's per-point program split into
    20 loops that way).
    """
    lane_shape = (lane_shape,) if isinstance(lane_shape, (int, np.integer)) else tuple(lane_shape)
    by_vmap = _by_vmap(fn, lane_shape)

    def mapped(*args):
        if not _interpreting(strict):  # decided when the program is traced
            out = by_vmap(*args)
            if columns:
                return jax.tree_util.tree_map(lambda o: _as_columns(o, lane_shape), out)
            return out
        ev = _Evaluator(lane_shape, strict, token)
        specs, inputs = [], []
        for a in args:
            if isinstance(a, (tuple, list)):
                column = jnp.asarray(a[0])
                specs.append(jax.ShapeDtypeStruct((len(a),), column.dtype))
                inputs.append(_Lanes(_object_array([jnp.asarray(c) for c in a], (len(a),)), column.dtype))
            else:
                a = jnp.asarray(a)
                specs.append(jax.ShapeDtypeStruct(a.shape[len(lane_shape):], a.dtype))
                inputs.append(_Stacked(a))
        closed, out_tree = _trace(fn, specs)
        outs = ev.run(closed.jaxpr, closed.consts, inputs)
        stacked = []
        for o, aval in zip(outs, closed.out_avals):
            if columns and isinstance(o, _Lanes):
                stacked.append(tuple(ev.lane(c).astype(aval.dtype) for c in o.cells.ravel()))
            elif ev.batched(o):
                array = ev.as_stacked(o).array.astype(aval.dtype)
                stacked.append(_as_columns(array, lane_shape) if columns else array)
            else:  # the same for every point
                o = jnp.asarray(o)
                array = jnp.broadcast_to(o, lane_shape + o.shape)
                stacked.append(_as_columns(array, lane_shape) if columns else array)
        return jax.tree_util.tree_unflatten(out_tree, stacked)

    return mapped


def _trace(fn, specs):
    out_tree_box = []

    def flat(*xs):
        out = fn(*xs)
        leaves, tree = jax.tree_util.tree_flatten(out)
        out_tree_box.append(tree)
        return leaves

    closed = jax.make_jaxpr(flat)(*specs)
    return closed, out_tree_box[0]
