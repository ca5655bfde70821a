"""Deterministic quadrature baselines: trapezoid, Simpson and Gauss–Legendre, and their tensor products.

These are what Monte Carlo is measured against in the speed-against-error report. A quadrature rule
approximates an integral by a weighted sum of samples,

    ∫_a^b f(x) dx  ≈  Σ_i w_i f(x_i),

with nodes x_i and weights w_i fixed in advance (Chuang, *Monte Carlo Integration*, Digital Image
Synthesis lecture notes, 2008, after slides by Hanrahan and Möller: "Numerical quadrature"). With
n points the one-dimensional rules here converge like

=================  =====================================================  ===========================
kind               rule (h = (b - a) / (n - 1) for the equispaced rules)  error
=================  =====================================================  ===========================
"trapezoid"        h [f_0/2 + f_1 + ... + f_{n-2} + f_{n-1}/2]             O(h²) = O(n⁻²)
"simpson"          h/3 [f_0 + 4 f_1 + 2 f_2 + ... + 4 f_{n-2} + f_{n-1}]   O(h⁴) = O(n⁻⁴), n odd
"gauss_legendre"   Σ w_i f(x_i), x_i the roots of the Legendre P_n          exact for degree ≤ 2n - 1
=================  =====================================================  ===========================

In d dimensions the tensor product of a 1-D rule with m points per axis,

    ∫_box f dx  ≈  Σ_{i_1} ... Σ_{i_d} w_{i_1} ... w_{i_d} f(x_{i_1}, ..., x_{i_d}),

costs N = m^d evaluations; a 1-D error O(m^{-r}) becomes O(N^{-r/d}). That is the *curse of
dimensionality* (Chuang, "Curse of dimensionality and discontinuity"): trapezoid's N^{-2/d} is
already slower than Monte Carlo's dimension-free N^{-1/2} for d > 4, Simpson's N^{-4/d} for d > 8.
Gauss–Legendre's rate is set by the integrand's smoothness (geometric in m for analytic f, so
exp(-c N^{1/d}) in N), which delays the curse but does not lift it. For a discontinuous integrand
every one of these rules falls to O(N^{-1/d}).

Public API
----------
- `rule_1d(kind, n_points, a=0, b=1)` -> (nodes (n,), weights (n,)) on [a, b].
- `tensor_rule(kind, points_per_dim, dims, lower=0, upper=1)` -> (nodes (N, d), weights (N,)).
- `integrate(f, kind, n_points, lower=0, upper=1, dims=None)` -> Σ w f(x) with `f` mapping ONE point
  of shape (d,) to a value; vmapped, chunked in constant memory, jitted, and differentiable with
  respect to anything `f` closes over and to the bounds.
- `points_for_budget(kind, max_evaluations, dims)` -> the largest m with m^d ≤ budget.
- `integrate_with_budget(f, kind, max_evaluations, dims, lower=0, upper=1)` -> (value, evaluations).
- `convergence_table(f, exact, dims, kinds, budgets)` -> rows (kind, dims, points per dim,
  evaluations, value, absolute error) for the report.
- `gauss_legendre_nodes_weights(n)` -> the float64 NumPy rule on [-1, 1], cached per order.
- `sine_product`, `exponential_product`: smooth test integrands with integral 1 over [0, 1]^d.

Dtypes: every rule works in the floating dtype of its bounds (float32 for Python floats by default,
float64 under `jax.enable_x64`). The reference nodes and weights on [0, 1] are computed once in
float64 and rounded to the working dtype before they are scaled to the box, so a float32 rule
carries no error from a float32 root-finder, only the rounding of its nodes and weights.

Validation: concrete invalid arguments raise `ValueError` naming the parameter and its range.
`kind`, `n_points`, `points_per_dim`, `dims` and budgets set array shapes and must be concrete
Python values. The bounds may be traced (inside `jit`, `grad`, `vmap`); they are then not checked,
and a reversed box gives the oriented integral (its sign flips) while NaN bounds give NaN.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import operator
from typing import Callable, Iterable, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from ._core.params import concrete_value
from .samplers.domain import gauss_legendre_rule

__all__ = [
    "KINDS",
    "ConvergenceRow",
    "convergence_table",
    "exponential_product",
    "gauss_legendre_nodes_weights",
    "integrate",
    "integrate_with_budget",
    "points_for_budget",
    "rule_1d",
    "sine_product",
    "tensor_rule",
]

KINDS = ("trapezoid", "simpson", "gauss_legendre")

# Fewest points each rule is defined with (Gauss–Legendre with one point is the midpoint rule).
_MIN_POINTS = {"trapezoid": 2, "simpson": 3, "gauss_legendre": 1}

# Above this, the Newton iteration for Legendre roots (O(n²) work) stops being a baseline's job.
_MAX_GAUSS_LEGENDRE_POINTS = 10_000

# Flat point indices are int32 inside `integrate`.
_MAX_TOTAL_POINTS = 2**31 - 2**20

_DEFAULT_CHUNK = 1 << 16
_MAX_CHUNK = 1 << 20
_SUM_BLOCK = 256


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------

def _check_kind(kind) -> str:
    if not isinstance(kind, str) or kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
    return kind


def _check_int(name: str, value, minimum: int) -> int:
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be an integer >= {minimum}; got {value!r}")
    try:
        as_int = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be an integer >= {minimum}; got {value!r}") from None
    if as_int < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}; got {as_int}")
    return as_int


def _check_points(kind: str, n_points, name: str = "n_points") -> int:
    n = _check_int(name, n_points, _MIN_POINTS[kind])
    if kind == "simpson" and n % 2 == 0:
        raise ValueError(f"{name} must be an odd integer >= 3 for Simpson's rule (an even number of "
                         f"intervals); got {n}")
    if kind == "gauss_legendre" and n > _MAX_GAUSS_LEGENDRE_POINTS:
        raise ValueError(f"{name} must be in [1, {_MAX_GAUSS_LEGENDRE_POINTS}] for Gauss–Legendre; "
                         f"got {n}")
    return n


def _as_array(value):
    """A list or tuple of bounds as one array: NumPy when every entry is concrete (it keeps their
    dtype), JAX when one is traced."""
    if isinstance(value, (list, tuple)):
        return jnp.asarray(value) if concrete_value(value) is None else np.asarray(value)
    return value


def _box(lower, upper, dims: int | None, name_lower: str = "lower", name_upper: str = "upper"):
    """lower, upper as (d,) arrays in their common floating dtype, checked when concrete.

    Concrete bounds come back as NumPy arrays, so that building a rule dispatches no JAX
    operations (each would compile on first use of a shape); traced bounds stay traced.
    """
    lower, upper = (_as_array(v) for v in (lower, upper))
    dtype = jnp.result_type(lower, upper, float)
    if not jnp.issubdtype(dtype, jnp.floating):
        raise ValueError(f"{name_lower} and {name_upper} must be real; got dtype {dtype}")
    for name, value in ((name_lower, lower), (name_upper, upper)):
        if jnp.ndim(value) > 1:
            raise ValueError(f"{name} must be a scalar or a 1-D array of per-dimension bounds; "
                             f"got shape {jnp.shape(value)}")
    sizes = {jnp.shape(v)[0] for v in (lower, upper) if jnp.ndim(v) == 1}
    if dims is not None:
        sizes.add(dims)
    if len(sizes) > 1:
        raise ValueError(f"{name_lower}, {name_upper} and dims disagree on the dimension: "
                         f"shapes {jnp.shape(lower)}, {jnp.shape(upper)}, dims={dims}")
    d = sizes.pop() if sizes else 1
    if d < 1:
        raise ValueError(f"dims must be an integer >= 1; got {d}")
    bounds = []
    for value in (lower, upper):
        concrete = concrete_value(value)  # float64, or None when traced (then it cannot be checked)
        if concrete is None:
            bounds.append(jnp.broadcast_to(jnp.asarray(value, dtype), (d,)))
        else:
            bounds.append(np.broadcast_to(concrete.astype(dtype), (d,)))
    lower, upper = bounds
    if isinstance(lower, np.ndarray) and isinstance(upper, np.ndarray):
        if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
            raise ValueError(f"{name_lower} and {name_upper} must be finite, in (-inf, inf); "
                             f"got {lower.tolist()} and {upper.tolist()}")
        if not np.all(lower < upper):
            raise ValueError(f"{name_lower} must be < {name_upper} in every dimension; "
                             f"got {lower.tolist()} and {upper.tolist()}")
    return lower, upper, d, dtype


# --------------------------------------------------------------------------------------------
# Reference rules on [0, 1], float64, cached
# --------------------------------------------------------------------------------------------

def _readonly(*arrays):
    for a in arrays:
        a.flags.writeable = False
    return arrays


def gauss_legendre_nodes_weights(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The n-point Gauss–Legendre rule on [-1, 1] in float64 NumPy: (nodes ascending, weights).

    The nodes are the roots of the Legendre polynomial P_n, the weights w_i =
    2 / ((1 - x_i²) P_n'(x_i)²) (Abramowitz & Stegun, *Handbook of Mathematical Functions*,
    §25.4, Gaussian integration). The rule integrates every polynomial of degree ≤ 2n - 1 exactly,
    and for f with 2n continuous derivatives on [a, b]

        ∫_a^b f - Σ w_i f(x_i) = (b - a)^{2n+1} (n!)⁴ / ((2n + 1) ((2n)!)³) · f^{(2n)}(ξ).

    The rule is `jaxsample.samplers.domain.gauss_legendre_rule`, the package's one (the checks'
    panels use it too): Newton's method on P_n from Tricomi's estimate, as in Numerical Recipes'
    `gauleg`. Cached per order; the arrays are read-only.
    """
    n = _check_int("n", n, 1)
    if n > _MAX_GAUSS_LEGENDRE_POINTS:
        raise ValueError(f"n must be in [1, {_MAX_GAUSS_LEGENDRE_POINTS}]; got {n}")
    return gauss_legendre_rule(n)


