"""Per-point functions evaluated on a block of points, one array per coordinate ("lanes").

Why this exists. The estimators apply a per-sample function (warp, density, the user's f) to
blocks of tens of thousands of points. The obvious way, `jax.vmap(fn)` on a (count, d) block,
puts the small event axes (the 3 of a direction) minor-most, and XLA's CPU backend handles the
operations that mix them badly: a batched `x @ a` stays a separate (count, 3) x (3,) `dot` op fed
by a materialised (count, 3) stack, `jnp.sum(x * a)` reduces over a length-3 minor axis after
materialising the product, and the generator and the warp are fused twice, once into each
consumer (seen in the optimized HLO; `docs/xla-cpu-paths.md`). Written with explicit
components (`x[0] * a[0] + ...`) the same integrand is one loop fusion, 10-30x faster.

`lane_map(fn)` gets that fusion for every way of writing the integrand. It traces `fn` on ONE
point and evaluates the resulting jaxpr with a small interpreter in which a per-point value of
shape S is a NumPy object array of shape S whose elements are arrays over the points (one per element, the lanes):
reshapes, slices, stacks, broadcasts and transposes only rearrange those arrays; `dot_general`
and the reductions become sums of elementwise products written out in order; elementwise
primitives apply lane by lane. XLA then sees only elementwise arithmetic on (count,) vectors,
which it fuses into a single loop. Nothing is approximated: every lane computes the same
operations as the vmapped program (sums of a dot product in index order), so values and
gradients agree to float rounding, and autodiff, `jit` and `vmap` see ordinary JAX operations.

Anything else (gathers, loops, sorts, custom derivative rules, an operation with an operand or
result of more than `MAX_LANES` elements per point, a dot_general of more than `_MAX_TERMS`
multiply-adds, elementwise work on values already stacked) is evaluated as before, by `jax.vmap`
of that one primitive on the stacked (points, *S) arrays, so every program works and only the
small-vector part is rewritten; a rule that cannot handle its inputs falls back the same way.
`pjit` calls (functions under `jax.jit`) are inlined. Tuple inputs are coordinate columns of one
dtype (the first column's).
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jax.extend import core as jex_core

__all__ = ["lane_map", "MAX_LANES"]

# Per-point values with more elements than this stay stacked (count, *S) arrays: unrolling a
# (1000,) per-point vector into 1000 lanes would trade a tight loop for a huge program.
MAX_LANES = 64
# ... and a dot_general with more multiply-adds than this stays a dot (64x64 weights: 4096).
_MAX_TERMS = 4 * MAX_LANES

_ELEMENTWISE = frozenset("""
    neg sign floor ceil round is_finite exp exp2 log expm1 log1p tanh logistic sin cos tan asin
    acos atan sinh cosh asinh acosh atanh lgamma digamma erf erfc erf_inv real imag complex conj
    abs sqrt rsqrt cbrt not population_count clz integer_pow square convert_element_type
    reduce_precision add sub mul div rem pow max min nextafter atan2 and or xor shift_left
    shift_right_arithmetic shift_right_logical eq ne ge gt le lt select_n clamp copy
    igamma igammac random_gamma_grad bessel_i0e bessel_i1e polygamma zeta regularized_incomplete_beta
    eq_to le_to lt_to mulhi stop_gradient
