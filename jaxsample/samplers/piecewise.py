"""Piecewise-constant densities on [0, 1] and [0, 1]² (length and area measure).

The 2D form is what an environment map needs: a marginal over rows, then a conditional within the
chosen row (PBRT-v4 `PiecewiseConstant1D`/`PiecewiseConstant2D`; Pharr, Jakob & Humphreys,
*PBR* 4th ed., §A.5). Bins of value zero own empty CDF intervals and are never sampled.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.params import concrete_value
from .._core.pytree import parameter
from .discrete import (as_array, check_weights, normalized_tables, select_rows_with_remainder, valid_tables,
    select_with_remainder)
from .domain import Box, Interval


def cell_grid(rows: int, columns: int) -> Box:
    """[0, 1]² cut into rows x columns equal cells, integrated by the midpoint rule per cell: exact for
    a density constant on each cell (the piecewise-constant tables)."""
    return Box.from_bounds([0.0, 0.0], [1.0, 1.0],
                           breaks=[np.linspace(0.0, 1.0, columns + 1), np.linspace(0.0, 1.0, rows + 1)],
                           graded=False, order=1)


def _mean(values, dtype):
    """The mean of the values, in float64 NumPy when they are concrete."""
    concrete = concrete_value(values)
    if concrete is not None:
        return jnp.asarray(np.mean(np.asarray(concrete, np.float64)), dtype)
    return jnp.mean(jnp.asarray(values, dtype))


def _bin_index(x, n):
    """Bin of x in [0, 1] for n equal bins, as the warp places points: floor(x n), last bin closed."""
    return jnp.clip(jnp.floor(x * n), 0, n - 1).astype(jnp.int32)


def _place_in_bin(index, remainder, n):
    """x = (index + remainder) / n, nudged (at most two ulps) so that `_bin_index(x)` is `index`.

    (i + r)/n with r just below 1 can round up to the next bin's edge, and i/n times n can round
    down into the previous bin; a sample must never land in a neighbouring bin, which may have
    zero density.
    """
    return nudge_into_bin((index.astype(remainder.dtype) + remainder) / n, index, n)


def nudge_into_bin(x, index, n):
    """x moved by at most two ulps so that `_bin_index(x, n)` is `index` (x must lie within rounding
    of bin `index`). The nudge is a rounding correction: the derivative is x's."""
    nudged = jax.lax.stop_gradient(x)
    for _ in range(2):
        found = _bin_index(nudged, n)
        nudged = jnp.where(found > index, jnp.nextafter(nudged, jnp.zeros_like(x)),
                           jnp.where(found < index, jnp.nextafter(nudged, jnp.ones_like(x)), nudged))
    return x + jax.lax.stop_gradient(nudged - x)


def _in_unit_interval(x):
    return (x >= 0) & (x <= 1)


def _cdf_before(cdf, index):
    return jnp.where(index > 0, cdf[..., jnp.maximum(index - 1, 0)], 0.0)


