"""A piecewise-constant density on [0, 1]² restricted to a window (area measure), by a summed-area table:
sampling an environment map inside the bounds a light subtends (PBRT-v4 `SummedAreaTable`,
`WindowedPiecewiseConstant2D`).

`values` (R, C) is constant on cells: row j covers y in [j/R, (j+1)/R), column i covers x in
[i/C, (i+1)/C), as in `PiecewiseConstant2D`. The cumulative integral G(x, y) = ∫₀ˣ∫₀ʸ f is bilinear
within each cell, so it is the bilinear interpolation of its values at the grid's vertices (the
summed-area table), and the integral over any box [x₀, x₁] x [y₀, y₁] is four lookups:
G(x₁, y₁) − G(x₀, y₁) − G(x₁, y₀) + G(x₀, y₀), exact.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.params import concrete_value
from .._core.pytree import Pytree, parameter
from .base import Sampler, over_members, point_method
from .._core.numerics import clamp_rounding, one_minus_epsilon
from .discrete import as_array, check_weights, select_with_remainder
from .domain import Box
from .piecewise import _place_in_bin, nudge_into_bin


def _summed_area(values, dtype):
    """G at the grid's vertices, (R + 1, C + 1), 0 along the first row and column; in float64 NumPy
    when the values are concrete."""
    concrete = concrete_value(values)
    if concrete is not None:
        v = np.asarray(concrete, np.float64)
        table = np.zeros((v.shape[0] + 1, v.shape[1] + 1))
        table[1:, 1:] = np.cumsum(np.cumsum(v, 0), 1) / v.size
        return jnp.asarray(table, dtype)
    v = jnp.asarray(values, dtype)
    return jnp.pad(jnp.cumsum(jnp.cumsum(v, 0), 1) / v.size, ((1, 0), (1, 0)))


def _column_sums(values, dtype):
    """Each column's running integral in y at the row lines, (R + 1, C): ∫₀^{j/R} f(x, y) dy in column i
    (kept apart from the summed-area table, whose differences across a column would cancel)."""
    concrete = concrete_value(values)
    if concrete is not None:
        v = np.asarray(concrete, np.float64)
        return jnp.asarray(np.concatenate([np.zeros((1, v.shape[1])), np.cumsum(v, 0) / v.shape[0]]), dtype)
    v = jnp.asarray(values, dtype)
    return jnp.pad(jnp.cumsum(v, 0) / v.shape[0], ((1, 0), (0, 0)))


def _cell(coordinate, count):
    """(index, fraction): the cell of `count` equal cells of [0, 1] holding the coordinate (the last
    one for 1) and the position in it, in [0, 1]."""
    index = jnp.clip(jnp.floor(coordinate * count), 0, count - 1).astype(jnp.int32)
    return index, clamp_rounding(coordinate * count - index, 0.0, 1.0)


def _cumulative(table, x, y):
    """G(x, y): the bilinear interpolation of the summed-area table (exact for a piecewise-constant f)."""
    rows, columns = table.shape[-2] - 1, table.shape[-1] - 1
    j, t = _cell(jnp.clip(y, 0.0, 1.0), rows)
    i, s = _cell(jnp.clip(x, 0.0, 1.0), columns)
    return ((1.0 - t) * ((1.0 - s) * table[j, i] + s * table[j, i + 1])
            + t * ((1.0 - s) * table[j + 1, i] + s * table[j + 1, i + 1]))


def _box(table, low, high):
    """∫ f over [low₀, high₀] x [low₁, high₁] from four lookups of the summed-area table."""
    return (_cumulative(table, high[..., 0], high[..., 1]) - _cumulative(table, low[..., 0], high[..., 1])
            - _cumulative(table, high[..., 0], low[..., 1]) + _cumulative(table, low[..., 0], low[..., 1]))


def _last_at_most(line, target, count):
    """The largest k in [0, count − 1] with line(k) <= target, for a non-decreasing line with
    line(0) <= target: bisection, ceil(log2 count) steps of one lookup each."""
    low = jnp.zeros(jnp.shape(target), jnp.int32)
    high = jnp.full(jnp.shape(target), count - 1, jnp.int32)
    for _ in range(int(np.ceil(np.log2(max(count, 2))))):
        middle = (low + high + 1) // 2
        below = line(middle) <= target
        low, high = jnp.where(below, middle, low), jnp.where(below, high, middle - 1)
    return low


def _place(k, target, line, count):
    """(k + (target − line(k)) / (line(k + 1) − line(k))) / count: the point where the piecewise-linear
    line reaches target within cell k, kept inside cell k against rounding (`_place_in_bin`)."""
    below, above = line(k), line(k + 1)
    width = above - below
    fraction = jnp.where(width > 0, (target - below) / jnp.where(width > 0, width, 1.0), 0.0)
    return _place_in_bin(k, clamp_rounding(fraction, 0.0, one_minus_epsilon(fraction.dtype)), count)


def _window_masses(values, low, high):
    """∫ f over each window (low, high: (..., 2)), in float64 NumPy from every cell's overlap with it."""
    rows, columns = values.shape
    xs, ys = np.linspace(0.0, 1.0, columns + 1), np.linspace(0.0, 1.0, rows + 1)
    width = np.clip(np.minimum(xs[1:], high[..., 0:1]) - np.maximum(xs[:-1], low[..., 0:1]), 0.0, None)
    height = np.clip(np.minimum(ys[1:], high[..., 1:2]) - np.maximum(ys[:-1], low[..., 1:2]), 0.0, None)
    return np.einsum("...r,rc,...c->...", height, values, width)


