"""Tests for the deterministic quadrature baselines (jaxsample.quadrature)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsample import quadrature

KINDS = ("trapezoid", "simpson", "gauss_legendre")


def rule64(kind, n, a=0.0, b=1.0):
    """A 1-D rule as float64 NumPy arrays."""
    with jax.enable_x64(True):
        nodes, weights = quadrature.rule_1d(kind, n, np.float64(a), np.float64(b))
        assert nodes.dtype == weights.dtype == jnp.float64
        return np.asarray(nodes), np.asarray(weights)


def poly_integral(coefficients, a, b):
    antiderivative = np.polynomial.Polynomial(coefficients).integ()
    return antiderivative(b) - antiderivative(a)


def poly_rule(kind, n, coefficients, a, b):
    nodes, weights = rule64(kind, n, a, b)
    return float(np.sum(weights * np.polynomial.Polynomial(coefficients)(nodes)))


# ------------------------------------------------------------------------------------------------
# Gauss–Legendre nodes and weights
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("n", list(range(1, 41)) + [64, 100])
def test_gauss_legendre_matches_numpy_leggauss(n):
    nodes, weights = quadrature.gauss_legendre_nodes_weights(n)
    ref_nodes, ref_weights = np.polynomial.legendre.leggauss(n)
    assert nodes.dtype == weights.dtype == np.float64
    np.testing.assert_allclose(nodes, ref_nodes, rtol=0, atol=4e-16)
    # numpy's end weights carry ~1e-12 relative error at n = 100 (checked against long double);
    # ours are closer, so the tolerance is numpy's.
    np.testing.assert_allclose(weights, ref_weights, rtol=1e-11, atol=0)
    assert np.all(np.diff(nodes) > 0)
    np.testing.assert_allclose(nodes, -nodes[::-1], rtol=0, atol=0)
    assert abs(weights.sum() - 2.0) < 1e-14


def test_gauss_legendre_is_cached_and_read_only():
    first = quadrature.gauss_legendre_nodes_weights(12)
    assert quadrature.gauss_legendre_nodes_weights(12) is first
    with pytest.raises(ValueError):
        first[0][0] = 0.0


def test_the_checks_panels_use_the_quadrature_rule():
    """One Gauss–Legendre rule in the package: the checks' panels (`jaxsample.domains`) on [-1, 1]
    are `gauss_legendre_nodes_weights` bit for bit, at the checks' order and beyond. Catches a
    second rule (the panels once used NumPy's `leggauss`, whose weights differ in the last bits)."""
    from jaxsample.domains import GAUSS_ORDER, gauss_legendre_panels

    for order in (1, 2, GAUSS_ORDER, 24, 100):
        nodes, weights = gauss_legendre_panels(np.array([-1.0, 1.0]), order)
        reference_nodes, reference_weights = quadrature.gauss_legendre_nodes_weights(order)
        assert np.array_equal(nodes, reference_nodes) and np.array_equal(weights, reference_weights), order


def test_rule_1d_maps_to_interval():
    for kind, n in (("trapezoid", 5), ("simpson", 5), ("gauss_legendre", 5)):
        nodes, weights = rule64(kind, n, -0.5, 2.5)
        assert nodes.shape == weights.shape == (n,)
        assert np.all(np.diff(nodes) > 0) and np.all(weights > 0)
        assert -0.5 <= nodes[0] and nodes[-1] <= 2.5
        assert abs(weights.sum() - 3.0) < 1e-14
    nodes, weights = rule64("simpson", 5, 0.0, 2.0)
    np.testing.assert_allclose(nodes, [0, 0.5, 1, 1.5, 2])
    np.testing.assert_allclose(weights, np.array([1, 4, 2, 4, 1]) * 0.5 / 3)
    nodes, weights = rule64("trapezoid", 3, 0.0, 1.0)
    np.testing.assert_allclose(weights, [0.25, 0.5, 0.25])


# ------------------------------------------------------------------------------------------------
# Exactness, and that the stated degree is sharp
# ------------------------------------------------------------------------------------------------

A, B = -0.3, 1.7  # an interval that is neither symmetric nor unit


@pytest.mark.parametrize("kind,n,degree", [("trapezoid", n, 1) for n in (2, 3, 8)]
                         + [("simpson", n, 3) for n in (3, 5, 9)]
                         + [("gauss_legendre", n, 2 * n - 1) for n in range(1, 13)])
def test_exact_up_to_stated_degree(kind, n, degree):
    rng = np.random.default_rng(1234 + n)
    coefficients = rng.uniform(-1, 1, degree + 1)
    exact = poly_integral(coefficients, A, B)
    scale = poly_integral(np.abs(coefficients), 0.0, max(abs(A), abs(B))) * 2 + 1
    assert abs(poly_rule(kind, n, coefficients, A, B) - exact) <= 1e-13 * scale


@pytest.mark.parametrize("kind,n", [("trapezoid", 2), ("trapezoid", 7), ("simpson", 3), ("simpson", 9)]
                         + [("gauss_legendre", n) for n in range(1, 9)])
def test_stated_degree_is_sharp(kind, n):
    """On the monomial one degree higher the error is nonzero and equals the documented term.

    Every documented error term is C · f^{(k)}(ξ); for f = x^k, f^{(k)} = k! is constant, so the
    error is known exactly.
    """
    width = B - A
    if kind == "trapezoid":
        k, intervals = 2, n - 1
        rule_minus_exact = width**3 / (12 * intervals**2) * math.factorial(2)
    elif kind == "simpson":
        k, intervals = 4, n - 1
        rule_minus_exact = width**5 / (180 * intervals**4) * math.factorial(4)
    else:
        k = 2 * n
        exact_minus_rule = (width ** (2 * n + 1) * math.factorial(n) ** 4
                            / ((2 * n + 1) * math.factorial(2 * n) ** 3) * math.factorial(2 * n))
        rule_minus_exact = -exact_minus_rule
    coefficients = np.zeros(k + 1)
    coefficients[k] = 1.0
    error = poly_rule(kind, n, coefficients, A, B) - poly_integral(coefficients, A, B)
    assert abs(error) > 1e-9  # not exact, far above float64 rounding
    np.testing.assert_allclose(error, rule_minus_exact, rtol=1e-7)


# ------------------------------------------------------------------------------------------------
# Observed convergence orders in one dimension
# ------------------------------------------------------------------------------------------------

def _observed_order(kind, counts):
    exact = math.expm1(1.0)
    errors = []
    for n in counts:
        nodes, weights = rule64(kind, n)
        errors.append(abs(np.sum(weights * np.exp(nodes)) - exact))
    slope = np.polyfit(np.log(np.array(counts) - 1.0), np.log(errors), 1)[0]
    return slope, errors


def test_trapezoid_converges_at_second_order():
    slope, _ = _observed_order("trapezoid", [5, 9, 17, 33, 65, 129])
    assert slope == pytest.approx(-2.0, abs=0.05)


def test_simpson_converges_at_fourth_order():
    slope, _ = _observed_order("simpson", [5, 9, 17, 33, 65])
    assert slope == pytest.approx(-4.0, abs=0.1)


def test_gauss_legendre_reaches_machine_precision_quickly():
    errors = {}
    for n in range(2, 12):
        nodes, weights = rule64("gauss_legendre", n)
        errors[n] = abs(np.sum(weights * np.exp(nodes)) - math.expm1(1.0))
    assert max(errors[n] for n in range(6, 12)) < 1e-15
    # Geometric, not algebraic: each extra point gains more than two decades until rounding.
    assert all(errors[n + 1] < 1e-2 * errors[n] for n in range(2, 5))
    # float32 through `integrate`: at float32 rounding with five points.
    value = quadrature.integrate(lambda x: jnp.exp(x[0]), "gauss_legendre", 5)
    assert value.dtype == jnp.float32
    assert abs(float(value) - math.expm1(1.0)) < 4e-7


# ------------------------------------------------------------------------------------------------
# Tensor products in d = 1..6
# ------------------------------------------------------------------------------------------------

def test_tensor_rule_shapes_and_weights():
    nodes, weights = quadrature.tensor_rule("simpson", 5, 3, [0.0, -1.0, 2.0], [1.0, 1.0, 2.5])
    assert nodes.shape == (125, 3) and weights.shape == (125,)
    assert weights.dtype == jnp.float32
    np.testing.assert_allclose(float(jnp.sum(weights)), 1.0 * 2.0 * 0.5, rtol=1e-6)
    # Row-major: the last coordinate varies fastest.
    np.testing.assert_allclose(nodes[:5, 2], np.linspace(2.0, 2.5, 5), rtol=1e-6)
    assert np.all(nodes[:5, :2] == nodes[0, :2])
    nodes, weights = quadrature.tensor_rule("gauss_legendre", [2, 3, 4])
    assert nodes.shape == (24, 3) and weights.shape == (24,)
    # `integrate` is the same weighted sum, without materialising the grid.
    with jax.enable_x64(True):
        nodes, weights = quadrature.tensor_rule("gauss_legendre", 6, 3)
        nodes, weights = np.asarray(nodes), np.asarray(weights)
        explicit = float(np.sum(weights * np.prod(0.5 * np.pi * np.sin(np.pi * nodes), axis=-1)))
        value = float(quadrature.integrate(quadrature.sine_product, "gauss_legendre", 6, dims=3))
    assert value == pytest.approx(explicit, rel=1e-14)


@pytest.mark.parametrize("dims", [1, 2, 3, 4, 5, 6])
def test_tensor_product_on_sine_product(dims):
    # Five Gauss–Legendre points err by 5.514e-8 on one axis of (π/2) sin(πx); the product of d
    # axes, (1 + e)^d - 1, errs by about d times that.
    one_axis = 5.514223588853895e-08
    with jax.enable_x64(True):
        value = quadrature.integrate(quadrature.sine_product, "gauss_legendre", 5, dims=dims)
        assert value.dtype == jnp.float64
        np.testing.assert_allclose(float(value) - 1.0, (1 + one_axis) ** dims - 1, rtol=1e-6)
    if dims == 6:
        value32 = quadrature.integrate(quadrature.sine_product, "gauss_legendre", 5, dims=dims)
        assert value32.dtype == jnp.float32
        assert abs(float(value32) - 1.0) < 2e-6


def test_integrate_on_a_box_with_per_dimension_points():
    lower, upper = np.array([-1.0, 0.5, 0.0]), np.array([0.5, 2.0, 0.25])
    exact = float(np.prod(np.exp(upper) - np.exp(lower)))
    with jax.enable_x64(True):
        value = quadrature.integrate(lambda x: jnp.exp(jnp.sum(x)), "gauss_legendre", [9, 10, 6],
                                     lower, upper)
    assert float(value) == pytest.approx(exact, rel=1e-13)


def test_chunking_does_not_change_the_value():
    with jax.enable_x64(True):
        whole = quadrature.integrate(quadrature.exponential_product, "simpson", 11, dims=3)
        chunked = quadrature.integrate(quadrature.exponential_product, "simpson", 11, dims=3,
                                       chunk_size=97)  # 1331 points, ragged last chunk
    assert float(chunked) == pytest.approx(float(whole), rel=1e-14)
    # Vector-valued integrands are integrated per component.
    value = quadrature.integrate(lambda x: jnp.stack([x[0], x[0] * x[1]]), "gauss_legendre", 3,
                                 dims=2, chunk_size=4)
    np.testing.assert_allclose(np.asarray(value), [0.5, 0.25], rtol=1e-6)


def test_tensor_trapezoid_rate_is_two_over_d():
    """Error O(N^{-2/d}) in N evaluations: the rate per evaluation is 2/d.

    The error is ≈ C (m - 1)^{-2} in m = N^{1/d} points per axis, so a fit against log N at these
    moderate m comes out about 5 % steeper than the asymptotic -2/d (m / (m - 1) ≈ 1.05).
    """
    for dims in (1, 2, 3):
        counts = [9, 17, 33, 65] if dims < 3 else [9, 17, 33]
        evaluations, errors = [], []
        for m in counts:
            with jax.enable_x64(True):
                nodes, weights = quadrature.tensor_rule("trapezoid", m, dims)
                nodes, weights = np.asarray(nodes), np.asarray(weights)
            value = float(np.sum(weights * np.prod(np.exp(nodes), axis=-1)))
            evaluations.append(m**dims)
            errors.append(abs(value - math.expm1(1.0) ** dims))
        slope = np.polyfit(np.log(evaluations), np.log(errors), 1)[0]
        assert slope * dims / 2.0 == pytest.approx(-1.05, abs=0.03)


# ------------------------------------------------------------------------------------------------
# The curse of dimensionality at a fixed budget
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", KINDS)
def test_error_at_fixed_budget_grows_with_dimension(kind):
    budget = 4096
    # Gauss–Legendre stays at rounding level up to d = 3 (at least 16 points per axis), so only the
    # dimensions where it is not are compared.
    all_dims = (1, 4, 5, 6) if kind == "gauss_legendre" else (1, 2, 3, 4, 5, 6)
    errors = []
    with jax.enable_x64(True):
        for dims in all_dims:
            value, evaluations = quadrature.integrate_with_budget(
                quadrature.sine_product, kind, budget, dims)
            m = round(evaluations ** (1 / dims))
            assert m**dims == evaluations <= budget
            step = 2 if kind == "simpson" else 1
            assert (m + step) ** dims > budget  # the largest admissible rule
            errors.append(abs(float(value) - 1.0))
    # The curse: the same 4096 evaluations that integrate to 1e-8 or better in 1-D leave a
    # 6-D error at least a million times larger.
    assert errors[0] < 1e-7 and errors[-1] > 1e6 * max(errors[0], 1e-16)
    assert all(later > earlier for earlier, later in zip(errors[1:], errors[2:]))
    assert errors[1] > errors[0] or kind == "gauss_legendre"


def test_points_for_budget():
    assert quadrature.points_for_budget("trapezoid", 4096, 6) == 4
    assert quadrature.points_for_budget("trapezoid", 4095, 6) == 3
    assert quadrature.points_for_budget("simpson", 4096, 2) == 63
    assert quadrature.points_for_budget("simpson", 27, 3) == 3
    assert quadrature.points_for_budget("gauss_legendre", 1, 6) == 1
    assert quadrature.points_for_budget("trapezoid", 10**12, 4) == 1000
    assert quadrature.points_for_budget("trapezoid", 10**12 - 1, 4) == 999


def test_convergence_table():
    rows = quadrature.convergence_table(dims=(2, 3), kinds=("trapezoid", "gauss_legendre"),
                                        budgets=(5, 70, 80))
    keys = [(r.kind, r.dims, r.points_per_dim, r.evaluations) for r in rows]
    # Too small a budget gives no row (8 trapezoid points > 5 in 3-D), and a budget that rounds to
    # a rule already run (80 -> 8^2 and 4^3, as 70 did) is not repeated.
    assert keys == [("trapezoid", 2, 2, 4), ("trapezoid", 2, 8, 64), ("trapezoid", 3, 4, 64),
                    ("gauss_legendre", 2, 2, 4), ("gauss_legendre", 2, 8, 64),
                    ("gauss_legendre", 3, 1, 1), ("gauss_legendre", 3, 4, 64)]
    for row in rows:
        assert row.points_per_dim**row.dims == row.evaluations
        assert row.abs_error == pytest.approx(abs(row.value - 1.0))
    gauss_3d = [r.abs_error for r in rows if r.kind == "gauss_legendre" and r.dims == 3]
    assert gauss_3d[1] < gauss_3d[0]


# ------------------------------------------------------------------------------------------------
# dtypes, jit, grad
# ------------------------------------------------------------------------------------------------

def test_dtype_follows_inputs():
    nodes, weights = quadrature.rule_1d("gauss_legendre", 4)
    assert nodes.dtype == weights.dtype == jnp.float32
    with jax.enable_x64(True):
        nodes, weights = quadrature.rule_1d("gauss_legendre", 4)
        assert nodes.dtype == weights.dtype == jnp.float64
        nodes, weights = quadrature.rule_1d("gauss_legendre", 4, jnp.float32(0), jnp.float32(1))
        assert nodes.dtype == weights.dtype == jnp.float32
        value = quadrature.integrate(lambda x: jnp.exp(x[0]), "gauss_legendre", 10)
        assert value.dtype == jnp.float64
        assert abs(float(value) - math.expm1(1.0)) < 1e-15


def _exp_box_integral(theta, dims):
    """∫_[0,1]^d exp(θ Σ x_i) dx and its derivative in θ, in float64 NumPy."""
    theta = np.asarray(theta, np.float64)
    one_axis = np.expm1(theta) / theta
    one_axis_grad = (theta * np.exp(theta) - np.expm1(theta)) / theta**2
    return one_axis**dims, dims * one_axis ** (dims - 1) * one_axis_grad


def test_grad_and_jit_through_integrate():
    dims = 2

    def integral(theta):
        return quadrature.integrate(lambda x: jnp.exp(theta * jnp.sum(x)), "gauss_legendre", 8,
                                    dims=dims)

    theta = jnp.float32(0.7)
    expected_value, expected_grad = _exp_box_integral(0.7, dims)
    value, grad = jax.jit(jax.value_and_grad(integral))(theta)
    np.testing.assert_allclose(value, expected_value, rtol=1e-6)
    np.testing.assert_allclose(grad, expected_grad, rtol=1e-5)
    thetas = jnp.array([0.1, 0.7, 1.5], jnp.float32)
    np.testing.assert_allclose(jax.jit(jax.vmap(jax.grad(integral)))(thetas),
                               _exp_box_integral(np.asarray(thetas), dims)[1], rtol=1e-5)
    # Eagerly, and with many chunks (a lax.scan), the derivative is the same.
    chunked = lambda t: quadrature.integrate(lambda x: jnp.exp(t * jnp.sum(x)), "gauss_legendre",
                                             8, dims=dims, chunk_size=10)
    np.testing.assert_allclose(jax.grad(chunked)(theta), expected_grad, rtol=1e-5)


def test_grad_with_respect_to_bounds():
    # d/db ∫_a^b g = g(b) and d/da = -g(a) (Leibniz), reproduced by the rule's derivative.
    g = lambda x: jnp.exp(x[0])
    grad_a, grad_b = jax.jit(jax.grad(
        lambda a, b: quadrature.integrate(g, "gauss_legendre", 8, a, b), argnums=(0, 1)))(0.2, 1.3)
    np.testing.assert_allclose(grad_b, math.exp(1.3), rtol=1e-5)
    np.testing.assert_allclose(grad_a, -math.exp(0.2), rtol=1e-5)


# ------------------------------------------------------------------------------------------------
# Invalid arguments
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("call,match", [
    (lambda: quadrature.rule_1d("trapezoid", 1), r"n_points must be an integer >= 2"),
    (lambda: quadrature.rule_1d("gauss_legendre", 0), r"n_points must be an integer >= 1"),
    (lambda: quadrature.rule_1d("simpson", 1), r"n_points must be an integer >= 3"),
    (lambda: quadrature.rule_1d("simpson", 4), r"n_points must be an odd integer >= 3"),
    (lambda: quadrature.rule_1d("trapezoid", 2.5), r"n_points must be an integer"),
    (lambda: quadrature.rule_1d("trapezoid", True), r"n_points must be an integer"),
    (lambda: quadrature.rule_1d("gauss_legendre", 10**6), r"n_points must be in \[1, 10000\]"),
    (lambda: quadrature.rule_1d("trapezoid", 3, 1.0, 1.0), r"a must be < b"),
    (lambda: quadrature.rule_1d("trapezoid", 3, 2.0, 1.0), r"a must be < b"),
    (lambda: quadrature.rule_1d("trapezoid", 3, 0.0, np.inf), r"a and b must be finite"),
    (lambda: quadrature.rule_1d("trapezoid", 3, np.nan, 1.0), r"a and b must be finite"),
    (lambda: quadrature.rule_1d("midpoint", 3), r"kind must be one of"),
    (lambda: quadrature.tensor_rule("simpson", 6, 2), r"points_per_dim must be an odd integer"),
    (lambda: quadrature.tensor_rule("trapezoid", 3, 2, [0.0, 1.0], [1.0, 0.5]),
     r"lower must be < upper"),
    (lambda: quadrature.tensor_rule("trapezoid", 3, 2, [0.0, 0.0, 0.0], 1.0), r"disagree"),
    (lambda: quadrature.tensor_rule("trapezoid", [3, 3], 3), r"disagree|length 3"),
    (lambda: quadrature.tensor_rule("trapezoid", 3, 0), r"dims must be an integer >= 1"),
    (lambda: quadrature.integrate(jnp.sum, "gauss_legendre", 3, [0.0, -np.inf], 1.0),
     r"lower and upper must be finite"),
    (lambda: quadrature.integrate(jnp.sum, "simpson", 2), r"n_points must be an integer >= 3"),
    (lambda: quadrature.integrate(jnp.sum, "trapezoid", 3, chunk_size=0), r"chunk_size"),
    (lambda: quadrature.integrate_with_budget(jnp.sum, "trapezoid", 63, 6),
     r"max_evaluations must be an integer >= 64"),
    (lambda: quadrature.integrate_with_budget(jnp.sum, "simpson", 100, 0), r"dims must be"),
])
def test_invalid_arguments_raise(call, match):
    with pytest.raises(ValueError, match=match):
        call()
