"""What keeps `lane_map` on its fast path, and what it does at the edges of it: the primitive
objects its tables rely on exist in this JAX; the integrands users write stay on the lanes
(`strict=True` raises where a primitive would go to vmap); a bug inside a rule is an error, not a
silent vmap; max/min reductions have JAX's derivative at ties."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax import lax
from jax.extend.core import primitives as P

from jaxsample._core import lanes
from jaxsample._core.lanes import LaneFallback, lane_map

A = jnp.array([0.3, -0.2, 0.9327379], jnp.float32)
R = jnp.array([[0.36, 0.48, -0.8], [-0.8, 0.6, 0.0], [0.48, 0.64, 0.6]], jnp.float32)
N = 64

# The primitives the fast path relies on in this JAX, by role. `pjit`, `core_call` and
# `random_gamma_grad` are not primitives of JAX 0.10 (a `jax.jit` call binds `jit`).
RELIED_ON = {
    "inlined": "jit closed_call call",
    "rearranging": "broadcast_in_dim reshape squeeze transpose rev slice concatenate split stack unstack "
                   "tile pad bitcast_convert_type",
    "mixing": "dot_general reduce_sum reduce_max reduce_min reduce_prod reduce_and reduce_or reduce_xor",
    "elementwise": "add sub mul div neg max min abs sqrt rsqrt exp log sin cos atan2 integer_pow square pow "
                   "select_n clamp convert_element_type eq ne lt le gt ge and or not stop_gradient copy",
}


def _object(name):
    for module in (P, lax):
        prim = getattr(module, name + "_p", None)
        if prim is not None:
            return prim
    from jax._src.lax import lax as src_lax  # stack, unstack, tile: not exported by jax.lax
    return getattr(src_lax, name + "_p")


@pytest.mark.parametrize("role", sorted(RELIED_ON))
def test_every_primitive_the_fast_path_relies_on_exists(role):
    """Each primitive object exists in the installed JAX, carries the name its jaxprs print, and is
    a key of the interpreter's tables (so a program binding it is taken on the lanes)."""
    for name in RELIED_ON[role].split():
        prim = _object(name)
        assert isinstance(prim, jax.extend.core.Primitive) and prim.name == name, name
        table = lanes._INLINED if role == "inlined" else lanes._RULES
        assert prim in table, f"{name} is not in the lane tables"
    if role == "mixing":
        assert lanes._RULES[lax.reduce_max_p] is lanes._reduce and lanes._RULES[lax.dot_general_p] is lanes._dot_general


def test_the_tables_hold_primitive_objects_and_a_missing_one_is_recorded_not_raised(monkeypatch):
    """Catches a primitive missing from this JAX raising (an ImportError of the whole package when
    the tables are built at import) instead of being recorded, which turns the interpreter off
    (tests/_core/test_lane_fallback.py); and a primitive newer than an old JAX being required there."""
    keys = list(lanes._RULES) + list(lanes._INLINED) + list(lanes._REDUCERS)
    assert all(isinstance(k, jax.extend.core.Primitive) for k in keys)
    assert lanes._MISSING == []
    monkeypatch.setattr(lanes, "_MISSING", [])
    assert lanes._keyed({"add": 1, "random_gamma_grad": 2}) == {lax.add_p: 1}
    assert lanes._MISSING == ["random_gamma_grad"]
    # A primitive newer than the installed JAX is left out, not required; from its version on it is.
    monkeypatch.setattr(lanes, "_MISSING", [])
    monkeypatch.setattr(lanes, "_jax_version", lambda: (0, 7, 0))
    assert lanes._keyed({"add": 1, "no_such_primitive": 2}, since=(0, 10, 1)) == {lax.add_p: 1}
    assert lanes._MISSING == []
    monkeypatch.setattr(lanes, "_jax_version", lambda: (0, 10, 1))
    assert lanes._keyed({"no_such_primitive": 2}, since=(0, 10, 1)) == {}
    assert lanes._MISSING == ["no_such_primitive"]


