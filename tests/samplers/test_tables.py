"""The tables' integrals and the bilinear table against an independent float64 interpolant; their
contract (normalization, chi-square, inverse, Jacobian, hard cases) is `test_contract.py`.

Deterministic: fixed tables and points, no keys.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js

GRID = np.random.default_rng(21).random((7, 10)) + np.outer(np.linspace(0, 2, 7), np.linspace(1, 0, 10))


def _bilinear(values, x, y):
    """The bilinear interpolant of `values` ((R + 1) x (C + 1) vertices on [0, 1]²) at (x, y), in NumPy."""
    rows, columns = values.shape[0] - 1, values.shape[1] - 1
    j = np.clip(np.floor(y * rows).astype(int), 0, rows - 1)
    i = np.clip(np.floor(x * columns).astype(int), 0, columns - 1)
    t, s = y * rows - j, x * columns - i
    return ((1 - t) * ((1 - s) * values[j, i] + s * values[j, i + 1])
            + t * ((1 - s) * values[j + 1, i] + s * values[j + 1, i + 1]))


def _gauss_legendre_2d(f, rows, columns, order=4):
    """∫∫ f over [0, 1]² by Gauss-Legendre on every cell of the grid (exact for a bilinear f)."""
    nodes, weights = np.polynomial.legendre.leggauss(order)
    xs = (np.arange(columns)[:, None] + 0.5 * (nodes + 1)) / columns
    ys = (np.arange(rows)[:, None] + 0.5 * (nodes + 1)) / rows
    wx = np.tile(0.5 * weights / columns, columns)
    wy = np.tile(0.5 * weights / rows, rows)
    x, y = np.meshgrid(xs.ravel(), ys.ravel())
    return float(np.sum(f(x, y) * np.outer(wy, wx)))


def test_the_bilinear_table_is_its_interpolant_over_its_integral():
    """In float64: pdf at 4096 points against the NumPy interpolant divided by its Gauss-Legendre
    integral, and `integral()` against that integral (to 1e-12); the warp's inverse round trip (to
    1e-12) and its Jacobian, p(T(u)) |det T'(u)| = 1 (to 1e-9), at 512 points."""
    with jax.enable_x64(True):
        table = js.PiecewiseLinear2D(jnp.asarray(GRID))
        integral = _gauss_legendre_2d(lambda x, y: _bilinear(GRID, x, y), 6, 9)
        points = np.random.default_rng(3).random((4096, 2))
        np.testing.assert_allclose(float(table.integral()), integral, rtol=1e-12)
        np.testing.assert_allclose(np.asarray(table.pdf(jnp.asarray(points))),
                                   _bilinear(GRID, points[:, 0], points[:, 1]) / integral, rtol=1e-12)
        u = jnp.asarray(points[:512])
        x = table.warp(u)
        np.testing.assert_allclose(np.asarray(table.inverse(x)), points[:512], rtol=0, atol=1e-12)
        jacobian = jax.vmap(jax.jacfwd(lambda row: table.warp(row)))(u)
        volume = np.abs(np.linalg.det(np.asarray(jacobian)))
        np.testing.assert_allclose(np.asarray(table.pdf(x)) * volume, 1.0, rtol=1e-9)


def test_the_hierarchical_table_has_the_piecewise_constant_density_and_inverts():
    """In float64, on a 16 x 32 table with a zero row and column: the density and the integral of
    `PiecewiseConstant2D` on the same values (exactly, to rounding), the warp's inverse round trip
    (to 1e-12) and its Jacobian p(T(u)) |det T'(u)| = 1 (to 1e-9) at 512 points."""
    values = np.random.default_rng(8).random((16, 32))
    values[5], values[:, 11] = 0.0, 0.0
    points = np.random.default_rng(4).random((512, 2))
    with jax.enable_x64(True):
        table, constant = js.Hierarchical2D(jnp.asarray(values)), js.PiecewiseConstant2D(jnp.asarray(values))
        np.testing.assert_allclose(float(table.integral()), float(constant.integral()), rtol=1e-13)
        u = jnp.asarray(points)
        x = table.warp(u)
        np.testing.assert_allclose(np.asarray(table.pdf(x)), np.asarray(constant.pdf(x)), rtol=1e-12)
        np.testing.assert_allclose(np.asarray(table.inverse(x)), points, rtol=0, atol=1e-12)
        jacobian = jax.vmap(jax.jacfwd(lambda row: table.warp(row)))(u)
        volume = np.abs(np.linalg.det(np.asarray(jacobian)))
        np.testing.assert_allclose(np.asarray(table.pdf(x)) * volume, 1.0, rtol=1e-9)
    with pytest.raises(ValueError, match="power-of-two"):
        js.Hierarchical2D(np.ones((3, 4)))


def test_every_table_knows_its_integral():
    """A piecewise-constant table integrates to the mean of its values (each bin 1/K wide), and a traced
    table (inside jit) gives the same as a concrete one."""
    values = np.array([0.0, 2.0, 1.0, 5.0])
    assert float(js.PiecewiseConstant1D(values).integral()) == pytest.approx(2.0, rel=1e-7)
    assert float(js.PiecewiseConstant2D(GRID).integral()) == pytest.approx(GRID.mean(), rel=1e-6)
    traced = jax.jit(lambda v: js.PiecewiseLinear2D(v).integral())(jnp.asarray(GRID, jnp.float32))
    assert float(traced) == pytest.approx(float(js.PiecewiseLinear2D(GRID).integral()), rel=1e-6)


def test_a_bilinear_table_needs_a_grid_of_vertices():
    with pytest.raises(ValueError, match="at least 2 x 2"):
        js.PiecewiseLinear2D(np.ones((1, 5)))
    with pytest.raises(ValueError, match="'values'"):
        js.PiecewiseLinear2D(-np.ones((3, 3)))