class PiecewiseConstant1D(Sampler):
    """Density p(x) = K f_i / Σ f on bin i = [i/K, (i+1)/K) of [0, 1] (length measure), 0 outside.

    Warp: choose bin i from the CDF of f with u (`select_with_remainder`), then x = (i + r)/K with
    the remainder r — the inversion of the piecewise-linear CDF. Inverse: u = P_{i-1} + (xK - i) p_i.
    Values must be finite, >= 0 and not all zero (ValueError when concrete). Tables are built in
    float64 NumPy when the values are concrete, in JAX otherwise.
    """

    pmf: jax.Array = parameter(rank=1, doc="the bins' probabilities")
    cdf: jax.Array = parameter(rank=1)
    mean_value: jax.Array = parameter(doc="the mean of the values, their piecewise-constant function's integral")
    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "length"
    batchable: ClassVar = False

    def _parameters_valid(self):
        # Traced weights are checked here, as `check_weights` checks concrete ones: a normalised
        # table with a NaN entry (all-zero, negative or non-finite weights) is invalid.
        return valid_tables(self.pmf)

    def __init__(self, values):
        values = as_array(values)
        check_weights("PiecewiseConstant1D", "values", values)
        self.pmf, self.cdf = normalized_tables(values)
        self.mean_value = _mean(values, self.pmf.dtype)

    def __repr__(self):
        return f"PiecewiseConstant1D(size={self.size})"

    @property
    def size(self) -> int:
        return self.pmf.shape[-1]

    def integral(self) -> jax.Array:
        """∫₀¹ of the piecewise-constant function of the values (their mean): the density's normalization."""
        return self.mean_value

    @point_method
    def warp(self, u):
        index, remainder = select_with_remainder(self.cdf, u[..., 0])
        return _place_in_bin(index, remainder, self.size)

    @point_method
    def pdf(self, x):
        n = self.size
        return jnp.where(_in_unit_interval(x), n * self.pmf[_bin_index(x, n)], 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        n = self.size
        index = _bin_index(x, n)
        u = _cdf_before(self.cdf, index) + (x * n - index) * self.pmf[index]
        return jnp.clip(u, 0.0, 1.0)[..., None]

    def domain(self):
        # Midpoints of the bins integrate a piecewise-constant density exactly.
        return Interval(0.0, 1.0, breaks=np.linspace(0.0, 1.0, self.size + 1), graded=False, order=1)


class PiecewiseConstant2D(Sampler):
    """Density p(x, y) = f[j, i] / mean(f) on [0, 1]² (area measure): row j covers y in
    [j/R, (j+1)/R), column i covers x in [i/C, (i+1)/C) for `values` of shape (R, C).

    Warp (PBRT-v4 convention): u₁ chooses the row from the marginal (row sums), its remainder
    places y; u₀ chooses the column from that row's conditional CDF, its remainder places x.
    pdf = marginal × conditional × R C. The inverse runs the same steps backwards.
    For an environment map pass the image's luminance times sin θ of each row and divide the area
    density by 2π² sin θ to get a solid-angle density.
    """

    marginal_pmf: jax.Array = parameter(rank=1, doc="the rows' probabilities")
    marginal_cdf: jax.Array = parameter(rank=1)
    conditional_pmf: jax.Array = parameter(rank=2, doc="each row's columns' probabilities")
    conditional_cdf: jax.Array = parameter(rank=2)
    mean_value: jax.Array = parameter(doc="the mean of the values, their piecewise-constant function's integral")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (2,)
    measure: ClassVar = "area"
    batchable: ClassVar = False

    def _parameters_valid(self):
        # Traced weights are checked here, as `check_weights` checks concrete ones: a normalised
        # table with a NaN entry (all-zero, negative or non-finite weights) is invalid.
        return valid_tables(self.marginal_pmf, self.conditional_pmf)

    def __init__(self, values):
        values = as_array(values)
        check_weights("PiecewiseConstant2D", "values", values, ndim=2)
        v = concrete_value(values)
        self.marginal_pmf, self.marginal_cdf = normalized_tables(
            v.sum(axis=-1) if v is not None else jnp.sum(jnp.asarray(values), axis=-1))
        self.conditional_pmf, self.conditional_cdf = normalized_tables(values)
        self.mean_value = _mean(values, self.marginal_pmf.dtype)

    def integral(self) -> jax.Array:
        """∫∫ over [0, 1]² of the piecewise-constant function of the values (their mean): the density's
        normalization."""
        return self.mean_value

    @property
    def shape(self) -> tuple[int, int]:
        return self.conditional_pmf.shape[-2:]

    def __repr__(self):
        return f"PiecewiseConstant2D(shape={self.shape})"

    @point_method
    def warp(self, u):
        rows, columns = self.shape
        row, remainder_y = select_with_remainder(self.marginal_cdf, u[..., 1])
        column, remainder_x = select_rows_with_remainder(self.conditional_cdf, row, u[..., 0])
        return jnp.stack([_place_in_bin(column, remainder_x, columns), _place_in_bin(row, remainder_y, rows)], axis=-1)

    @point_method
    def pdf(self, x):
        rows, columns = self.shape
        row = _bin_index(x[..., 1], rows)
        column = _bin_index(x[..., 0], columns)
        inside = _in_unit_interval(x[..., 0]) & _in_unit_interval(x[..., 1])
        density = rows * columns * self.marginal_pmf[row] * self.conditional_pmf[row, column]
        return jnp.where(inside, density, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        rows, columns = self.shape
        row = _bin_index(x[..., 1], rows)
        column = _bin_index(x[..., 0], columns)
        u1 = _cdf_before(self.marginal_cdf, row) + (x[..., 1] * rows - row) * self.marginal_pmf[row]
        before = jnp.where(column > 0, self.conditional_cdf[row, jnp.maximum(column - 1, 0)], 0.0)
        u0 = before + (x[..., 0] * columns - column) * self.conditional_pmf[row, column]
        return jnp.clip(jnp.stack([u0, u1], axis=-1), 0.0, 1.0)

    def domain(self):
        return cell_grid(*self.shape)