# Integrands as users write them; every one must run entirely on the lanes.
FAST = {
    "dot": lambda x: jnp.dot(x, A),
    "matmul_operator": lambda x: x @ A,
    "sum_product": lambda x: jnp.sum(x * A),
    "einsum": lambda x: jnp.einsum("i,i->", x, A),
    "vdot": lambda x: jnp.vdot(x, A),
    "norm": lambda x: jnp.linalg.norm(x),
    "normalize": lambda x: x / jnp.linalg.norm(x),
    "norm_axis": lambda x: jnp.linalg.norm(jnp.outer(x, A), axis=0),
    "cross": lambda x: jnp.cross(x, A),
    "rotation_3x3": lambda x: R @ x,
    "rotation_transposed": lambda x: x @ R.T,
    "where": lambda x: jnp.where(x[2] > 0, x[0], -x[1]),
    "clip": lambda x: jnp.clip(x @ A, 0.0, 1.0),
    "relu_cubed": lambda x: jnp.maximum(x @ A, 0.0) ** 3,
    "stack": lambda x: jnp.stack([x[0] * x[1], x[2]]),
    "index": lambda x: x[2] * x[0],
    "slices": lambda x: x[:2] @ A[1:],
    "max_min": lambda x: jnp.max(x) - jnp.min(x),
    "abs_sum": lambda x: jnp.abs(x).sum(),
    "mean": lambda x: jnp.mean(x ** 2),
    "exp_cos": lambda x: jnp.exp(-x[0] ** 2) * jnp.cos(3.0 * x[1]),
    "arctan2": lambda x: jnp.arctan2(x[1], x[0]),
    "sqrt_safe": lambda x: jnp.sqrt(jnp.maximum(1.0 - x[2] ** 2, 0.0)),
    "reflect": lambda x: x - 2.0 * jnp.dot(x, A) * A,
    "concatenate": lambda x: jnp.concatenate([x, x[:1]]) @ jnp.ones(4),
    "outer_trace": lambda x: jnp.trace(jnp.outer(x, A)),
    "jitted_helper": jax.jit(lambda x: jnp.sum(jnp.sin(x) * A)),
    "cast_int": lambda x: (x[0] > 0).astype(jnp.float32) + jnp.floor(x[1] * 4.0),
    "pytree": lambda x: {"value": x @ A, "direction": x / jnp.linalg.norm(x)},
    # Derivatives taken inside the per-point program (the engine's sensitivities are JVPs on one
    # point): a value read twice makes autodiff sum its tangents with `add_any`.
    "jvp_inside": lambda x: jax.jvp(lambda c: jnp.sin(c * x[0]) * c * x[1], (1.5,), (1.0,))[1],
    "grad_inside": lambda x: jax.grad(lambda v: jnp.sum(v * v * A) + v[0] * v[1])(x),
}


@pytest.fixture(scope="module")
def points():
    return jax.random.normal(jax.random.key(1), (N, 3), jnp.float32)


def _lanes(points):
    return tuple(points[:, j] for j in range(points.shape[1]))


@pytest.mark.parametrize("name", sorted(FAST))
def test_user_programs_stay_on_the_fast_path(name, points):
    """strict=True raises on any fallback: each program (and its gradient) runs on the lanes and
    equals vmap."""
    fn = FAST[name]
    got = jax.jit(lane_map(fn, N, strict=True))(_lanes(points))
    expected = jax.vmap(fn)(points)
    jax.tree_util.tree_map(lambda g, e: np.testing.assert_allclose(g, e, rtol=2e-6, atol=2e-6), got, expected)

    def total(mapper, scale):
        leaves = jax.tree_util.tree_leaves(mapper(lambda x: fn(x * scale)))
        return sum(jnp.sum(leaf) for leaf in leaves)

    g_lanes = jax.grad(lambda s: total(lambda f: lane_map(f, N, strict=True)(_lanes(points)), s))(1.5)
    g_vmap = jax.grad(lambda s: total(lambda f: jax.vmap(f)(points), s))(1.5)
    np.testing.assert_allclose(g_lanes, g_vmap, rtol=2e-5, atol=2e-5)


@pytest.mark.parametrize("fn, what", [
    (lambda x: A[jnp.clip((x[0] * 3).astype(jnp.int32), 0, 2)], "dynamic_slice|gather"),
    (lambda x: jnp.sort(x), "sort"),
    (lambda x: jnp.sum(jnp.sin(jnp.outer(jnp.linspace(0.0, 1.0, 40), x)), axis=0), "MAX_LANES"),
    (lambda x: jax.nn.relu(x), "custom_jvp_call"),
])
def test_strict_names_the_fallback_and_the_default_takes_it(fn, what, points):
    with pytest.raises(LaneFallback, match=what):
        lane_map(fn, N, strict=True)(_lanes(points))
    np.testing.assert_allclose(lane_map(fn, N)(_lanes(points)), jax.vmap(fn)(points), rtol=2e-6, atol=2e-6)


