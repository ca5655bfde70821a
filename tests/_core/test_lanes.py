"""The per-point evaluation on coordinate lanes: same values and gradients as vmap,
whatever shape of program; the sources' lane layouts give the points of `block`; the engine's
compiled program has the fused shape that made it fast (a structural check, no clock)."""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import uniforms as U
from jaxsample._core.computed_once import computed_once
from jaxsample._core.doublefloat import sum_axis0
from jaxsample._core.lanes import lane_map

A = jnp.array([0.3, -0.2, 0.9327379], jnp.float32)
M = jnp.array([[0.5, -1.0, 2.0], [0.25, 0.0, -0.75]], jnp.float32)

# Per-point programs covering the rules of jaxsample._core.lanes (dot_general, reductions, reshapes,
# slices, concatenation, padding, broadcasting of size-1 axes, integer and boolean arithmetic)
# and the fallback (gather, sort, cumsum, a while loop, a custom derivative rule).
PROGRAMS = {
    "matmul": lambda x: jnp.maximum(x @ A, 0.0) ** 3,
    "dot": lambda x: jnp.dot(x, A) * x[0],
    "sum_product": lambda x: jnp.sum(x * A),
    "matrix": lambda x: M @ x,
    "outer": lambda x: jnp.outer(x, A).T.reshape(-1)[::2],
    "norm": lambda x: x / jnp.linalg.norm(x),
    "cross": lambda x: jnp.cross(x, A),
    "max_min": lambda x: jnp.max(x) - jnp.min(x) + jnp.prod(x),
    "concat_pad": lambda x: jnp.pad(jnp.concatenate([x, x[:1] * 2.0]), (1, 2), constant_values=0.5),
    "broadcast_1": lambda x: (x[0:1] * A).sum(),
    "where_int": lambda x: jnp.where(x[0] > 0, (x[1] * 8).astype(jnp.int32) % 3, -1).astype(jnp.float32),
    "flip_roll": lambda x: jnp.flip(x) + jnp.roll(x, 1),
    "gather": lambda x: A[jnp.clip((x[0] * 3).astype(jnp.int32), 0, 2)] + A[jnp.array([2, 0])].sum(),
    "sort_cumsum": lambda x: jnp.sort(x) + jnp.cumsum(x),
    "while": lambda x: jax.lax.fori_loop(0, 3, lambda i, v: v * x[1] + 1.0, x[0]),
    "relu": lambda x: jax.nn.relu(x) * jax.nn.softplus(x[2]),
    "pytree": lambda x: {"a": x[2], "b": (x[:2] ** 2, jnp.ones(()))},
    "bool_dot": lambda x: jax.lax.dot_general(x > 0, x < 0.5, (((0,), (0,)), ((), ()))).astype(jnp.float32),
    "wide": lambda x: jnp.sum(jnp.sin(jnp.outer(jnp.linspace(0.0, 1.0, 40), x)), axis=0),  # > MAX_LANES
    "stop_gradient": lambda x: jax.lax.stop_gradient(x) * x,
    # A batched contraction (every batch member its own matrix), a transpose of three axes (its
    # inverse permutation is another, wrong, one) and a join along axis 1: programs that break
    # these rules where a lane rule gets them wrong.
    "einsum_batched": lambda x: jnp.einsum("bij,bj->bi", jnp.stack([jnp.outer(x, A), 2.0 * jnp.outer(A, x)]),
                                           jnp.stack([x, x[::-1] + 1.0])).reshape(-1),
    "transpose_3_axes": lambda x: jnp.transpose(x[:2, None, None] * A[None, :, None] * x[None, None, :],
                                                (1, 2, 0)).reshape(-1),
    "hstack": lambda x: jnp.hstack([jnp.outer(x[:2], A), 2.0 * x[:2, None]]).reshape(-1),
}


@pytest.fixture(scope="module")
def points():
    return jax.random.normal(jax.random.key(0), (64, 3), jnp.float32)


@pytest.mark.parametrize("name", sorted(PROGRAMS))
def test_lane_map_equals_vmap(name, points):
    """Values to float rounding (a dot product's sum may be ordered differently by XLA), on both
    input forms (coordinate lanes and the stacked vmap layout), under jit."""
    fn = PROGRAMS[name]
    expected = jax.vmap(fn)(points)
    lanes = tuple(points[:, j] for j in range(3))
    for got in (jax.jit(lane_map(fn, 64))(lanes), jax.jit(lane_map(fn, 64))(points)):
        jax.tree_util.tree_map(lambda g, e: np.testing.assert_allclose(g, e, rtol=2e-6, atol=2e-6), got, expected)