@functools.lru_cache(maxsize=256)
def _unit_rule(kind: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Float64 nodes and weights on [0, 1] (weights sum to 1), cached per (kind, n)."""
    if kind == "gauss_legendre":
        x, w = gauss_legendre_nodes_weights(n)
        nodes, weights = 0.5 * (1.0 + x), 0.5 * w
        return _readonly(nodes, weights)
    intervals = n - 1
    nodes = np.arange(n, dtype=np.float64) / intervals  # i / (n-1) keeps 0 and 1 exact
    h = 1.0 / intervals
    if kind == "trapezoid":
        weights = np.full(n, h)
        weights[[0, -1]] = 0.5 * h
    else:  # simpson: h/3 [1, 4, 2, 4, ..., 2, 4, 1]
        weights = np.where(np.arange(n) % 2 == 1, 4.0, 2.0) * (h / 3.0)
        weights[[0, -1]] = h / 3.0
    return _readonly(nodes, weights)


# --------------------------------------------------------------------------------------------
# Rules on [a, b] and on boxes
# --------------------------------------------------------------------------------------------

def rule_1d(kind: str, n_points: int, a: ArrayLike = 0.0, b: ArrayLike = 1.0) -> tuple[jax.Array, jax.Array]:
    """Nodes and weights of an n-point rule on [a, b]: ∫_a^b f ≈ Σ_i weights[i] f(nodes[i]).

    Args:
      kind: "trapezoid", "simpson" or "gauss_legendre".
        - trapezoid (n ≥ 2), h = (b - a)/(n - 1): h [f(a)/2 + f(a + h) + ... + f(b - h) + f(b)/2].
          Exact for degree ≤ 1; error (b - a)³/(12 (n-1)²) · f''(ξ) = O(h²) (Chuang's notes,
          "Trapezoid rule").
        - simpson (n odd ≥ 3): h/3 [f(a) + 4 f(a + h) + 2 f(a + 2h) + ... + 4 f(b - h) + f(b)],
          a parabola through each pair of intervals. Exact for degree ≤ 3; error
          (b - a)⁵/(180 (n-1)⁴) · f⁽⁴⁾(ξ) = O(h⁴) (Chuang's notes, "Simpson's rule").
        - gauss_legendre (n ≥ 1): nodes at the roots of P_n mapped to [a, b]. Exact for degree
          ≤ 2n - 1 (and not 2n); see `gauss_legendre_nodes_weights` for its error term. For
          analytic f the error falls geometrically in n.
        In each case the sign of the error term is that of (rule - integral) for the equispaced
        rules and of (integral - rule) for Gauss–Legendre.
      n_points: number of nodes, a concrete Python int.
      a, b: finite bounds with a < b (scalars). Their dtype sets the dtype of the result.

    Returns:
      (nodes, weights), each of shape (n_points,); nodes ascending, weights positive summing to
      b - a.
    """
    kind = _check_kind(kind)
    n = _check_points(kind, n_points)
    if jnp.ndim(a) != 0 or jnp.ndim(b) != 0:
        raise ValueError(f"a and b must be scalars; got shapes {jnp.shape(a)} and {jnp.shape(b)}")
    lower, upper, _, dtype = _box(a, b, 1, "a", "b")
    t, w = _unit_rule(kind, n)
    return _map_rule(lower[0], upper[0], t.astype(dtype), w.astype(dtype))


@jax.jit
def _map_rule(a, b, t, w):
    """The [0, 1] rule (t, w) carried to [a, b] by x = a + (b - a) t, dx = (b - a) dt."""
    width = b - a
    return a + width * t, width * w


def _map_rules(lower, upper, unit_nodes, unit_weights):
    """Per-axis rules on [lower_k, upper_k] from the [0, 1] rules; traceable."""
    mapped = [_map_rule(lower[k], upper[k], t, w)
              for k, (t, w) in enumerate(zip(unit_nodes, unit_weights))]
    return tuple(m[0] for m in mapped), tuple(m[1] for m in mapped)


def _points_per_dim(kind: str, points_per_dim, d: int | None, name: str) -> tuple[int, ...]:
    if isinstance(points_per_dim, (Sequence, np.ndarray)) and not isinstance(points_per_dim, str):
        counts = tuple(_check_points(kind, m, name) for m in points_per_dim)
        if d is not None and len(counts) != d:
            raise ValueError(f"{name} must be an int or a sequence of length {d}; got {len(counts)} "
                             "entries")
        if not counts:
            raise ValueError(f"{name} must not be empty")
        return counts
    m = _check_points(kind, points_per_dim, name)
    return (m,) * (1 if d is None else d)


def _rules_per_dim(kind, points_per_dim, dims, lower, upper, name="points_per_dim"):
    """Checked (lower (d,), upper (d,), [0, 1] nodes per axis, [0, 1] weights per axis)."""
    kind = _check_kind(kind)
    if dims is not None:
        dims = _check_int("dims", dims, 1)
    if dims is None and isinstance(points_per_dim, (Sequence, np.ndarray)):
        dims = len(points_per_dim)
    lower, upper, d, dtype = _box(lower, upper, dims)
    counts = _points_per_dim(kind, points_per_dim, d, name)
    total = math.prod(counts)
    if total > _MAX_TOTAL_POINTS:
        raise ValueError(f"{name} gives {total} points in all; the product over dimensions must be "
                         f"≤ {_MAX_TOTAL_POINTS}")
    unit = [_unit_rule(kind, m) for m in counts]
    unit_nodes = tuple(t.astype(dtype) for t, _ in unit)
    unit_weights = tuple(w.astype(dtype) for _, w in unit)
    return lower, upper, unit_nodes, unit_weights


def tensor_rule(kind: str, points_per_dim: int | Sequence[int], dims: int | None = None,
                lower: ArrayLike = 0.0, upper: ArrayLike = 1.0) -> tuple[jax.Array, jax.Array]:
    """The tensor product of a 1-D rule over the box ∏_k [lower_k, upper_k], materialised.

        ∫_box f ≈ Σ_{i_1..i_d} w¹_{i_1} ... wᵈ_{i_d} f(x¹_{i_1}, ..., xᵈ_{i_d})

    With m points per axis this is N = m^d points, and a 1-D error O(m^{-r}) (r = 2 trapezoid,
    4 Simpson) becomes O(N^{-r/d}) in the number of evaluations: the curse of dimensionality
    (Chuang's notes). Exactness carries over: the product is exact for every polynomial whose degree
    in each variable separately is within the 1-D rule's exact degree.

    Args:
      kind: "trapezoid", "simpson" or "gauss_legendre" (see `rule_1d`).
      points_per_dim: points on each axis, an int or one int per dimension.
      dims: the dimension d; may be omitted when `lower`, `upper` or `points_per_dim` give it.
      lower, upper: scalars or (d,) arrays of finite bounds, lower < upper.

    Returns:
      nodes of shape (N, d), row-major (the last coordinate varies fastest), and weights (N,)
      summing to the box's volume. Use `integrate` to avoid holding all N points in memory.
    """
    return _materialise(*_rules_per_dim(kind, points_per_dim, dims, lower, upper))


@jax.jit
def _materialise(lower, upper, unit_nodes, unit_weights):
    # One compiled program per grid shape, rather than one dispatch (and compile) per operation.
    nodes_1d, weights_1d = _map_rules(lower, upper, unit_nodes, unit_weights)
    grids = jnp.meshgrid(*nodes_1d, indexing="ij")
    nodes = jnp.stack([g.reshape(-1) for g in grids], axis=-1)
    weights = functools.reduce(jnp.multiply, jnp.meshgrid(*weights_1d, indexing="ij")).reshape(-1)
    return nodes, weights


# --------------------------------------------------------------------------------------------
# Integration
# --------------------------------------------------------------------------------------------

def _blocked_sum(x: jax.Array) -> jax.Array:
    """Sum over axis 0 in blocks of 256: the worst-case rounding error grows with 256 + n/256
    additions rather than n (about 2√n at the default chunk of 2^16)."""
    n = x.shape[0]
    if n <= _SUM_BLOCK:
        return jnp.sum(x, axis=0)
    pad = (-n) % _SUM_BLOCK
    if pad:
        x = jnp.concatenate([x, jnp.zeros((pad,) + x.shape[1:], x.dtype)])
    return jnp.sum(jnp.sum(x.reshape((-1, _SUM_BLOCK) + x.shape[1:]), axis=1), axis=0)


def _tensor_sum(f, nodes_1d, weights_1d, chunk_size: int):
    """Σ over the tensor grid of w(i) f(x(i)), generating points chunk by chunk from flat indices."""
    counts = tuple(n.shape[0] for n in nodes_1d)
    total = math.prod(counts)
    # Capped so that padded flat indices stay below 2^31 (they are int32).
    chunk = min(chunk_size, total, _MAX_CHUNK)
    n_chunks = -(-total // chunk)
    strides = [math.prod(counts[k + 1:]) for k in range(len(counts))]

    def points_and_weights(flat):
        index = [(flat // stride) % count for stride, count in zip(strides, counts)]
        x = jnp.stack([nodes[i] for nodes, i in zip(nodes_1d, index)], axis=-1)
        w = functools.reduce(jnp.multiply, [weights[i] for weights, i in zip(weights_1d, index)])
        return x, w

    x0, _ = points_and_weights(jnp.zeros((1,), jnp.int32))
    out_shape = jax.eval_shape(f, x0[0])

    def chunk_sum(c):
        flat = c * chunk + jnp.arange(chunk, dtype=jnp.int32)
        valid = flat < total
        # The padded tail re-evaluates a real point (so f stays finite) with zero weight.
        x, w = points_and_weights(jnp.minimum(flat, total - 1))
        w = jnp.where(valid, w, 0)
        values = jax.vmap(f)(x)
        return jax.tree_util.tree_map(
            lambda v: _blocked_sum(w.reshape((chunk,) + (1,) * (v.ndim - 1)) * v), values)

    if n_chunks == 1:
        return chunk_sum(jnp.int32(0))

    def step(carry, c):
        # Kahan's compensated summation across chunks: the running error is O(eps), not O(chunks).
        total_sum, compensation = carry
        part = chunk_sum(c)
        y = jax.tree_util.tree_map(jnp.subtract, part, compensation)
        t = jax.tree_util.tree_map(jnp.add, total_sum, y)
        compensation = jax.tree_util.tree_map(lambda t, s, y: (t - s) - y, t, total_sum, y)
        return (t, compensation), None

    dtype = jnp.result_type(x0, weights_1d[0])
    zeros = jax.tree_util.tree_map(
        lambda s: jnp.zeros(s.shape, jnp.result_type(s.dtype, dtype)), out_shape)
    (result, _), _ = jax.lax.scan(step, (zeros, zeros), jnp.arange(n_chunks, dtype=jnp.int32))
    return result


def integrate(f: Callable[[jax.Array], jax.Array], kind: str, n_points: int | Sequence[int],
              lower: ArrayLike = 0.0, upper: ArrayLike = 1.0, *, dims: int | None = None,
              chunk_size: int = _DEFAULT_CHUNK):
    """∫_box f(x) dx by the tensor-product rule with `n_points` points per axis.

    Args:
      f: maps ONE point, an array of shape (d,), to a value (a scalar, or any array or pytree of
        arrays, each integrated separately). It is evaluated with `jax.vmap` inside `jax.jit`, so it
        must be traceable. Derivatives flow (by `jax.grad`, `jax.jvp`, ...) to anything f closes
        over and to `lower` and `upper`; the whole call may itself sit inside `jit` or `vmap`.
      kind: "trapezoid", "simpson" or "gauss_legendre" (see `rule_1d` for each rule's error).
      n_points: points per axis, an int or one int per dimension; concrete. N = ∏ n_points
        evaluations in all, error O(N^{-r/d}) for a 1-D rule of order r.
      lower, upper: scalars or (d,) arrays of finite bounds with lower < upper (checked when
        concrete). Their dtype is the working dtype.
      dims: d, when neither the bounds nor `n_points` say it; default 1.
      chunk_size: points evaluated per step (at most 2^20). Memory is O(chunk_size · d), whatever
        N is; chunks are summed with Kahan compensation.

    Returns:
      The rule's value, with the structure and shape of f's output.
    """
    rules = _rules_per_dim(kind, n_points, dims, lower, upper, name="n_points")
    chunk_size = _check_int("chunk_size", chunk_size, 1)

    # A fresh jit per call: f is usually a new closure, and jit's cache holds it only weakly.
    @jax.jit
    def weighted_sum(lower, upper, unit_nodes, unit_weights):
        nodes_1d, weights_1d = _map_rules(lower, upper, unit_nodes, unit_weights)
        return _tensor_sum(f, nodes_1d, weights_1d, chunk_size)

    return weighted_sum(*rules)


def points_for_budget(kind: str, max_evaluations: int, dims: int) -> int:
    """The largest m valid for `kind` (odd for Simpson) with m^dims ≤ max_evaluations.

    Gauss–Legendre is capped at 10,000 points per axis, far past float64 accuracy for any smooth f.

    Raises ValueError when even the smallest rule (2^d trapezoid, 3^d Simpson, 1 Gauss–Legendre
    point) is over budget.
    """
    kind = _check_kind(kind)
    dims = _check_int("dims", dims, 1)
    smallest = _MIN_POINTS[kind] ** dims
    budget = _check_int("max_evaluations", max_evaluations, smallest)
    m = int(round(budget ** (1.0 / dims)))
    # Correct the float root with exact integer arithmetic.
    while m ** dims > budget:
        m -= 1
    while (m + 1) ** dims <= budget:
        m += 1
    if kind == "simpson" and m % 2 == 0:
        m -= 1
    if kind == "gauss_legendre":
        m = min(m, _MAX_GAUSS_LEGENDRE_POINTS)
    return m


def integrate_with_budget(f: Callable[[jax.Array], jax.Array], kind: str, max_evaluations: int,
                          dims: int, lower: ArrayLike = 0.0, upper: ArrayLike = 1.0, *,
                          chunk_size: int = _DEFAULT_CHUNK):
    """`integrate` with the most points per axis, m, that keeps m^dims ≤ max_evaluations.

    Returns:
      (value, evaluations) with evaluations = m^dims, a Python int. Fixing the budget and raising
      `dims` shows the curse of dimensionality: m = budget^{1/d} falls and the error
      O(m^{-r}) = O(budget^{-r/d}) rises.
    """
    m = points_for_budget(kind, max_evaluations, dims)
    value = integrate(f, kind, m, lower, upper, dims=dims, chunk_size=chunk_size)
    return value, m ** dims


# --------------------------------------------------------------------------------------------
# Report support
# --------------------------------------------------------------------------------------------

def sine_product(x: jax.Array) -> jax.Array:
    """∏_i (π/2) sin(π x_i): smooth, integral exactly 1 over [0, 1]^d, zero on the box's boundary."""
    return jnp.prod(0.5 * jnp.pi * jnp.sin(jnp.pi * x), axis=-1)


def exponential_product(x: jax.Array) -> jax.Array:
    """∏_i e^{x_i} / (e - 1): smooth, integral exactly 1 over [0, 1]^d."""
    return jnp.prod(jnp.exp(x) / math.expm1(1.0), axis=-1)


@dataclasses.dataclass(frozen=True)
class ConvergenceRow:
    kind: str
    dims: int
    points_per_dim: int
    evaluations: int
    value: float
    abs_error: float


def convergence_table(f: Callable[[jax.Array], jax.Array] = sine_product,
                      exact: float | Callable[[int], float] = 1.0,
                      dims: Iterable[int] = (1, 2, 3, 4, 5, 6),
                      kinds: Iterable[str] = KINDS,
                      budgets: Iterable[int] = (10, 100, 1_000, 10_000, 100_000),
                      lower: ArrayLike = 0.0, upper: ArrayLike = 1.0) -> list[ConvergenceRow]:
    """Error against evaluations for each rule and dimension: the report's quadrature baseline.

    For every (kind, d, budget) the largest tensor rule within the budget is run on f over
    [lower, upper]^d and compared with `exact` (a number, or a function of d). A budget too small
    for the rule in that dimension gives no row, and budgets that round to a rule already run for
    that (kind, d) are not repeated. Runs in the current default dtype; under `jax.enable_x64` the
    errors are not floored by float32 rounding (~1e-7).

    Returns:
      ConvergenceRow(kind, dims, points_per_dim, evaluations, value, abs_error) in order of kind,
      then d, then evaluations.
    """
    rows = []
    for kind in kinds:
        kind = _check_kind(kind)
        for d in dims:
            d = _check_int("dims", d, 1)
            reference = float(exact(d)) if callable(exact) else float(exact)
            done = set()
            for budget in sorted(budgets):
                budget = _check_int("budgets", budget, 1)
                if budget < _MIN_POINTS[kind] ** d:
                    continue
                m = points_for_budget(kind, budget, d)
                if m in done:
                    continue
                done.add(m)
                value = float(integrate(f, kind, m, lower, upper, dims=d))
                rows.append(ConvergenceRow(kind, d, m, m ** d, value, abs(value - reference)))
    return rows