def test_an_error_inside_a_rule_propagates(monkeypatch, points):
    """A rule that raises is a bug to see, not a reason to fall back to vmap silently."""

    def broken(ev, eqn, inputs):
        raise ValueError("broken rule")

    monkeypatch.setitem(lanes._RULES, lax.dot_general_p, broken)
    with pytest.raises(ValueError, match="broken rule"):
        lane_map(lambda x: x @ A, N)(_lanes(points))


# Ties: JAX's reduce_max/reduce_min derivative splits the tangent evenly among the elements equal
# to the result; elementwise max/min split 0.5/0.5. The parameter p = 1 makes the ties.
TIES = {
    "issue_three_way": lambda x, p: jnp.max(jnp.stack([x[0] * p, x[0] * p ** 2, x[0] * p ** 3])),
    "two_way": lambda x, p: jnp.max(jnp.stack([x[0] * p, x[0] * p ** 2, x[0] - 10.0])),
    "three_way_min": lambda x, p: jnp.min(jnp.stack([x[1] * p ** 3, x[1] * p, x[1] * p ** 2])),
    "four_way_axis": lambda x, p: jnp.max(jnp.stack([x * p, x * p ** 2, x * p ** 3, x * p ** 4]), axis=0) @ A,
    "tied_in_the_points": lambda x, p: jnp.max(jnp.stack([x[0], x[0], x[1]]) * p ** jnp.arange(3.0)),
    "elementwise_maximum": lambda x, p: jnp.maximum(x[0] * p, x[0] * p ** 2) + jnp.minimum(x[1] * p ** 3, x[1]),
    "amax_of_a_matrix": lambda x, p: jnp.max(jnp.outer(x, jnp.array([p, p ** 2]))),
}


@pytest.mark.parametrize("name", sorted(TIES))
def test_max_and_min_follow_jax_derivative_at_ties(name):
    """Values, reverse- and forward-mode derivatives (in the parameter and in the points) equal
    vmap's at exact ties, on the lanes (strict)."""
    fn = TIES[name]
    x = jax.random.normal(jax.random.key(2), (512, 3), jnp.float32)
    x = x.at[:, 1].set(jnp.where(jnp.arange(512) % 2 == 0, x[:, 0], x[:, 1]))  # ties between coordinates

    def total(mapper, p, pts):
        return jnp.sum(mapper(lambda v: fn(v, p), pts))

    by_vmap = lambda f, pts: jax.vmap(f)(pts)  # noqa: E731
    by_lanes = lambda f, pts: lane_map(f, 512, strict=True)(_lanes(pts))  # noqa: E731
    np.testing.assert_allclose(total(by_lanes, 1.0, x), total(by_vmap, 1.0, x), rtol=1e-6)
    g_lanes = jax.grad(total, argnums=(1, 2))(by_lanes, 1.0, x)
    g_vmap = jax.grad(total, argnums=(1, 2))(by_vmap, 1.0, x)
    for g, e in zip(g_lanes, g_vmap):
        np.testing.assert_allclose(g, e, rtol=1e-5, atol=1e-5)
    t_lanes = jax.jvp(lambda p: total(by_lanes, p, x), (1.0,), (1.0,))[1]
    t_vmap = jax.jvp(lambda p: total(by_vmap, p, x), (1.0,), (1.0,))[1]
    np.testing.assert_allclose(t_lanes, t_vmap, rtol=1e-5)


def test_the_issue_example_at_a_three_way_tie():
    """jnp.max of x0 p, x0 p^2, x0 p^3 at p = 1: the derivative is x0 (1 + 2 + 3) / 3 = 2 x0 where
    x0 > 0 (JAX's even split), not the pairwise chain's x0 (1/4 + 2/4 + 3/2) = 2.25 x0."""
    x0 = jax.random.uniform(jax.random.key(3), (512,), jnp.float32, 0.1, 1.0)
    fn = lambda x, p: jnp.max(jnp.stack([x[0] * p, x[0] * p ** 2, x[0] * p ** 3]))  # noqa: E731
    grad = jax.grad(lambda p: jnp.sum(lane_map(lambda v: fn(v, p), 512, strict=True)((x0,))))(1.0)
    np.testing.assert_allclose(grad, 2.0 * jnp.sum(x0), rtol=1e-5)
    np.testing.assert_allclose(grad, jax.grad(lambda p: jnp.sum(jax.vmap(lambda v: fn(v[None], p))(x0)))(1.0),
                               rtol=1e-6)