@pytest.mark.parametrize("name", ["matmul", "norm", "cross", "relu", "gather", "while", "wide", "stop_gradient"])
def test_lane_map_gradients_equal_vmap(name, points):
    """Reverse mode through the lane program gives vmap's gradients, for the input points and for
    a closed-over parameter (the custom rule of relu is kept: its derivative at 0 is 0)."""
    fn = PROGRAMS[name]

    def total(mapper, scale, pts):
        out = mapper(lambda x: fn(x * scale))(pts)
        return jnp.sum(out)

    by_vmap = jax.grad(total, argnums=(1, 2))(jax.vmap, 1.5, points)
    by_lanes = jax.grad(total, argnums=(1, 2))(lambda f: lane_map(f, 64), 1.5, points)
    for g, e in zip(by_lanes, by_vmap):
        np.testing.assert_allclose(g, e, rtol=2e-5, atol=2e-5)


def test_lane_map_under_vmap_of_a_parameter(points):
    """A batched closed-over parameter (vmap over it outside) works like vmap inside."""
    scales = jnp.array([0.5, 1.0, 2.0])
    got = jax.vmap(lambda s: lane_map(lambda x: x @ (A * s), 64)(points))(scales)
    expected = jax.vmap(lambda s: jax.vmap(lambda x: x @ (A * s))(points))(scales)
    np.testing.assert_allclose(got, expected, rtol=2e-6, atol=2e-6)


def test_lane_map_on_two_dimensional_lanes(points):
    """Lanes may have any shape (Sobol' hands over (points per replicate, replicates))."""
    lanes = tuple(points[:, j].reshape(8, 8) for j in range(3))
    got = lane_map(PROGRAMS["matmul"], (8, 8))(lanes)
    np.testing.assert_allclose(got.reshape(-1), jax.vmap(PROGRAMS["matmul"])(points), rtol=2e-6)


def test_a_small_network_integrand_stays_a_matrix_product(points):
    """An integrand with a 64-wide hidden layer (a neural control variate, say): its 64x64 matrix
    product is not written out as 4096 lane multiply-adds (slow to compile, and slower to run than
    vmap); it stays one XLA dot, so the program stays small."""
    k1, k2, k3 = jax.random.split(jax.random.key(9), 3)
    w1 = jax.random.normal(k1, (64, 3))
    w2 = jax.random.normal(k2, (64, 64)) / 8
    w3 = jax.random.normal(k3, (64,))
    mlp = lambda x: jnp.tanh(jnp.tanh(x @ w1.T) @ w2.T) @ w3  # noqa: E731
    lowered = jax.jit(lane_map(mlp, 64)).lower(points)
    np.testing.assert_allclose(jax.jit(lane_map(mlp, 64))(points), jax.vmap(mlp)(points), rtol=1e-4, atol=1e-4)
    assert len(lowered.as_text()) < 200_000, len(lowered.as_text())


def _compiled(fn):
    return jax.jit(fn).lower(jax.random.key(0)).compile().as_text()


def test_engine_fuses_a_dot_product_integrand():
    """The defect the lanes prevent, checked on the compiled program: evaluated by `vmap`, `x @ a`
    leaves a separate `dot` op in the optimized HLO, and Philox is computed once per consumer (its
    multiplier 0xD2511F53 = 3528531795 appears more often than with explicit components). On the
    lanes no dot remains and the generator's rounds appear as often as for explicit components."""
    n = 1 << 16

    def program(f):
        return _compiled(lambda k: js.estimate(f, js.CosineHemisphere(), k, n).mean)

    matmul = program(lambda x: jnp.maximum(x @ A, 0.0) ** 3)
    explicit = program(lambda x: jnp.maximum(x[0] * A[0] + x[1] * A[1] + x[2] * A[2], 0.0) ** 3)
    assert " dot(" not in matmul
    assert matmul.count("3528531795") == explicit.count("3528531795")


@pytest.mark.parametrize("source", [U.Random(), U.Stratified(), U.Sobol(), U.Stratified(3), U.Sobol(4)],
                         ids=repr)
@pytest.mark.parametrize("dims", [1, 2, 3, 5])
def test_source_lanes_are_the_block_points(source, dims):
    """`Source.lanes` (what the estimators and `sample` consume) gives bit for bit the points of
    `Source.block`, group q holding points offset + g b + q in C order, for aligned chunks (the
    fast paths: Philox groups, the Sobol' table) and unaligned ones (the general path). The
    reference is one block from index 0, sliced per window (that a block at an offset is that
    slice of the whole is tests/uniforms/test_uniforms.py's chunking test)."""
    seed = U.seed_from_key(jax.random.key(3))
    total = 3 << 16
    windows = [(0, 1 << 12, 1 << 12), (1 << 12, 1 << 12, 1 << 12), (192, 384, 12), (0, 48, 48)]

    @jax.jit
    def both(seed):  # one compilation for every window; the offsets are traced, as in the engine
        out = []
        for offset, count, aligned in windows:
            offset = jnp.uint32(offset) + 0 * seed[0]
            groups = source.lanes(seed, offset, count, dims, total=total, aligned=aligned)
            got = jnp.stack([jnp.stack([c.reshape(-1) for c in lanes], -1) for lanes in groups], axis=1)
            out.append(got.reshape(count, dims))
        return out, source.block(seed, 0, max(o + c for o, c, _ in windows), dims, total=total)

    got, whole = both(seed)
    for (offset, count, _), lanes_points in zip(windows, got):
        np.testing.assert_array_equal(lanes_points, np.asarray(whole)[offset:offset + count])


