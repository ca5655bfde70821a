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


# Uneven nodes, a peak, a flat stretch and a fall towards 0 (whose spline stays >= 0).
SPLINE_NODES = np.array([0.0, 0.3, 0.5, 1.2, 2.0, 2.1, 3.0])
SPLINE_VALUES = np.array([1.0, 2.0, 0.8, 1.5, 1.5, 1.2, 0.3])


def _catmull_rom(nodes, values, x):
    """PBRT-v4's Catmull-Rom spline at x in float64 NumPy, from the cubic Hermite basis
    h00 = 2t³ − 3t² + 1, h10 = t³ − 2t² + t, h01 = −2t³ + 3t², h11 = t³ − t² with the node slopes
    of `CatmullRomWeights`: centred differences (v_{k+1} − v_{k−1})/(x_{k+1} − x_{k−1}) inside,
    one-sided at the two ends, scaled by the segment's width."""
    last = len(nodes) - 1
    slope = np.array([(values[min(k + 1, last)] - values[max(k - 1, 0)]) / (nodes[min(k + 1, last)]
                                                                          - nodes[max(k - 1, 0)])
                      for k in range(len(nodes))])
    k = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, last - 1)
    width = nodes[k + 1] - nodes[k]
    t = (x - nodes[k]) / width
    return ((2 * t ** 3 - 3 * t ** 2 + 1) * values[k] + (t ** 3 - 2 * t ** 2 + t) * width * slope[k]
            + (-2 * t ** 3 + 3 * t ** 2) * values[k + 1] + (t ** 3 - t ** 2) * width * slope[k + 1])


def _gauss_legendre_1d(f, breaks, order=4):
    """∫ f by Gauss-Legendre on every piece between consecutive breaks (exact for a piecewise cubic)."""
    nodes, weights = np.polynomial.legendre.leggauss(order)
    low, high = breaks[:-1, None], breaks[1:, None]
    x = low + 0.5 * (nodes + 1) * (high - low)
    return float(np.sum(f(x) * 0.5 * weights * (high - low)))


def test_the_catmull_rom_density_is_pbrts_spline_over_its_integral():
    """In float64: pdf at 4096 points against the independent spline divided by its Gauss-Legendre
    integral, and `integral()` against that integral (both to 1e-12); the inverse round trip (to 1e-12)
    and dx/du = 1/p(x) (to 1e-9) at 512 points."""
    with jax.enable_x64(True):
        table = js.CatmullRom1D(SPLINE_NODES, SPLINE_VALUES)
        integral = _gauss_legendre_1d(lambda x: _catmull_rom(SPLINE_NODES, SPLINE_VALUES, x), SPLINE_NODES)
        points = np.random.default_rng(4).uniform(0.0, 3.0, 4096)
        np.testing.assert_allclose(float(table.integral()), integral, rtol=1e-12)
        np.testing.assert_allclose(np.asarray(table.pdf(jnp.asarray(points))),
                                   _catmull_rom(SPLINE_NODES, SPLINE_VALUES, points) / integral, rtol=1e-12)
        u = jnp.asarray(np.concatenate([np.zeros((1, 1)), np.random.default_rng(5).random((511, 1))]))
        x, p = table.warp_with_pdf(u)
        np.testing.assert_allclose(np.asarray(table.inverse(x)), np.asarray(u), rtol=0, atol=1e-12)
        slope = jax.vmap(jax.grad(lambda row: table.warp(row[None])[0]))(u)  # u = 0 included: x on x_0
        np.testing.assert_allclose(np.asarray(slope)[:, 0] * np.asarray(p), 1.0, rtol=1e-9)
        # The density's derivative on the inner nodes against central differences (the spline is C¹ there,
        # its second derivative jumps: the difference is good to h times that jump, 1e-6 here).
        inner = jnp.asarray(SPLINE_NODES[1:-1])
        by_differences = (table.pdf(inner + 1e-7) - table.pdf(inner - 1e-7)) / 2e-7
        np.testing.assert_allclose(np.asarray(jax.vmap(jax.grad(table.pdf))(inner)), np.asarray(by_differences),
                                   rtol=1e-4)
        # A spline that touches 0 inside (a triple root of the CDF equation) inverts to rounding too.
        touching = js.CatmullRom1D([0.0, 1.0, 2.0], [1.0, 0.0, 1.0])
        u = jnp.asarray(np.random.default_rng(12).random((20000, 1)))
        np.testing.assert_allclose(np.asarray(touching.inverse(touching.warp(u))), np.asarray(u), rtol=0, atol=1e-12)


