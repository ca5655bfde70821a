"""A bilinearly interpolated density on [0, 1]² (area measure): the 2-D table of measured BRDFs and
smooth environment maps, continuous where a piecewise-constant table has steps.

`PiecewiseLinear2D(values)` takes the density's values at the (R + 1) x (C + 1) vertices of a grid of
R x C cells and interpolates them bilinearly (Mitsuba 3's `Marginal2D` with bilinear interpolation;
PBRT-v4's `PiecewiseLinear2D`, without their conditional parameters). Sampling inverts the marginal
in y, which is linear across each row of cells, then the conditional in x at that y, which is linear
across each cell: two `linear_quantile`s after two table searches.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.numerics import one_minus_epsilon
from .._core.params import concrete_value
from .._core.pytree import parameter
from .base import Sampler, point_method
from .discrete import as_array, check_weights, select_with_remainder
from .domain import Box
from .polynomial import linear_cdf, linear_quantile


def _trapezoids(values):
    """Each row's integral over x of its linear interpolant, Σ_i (v_i + v_{i+1}) / (2C): (..., R + 1)."""
    columns = values.shape[-1] - 1
    return jnp.sum(values[..., :-1] + values[..., 1:], axis=-1) / (2.0 * columns)


def _cumulative_cells(values):
    """Per row, the running integral of the interpolant up to each vertex: (R + 1, C + 1), 0 first."""
    columns = values.shape[-1] - 1
    cells = (values[..., :-1] + values[..., 1:]) / (2.0 * columns)
    return jnp.concatenate([jnp.zeros(values.shape[:-1] + (1,), values.dtype), jnp.cumsum(cells, axis=-1)], axis=-1)