""".split())

_REDUCERS = {"reduce_sum": lax.add, "reduce_max": lax.max, "reduce_min": lax.min,
             "reduce_prod": lax.mul, "reduce_and": lax.bitwise_and, "reduce_or": lax.bitwise_or,
             "reduce_xor": lax.bitwise_xor}


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


def _bind(prim, params, operands):
    """prim.bind with the parameters as `jax.core.eval_jaxpr` passes them (call primitives turn
    their jaxpr parameters into functions; older JAX returns those as a separate list)."""
    bind_params = prim.get_bind_params(params)
    if isinstance(bind_params, tuple):
        subfuns, bind_params = bind_params
        return prim.bind(*subfuns, *operands, **bind_params)
    return prim.bind(*operands, **bind_params)


def _object_array(items, shape) -> np.ndarray:
    cells = np.empty(len(items), dtype=object)
    for i, item in enumerate(items):
        cells[i] = item
    return cells.reshape(shape)


class _Evaluator:
    def __init__(self, lane_shape: tuple[int, ...]):
        self.lane_shape = lane_shape

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
            if isinstance(v, jex_core.Literal):
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
        name = prim.name
        if name in ("pjit", "jit", "closed_call", "core_call"):
            closed = params.get("jaxpr") or params.get("call_jaxpr")
            inner = closed.jaxpr if hasattr(closed, "jaxpr") else closed
            consts = closed.consts if hasattr(closed, "consts") else ()
            return self.run(inner, consts, inputs)
        rule = _RULES.get(name)
        if rule is None and name in _ELEMENTWISE:
            rule = _elementwise
        too_wide = any(_size(v) > MAX_LANES for v in list(eqn.outvars) + list(eqn.invars))
        # A value the fallback already stacked stays stacked through elementwise work: XLA is fast
        # on elementwise (points, *S) arrays; only mixing the small axes (dots, reductions,
        # rearrangements) needed lanes.
        stacked_elementwise = rule is _elementwise and any(isinstance(x, _Stacked) for x in inputs)
        if rule is not None and not too_wide and not stacked_elementwise:
            lanes = [self.as_lanes(x) if self.batched(x) else x for x in inputs]
            if all(x is not None for x in lanes):
                try:
                    result = rule(self, eqn, lanes)
                except (TypeError, ValueError):
                    result = NotImplemented  # a gap in a rule: vmap is always right
                if result is not NotImplemented:
                    return result
        return self.fallback(eqn, inputs)

    def fallback(self, eqn, inputs):
        """vmap of this one primitive over the stacked (points, *S) operands."""
        prim = eqn.primitive
        lanes = self.lane_shape
        points = int(np.prod(lanes, dtype=np.int64))
        axes = [0 if self.batched(x) else None for x in inputs]
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
    x = jnp.asarray(x, dtype=dtype)
    if x.shape == ():
        return _object_array([x] * int(np.prod(shape, dtype=np.int64)), shape)
    flat = x.reshape(-1)
    return _object_array([flat[i] for i in range(flat.shape[0])], x.shape)


def _elementwise(ev, eqn, inputs):
    shape = eqn.outvars[0].aval.shape
    prim = eqn.primitive
    if prim.multiple_results:
        return NotImplemented
    cells = [_cells_of(ev, x, shape, v.aval.dtype) for x, v in zip(inputs, eqn.invars)]
    try:  # size-1 axes broadcast (lax accepts (1,) against (3,))
        cells = [c if c.shape == shape else np.broadcast_to(c, shape) for c in cells]
    except ValueError:
        return NotImplemented
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
    return [_Lanes(np.take(cells, i, axis=axis), v.aval.dtype) for i, v in enumerate(eqn.outvars)]


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


def _reduce(ev, eqn, inputs):
    combine = _REDUCERS[eqn.primitive.name]
    cells = inputs[0].cells
    axes = tuple(eqn.params["axes"])
    keep = [d for d in range(cells.ndim) if d not in axes]
    moved = cells.transpose(keep + list(axes))
    out_shape = moved.shape[: len(keep)]
    flat = moved.reshape(out_shape + (-1,))
    outs = []
    for idx in np.ndindex(out_shape):
        terms = [ev.lane(t) for t in flat[idx]]
        if not terms:
            return NotImplemented
        total = terms[0]
        for t in terms[1:]:
            total = combine(total, t)
        outs.append(total)
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


_RULES = {
    "broadcast_in_dim": _broadcast_in_dim,
    "reshape": _reshape,
    "squeeze": _squeeze,
    "transpose": _transpose,
    "rev": _rev,
    "slice": _slice,
    "concatenate": _concatenate,
    "stack": _stack,
    "split": _split,
    "unstack": _unstack,
    "tile": _tile,
    "bitcast_convert_type": _bitcast_convert_type,
    "pad": _pad,
    "dot_general": _dot_general,
    **{name: _reduce for name in _REDUCERS},
}


def lane_map(fn: Callable, lane_shape) -> Callable:
    """`fn` maps ONE point (arrays of any shape, a pytree) to a pytree of arrays; the result maps
    per-coordinate lanes to the same outputs over all the points, like `jax.vmap(fn)`.

    The points are laid out in an array of shape `lane_shape` (an int for a flat block). The
    returned function takes, for each argument of `fn`, either a tuple of d arrays of shape
    `lane_shape` (the coordinates of a flat (d,) argument: lanes as the sources make them) or one
    array of shape lane_shape + S (the vmap layout). It returns outputs of shape lane_shape + out.
    """
    lane_shape = (lane_shape,) if isinstance(lane_shape, (int, np.integer)) else tuple(lane_shape)

    def mapped(*args):
        ev = _Evaluator(lane_shape)
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
            if ev.batched(o):
                stacked.append(ev.as_stacked(o).array.astype(aval.dtype))
            else:  # the same for every point
                o = jnp.asarray(o)
                stacked.append(jnp.broadcast_to(o, lane_shape + o.shape))
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