def test_integer_max_reduction_stays_exact(points):
    fn = lambda x: jnp.max((x * 8).astype(jnp.int32)) - jnp.min((x * 8).astype(jnp.int32))  # noqa: E731
    np.testing.assert_array_equal(lane_map(fn, N, strict=True)(_lanes(points)), jax.vmap(fn)(points))


# ------------------------------------------------------------------------------------------------
# Many outputs per point: the generator and the warp run once, not once per output
# ------------------------------------------------------------------------------------------------

def test_stored_once_is_the_identity_for_values_vmap_and_derivatives():
    from jaxsample._core.computed_once import stored_once

    x = jnp.linspace(0.1, 2.0, 12, dtype=jnp.float32).reshape(4, 3)
    f = lambda v: jnp.sum(jnp.sin(stored_once(v * v)) * v)
    plain = lambda v: jnp.sum(jnp.sin(v * v) * v)
    np.testing.assert_array_equal(jax.jit(f)(x), jax.jit(plain)(x))
    np.testing.assert_allclose(jax.grad(f)(x), jax.grad(plain)(x), rtol=1e-6)
    np.testing.assert_allclose(jax.jacfwd(f)(x), jax.jacfwd(plain)(x), rtol=1e-6)
    np.testing.assert_array_equal(jax.vmap(f)(x), jax.vmap(plain)(x))
    # On the lanes: the marked values are the same lanes, and the outputs those of vmap.
    g = lambda v: jnp.stack([stored_once(v)[i] * (k + 1.0) for i in range(3) for k in range(4)])
    lanes_out = lane_map(g, 4, strict=True)(tuple(x.T))
    np.testing.assert_array_equal(lanes_out, jax.vmap(g)(x))


def _computations_with(text, needle):
    import re

    blocks, current = {}, None
    for line in text.splitlines():
        m = re.match(r"^(?:ENTRY )?%(\S+) ", line)
        if m and line.rstrip().endswith("{"):
            current = m.group(1)
            blocks[current] = []
        elif current is not None:
            blocks[current].append(line)
    return sum(any(needle in line for line in body) for body in blocks.values())


def test_a_many_output_estimate_runs_the_generator_in_a_few_loops_not_one_per_output():
    """A 9-coefficient projection (degree < 3 harmonics times a lobe): in the optimized HLO the
    Philox multiplier 0xD2511F53 and the warp's quarter-turn rounding (`sincos_2pi`) each appear
    in at most 4 computations (the generator's and the warp's own loops), not once per output:
    XLA puts each output in its own loop and copies cheap-looking producers into each, which
    `computed_once` (the chunk's uniforms) and `stored_once` (the warped sample) prevent.
    Measured (Philox, rounding): 4, 4 with both; 10, 4 with the uniforms only through the
    sample; 4, 18 with the sample not stored; 22, 18 with neither. At 49 outputs the estimate
    runs 2x faster for it (benchmarks/compile_and_outputs.py)."""
    import jaxsample as js

    def projection(w):
        x, y, z = w[0], w[1], w[2]
        basis = jnp.stack([jnp.ones_like(x), y, z, x, x * y, y * z, 3 * z * z - 1, x * z, x * x - y * y])
        return basis * jnp.maximum(0.3 * x + 0.2 * y + 0.93 * z, 0.0) ** 3

    text = jax.jit(lambda k: js.estimate(projection, js.UniformSphere(), k, 1 << 18).mean).lower(
        jax.random.key(0)).compile().as_text()
    assert _computations_with(text, str(0xD2511F53)) <= 4
    assert _computations_with(text, "round-nearest") <= 4


