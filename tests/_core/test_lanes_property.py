"""A property-based differential test of the lane interpreter (`jaxsample._core.lanes`) against
`jax.vmap`.

Hypothesis writes per-point programs from a grammar of the operations integrands are written
with: dot products, `einsum` with batch and free indices (both operands per-point, or one shared),
matrix products, transposes of 2-4 axes, reshapes, strided slices, flips, pads (plain, interior,
negative), concatenation and stacking along every axis, splits, tiles, reductions, ties of max and
min, `where`, sorts, cumulative sums, gathers (constant and value-dependent indices), loops,
`cond`, complex arithmetic, and broadcasts through size-1 axes. Each program starts from a point
x of shape (3,) and applies 1-6 of these steps; the shapes it passes through have up to 96
elements, so some exceed `MAX_LANES` and exercise the fallback. Programs whose values pass 1e6
(or gradients 1e8: repeated squaring) are discarded, since they test float32's range, not the
interpreter.

The arbiter is float64 `jax.vmap` of the same program. In float64, `lane_map`'s values and its
reverse-mode gradients (with respect to the points and to a closed-over parameter) must equal
the arbiter's to 1e-9 of the output's scale: the interpreter only reorders sums, so anything more
is a wrong rule. In float32 (what the estimators run), lane values may be no further from the
arbiter than 8x vmap's own float32 error plus 2e-5 of the output's scale (rounding-order
differences of float32 sums, at most a few ulps of the largest term).

CI runs a fixed, derandomized set of `JAXSAMPLE_LANES_EXAMPLES` programs per step of the
grammar (default 2: each step appears in two programs, among random others), so the suite is
deterministic; set the variable higher, and `JAXSAMPLE_LANES_RANDOM=1` for fresh
programs (without hypothesis' shrinking, which takes minutes on these), to search more. The programs
run eagerly (no `jit`): the interpreter's
rules are Python that emits the same JAX operations either way, and eager evaluation spares a
compilation per program and per dtype. A failure prints the program (hypothesis' falsifying
example: the list of steps).
"""

from __future__ import annotations

import itertools
import math
import os
import string

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st

from jaxsample._core.lanes import MAX_LANES, lane_map

EXAMPLES = int(os.environ.get("JAXSAMPLE_LANES_EXAMPLES", "2"))   # per step of the grammar
RANDOM = os.environ.get("JAXSAMPLE_LANES_RANDOM", "") not in ("", "0")
MAX_SIZE = 96          # per-point elements along the way (MAX_LANES is 64: some steps fall back)
POINTS = 6             # points per evaluation (lanes of shape (6,))


# ----------------------------------------------------------------------------------------------
# The grammar: each step maps a per-point array of known shape to another. A step is data (a
# name and its parameters, which is what hypothesis prints); `_apply` gives it meaning.
# Constants come from a seed inside the step, so a step is reproducible from its printout.
# ----------------------------------------------------------------------------------------------


def _const(seed, shape, dtype):
    return jnp.asarray(np.random.default_rng(seed).uniform(-1.0, 1.0, size=shape), dtype)


def _letters(n):
    return string.ascii_lowercase[:n]


def _partner(v, kind):
    """A second per-point operand derived from v (both sides of a contraction per-point)."""
    return {"self": v, "sin": jnp.sin(v), "affine": 1.5 * v + 0.25, "flip": jnp.flip(v)}[kind]