def test_catmull_rom_samples_move_with_the_table_as_their_cdf_says():
    """The derivatives of a sample in the values and in the nodes (the implicit function C(x) = u, not
    the Newton iteration) against central differences of the warp, in float64, at five uniforms."""
    def sample(nodes, values):
        return js.CatmullRom1D(nodes, values).warp(u)

    with jax.enable_x64(True):
        u = jnp.asarray([[0.05], [0.3], [0.37], [0.71], [0.96]])
        nodes, values = jnp.asarray(SPLINE_NODES), jnp.asarray(SPLINE_VALUES)
        d_values = np.asarray(jax.jacfwd(sample, argnums=1)(nodes, values))
        d_nodes = np.asarray(jax.jacfwd(sample, argnums=0)(nodes, values))
        step = 1e-6
        for i in range(len(SPLINE_NODES)):
            bump = step * np.eye(len(SPLINE_NODES))[i]
            by_values = (sample(nodes, values + bump) - sample(nodes, values - bump)) / (2 * step)
            by_nodes = (sample(nodes + bump, values) - sample(nodes - bump, values)) / (2 * step)
            np.testing.assert_allclose(d_values[:, i], np.asarray(by_values), rtol=1e-6, atol=1e-8)
            np.testing.assert_allclose(d_nodes[:, i], np.asarray(by_nodes), rtol=1e-6, atol=1e-8)


def test_a_catmull_rom_table_must_make_a_density():
    """ValueError naming the parameter: nodes out of order, shapes that differ, too few nodes, a value
    below 0, and values whose spline overshoots below 0 between nodes (0, 0, 1, 0, 0)."""
    with pytest.raises(ValueError, match="'nodes'.*increasing"):
        js.CatmullRom1D([0.0, 2.0, 1.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="'nodes' and 'values'"):
        js.CatmullRom1D([0.0, 1.0, 2.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="at least 2"):
        js.CatmullRom1D([0.0], [1.0])
    with pytest.raises(ValueError, match="'values'.*>= 0"):
        js.CatmullRom1D([0.0, 1.0], [1.0, -1.0])
    with pytest.raises(ValueError, match="dips below 0"):
        js.CatmullRom1D([0.0, 1.0, 2.0, 3.0, 4.0], [0.0, 0.0, 1.0, 0.0, 0.0])
    traced = jax.jit(lambda v: js.CatmullRom1D(SPLINE_NODES, v).integral())(jnp.asarray(SPLINE_VALUES, jnp.float32))
    assert float(traced) == pytest.approx(float(js.CatmullRom1D(SPLINE_NODES, SPLINE_VALUES).integral()), rel=1e-6)


SPLINE_ALPHAS = np.array([0.0, 0.4, 1.0, 1.5])
SPLINE_ROWS = 1.0 + 0.5 * np.sin(3.0 * SPLINE_ALPHAS[:, None] + 2.0 * SPLINE_NODES[None, :])


def test_the_catmull_rom_conditional_interpolates_its_rows_as_pbrt_does():
    """In float64: at α = 0.7, pdf at 2048 points and `integral()` against the independent spline in x
    through the columns' independent splines in α at 0.7 (to 1e-12); at α = α_1 the conditional is
    row 1's `CatmullRom1D`; a batch of three α gives each member's integral."""
    with jax.enable_x64(True):
        row = np.array([_catmull_rom(SPLINE_ALPHAS, SPLINE_ROWS[:, k], 0.7) for k in range(len(SPLINE_NODES))])
        integral = _gauss_legendre_1d(lambda x: _catmull_rom(SPLINE_NODES, row, x), SPLINE_NODES)
        table = js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, SPLINE_ROWS, 0.7)
        points = np.random.default_rng(6).uniform(0.0, 3.0, 2048)
        np.testing.assert_allclose(float(table.integral()), integral, rtol=1e-12)
        np.testing.assert_allclose(np.asarray(table.pdf(jnp.asarray(points))),
                                   _catmull_rom(SPLINE_NODES, row, points) / integral, rtol=1e-12)
        on_a_row = js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, SPLINE_ROWS, 0.4)
        np.testing.assert_allclose(np.asarray(on_a_row.pdf(jnp.asarray(points))),
                                   np.asarray(js.CatmullRom1D(SPLINE_NODES, SPLINE_ROWS[1]).pdf(jnp.asarray(points))),
                                   rtol=1e-12)
        batch = js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, SPLINE_ROWS, jnp.asarray([0.0, 0.7, 1.5]))
        alone = [float(js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, SPLINE_ROWS, a).integral())
                 for a in (0.0, 0.7, 1.5)]
        np.testing.assert_allclose(np.asarray(batch.integral()), alone, rtol=1e-12)