def test_a_differentiated_estimate_runs_the_generator_once_per_pass_not_once_per_residual():
    """`jax.grad` of an estimate recomputes each chunk in the backward pass (the chunks are
    checkpointed), where every residual of the warp reads the uniforms; XLA's CPU fusion would
    copy the generator into each of those loops. `engine.group_values` takes the tangents on
    the uniforms stored once, so the Philox multiplier 0xD2511F53 appears in at most 6
    computations of the optimized HLO (measured: 5, of which 3 loops run the whole generator:
    the forward's and the backward's 2 packed pairs; 11 with the uniforms not stored, and the
    gradient runs slower: benchmarks/compile_and_outputs.py)."""
    import jaxsample as js

    axis = jnp.array([0.3, 0.2, 0.9327379])

    def program(scale, key):
        f = lambda w: scale * jnp.maximum(w @ axis, 0.0) ** 3
        return js.estimate(f, js.CosineHemisphere(), key, 1 << 18).mean

    text = jax.jit(jax.grad(program)).lower(jnp.float32(1.0), jax.random.key(0)).compile().as_text()
    assert _computations_with(text, str(0xD2511F53)) <= 6


def test_a_differentiated_estimate_may_close_over_traced_integers_bools_and_keys():
    """`engine.group_values` hoists every tracer its per-point program closes over into the
    arguments of its derivative rule. `jax.closure_convert` hoisted only float tracers, and an
    outer `jit` whose integrand closed over a traced int, bool or key failed in the lazily
    traced JVP rule ("No constant handler for type: DynamicJaxprTracer"). Each gradient must
    equal the one with the same value closed over as a constant."""
    import jaxsample as js

    def program(exponent, power, flip, noise_key):
        noise = jax.random.uniform(noise_key)
        f = lambda w: jnp.where(flip, w[2], w[0]) ** power * noise
        return js.estimate(f, js.PhongLobe(exponent), jax.random.key(0), 1024).mean

    traced = jax.jit(jax.grad(program))(jnp.float32(3.0), 2, True, jax.random.key(3))
    constant = jax.grad(lambda e: program(e, 2, True, jax.random.key(3)))(jnp.float32(3.0))
    assert jnp.isfinite(traced) and traced != 0.0
    np.testing.assert_allclose(traced, constant, rtol=1e-5)


def test_forward_mode_through_an_estimate_ignores_the_parameters_it_does_not_move():
    """Forward mode (`jax.jvp`, `jax.jacfwd`) of an estimate must push tangents only through what
    moves: the sampler's own parameters are traced (`compiled_entry`) but carry no tangent here,
    and sqrt(max(z, 0)) has an infinite partial derivative at the samples with z = 0, so a zero
    tangent pushed through it would make the derivative 0 · inf = NaN (it did, with the derivative
    rule of `engine.group_values` taking instantiated zeros). The forward derivative must be
    finite and equal the reverse one."""
    import jaxsample as js

    def program(scale):
        f = lambda w: scale * jnp.sqrt(jnp.maximum(w[2], 0.0))
        return js.estimate(f, js.UniformCone(-0.5), jax.random.key(0), 1024).mean

    forward = jax.jvp(program, (jnp.float32(1.0),), (jnp.float32(1.0),))[1]
    reverse = jax.grad(program)(jnp.float32(1.0))
    assert jnp.isfinite(forward) and forward > 0
    np.testing.assert_allclose(forward, reverse, rtol=1e-5)
    np.testing.assert_allclose(jax.jacfwd(program)(jnp.float32(1.0)), reverse, rtol=1e-5)


def test_a_one_group_estimate_computes_its_points_in_one_loop_whatever_the_integrand_combines():
    """A source with one group of lanes per chunk (Sobol', the lattice, Halton, Random past 2
    dimensions) hands the chunk's values to the replicate sums with no pair to pack. Without a
    boundary, XLA's CPU reduction fusion takes the integrand's last elementwise ops (here the sum
    of x, y and z) into the sums and leaves each operand a loop of its own, each re-running the
    Sobol' scramble and the warp: the Laine–Karras multiplier 0x6C50B47C sits in 3 computations
    and the estimate runs several times slower than with Philox (`paths.sobol_every_sampler`).
    The values are stored once (`computed_once(..., alone=True)`): one computation."""
    import jaxsample as js

    f = lambda w: w[0] + w[1] + w[2]
    program = lambda key: js.estimate(f, js.UniformSphere(), key, 1 << 18, uniforms="sobol").mean
    text = jax.jit(program).lower(jax.random.key(0)).compile().as_text()
    assert _computations_with(text, str(0x6C50B47C)) == 1