STREAM_SAMPLERS = [js.CosineHemisphere(), js.PhongLobe(20.0), js.UniformDisk(), js.Exponential(2.0),
                   js.Discrete(jnp.array([1.0, 2.0, 3.0])), js.UniformSphere(method="rejection", tries=2)]
STREAM_SHAPES = [(), (5,), (3, 7), (70001,)]
@functools.lru_cache(maxsize=None)
def _stream_reference(index):
    """warp_with_pdf of the stream's first points, enough for the largest shape; each shape's
    reference is its first prod(shape) rows (sample i depends only on the key and i)."""
    sampler = STREAM_SAMPLERS[index]
    count = max(math.prod(shape) for shape in STREAM_SHAPES)
    u = U.uniform_block("random", jax.random.key(7), 0, count, sampler.uniform_dims)
    x, p = jax.jit(lambda s, u: s.warp_with_pdf(u))(sampler, u)
    return np.asarray(x), np.asarray(p)


@pytest.mark.parametrize("index", range(len(STREAM_SAMPLERS)), ids=[type(s).__name__ for s in STREAM_SAMPLERS])
@pytest.mark.parametrize("shape", STREAM_SHAPES)
def test_sample_is_the_warp_of_the_stream(index, shape):
    """`sample_with_pdf` (one chunked program) returns warp_with_pdf of the first prod(shape)
    points of the Philox stream, in C order, for shapes that do not fill a Philox block or a chunk."""
    sampler = STREAM_SAMPLERS[index]
    key = jax.random.key(7)
    count = int(np.prod(shape))
    x_expected, p_expected = (a[:count].reshape(shape + a.shape[1:]) for a in _stream_reference(index))
    x, p = sampler.sample_with_pdf(jax.random.clone(key), shape)
    assert x.shape == x_expected.shape and p.shape == p_expected.shape
    np.testing.assert_allclose(x, x_expected, rtol=1e-6, atol=2e-7)
    np.testing.assert_allclose(p, p_expected, rtol=1e-6, atol=2e-7)
    np.testing.assert_array_equal(sampler.sample(key, shape), x)


def test_computed_once_returns_the_values_bit_for_bit():
    values = [jnp.array([1.0, -0.0, jnp.nan, jnp.inf], jnp.float32), jnp.array([1, -2, 3, 2**31 - 1], jnp.int32),
              jnp.array([0.5, 1e-45, -3.0, 7.0], jnp.float32), jnp.array([True, False, True, False])]
    got = jax.jit(lambda t: computed_once(values, t))(jnp.uint32(5))
    for g, v in zip(got, values):
        assert g.dtype == v.dtype
        np.testing.assert_array_equal(jax.lax.bitcast_convert_type(g, jnp.uint32) if g.dtype == jnp.float32 else g,
                                      jax.lax.bitcast_convert_type(v, jnp.uint32) if v.dtype == jnp.float32 else v)


def test_double_float_chunk_sums_keep_48_bits():
    """sum_axis0 (the replicate sums) within 2^-45 Σ|v| of the exactly rounded sum, on float32
    values where a float32 accumulator loses every small term: 1e8 (ulp 8) and -1e8 around 4095
    terms of 0.1, whose sum 409.5000061 is the whole answer."""
    values = jnp.concatenate([jnp.full((1, 4), 1e8, jnp.float32), jnp.full((4095, 4), 0.1, jnp.float32),
                              jnp.full((1, 4), -1e8, jnp.float32)])
    hi, lo = jax.jit(sum_axis0)(values)
    columns = np.asarray(values, np.float64).T
    exact = np.array([math.fsum(column) for column in columns])
    got = np.asarray(hi, np.float64) + np.asarray(lo, np.float64)
    assert np.all(np.abs(got - exact) <= 2.0 ** -45 * np.abs(columns).sum(axis=1)), (got, exact)
    np.testing.assert_allclose(got, exact, rtol=1e-6)  # 409.5000061, not a float32 sum's 0 or 8


def test_an_estimate_inside_an_integrand_keeps_its_64_bit_words():
    """An integrand may call `estimate` itself: the inner program switches x64 on inside (Philox's
    uint64 words, the replicate sums' float64 halves), and the outer lanes evaluator, running with
    x64 off, must keep those operands 64-bit (it cast a shared float64 value to float32 and the
    comparison beside it failed: "lax.gt requires arguments to have the same dtypes"). Every
    sample here has f/p constant (4π z over the sphere inside, 4π z / (z / π) over the cosine
    hemisphere outside), so the nested estimate is 4π² to float32 rounding."""
    import jaxsample as js

    inner = lambda x: js.estimate(lambda y: x[2] + 0.0 * y[0], js.UniformSphere(), jax.random.key(3), 16).mean
    value = js.estimate(inner, js.CosineHemisphere(), jax.random.key(4), 64).mean
    np.testing.assert_allclose(value, 4 * np.pi ** 2, rtol=1e-5)