class SummedAreaTable(Pytree):
    """The integral of the piecewise-constant function of `values` (R, C) over any axis-aligned box
    of [0, 1]² (area measure), in four lookups (PBRT-v4 `SummedAreaTable`; Crow 1984). Built in
    float64 when the values are concrete; in float32 a box's integral carries the table's rounding,
    about 1e-7 of the whole table's integral."""

    table: jax.Array = parameter(rank=2, doc="G at the grid's vertices, (R + 1, C + 1)")

    def __init__(self, values):
        values = as_array(values)
        check_weights("SummedAreaTable", "values", values, ndim=2)
        self.table = _summed_area(values, jnp.result_type(values, float))

    def integral(self, low, high) -> jax.Array:
        """∫ f over the boxes [low₀, high₀] x [low₁, high₁] (low, high: (..., 2), clipped to [0, 1]²)."""
        return _box(self.table, jnp.asarray(low), jnp.asarray(high))


class WindowedPiecewiseConstant2D(Sampler):
    """p(x, y) = f(x, y) / ∫_W f on the window W = [low₀, high₀] x [low₁, high₁] (area measure), 0
    outside, f the piecewise-constant function of `values` (R, C) on [0, 1]² (PBRT-v4
    `WindowedPiecewiseConstant2D`, which samples an environment map inside a light's bounds).

    Warp: each column i's mass inside the window is its overlap with [low₀, high₀] times its own
    running integral in y between low₁ and high₁ (the columns' running sums, one lookup at each
    end); u₀ chooses the column by those masses and places x uniformly in its overlap, then u₁
    places y in that column between low₁ and high₁ by its running integral (bisection over the
    row lines, linear within the row). Exact, with no iteration to converge, and differentiable in
    u, the window and the values. Across columns the masses are sums of positive terms, so a window
    narrow in x keeps float32's relative precision, which differences of a summed-area table lose
    (three digits on a window of 5e-4 of the mass); a column's height is a difference of its running
    sums in y, so a window thin in y far up the table loses digits as the table would (in float32,
    5e-4 relative for y in [0.95, 0.9501]). Inverse: the two running integrals, normalized.
    `integral()` is ∫_W f. The window may be a batch ((..., 2) corners), the table shared. Values
    finite and >= 0; 0 <= low < high <= 1 on both axes; the window must hold mass (ValueError when
    concrete, NaN when traced).
    """

    values: jax.Array = parameter(rank=2, doc="f on each cell, (R, C)")
    columns: jax.Array = parameter(rank=2)
    # The corners' range is a joint one (0 <= low < high <= 1), checked here rather than declared per corner.
    low: jax.Array = parameter(rank=1, doc="the window's lower corner (x₀, y₀), in [0, 1]²")
    high: jax.Array = parameter(rank=1, doc="the window's upper corner (x₁, y₁), above low, in [0, 1]²")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (2,)
    measure: ClassVar = "area"

    def __init__(self, values, low, high):
        values = as_array(values)
        check_weights("WindowedPiecewiseConstant2D", "values", values, ndim=2)
        dtype = jnp.result_type(values, float)
        self.values, self.columns = jnp.asarray(values, dtype), _column_sums(values, dtype)
        self.low, self.high = as_array(low), as_array(high)
        corner_low, corner_high = concrete_value(self.low), concrete_value(self.high)
        if corner_low is None or corner_high is None:
            return
        corner_low, corner_high = np.asarray(corner_low, np.float64), np.asarray(corner_high, np.float64)
        if (corner_low.shape[-1:] != (2,) or corner_high.shape[-1:] != (2,)
                or not np.all((0.0 <= corner_low) & (corner_low < corner_high) & (corner_high <= 1.0))):
            raise ValueError(f"WindowedPiecewiseConstant2D: parameters 'low' and 'high' must be corners (x, y) with "
                             f"0 <= low < high <= 1 on both axes; got {corner_low.tolist()} and {corner_high.tolist()}")
        cells = concrete_value(values)
        if cells is not None:
            mass = _window_masses(np.asarray(cells, np.float64), corner_low, corner_high)
            if not np.all(mass > 0):
                raise ValueError(f"WindowedPiecewiseConstant2D: the window low = {corner_low.tolist()}, high = "
                                 f"{corner_high.tolist()} holds no mass of 'values' (every cell it overlaps is 0)")

    @property
    def shape(self) -> tuple[int, int]:
        """(R, C): the table's cells."""
        return self.values.shape[-2], self.values.shape[-1]

    def __repr__(self):
        return f"WindowedPiecewiseConstant2D(shape={self.shape})"

    def _parameters_valid(self):
        if self.batch_shape:
            return jnp.all(over_members(lambda member: member._parameters_valid(), self))
        declared = super()._parameters_valid()
        valid = (jnp.all((0.0 <= self.low) & (self.low < self.high) & (self.high <= 1.0))
                 & jnp.all(jnp.isfinite(self.values) & (self.values >= 0))
                 & (self._column_masses()[2][-1] > 0))
        return valid if declared is None else declared & valid

    def integral(self) -> jax.Array:
        """∫ f over the window (the density's normalization), one per window of a batch."""
        if self.batch_shape:
            return over_members(lambda member: member.integral(), self)
        return jnp.where(self._parameters_valid(), self._column_masses()[2][-1], jnp.nan)

    def _column_at(self, i, y):
        """Column i's running integral in y up to y (linear between its row lines)."""
        rows, _ = self.shape
        j, t = _cell(y, rows)
        return (1.0 - t) * self.columns[j, i] + t * self.columns[j + 1, i]

    def _column_masses(self):
        """(start, overlap, cumulative): each column's first x inside the window, the width of its
        overlap with it, and the running sum of the columns' masses inside the window."""
        _, count = self.shape
        edges = jnp.arange(count + 1, dtype=self.columns.dtype) / count
        start = jnp.clip(edges[:-1], self.low[0], self.high[0])
        overlap = jnp.clip(edges[1:], self.low[0], self.high[0]) - start
        every = jnp.arange(count)
        height = self._column_at(every, self.high[1]) - self._column_at(every, self.low[1])
        return start, overlap, jnp.cumsum(overlap * height)

    @point_method
    def warp(self, u):
        rows, _ = self.shape
        start, overlap, cumulative = self._column_masses()
        k, remainder = select_with_remainder(cumulative / cumulative[-1], u[..., 0])
        # x in column k even where rounding puts start[k] = k/C at the previous column's end.
        _, columns = self.shape
        x = nudge_into_bin(clamp_rounding(start[k] + remainder * overlap[k], self.low[0], self.high[0]), k, columns)
        bottom, top = self._column_at(k, self.low[1]), self._column_at(k, self.high[1])
        target = bottom + u[..., 1] * (top - bottom)
        # Kept below the top, which a u₁ next to 1 can round to: there the search would pass the
        # column's last row of mass into zero rows up to the window's edge.
        below_top = jnp.nextafter(jax.lax.stop_gradient(top), jax.lax.stop_gradient(bottom))
        rounded_up = (target >= top) & (top > bottom)
        target = jnp.where(rounded_up, target + jax.lax.stop_gradient(below_top - target), target)
        line = lambda j: self.columns[j, k]  # noqa: E731
        y = clamp_rounding(_place(_last_at_most(line, target, rows), target, line, rows), self.low[1], self.high[1])
        return jnp.stack([x, y], axis=-1)

    @point_method
    def pdf(self, x):
        rows, columns = self.shape
        j, _ = _cell(x[..., 1], rows)
        i, _ = _cell(x[..., 0], columns)
        inside = jnp.all((x >= self.low) & (x <= self.high), axis=-1)
        total = self._column_masses()[2][-1]
        return jnp.where(inside, self.values[j, i] / total, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        _, columns = self.shape
        start, overlap, cumulative = self._column_masses()
        i, _ = _cell(x[..., 0], columns)
        before = jnp.where(i > 0, cumulative[jnp.maximum(i - 1, 0)], 0.0)
        mass = cumulative[i] - before
        within = jnp.where(overlap[i] > 0, (x[..., 0] - start[i]) / jnp.where(overlap[i] > 0, overlap[i], 1.0), 0.0)
        u0 = (before + within * mass) / cumulative[-1]
        bottom, top = self._column_at(i, self.low[1]), self._column_at(i, self.high[1])
        height = top - bottom
        u1 = jnp.where(height > 0, (self._column_at(i, x[..., 1]) - bottom) / jnp.where(height > 0, height, 1.0), 0.0)
        return clamp_rounding(jnp.stack([u0, u1], axis=-1), 0.0, 1.0)

    def domain(self):
        low, high = concrete_value(self.low), concrete_value(self.high)
        if low is None or high is None or np.ndim(low) != 1:
            raise ValueError("WindowedPiecewiseConstant2D.domain: needs one concrete window")
        rows, columns = self.shape
        xs, ys = np.linspace(0.0, 1.0, columns + 1), np.linspace(0.0, 1.0, rows + 1)
        return Box.from_bounds([float(low[0]), float(low[1])], [float(high[0]), float(high[1])],
                               breaks=[xs[(xs > low[0]) & (xs < high[0])], ys[(ys > low[1]) & (ys < high[1])]],
                               graded=False, order=1)