def test_columns_come_back_one_lane_array_per_element_with_no_stack_traced(points):
    """`lane_map(..., columns=True)` returns each per-point element as its own array over the
    points (what the engine's moments read), equal to vmap's columns, and traces no
    `concatenate`: the stack it replaces is what XLA's CPU backend turned into an element-by-element
    loop over the whole program (`test_colour_channels_are_lanes_of_their_own...`)."""
    fn = lambda x: {"rgb": jnp.stack([x[0] * x[1], jnp.sin(x[2]), x[0]]), "grey": x @ A}
    mapped = lane_map(fn, N, strict=True, columns=True)
    got = mapped(_lanes(points))
    expected = jax.vmap(fn)(points)
    assert isinstance(got["rgb"], tuple) and len(got["rgb"]) == 3 and len(got["grey"]) == 1
    for j in range(3):
        np.testing.assert_allclose(got["rgb"][j], expected["rgb"][:, j], rtol=2e-6)
    np.testing.assert_allclose(got["grey"][0], expected["grey"], rtol=2e-6)
    traced = {eqn.primitive.name for eqn in jax.make_jaxpr(mapped)(_lanes(points)).jaxpr.eqns}
    assert not traced & {"concatenate", "stack"}, traced
    # Off the lanes (vmap, as on other platforms) the same columns come back.
    fallback = lane_map(lambda x: jnp.sort(x), N, columns=True)(_lanes(points))
    for j in range(3):
        np.testing.assert_allclose(fallback[j], jnp.sort(points, axis=1)[:, j], rtol=2e-6)


def test_the_lanes_a_fallback_stacks_are_stored_first(points):
    """The (i, j) index of a 2-D lookup (a vmapped `dynamic_slice`, whose batching rule stacks the
    indices) comes from two lanes. Stacked straight from them, the stack was a concatenate fusion
    that computed everything upstream element by element; with a token (the engine's) the lanes a
    fallback stacks are stored once first (`computed_once`: a `cond` traced before the stack)."""
    grid = jnp.arange(12.0).reshape(3, 4)

    def lookup(x):
        i = jnp.clip((jnp.abs(x[0]) * 3.0).astype(jnp.int32), 0, 2)
        j = jnp.clip((jnp.abs(x[1]) * 4.0).astype(jnp.int32), 0, 3)
        return grid[i, j] * x[2]

    tok = jnp.uint32(7)
    mapped = lambda lanes, tok: lane_map(lookup, N, token=tok)(lanes)
    np.testing.assert_allclose(mapped(_lanes(points), tok), jax.vmap(lookup)(points), rtol=2e-6)
    traced = [eqn.primitive.name for eqn in jax.make_jaxpr(mapped)(_lanes(points), tok).jaxpr.eqns]
    last_stack = max(i for i, name in enumerate(traced) if name in ("stack", "concatenate"))
    assert "cond" in traced and traced.index("cond") < last_stack


def _largest_fusion_of_shape(text, suffix):
    """The most instructions in one fusion over the points (a (points, k) result, at least 1024
    points) whose result shape ends in `suffix` (e.g. ",3]")."""
    import re

    sizes, current = {}, None
    for line in text.splitlines():
        m = re.match(r"^%(\S+) ", line)
        if m and line.rstrip().endswith("{"):
            current = m.group(1)
            sizes[current] = 0
        elif line.startswith("}"):
            current = None
        elif current is not None:
            sizes[current] += 1
    largest = 0
    for shape, called in re.findall(r"= (\S+) fusion\(.*?calls=%([\w.\-]+)", text):
        dims = re.findall(r"\d+", shape.split("[", 1)[-1].split("]")[0])
        if shape.split("{")[0].endswith(suffix) and len(dims) == 2 and int(dims[0]) >= 1024:
            largest = max(largest, sizes.get(called, 0))
    return largest