def test_catmull_rom_conditional_samples_move_with_alpha():
    """dx/dα of samples at five uniforms against central differences of the warp, in float64."""
    def sample(alpha):
        return js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, SPLINE_ROWS, alpha).warp(u)

    with jax.enable_x64(True):
        u = jnp.asarray([[0.05], [0.3], [0.37], [0.71], [0.96]])
        for alpha in (0.2, 0.4, 0.7, 1.0, 1.3):
            # On the rows' nodes 0.4 and 1.0 the spline in α is C¹ with a jump in its second derivative,
            # which central differences see at h times the jump (1e-6): 1e-4 there.
            step = 1e-6
            by_differences = (sample(alpha + step) - sample(alpha - step)) / (2 * step)
            np.testing.assert_allclose(np.asarray(jax.jacfwd(sample)(jnp.asarray(alpha))), np.asarray(by_differences),
                                       rtol=1e-4 if alpha in (0.4, 1.0) else 1e-6, atol=1e-8)
        for alpha, step in ((0.0, 1e-7), (1.5, -1e-7)):  # the end rows: a one-sided difference
            by_differences = (sample(alpha + step) - sample(alpha)) / step
            np.testing.assert_allclose(np.asarray(jax.jacfwd(sample)(jnp.asarray(alpha))), np.asarray(by_differences),
                                       rtol=1e-5, atol=1e-7)


def test_a_catmull_rom_conditional_must_make_a_density():
    """ValueError naming the parameter: α outside the rows' range, a table of the wrong shape, and rows
    whose interpolation between them overshoots below 0 (a row of zeros next to positive rows)."""
    with pytest.raises(ValueError, match="'alpha' must lie in"):
        js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, SPLINE_ROWS, 1.6)
    with pytest.raises(ValueError, match="'values' must have shape"):
        js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, SPLINE_ROWS[:, :-1], 0.7)
    rows = SPLINE_ROWS.copy()
    rows[:2] = 0.0
    with pytest.raises(ValueError, match="interpolated at alpha = 0.2 .*dips below 0"):
        js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, rows, jnp.asarray([1.2, 0.2]))
    traced = jax.jit(lambda a: js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, SPLINE_ROWS, a).integral())
    assert np.isnan(float(traced(2.0))) and np.isfinite(float(traced(0.7)))
    # A batch of α of any shape is checked; traced nodes with concrete rows and α are built and differentiated.
    assert js.CatmullRom2D(SPLINE_ALPHAS, SPLINE_NODES, SPLINE_ROWS, np.full((2, 3), 0.7)).batch_shape == (2, 3)
    grad = jax.grad(lambda n: js.CatmullRom2D(SPLINE_ALPHAS, n, SPLINE_ROWS, 0.7).warp(jnp.asarray([[0.3]]))[0])
    assert np.all(np.isfinite(np.asarray(grad(jnp.asarray(SPLINE_NODES, jnp.float32)))))