class PiecewiseLinear2D(Sampler):
    """p(x, y) = f(x, y) / ∫f over [0, 1]² (area measure), f the bilinear interpolation of `values`
    (shape (R + 1, C + 1): values[j, i] at x = i/C, y = j/R); 0 outside the square.

    Warp: the marginal m(y) = ∫₀¹ f(x, y) dx is linear in y across row j of cells (between the
    rows' trapezoid integrals S_j and S_{j+1}): u₁ chooses the row of cells by its mass
    (S_j + S_{j+1})/(2R) and places y in it by `linear_quantile`; at that y the conditional f(·, y)
    is linear across each cell, with vertex values g_i = (1 − t) v[j, i] + t v[j + 1, i]
    (t = yR − j), and its running integral is the same interpolation of the two rows' running
    integrals, so u₀ chooses the cell by bisection on it and places x by `linear_quantile`
    (Mitsuba 3's `Marginal2D` sampling; Jakob 2019's measured-BRDF tables). The inverse runs the
    steps backwards; `integral()` is ∫f. Values must be finite, >= 0 and not all zero
    (ValueError when concrete), on a grid of at least 2 x 2 vertices.
    """

    values: jax.Array = parameter(rank=2, doc="the density's values at the grid's vertices")
    marginal_cdf: jax.Array = parameter(rank=1)
    running: jax.Array = parameter(rank=2)
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (2,)
    measure: ClassVar = "area"
    batchable: ClassVar = False

    def __init__(self, values):
        values = as_array(values)
        check_weights("PiecewiseLinear2D", "values", values, ndim=2)
        if values.shape[-1] < 2 or values.shape[-2] < 2:
            raise ValueError(f"PiecewiseLinear2D: parameter 'values' must hold at least 2 x 2 vertices; got shape "
                             f"{values.shape}")
        concrete = concrete_value(values)
        values = jnp.asarray(values)
        if not jnp.issubdtype(values.dtype, jnp.floating):
            values = values.astype(jnp.result_type(float))
        self.values = values
        if concrete is not None:  # the tables in float64, as PiecewiseConstant2D's
            rows = np.asarray(concrete, np.float64)
            trapezoid = (rows[:, :-1] + rows[:, 1:]).sum(-1) / (2.0 * (rows.shape[-1] - 1))
            masses = (trapezoid[:-1] + trapezoid[1:]) / (2.0 * (rows.shape[0] - 1))
            cells = (rows[:, :-1] + rows[:, 1:]) / (2.0 * (rows.shape[-1] - 1))
            self.marginal_cdf = jnp.asarray(np.cumsum(masses), values.dtype)
            self.running = jnp.asarray(np.concatenate([np.zeros((rows.shape[0], 1)), np.cumsum(cells, -1)], -1),
                                       values.dtype)
        else:
            trapezoid = _trapezoids(values)
            self.marginal_cdf = jnp.cumsum((trapezoid[:-1] + trapezoid[1:]) / (2.0 * (values.shape[-2] - 1)))
            self.running = _cumulative_cells(values)

    def __repr__(self):
        return f"PiecewiseLinear2D(shape={self.shape})"

    @property
    def shape(self) -> tuple[int, int]:
        """(R, C): the grid's cells."""
        return self.values.shape[-2] - 1, self.values.shape[-1] - 1

    def _parameters_valid(self):
        return jnp.all(jnp.isfinite(self.values) & (self.values >= 0)) & (self.marginal_cdf[-1] > 0)

    def integral(self) -> jax.Array:
        """∫∫ f over [0, 1]², f the bilinear interpolant of the values (the density's normalization)."""
        return self.marginal_cdf[-1]

    def _row_point(self, u1):
        """(j, t, y) for u₁: the row of cells, the position in it and y."""
        rows, _ = self.shape
        j, remainder = select_with_remainder(self.marginal_cdf / self.marginal_cdf[-1], u1)
        low, high = self.running[j, -1], self.running[j + 1, -1]
        t = linear_quantile(remainder, low, high)[0]
        return j, t, (j.astype(t.dtype) + t) / rows

    def _column(self, j, t, target):
        """The cell i whose running integral at y brackets `target`, by bisection, and the bracket."""
        _, columns = self.shape
        lerp = lambda i: (1.0 - t) * self.running[j, i] + t * self.running[j + 1, i]  # noqa: E731
        low = jnp.zeros(target.shape, jnp.int32)
        high = jnp.full(target.shape, columns, jnp.int32)
        for _ in range(int(np.ceil(np.log2(columns + 1)))):
            middle = (low + high) // 2
            go_left = lerp(jnp.minimum(middle + 1, columns)) > target
            high = jnp.where(go_left, middle, high)
            low = jnp.where(go_left, low, middle + 1)
        i = jnp.clip(low, 0, columns - 1)
        return i, lerp(i), lerp(i + 1)

    def _vertex(self, j, t, i):
        return (1.0 - t) * self.values[j, i] + t * self.values[j + 1, i]

    @point_method
    def warp(self, u):
        _, columns = self.shape
        j, t, y = self._row_point(u[..., 1])
        total = (1.0 - t) * self.running[j, -1] + t * self.running[j + 1, -1]
        i, below, above = self._column(j, t, u[..., 0] * total)
        width = above - below
        remainder = jnp.clip((u[..., 0] * total - below) / jnp.where(width > 0, width, 1.0), 0.0,
                             one_minus_epsilon(u.dtype))
        s = linear_quantile(remainder, self._vertex(j, t, i), self._vertex(j, t, i + 1))[0]
        return jnp.stack([(i.astype(s.dtype) + s) / columns, y], axis=-1)

    def _locate(self, x):
        rows, columns = self.shape
        j = jnp.clip(jnp.floor(x[..., 1] * rows), 0, rows - 1).astype(jnp.int32)
        i = jnp.clip(jnp.floor(x[..., 0] * columns), 0, columns - 1).astype(jnp.int32)
        t = jnp.clip(x[..., 1] * rows - j, 0.0, 1.0)
        s = jnp.clip(x[..., 0] * columns - i, 0.0, 1.0)
        return j, i, t, s

    @point_method
    def pdf(self, x):
        j, i, t, s = self._locate(x)
        f = (1.0 - s) * self._vertex(j, t, i) + s * self._vertex(j, t, i + 1)
        inside = jnp.all((x >= 0) & (x <= 1), axis=-1)
        return jnp.where(inside, f / self.marginal_cdf[-1], 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        rows, _ = self.shape
        j, i, t, s = self._locate(x)
        before_row = jnp.where(j > 0, self.marginal_cdf[jnp.maximum(j - 1, 0)], 0.0)
        row_mass = (self.running[j, -1] + self.running[j + 1, -1]) / (2.0 * rows)
        within = linear_cdf(t, self.running[j, -1], self.running[j + 1, -1])
        u1 = (before_row + row_mass * within) / self.marginal_cdf[-1]
        lerp = lambda k: (1.0 - t) * self.running[j, k] + t * self.running[j + 1, k]  # noqa: E731
        total = lerp(-1)
        cell = lerp(i + 1) - lerp(i)
        u0 = (lerp(i) + cell * linear_cdf(s, self._vertex(j, t, i), self._vertex(j, t, i + 1)))
        u0 = u0 / jnp.where(total > 0, total, 1.0)
        return jnp.clip(jnp.stack([u0, u1], axis=-1), 0.0, 1.0)

    def domain(self):
        rows, columns = self.shape
        return Box.from_bounds([0.0, 0.0], [1.0, 1.0],
                               breaks=[np.linspace(0.0, 1.0, columns + 1), np.linspace(0.0, 1.0, rows + 1)])