def _apply(step, v):
    name, p = step[0], dict(step[1])
    dt = v.dtype
    if name == "unary":
        return {"sin": jnp.sin, "tanh": jnp.tanh, "square": jnp.square, "swish": lambda w: w * jax.nn.sigmoid(w),
                "log1p_sq": lambda w: jnp.log1p(w * w), "cos": jnp.cos}[p["fn"]](v)
    if name == "broadcast_mul":        # elementwise with a shared array; size-1 axes broadcast
        return v * _const(p["seed"], p["cshape"], dt) + 0.5
    if name == "tensordot":            # a free index of a shared matrix against one axis of v
        return jnp.tensordot(v, _const(p["seed"], (v.shape[p["axis"]], p["k"]), dt), axes=([p["axis"]], [0]))
    if name == "einsum":               # batch, contracted and free indices; the partner per-point or shared
        letters = _letters(v.ndim)
        rhs_axes = p["rhs_axes"]
        rhs_shape = tuple(v.shape[a] for a in rhs_axes)
        rhs_sub = "".join(letters[a] for a in rhs_axes)
        if p["partner"] == "shared":
            rhs = _const(p["seed"], rhs_shape + (p["k"],), dt)
            rhs_sub += "z"
        else:
            others = tuple(a for a in range(v.ndim) if a not in rhs_axes)
            rhs = _partner(v, p["partner"])
            rhs = jnp.sum(rhs, axis=others) if others else rhs
        out = "".join(letters[a] for a in range(v.ndim) if a not in p["contract"]) + ("z" if "z" in rhs_sub else "")
        return jnp.einsum(f"{letters},{rhs_sub}->{out}", v, rhs)
    if name == "matmul":               # (..., m, n) @ (..., n, m) with both sides per-point
        return jnp.matmul(v, jnp.swapaxes(_partner(v, p["partner"]), -1, -2))
    if name == "transpose":
        return jnp.transpose(v, p["perm"])
    if name == "reshape":
        return v.reshape(p["shape"])
    if name == "slice":
        return jax.lax.slice_in_dim(v, p["start"], p["stop"], p["stride"], p["axis"])
    if name == "pad":
        if p["mode"] == "constant":
            widths = [(0, 0)] * v.ndim
            widths[p["axis"]] = (p["lo"], p["hi"])
            return jnp.pad(v, widths, constant_values=p["value"])
        config = [(0, 0, 0)] * v.ndim     # lax.pad: interior or negative (cropping) padding
        config[p["axis"]] = (p["lo"], p["hi"], p["interior"])
        return jax.lax.pad(v, jnp.asarray(p["value"], dt), config)
    if name == "concatenate":
        return jnp.concatenate([v, _partner(v, p["partner"])], axis=p["axis"])
    if name == "stack":
        return jnp.stack([v, _partner(v, p["partner"])], axis=p["axis"])
    if name == "split":
        a, b = jnp.split(v, 2, axis=p["axis"])
        return a * b + a
    if name == "tile":
        return jnp.tile(v, p["reps"])
    if name == "tie":                  # max and min with tied terms of unequal tangents (one held
        held = jax.lax.stop_gradient(v)   # constant): JAX gives each tied term an equal share
        return jnp.max(jnp.stack([v, held, v, v - 1.0]), axis=0) + jnp.min(jnp.stack([v, 2.0 * v, held]), axis=0)
    if name == "flip":
        return jnp.flip(v, axis=p["axis"]) - 0.5 * v
    if name == "reduce":
        return {"sum": jnp.sum, "max": jnp.max, "min": jnp.min, "prod": jnp.prod, "mean": jnp.mean}[p["fn"]](
            v, axis=p["axes"])
    if name == "grow":                 # a scalar or small value spread along a new axis
        return v[..., None] * _const(p["seed"], (p["k"],), dt) + v[..., None] ** 2
    if name == "where":
        return jnp.where(v > p["threshold"], v, jnp.sin(3.0 * v) - 0.5)
    if name == "sort":
        return jnp.sort(v, axis=p["axis"])
    if name == "cumsum":
        return jnp.cumsum(v, axis=p["axis"])
    if name == "gather_const":
        flat = v.reshape(-1)
        return flat[jnp.asarray(p["index"], jnp.int32)] * 2.0
    if name == "gather_dynamic":       # an index that depends on the point's values
        flat = v.reshape(-1)
        i = (jnp.abs(flat[0]) * 7.0).astype(jnp.int32) % flat.shape[0]
        return v * flat[i]
    if name == "loop":
        return jax.lax.fori_loop(0, p["trips"], lambda i, w: 0.5 * w + 0.25 * jnp.sin(w + i), v)
    if name == "cond":
        return jax.lax.cond(jnp.sum(v) > p["threshold"], lambda w: 2.0 * w * w, lambda w: jnp.cos(w), v)
    if name == "complex":              # complex intermediate values, a real result
        z = jax.lax.complex(v, jnp.sin(v)) * jnp.asarray(0.3 - 0.7j, jnp.result_type(dt, jnp.complex64))
        if p["kind"] == "abs2":
            return jnp.real(z * jnp.conj(z)) + jnp.imag(z)
        if p["kind"] == "exp":
            return jnp.real(jnp.exp(1j * v.astype(z.dtype)) * z)
        return jnp.real(jnp.sum(z * z, axis=-1, keepdims=True)) * v   # a complex reduction
    raise AssertionError(name)


