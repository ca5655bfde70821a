"""A piecewise-constant density on [0, 1]² sampled by hierarchical (mip-map) warping (area measure).

`Hierarchical2D(values)` has the density of `PiecewiseConstant2D(values)`; it draws it by descending
a pyramid of partial sums (McCool & Harwood 1997, "Probability trees"; Clarberg et al. 2005,
"Wavelet importance sampling"; Mitsuba 3's `Hierarchical2D`): at each level the current cell splits
into halves along x, then y, and each split chooses a half in proportion to its mass and rescales the
uniform into it. The uniforms that make the same first k choices form one rectangle of [0, 1)², of
area the mass of the cell of level k they reach: points that are evenly spread over such rectangles
(stratified, Sobol') are spread over the image's cells at every scale, in x and y together, where
the marginal-then-conditional map of `PiecewiseConstant2D` spreads them over rows first and then
within each row.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.numerics import one_minus_epsilon
from .._core.params import concrete_value
from .base import Sampler, point_method
from .discrete import as_array, check_weights
from .piecewise import cell_grid


def _power_of_two(n: int) -> bool:
    return n >= 1 and n & (n - 1) == 0


def _pyramid(values, xp):
    """Partial sums from the finest level (the table) up to one cell: the list, coarsest first. Each
    coarser level sums pairs of columns while there are several, and pairs of rows likewise."""
    levels = [values]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        level = levels[-1]
        if level.shape[1] > 1:
            level = level[:, 0::2] + level[:, 1::2]
        if level.shape[0] > 1:
            level = level[0::2, :] + level[1::2, :]
        levels.append(level)
    return levels[::-1]


def _split(mass_low, mass_high, u):
    """Choose the low half with probability mass_low / (mass_low + mass_high) and rescale u into it:
    (high?, u')."""
    total = mass_low + mass_high
    p_low = jnp.where(total > 0, mass_low / jnp.where(total > 0, total, 1.0), 0.5)
    high = u >= p_low
    u = jnp.where(high, (u - p_low) / jnp.where(p_low < 1, 1.0 - p_low, 1.0), u / jnp.where(p_low > 0, p_low, 1.0))
    return high, jnp.clip(u, 0.0, one_minus_epsilon(u.dtype))


class Hierarchical2D(Sampler):
    """Density p(x, y) = f[j, i] / mean(f) on [0, 1]² (area measure), as `PiecewiseConstant2D`
    (`values` of shape (R, C), row j covering y in [j/R, (j+1)/R)); R and C powers of two.

    Warp: from the coarsest level down, a cell of the pyramid splits into its left and right halves
    (u₀ chooses by their masses and is rescaled into the chosen half), then that half into its lower
    and upper quarters (u₁ likewise); at the table's level the rescaled (u₀, u₁) place the point in
    its cell. Where a level has a single column (or row) only the other axis splits. The inverse runs
    the same splits upwards from the point's cell. Values must be finite, >= 0, not all zero
    (ValueError when concrete).
    """

    # `levels`, set by the constructor: the pyramid of partial sums, coarsest first (a tuple of
    # arrays: leaves of the pytree).
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (2,)
    measure: ClassVar = "area"
    batchable: ClassVar = False

    def __init__(self, values):
        values = as_array(values)
        check_weights("Hierarchical2D", "values", values, ndim=2)
        rows, columns = values.shape[-2:]
        if not (_power_of_two(rows) and _power_of_two(columns)):
            raise ValueError(f"Hierarchical2D: parameter 'values' must have power-of-two sides (pad with zeros); got "
                             f"shape {values.shape}")
        concrete = concrete_value(values)
        dtype = jnp.asarray(values).dtype if jnp.issubdtype(jnp.asarray(values).dtype, jnp.floating) else jnp.float32
        if concrete is not None:  # sums in float64, as the other tables
            self.levels = tuple(jnp.asarray(level, dtype) for level in _pyramid(np.asarray(concrete, np.float64), np))
        else:
            self.levels = tuple(_pyramid(jnp.asarray(values, dtype), jnp))

    @property
    def shape(self) -> tuple[int, int]:
        return self.levels[-1].shape

    def __repr__(self):
        return f"Hierarchical2D(shape={self.shape})"

    def _parameters_valid(self):
        table = self.levels[-1]
        return jnp.all(jnp.isfinite(table) & (table >= 0)) & (self.levels[0][0, 0] > 0)

    def integral(self) -> jax.Array:
        """∫∫ over [0, 1]² of the piecewise-constant function of the values (their mean)."""
        rows, columns = self.shape
        return self.levels[0][0, 0] / (rows * columns)

    @point_method
    def warp(self, u):
        u0, u1 = u[..., 0], u[..., 1]
        row = jnp.zeros(u0.shape, jnp.int32)
        column = jnp.zeros(u0.shape, jnp.int32)
        for coarse, fine in zip(self.levels[:-1], self.levels[1:]):
            splits_x = fine.shape[1] > coarse.shape[1]
            splits_y = fine.shape[0] > coarse.shape[0]
            rows_here = 2 * row if splits_y else row
            if splits_x:
                left, right = 2 * column, 2 * column + 1
                mass = lambda c: fine[rows_here, c] + (fine[rows_here + 1, c] if splits_y else 0.0)  # noqa: E731
                high, u0 = _split(mass(left), mass(right), u0)
                column = jnp.where(high, right, left)
            if splits_y:
                high, u1 = _split(fine[rows_here, column], fine[rows_here + 1, column], u1)
                row = jnp.where(high, rows_here + 1, rows_here)
        rows, columns = self.shape
        return jnp.stack([(column.astype(u0.dtype) + u0) / columns, (row.astype(u1.dtype) + u1) / rows], axis=-1)

    def _cell(self, x):
        rows, columns = self.shape
        column = jnp.clip(jnp.floor(x[..., 0] * columns), 0, columns - 1).astype(jnp.int32)
        row = jnp.clip(jnp.floor(x[..., 1] * rows), 0, rows - 1).astype(jnp.int32)
        return row, column

    @point_method
    def pdf(self, x):
        rows, columns = self.shape
        row, column = self._cell(x)
        inside = jnp.all((x >= 0) & (x <= 1), axis=-1)
        density = self.levels[-1][row, column] * (rows * columns) / self.levels[0][0, 0]
        return jnp.where(inside, density, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        rows, columns = self.shape
        row, column = self._cell(x)
        u0 = jnp.clip(x[..., 0] * columns - column, 0.0, 1.0)
        u1 = jnp.clip(x[..., 1] * rows - row, 0.0, 1.0)
        for coarse, fine in zip(self.levels[-2::-1], self.levels[:0:-1]):
            splits_x = fine.shape[1] > coarse.shape[1]
            splits_y = fine.shape[0] > coarse.shape[0]
            if splits_y:  # undo the row split first: it was made last
                low_row = row - row % 2
                low, high = fine[low_row, column], fine[low_row + 1, column]
                p_low = jnp.where(low + high > 0, low / jnp.where(low + high > 0, low + high, 1.0), 0.5)
                u1 = jnp.where(row % 2 == 1, p_low + u1 * (1.0 - p_low), u1 * p_low)
                row = low_row
            if splits_x:
                left = column - column % 2
                mass = lambda c: fine[row, c] + (fine[row + 1, c] if splits_y else 0.0)  # noqa: E731
                low, high = mass(left), mass(left + 1)
                p_low = jnp.where(low + high > 0, low / jnp.where(low + high > 0, low + high, 1.0), 0.5)
                u0 = jnp.where(column % 2 == 1, p_low + u0 * (1.0 - p_low), u0 * p_low)
                column = left
            row = row // 2 if splits_y else row
            column = column // 2 if splits_x else column
        return jnp.clip(jnp.stack([u0, u1], axis=-1), 0.0, 1.0)

    def domain(self):
        return cell_grid(*self.shape)