WINDOW_TABLE = np.random.default_rng(8).random((6, 9))
WINDOW_TABLE[2], WINDOW_TABLE[:, 4] = 0.0, 0.0
WINDOW = (np.array([0.13, 0.2]), np.array([0.71, 0.93]))


def _box_integral(values, low, high):
    """∫ over [low, high] of the cells' constant function, in NumPy from each cell's overlap with the box."""
    rows, columns = values.shape
    xs, ys = np.linspace(0, 1, columns + 1), np.linspace(0, 1, rows + 1)
    width = np.clip(np.minimum(xs[1:], high[0]) - np.maximum(xs[:-1], low[0]), 0, None)
    height = np.clip(np.minimum(ys[1:], high[1]) - np.maximum(ys[:-1], low[1]), 0, None)
    return float(np.sum(values * np.outer(height, width)))


def test_the_windowed_table_is_its_cells_over_the_window_mass():
    """In float64: `integral()` and `SummedAreaTable.integral` on 64 random boxes against the cells'
    overlaps (to 1e-12); pdf at 4096 points of the square (in and out of the window) against the
    cell's value over that integral; the inverse round trip (to 1e-12) and p(T(u)) |det T'(u)| = 1
    (to 1e-9) at 512 points."""
    with jax.enable_x64(True):
        table = js.WindowedPiecewiseConstant2D(WINDOW_TABLE, *WINDOW)
        integral = _box_integral(WINDOW_TABLE, *WINDOW)
        np.testing.assert_allclose(float(table.integral()), integral, rtol=1e-12)
        corners = np.sort(np.random.default_rng(9).random((64, 2, 2)), axis=1)
        summed = js.SummedAreaTable(WINDOW_TABLE).integral(jnp.asarray(corners[:, 0]), jnp.asarray(corners[:, 1]))
        np.testing.assert_allclose(np.asarray(summed), [_box_integral(WINDOW_TABLE, *c) for c in corners],
                                   rtol=1e-12, atol=1e-15)
        points = np.random.default_rng(10).random((4096, 2))
        inside = np.all((points >= WINDOW[0]) & (points <= WINDOW[1]), axis=-1)
        row, column = np.minimum((points[:, 1] * 6).astype(int), 5), np.minimum((points[:, 0] * 9).astype(int), 8)
        cell = WINDOW_TABLE[row, column]
        np.testing.assert_allclose(np.asarray(table.pdf(jnp.asarray(points))), np.where(inside, cell / integral, 0.0),
                                   rtol=1e-12)
        u = jnp.asarray(points[:512])
        x = table.warp(u)
        np.testing.assert_allclose(np.asarray(table.inverse(x)), points[:512], rtol=0, atol=1e-12)
        volume = np.abs(np.linalg.det(np.asarray(jax.vmap(jax.jacfwd(lambda row: table.warp(row)))(u))))
        np.testing.assert_allclose(np.asarray(table.pdf(x)) * volume, 1.0, rtol=1e-9)
        # u on the edges: the Jacobian at u = 0, and a window whose top edge lies in a zero row (u₁ next
        # to 1 must not carry y into it).
        corner = jnp.asarray([[0.0, 0.0], [0.0, 0.5], [0.5, 0.0]])
        volume = np.abs(np.linalg.det(np.asarray(jax.vmap(jax.jacfwd(lambda row: table.warp(row)))(corner))))
        np.testing.assert_allclose(np.asarray(table.pdf(table.warp(corner))) * volume, 1.0, rtol=1e-9)
        capped = js.WindowedPiecewiseConstant2D(WINDOW_TABLE, [0.1, 0.2], [0.9, 0.45])
        top = jnp.asarray([[u0, np.nextafter(1.0, 0.0)] for u0 in np.linspace(0.0, 0.99, 64)])
        assert np.all(np.asarray(capped.pdf(capped.warp(top))) > 0)