def _program(steps):
    def fn(x):
        v = x
        for step in steps:
            v = _apply(step, v)
        return {"out": v, "first": x[0] * jnp.sum(v)}   # a pytree output, one leaf a scalar
    return fn


def _shape_after(step, shape):
    return jax.eval_shape(lambda v: _apply(step, v), jax.ShapeDtypeStruct(shape, jnp.float32)).shape


def _factorizations(size, max_rank=4):
    out = set()
    for rank in range(1, max_rank + 1):
        for dims in itertools.product([d for d in range(1, size + 1) if size % d == 0], repeat=rank):
            if math.prod(dims) == size:
                out.add(dims)
    return sorted(out)


def _options(shape):
    """The steps the grammar allows on a per-point value of this shape."""
    nd, size = len(shape), math.prod(shape)
    if nd == 0:
        return ["grow", "unary", "where", "cond", "complex"]
    options = ["unary", "broadcast_mul", "where", "loop", "cond", "complex", "gather_dynamic", "gather_const",
               "tensordot", "einsum", "slice", "reduce", "sort", "cumsum", "reshape", "pad", "flip"]
    if size * 4 <= MAX_LANES:
        options += ["tie"]
    if size * 2 <= MAX_SIZE:
        options += ["concatenate", "stack", "tile", "grow"]
    if nd >= 2:
        options += ["transpose", "matmul"]
    if any(s % 2 == 0 for s in shape):
        options += ["split"]
    return options


STEPS = sorted(set(_options(()) + _options((2, 2)) + _options((2, 3))))