def test_colour_channels_are_lanes_of_their_own_not_an_interleaved_array():
    """An RGB `shade` has 3 values per point. Stacked by the lanes program into a (points, 3)
    array, the channels became one concatenate fusion that XLA's CPU backend evaluates element by
    element, the whole per-point program per element (500 instructions), without vectorizing: the
    RGB value ran 75x slower than the grey one, its gradient 30x (`lane_map(..., columns=True)`
    keeps each channel a lane of its own). In the optimized HLO of the value and of its gradient,
    no fusion with a trailing axis of 3 may hold more than a copy's worth of work (measured: 9
    instructions, the stored channels stacked for the moments; 500 before)."""
    from jaxsample import scene

    colour = jnp.array([0.8, 0.5, 0.2])
    light = scene.SphereLight(jnp.array([-1.0, 0.3, 3.0]), 0.5, 20.0 * colour)

    def value(exponent, key):
        return scene.shade(jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 0.9]),
                           scene.Phong(exponent, colour), light, key, 1 << 16).mean.sum()

    for program in (value, jax.grad(value)):
        text = jax.jit(program).lower(jnp.float32(25.0), jax.random.key(0)).compile().as_text()
        assert _largest_fusion_of_shape(text, ",3]") <= 40


def test_the_gradient_of_a_mean_runs_the_derivative_stream_alone():
    """`jax.grad` of an estimate's mean needs Σ ∂Y/∂θ only, which the forward derivative stream
    gives (`engine._differentiable_stream`). The mean chooses its compensated or plain form by
    whether the sums are finite; a tangent that read that choice needed the value's stream too, and
    the gradient program ran both loops (3 while loops where the value has 2: its key's and its
    stream's). The gradient's program may have no more loops than the value's."""
    from jaxsample import scene

    def value(exponent, key):
        return scene.shade(jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 0.9]),
                           scene.Phong(exponent, 0.8), scene.SphereLight(jnp.array([-1.0, 0.3, 3.0]), 0.5, 20.0),
                           key, 1 << 18).mean

    loops = [jax.jit(p).lower(jnp.float32(25.0), jax.random.key(0)).compile().as_text().count(" while(")
             for p in (value, jax.grad(value))]
    assert loops[1] <= loops[0], loops


_MOVES = {"bitcast", "reshape", "broadcast", "copy", "slice", "transpose", "convert", "bitcast-convert", "real", "imag"}


def _computed_concatenates(text):
    """The concatenates over the points (a leading axis of at least 1024) in the optimized HLO that
    compute an operand in their own fusion: an operand that, through data movement only, does not
    come from a parameter or constant of that fusion (a stored array)."""
    import re

    found, bodies, current = [], {}, None
    for line in text.splitlines():
        m = re.match(r"^%(\S+) ", line)
        if m and line.rstrip().endswith("{"):
            current = m.group(1)
            bodies[current] = {}
        elif line.startswith("}"):
            current = None
        elif current is not None:
            d = re.match(r"\s*(?:ROOT )?%(\S+) = (\S+) ([\w-]+)\((.*?)\)", line)
            if d:
                bodies[current][d.group(1)] = (d.group(2), d.group(3), re.findall(r"%([\w.\-]+)", d.group(4)))
    for name, defs in bodies.items():
        def source(v):
            while v in defs and defs[v][1] in _MOVES and defs[v][2]:
                v = defs[v][2][0]
            return defs[v][1] if v in defs else "parameter"
        for shape, op, operands in defs.values():
            dims = re.findall(r"\d+", shape.split("[", 1)[-1].split("]")[0])
            if op == "concatenate" and dims and int(dims[0]) >= 1024:
                if any(source(o) not in ("parameter", "constant") for o in operands):
                    found.append((name, shape))
    return found


def test_an_rgb_environment_map_program_stacks_only_stored_values():
    """Shading under an RGB environment map (its texels gathered per point, a (3,) value stacked by
    the gather's fallback) in one chunk (n = 2^16, MIS: 2^15 pairs, the stream has no loop). Three
    ways it went into element-by-element concatenate fusions of the whole per-point program
    (measured 600 ms per call against 30 ms now): the texel times per-point lanes stacked the lanes;
    the texel index (i, j) was stacked straight from its lanes; and with the stream's chunk offset
    a constant, XLA folded every `computed_once` boundary (the token now mixes in a seed word). In
    the optimized HLO no concatenate over the points may compute its operands: it may only read
    stored arrays."""
    from jaxsample import scene

    texels = jnp.asarray(np.random.default_rng(0).uniform(0.2, 2.0, (8, 16, 3)).astype(np.float32))

    def value(exponent, key):
        return jnp.sum(scene.shade(jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 1.0]),
                                   scene.Phong(exponent, 0.8), scene.EnvironmentMap(texels), key, 1 << 16).mean)

    text = jax.jit(value).lower(jnp.float32(25.0), jax.random.key(0)).compile().as_text()
    assert _computed_concatenates(text) == []