def test_windowed_samples_move_with_the_window_and_small_windows_keep_float32_precision():
    """The derivatives of samples in the window's corners against central differences of the warp
    (float64, five uniforms); a window holding 4.6e-4 of the table's mass has its float32 integral within
    1e-5 of the float64 one (differences of a summed-area table are off by 1e-4 there)."""
    def sample(low, high):
        return js.WindowedPiecewiseConstant2D(WINDOW_TABLE, low, high).warp(u)

    with jax.enable_x64(True):
        u = jnp.asarray(np.random.default_rng(11).random((5, 2)))
        low, high = jnp.asarray(WINDOW[0]), jnp.asarray(WINDOW[1])
        d_low, d_high = (np.asarray(d) for d in jax.jacfwd(sample, argnums=(0, 1))(low, high))
        step = 1e-7
        for axis in range(2):
            bump = step * np.eye(2)[axis]
            by_low = (sample(low + bump, high) - sample(low - bump, high)) / (2 * step)
            by_high = (sample(low, high + bump) - sample(low, high - bump)) / (2 * step)
            np.testing.assert_allclose(d_low[..., axis], np.asarray(by_low), rtol=1e-6, atol=1e-8)
            np.testing.assert_allclose(d_high[..., axis], np.asarray(by_high), rtol=1e-6, atol=1e-8)
        small = (np.array([0.905, 0.905]), np.array([0.92, 0.92]))
        exact = float(js.WindowedPiecewiseConstant2D(WINDOW_TABLE, *small).integral())
    assert exact / _box_integral(WINDOW_TABLE, np.zeros(2), np.ones(2)) < 5e-4
    single = js.WindowedPiecewiseConstant2D(jnp.asarray(WINDOW_TABLE, jnp.float32), jnp.asarray(small[0], jnp.float32),
                                            jnp.asarray(small[1], jnp.float32))
    assert float(single.integral()) == pytest.approx(exact, rel=1e-5)


def test_a_window_must_hold_mass():
    """ValueError naming the corners when low >= high, and the window when every cell it overlaps is 0;
    a batch of windows gives each one's integral."""
    with pytest.raises(ValueError, match="'low' and 'high'"):
        js.WindowedPiecewiseConstant2D(WINDOW_TABLE, [0.5, 0.2], [0.4, 0.9])
    with pytest.raises(ValueError, match="0 <= low < high <= 1"):
        js.WindowedPiecewiseConstant2D(WINDOW_TABLE, [0.5, 0.2], [1.1, 0.9])
    traced = jax.jit(lambda high: js.WindowedPiecewiseConstant2D(WINDOW_TABLE, jnp.asarray([0.1, 0.2]),
                                                                  high).integral())
    assert np.isnan(float(traced(jnp.asarray([1.1, 0.9])))) and np.isfinite(float(traced(jnp.asarray([0.9, 0.9]))))
    with pytest.raises(ValueError, match="holds no mass"):
        js.WindowedPiecewiseConstant2D(WINDOW_TABLE, [0.45, 0.34], [0.54, 0.49])
    with pytest.raises(ValueError, match="holds no mass"):  # inside the zero row, across every column
        js.WindowedPiecewiseConstant2D(WINDOW_TABLE, [0.05, 0.35], [0.95, 0.45])
    tiny = js.WindowedPiecewiseConstant2D(jnp.asarray(WINDOW_TABLE, jnp.float32), [0.9, 0.9], [0.90001, 0.90001])
    assert float(tiny.integral()) > 0  # 1e-10 of the square: accepted (its mass is checked in float64)
    lows, highs = np.array([[0.0, 0.0], [0.1, 0.5]]), np.array([[1.0, 1.0], [0.9, 0.7]])
    batch = js.WindowedPiecewiseConstant2D(WINDOW_TABLE, lows, highs)
    np.testing.assert_allclose(np.asarray(batch.integral()), [_box_integral(WINDOW_TABLE, lo, hi)
                                                              for lo, hi in zip(lows, highs)], rtol=1e-5)