@st.composite
def _step(draw, shape, name=None):
    """One step valid for a per-point value of this shape (the draws are its parameters); `name`
    given: that step."""
    nd, size = len(shape), math.prod(shape)
    seed = draw(st.integers(0, 2**16))
    partners = st.sampled_from(["flip", "sin", "affine", "self"])
    axis_draw = st.sampled_from(list(range(nd))[::-1])   # the last axis first (see `programs`)
    if name is None:
        name = draw(st.sampled_from(_options(shape)))
    p = {}
    if name == "unary":
        p["fn"] = draw(st.sampled_from(["sin", "tanh", "square", "swish", "log1p_sq", "cos"]))
    elif name == "broadcast_mul":
        p["seed"] = seed
        p["cshape"] = tuple(draw(st.sampled_from([s, 1])) for s in shape)[draw(st.integers(0, nd)):]
    elif name == "tensordot":
        p.update(seed=seed, axis=draw(axis_draw), k=draw(st.integers(1, 3)))
    elif name == "einsum":
        contract = (draw(axis_draw),) if nd > 1 and draw(st.booleans()) is False else \
            tuple(sorted(draw(st.sets(st.integers(0, nd - 1), min_size=1, max_size=nd))))
        batch = tuple(sorted(draw(st.sets(st.sampled_from([a for a in range(nd) if a not in contract] or [0]),
                                          max_size=2)) - set(contract)))
        p.update(seed=seed, contract=contract, k=draw(st.integers(1, 2)),
                 rhs_axes=tuple(sorted(set(contract) | set(batch))),
                 partner=draw(st.sampled_from(["shared", "self", "sin", "affine", "flip"])))
    elif name == "matmul":
        p["partner"] = draw(partners)
    elif name == "transpose":
        perms = sorted(itertools.permutations(range(nd)), key=lambda q: (q == tuple(np.argsort(q)), q))
        p["perm"] = draw(st.sampled_from(perms))     # those unequal to their inverse first
    elif name == "reshape":
        p["shape"] = draw(st.sampled_from(_factorizations(size)))
    elif name == "slice":
        axis = draw(axis_draw)
        n = shape[axis]
        start = draw(st.integers(0, n - 1))
        stop = draw(st.integers(start + 1, n))
        p.update(axis=axis, start=start, stop=stop, stride=draw(st.integers(1, 3)))
    elif name == "pad":
        axis = draw(axis_draw)
        mode = draw(st.sampled_from(["constant", "lax"]))
        room = max(0, (MAX_SIZE // max(size, 1) - 1) * shape[axis])
        lo, hi = draw(st.sampled_from(range(min(2, room), -1, -1))), draw(st.integers(0, min(2, room)))
        p.update(axis=axis, mode=mode, lo=lo, hi=hi, value=draw(st.sampled_from([0.0, 0.5, -1.25])))
        if mode == "lax":
            p["interior"] = draw(st.integers(0, 1 if size * 2 <= MAX_SIZE else 0))
            if shape[axis] > 1 and draw(st.booleans()):
                p["lo"] = -1                                   # crop one element
    elif name in ("concatenate", "stack"):
        p.update(axis=draw(st.sampled_from(list(range(nd + (name == "stack")))[::-1])), partner=draw(partners))
    elif name == "split":
        p["axis"] = draw(st.sampled_from([a for a, s in enumerate(shape) if s % 2 == 0][::-1]))
    elif name == "tile":
        reps = [1] * nd
        reps[draw(axis_draw)] = 2
        p["reps"] = tuple(reps)
    elif name == "reduce":
        subsets = [q for r in range(1, nd + 1) for q in itertools.combinations(range(nd), r)]
        subsets.sort(key=lambda q: (len(q) == nd, 0 in q, q))     # partial, axis 0 kept, first
        p.update(fn=draw(st.sampled_from(["max", "sum", "min", "prod", "mean"])), axes=draw(st.sampled_from(subsets)))
    elif name == "grow":
        p.update(seed=seed, k=draw(st.integers(2, min(4, max(2, MAX_SIZE // max(size, 1))))))
    elif name == "where":
        p["threshold"] = draw(st.sampled_from([-0.3, 0.1, 0.6]))
    elif name in ("sort", "cumsum", "flip"):
        p["axis"] = draw(axis_draw)
    elif name == "gather_const":
        count = draw(st.integers(1, 4))
        p["index"] = tuple(draw(st.integers(0, size - 1)) for _ in range(count))
    elif name == "loop":
        p["trips"] = draw(st.integers(1, 3))
    elif name == "cond":
        p["threshold"] = draw(st.sampled_from([-0.5, 0.0, 0.5]))
    elif name == "complex":
        p["kind"] = draw(st.sampled_from(["abs2", "exp", "reduce"] if nd else ["abs2", "exp"]))
    return (name, tuple(sorted(p.items())))


@st.composite
def programs(draw, focus):
    """1-6 random steps with the step `focus` among them, on a value of 1-3 axes (`grow` steps
    are put before it where the shape so far has fewer, or does not admit it: a transpose needs
    two axes, a split an even one).

    Hypothesis' first example of a test is its simplest (every draw at its first choice), and CI
    runs two: so the first choices are the searching ones (three axes, the last axis, a partial
    reduction, a permutation unlike its inverse), and a rule that mixes up axes fails there."""
    shape, steps = (3,), []
    length = draw(st.integers(1, 6))
    at = draw(st.integers(0, length - 1))
    rank = draw(st.sampled_from([3, 2, 1]))
    for position in range(length):
        while position == at and (focus not in _options(shape) or len(shape) < rank):
            steps.append(("grow", (("k", 2), ("seed", 0))))
            shape = _shape_after(steps[-1], shape)
        step = draw(_step(shape, focus if position == at else None))
        new_shape = _shape_after(step, shape)
        if position != at and (math.prod(new_shape) == 0 or math.prod(new_shape) > MAX_SIZE):
            continue
        steps.append(step)
        shape = new_shape
    return steps


# ----------------------------------------------------------------------------------------------
# The comparison
# ----------------------------------------------------------------------------------------------


def _points(dtype):
    return jnp.asarray(np.random.default_rng(11).normal(size=(POINTS, 3)), dtype)


def _both(fn, pts, lanes_form):
    by_vmap = jax.vmap(fn)(pts)
    arg = tuple(pts[:, j] for j in range(3)) if lanes_form else pts
    by_lanes = lane_map(fn, POINTS)(arg)
    return by_vmap, by_lanes


def _loss(mapper, fn, scale, pts):
    out = mapper(lambda x: fn(x * scale))(pts)
    weights = [jnp.cos(jnp.arange(leaf.size, dtype=leaf.dtype)).reshape(leaf.shape) for leaf in jax.tree.leaves(out)]
    return sum(jnp.sum(w * leaf) for w, leaf in zip(weights, jax.tree.leaves(out)))


def _scale(reference):
    return max(1.0, max(float(np.max(np.abs(np.asarray(r)))) for r in jax.tree.leaves(reference)))


@pytest.mark.parametrize("focus", STEPS)
@settings(max_examples=EXAMPLES, derandomize=not RANDOM, deadline=None, database=None,
          phases=[Phase.explicit, Phase.generate] if RANDOM else list(Phase),   # shrinking is slow here
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(data=st.data(), lanes_form=st.booleans())
def test_lane_programs_equal_vmap_in_values_and_gradients(focus, data, lanes_form):
    """Every step of the grammar appears in EXAMPLES programs (2 in CI) among random others."""
    steps = data.draw(programs(focus), label="steps")
    fn = _program(steps)
    with jax.enable_x64(True):
        pts = _points(jnp.float64)
        arbiter, lanes64 = _both(fn, pts, lanes_form)
        scale = _scale(arbiter)
        assume(scale < 1e6)    # programs whose values grow past float32's comfort (x^64) say nothing
        for got, want in zip(jax.tree.leaves(lanes64), jax.tree.leaves(arbiter)):
            assert got.shape == want.shape and got.dtype == want.dtype, (got.shape, want.shape, got.dtype, want.dtype)
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * scale, err_msg=f"values of {steps}")
        g_vmap = jax.grad(lambda s, q: _loss(jax.vmap, fn, s, q), argnums=(0, 1))(jnp.float64(1.25), pts)
        g_lanes = jax.grad(lambda s, q: _loss(lambda f: lane_map(f, POINTS), fn, s, q), argnums=(0, 1))(
            jnp.float64(1.25), pts)
        g_scale = _scale(g_vmap)
        assume(g_scale < 1e8)
        for got, want in zip(g_lanes, g_vmap):
            np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-8 * g_scale, err_msg=f"gradients of {steps}")
        arbiter = [np.asarray(a) for a in jax.tree.leaves(arbiter)]
    vmap32, lanes32 = _both(fn, _points(jnp.float32), lanes_form)
    for got, ref32, want in zip(jax.tree.leaves(lanes32), jax.tree.leaves(vmap32), arbiter):
        assert got.dtype == ref32.dtype == jnp.float32, (got.dtype, ref32.dtype)
        own_error = np.abs(np.asarray(ref32, np.float64) - want)
        bound = 8.0 * own_error + 2e-5 * scale
        excess = np.abs(np.asarray(got, np.float64) - want) - bound
        assert np.all(excess <= 0), f"float32 lanes of {steps}: worst excess {excess.max():.3g} over {bound.max():.3g}"
