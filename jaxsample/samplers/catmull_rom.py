"""A density on an interval given by a Catmull-Rom spline through tabulated values (length measure):
smooth where a piecewise-linear table has kinks, as PBRT-v4 uses it for measured scattering tables.

`CatmullRom1D(nodes, values)` interpolates f(x_k) = v_k at increasing nodes x_0 < ... < x_{N-1}
with PBRT-v4's Catmull-Rom spline (`CatmullRomWeights`, `IntegrateCatmullRom`, `SampleCatmullRom`):
on segment k, with width w = x_{k+1} - x_k and t = (x - x_k)/w, f is the cubic Hermite polynomial
with end values v_k, v_{k+1} and end slopes (in t) d_k = w m_k, d_{k+1} = w m_{k+1}, where the slope
in x at a node is the centred difference m_k = (v_{k+1} - v_{k-1})/(x_{k+1} - x_{k-1}) and the
one-sided difference at the first and last node. The spline is C¹ across nodes.
"""

from __future__ import annotations

from typing import ClassVar, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._core.numerics import clamp_rounding
from .._core.params import concrete_value
from .._core.pytree import parameter
from .base import Sampler, over_members, point_method
from .discrete import as_array, search_right, select_with_remainder
from .domain import Interval
from .polynomial import linear_quantile

# Newton-bisection steps of the inversion within a segment, from the quantile of the segment's
# linear interpolant. Where the density is positive Newton converges quadratically in a few steps;
# where it touches 0 inside the segment the root is triple and bisection takes over (`_Spline.solve`).
# 12 steps invert both to rounding in float64 (round trips within 2e-14 over random tables and
# 9e-15 on a spline that touches 0; 8 left 1e-6).
_NEWTON_STEPS = 12


def _slopes(xp, nodes, values):
    """m_k, the spline's slope in x at each node: centred differences inside, one-sided at the ends
    (values along axis 0, any trailing axes)."""
    nodes = nodes.reshape(nodes.shape + (1,) * (values.ndim - 1))
    if nodes.shape[-1] == 2:
        slope = (values[1] - values[0]) / (nodes[1] - nodes[0])
        return xp.stack([slope, slope])
    first = (values[1] - values[0]) / (nodes[1] - nodes[0])
    last = (values[-1] - values[-2]) / (nodes[-1] - nodes[-2])
    inner = (values[2:] - values[:-2]) / (nodes[2:] - nodes[:-2])
    return xp.concatenate([first[None], inner, last[None]])


def _hermite(f0, f1, d0, d1):
    """Coefficients (a0, a1, a2, a3) of the cubic in t with values f0, f1 and slopes d0, d1 at t = 0, 1."""
    return f0, d0, 3.0 * (f1 - f0) - 2.0 * d0 - d1, 2.0 * (f0 - f1) + d0 + d1


def _segment_integrals(xp, nodes, values, slopes):
    """∫ f over each segment: w ((v_k + v_{k+1})/2 + (d_k − d_{k+1})/12), the cubic's exact integral."""
    width = nodes[1:] - nodes[:-1]
    return width * (0.5 * (values[:-1] + values[1:]) + width * (slopes[:-1] - slopes[1:]) / 12.0)


def _minimum(nodes, values):
    """(min f, where) of the spline of each row of `values` (..., N), in float64 NumPy: each cubic at
    its segment's ends and at the zeros of its derivative 3a₃t² + 2a₂t + a₁ inside the segment."""
    width = np.diff(nodes)
    slopes = np.moveaxis(_slopes(np, nodes, np.moveaxis(values, -1, 0)), 0, -1)
    a0, a1, a2, a3 = _hermite(values[..., :-1], values[..., 1:], width * slopes[..., :-1], width * slopes[..., 1:])
    discriminant = a2 * a2 - 3.0 * a3 * a1
    root = np.sqrt(np.maximum(discriminant, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        cubic = (a3 != 0) & (discriminant >= 0)
        first = np.where(cubic, (-a2 + root) / (3.0 * a3), np.where((a3 == 0) & (a2 != 0), -a1 / (2.0 * a2), -1.0))
        second = np.where(cubic, (-a2 - root) / (3.0 * a3), -1.0)
    t = np.stack([np.zeros_like(a0), np.ones_like(a0), first, second], axis=-1)
    f = a0[..., None] + t * (a1[..., None] + t * (a2[..., None] + t * a3[..., None]))
    f = np.where((t >= 0) & (t <= 1), f, np.inf).reshape(f.shape[:-2] + (-1,))
    best = np.argmin(f, axis=-1)
    segment = best // 4
    where = nodes[segment] + np.take_along_axis(t.reshape(f.shape), best[..., None], -1)[..., 0] * width[segment]
    return np.take_along_axis(f, best[..., None], -1)[..., 0], where


def _check_nodes(owner: str, name: str, nodes) -> None:
    """ValueError unless `nodes` holds at least 2 positions, finite and strictly increasing (when concrete)."""
    if nodes.ndim != 1 or nodes.size < 2:
        raise ValueError(f"{owner}: parameter '{name}' must hold at least 2 nodes in one dimension; got shape "
                         f"{nodes.shape}")
    concrete = concrete_value(nodes)
    if concrete is not None:
        concrete = np.asarray(concrete, np.float64)
        if not (np.all(np.isfinite(concrete)) and np.all(np.diff(concrete) > 0)):
            raise ValueError(f"{owner}: parameter '{name}' must be finite and strictly increasing; got {concrete}")


def _check(nodes, values, owner: str = "CatmullRom1D", name: str = "values") -> None:
    """ValueError, naming the parameter, for tables no density can be made of (concrete ones only)."""
    if nodes.ndim != 1 or nodes.shape != values.shape:
        raise ValueError(f"{owner}: parameters 'nodes' and '{name}' must be 1-D of one length; got shapes "
                         f"{nodes.shape} and {values.shape}")
    _check_nodes(owner, "nodes", nodes)
    nodes_c, values_c = concrete_value(nodes), concrete_value(values)
    if values_c is not None:
        values_c = np.asarray(values_c, np.float64)
        if not (np.all(np.isfinite(values_c)) and np.all(values_c >= 0) and np.any(values_c > 0)):
            raise ValueError(f"{owner}: parameter '{name}' must be finite, >= 0 and not all 0; got {values_c}")
    if nodes_c is not None and values_c is not None:
        lowest, where = _minimum(np.asarray(nodes_c, np.float64), values_c)
        if lowest < -1e-12 * values_c.max():
            raise ValueError(f"{owner}: parameter '{name}' makes a spline that dips below 0 (to {lowest:.3g} "
                             f"at x = {where:.6g}), which is no density; Catmull-Rom overshoots next to a jump "
                             f"to 0: add nodes there or use a piecewise-linear table")


def _tables(nodes, values, dtype):
    """(slopes, cdf) of the spline in `dtype`, computed in float64 NumPy when nodes and values are concrete."""
    nodes_c, values_c = concrete_value(nodes), concrete_value(values)
    if nodes_c is not None and values_c is not None:
        nodes_c, values_c = np.asarray(nodes_c, np.float64), np.asarray(values_c, np.float64)
        slopes = _slopes(np, nodes_c, values_c)
        cdf = np.cumsum(_segment_integrals(np, nodes_c, values_c, slopes))
        return jnp.asarray(slopes, dtype), jnp.asarray(cdf, dtype)
    nodes, values = jnp.asarray(nodes, dtype), jnp.asarray(values, dtype)
    slopes = _slopes(jnp, nodes, values)
    return slopes, jnp.cumsum(_segment_integrals(jnp, nodes, values, slopes))


@jax.custom_jvp
def _derivative_only(y):
    """0, with the derivative of y: adds a derivative to a value without changing the value."""
    return jnp.zeros_like(y)


@_derivative_only.defjvp
def _derivative_only_jvp(primals, tangents):
    return jnp.zeros_like(primals[0]), tangents[0]


class _Spline(NamedTuple):
    """One spline's arrays and the density they make: what `CatmullRom1D` and each row of
    `CatmullRom2D` sample."""

    nodes: jax.Array
    values: jax.Array
    slopes: jax.Array
    cdf: jax.Array

    def segment(self, k):
        """(x_k, w, a0, a1, a2, a3) of segment k: its start, width and cubic in t."""
        start, width = self.nodes[k], self.nodes[k + 1] - self.nodes[k]
        return (start, width, *_hermite(self.values[k], self.values[k + 1], width * self.slopes[k],
                                        width * self.slopes[k + 1]))

    def cdf_at(self, k, t):
        """C(x) for x = x_k + w t in segment k: the mass before the segment plus F_k(t), over ∫f."""
        _, width, a0, a1, a2, a3 = self.segment(k)
        before = jnp.where(k > 0, self.cdf[jnp.maximum(k - 1, 0)], 0.0)
        within = width * t * (a0 + t * (a1 / 2.0 + t * (a2 / 3.0 + t * a3 / 4.0)))
        return (before + within) / self.cdf[-1]

    def locate(self, x):
        """(k, t): the segment holding x (the last one for x = x_{N-1}) and the position in it, in [0, 1]."""
        k = jnp.clip(search_right(self.nodes, x) - 1, 0, self.nodes.shape[-1] - 2)
        start, width = self.nodes[k], self.nodes[k + 1] - self.nodes[k]
        return k, clamp_rounding((x - start) / width, 0.0, 1.0)

    def solve(self, k, r):
        """t in [0, 1] with F_k(t) = r F_k(1), by Newton-bisection (no derivatives flow through it).

        An iterate whose residual is within rounding of 0 is final: there the residual's sign is
        noise, and a bracket or bisection step taken on it would move t away from the root."""
        _, _, a0, a1, a2, a3 = jax.tree_util.tree_map(jax.lax.stop_gradient, self.segment(k))
        r = jax.lax.stop_gradient(r)
        target = r * (a0 + a1 / 2.0 + a2 / 3.0 + a3 / 4.0)
        noise = 8.0 * jnp.finfo(target.dtype).eps * (jnp.abs(a0) + jnp.abs(a1) + jnp.abs(a2) + jnp.abs(a3))
        t = linear_quantile(r, a0, a0 + a1 + a2 + a3)[0]
        def newton_or_bisection(_, state):
            t, low, high, done, last = state
            excess = t * (a0 + t * (a1 / 2.0 + t * (a2 / 3.0 + t * a3 / 4.0))) - target
            density = a0 + t * (a1 + t * (a2 + t * a3))
            done = done | (jnp.abs(excess) <= noise)
            low, high = jnp.where(excess < 0, t, low), jnp.where(excess < 0, high, t)
            newton = t - excess / jnp.where(density > 0, density, 1.0)
            # Newton's step is taken while it stays in the bracket and at most half the last step;
            # otherwise bisection, which halves the bracket where Newton is slow (a density that
            # touches 0 makes the root triple: Newton's error only falls by 2/3 a step there).
            fast = (density > 0) & (newton >= low) & (newton <= high) & (2.0 * jnp.abs(newton - t) <= last)
            step = jnp.where(fast, newton, 0.5 * (low + high))
            return jnp.where(done, t, step), low, high, done, jnp.abs(step - t)

        start = (t, jnp.zeros_like(t), jnp.ones_like(t), jnp.zeros(t.shape, bool), jnp.ones_like(t))
        return jax.lax.fori_loop(0, _NEWTON_STEPS, newton_or_bisection, start)[0]

    def warp_with_pdf(self, u0):
        k, r = select_with_remainder(self.cdf / self.cdf[-1], u0)
        t = self.solve(k, r)
        start, width, a0, a1, a2, a3 = self.segment(k)
        # The implicit function C(x) = u: with t held, x = x_k + w t moves with the nodes, and the
        # correction −(∂C at fixed t − du)/p adds what C(x) = u asks beyond that; its value is 0.
        residual = _derivative_only(self.cdf_at(k, t) - u0)
        p = jax.lax.stop_gradient(a0 + t * (a1 + t * (a2 + t * a3))) / jax.lax.stop_gradient(self.cdf[-1])
        correction = jnp.where(p > 0, residual / jnp.where(p > 0, p, 1.0), 0.0)
        x = clamp_rounding(start + width * t - correction, self.nodes[0], self.nodes[-1])
        s = (x - start) / width  # t again, carrying x's derivatives into the density
        density = (a0 + s * (a1 + s * (a2 + s * a3))) / self.cdf[-1]
        return x, jnp.maximum(density, 0.0)

    def pdf(self, x):
        k, t = self.locate(x)
        _, _, a0, a1, a2, a3 = self.segment(k)
        inside = (x >= self.nodes[0]) & (x <= self.nodes[-1])
        f = jnp.maximum(a0 + t * (a1 + t * (a2 + t * a3)), 0.0)
        return jnp.where(inside, f / self.cdf[-1], 0.0).astype(jnp.result_type(x, float))

    def inverse(self, x):
        k, t = self.locate(x)
        return clamp_rounding(self.cdf_at(k, t), 0.0, 1.0)[..., None]

    def valid(self):
        """The traced checks: finite nodes in order, finite values >= 0, segments of mass >= 0, some mass."""
        segments = _segment_integrals(jnp, self.nodes, self.values, self.slopes)
        return (jnp.all(jnp.isfinite(self.nodes) & jnp.isfinite(self.values) & (self.values >= 0))
                & jnp.all(self.nodes[1:] > self.nodes[:-1]) & jnp.all(segments >= 0) & (self.cdf[-1] > 0))


def _interval(owner, nodes):
    nodes = concrete_value(nodes)
    if nodes is None:
        raise ValueError(f"{owner}.domain: needs concrete 'nodes'")
    nodes = np.asarray(nodes, np.float64)
    return Interval(float(nodes[0]), float(nodes[-1]), breaks=nodes[1:-1], graded=False)


class _SplineDensity(Sampler):
    """What the two spline densities share: one spline over the nodes (`_spline()`, the subclass's),
    sampled, evaluated and inverted as `_Spline` does, over the length measure."""

    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "length"

    def _spline(self) -> _Spline:
        raise NotImplementedError

    @point_method
    def warp(self, u):
        return self._spline().warp_with_pdf(u[..., 0])[0]

    @point_method
    def warp_with_pdf(self, u):
        return self._spline().warp_with_pdf(u[..., 0])

    @point_method
    def pdf(self, x):
        return self._spline().pdf(x)

    @point_method
    def inverse(self, x):
        return self._spline().inverse(x)

    def domain(self):
        return _interval(type(self).__name__, self.nodes)


class CatmullRom1D(_SplineDensity):
    """p(x) = f(x) / ∫f on [x_0, x_{N-1}] (length measure), 0 outside, f the Catmull-Rom spline
    through (`nodes`, `values`) described in the module docstring (PBRT-v4 `SampleCatmullRom`).

    Warp: u chooses segment k by the segments' exact integrals (`select_with_remainder`), then t
    solves F_k(t) = r F_k(1) for the remainder r, F_k(t) = ∫₀ᵗ f = w (a₀t + a₁t²/2 + a₂t³/3 + a₃t⁴/4)
    for the cubic's coefficients a, by Newton-bisection from the quantile of the linear interpolant
    (as PBRT-v4 does); x = x_k + w t. The derivatives of x, in u and in the table, are those of the
    implicit function C(x) = u, C the CDF: dx = (du − ∂C)/p(x), not those of the iteration.
    Inverse: C(x) in closed form. `integral()` is ∫f. Nodes must be finite and strictly increasing,
    values finite, >= 0, not all 0, and the spline must not dip below 0 (ValueError when concrete;
    a traced table with nodes out of order or values below 0 gives NaN; a traced spline's dip below 0
    between nodes is not detected, and its density is clamped to 0 there).
    """

    nodes: jax.Array = parameter(rank=1, doc="x_0 < ... < x_{N-1}, where the values are given")
    values: jax.Array = parameter(rank=1, doc="f(x_k) >= 0")
    slopes: jax.Array = parameter(rank=1)
    cdf: jax.Array = parameter(rank=1)
    batchable: ClassVar = False

    def __init__(self, nodes, values):
        nodes, values = as_array(nodes), as_array(values)
        _check(nodes, values)
        dtype = jnp.result_type(nodes, values, float)
        self.nodes, self.values = jnp.asarray(nodes, dtype), jnp.asarray(values, dtype)
        self.slopes, self.cdf = _tables(nodes, values, dtype)

    def __repr__(self):
        return f"CatmullRom1D(nodes={self.nodes.shape[-1]})"

    def _spline(self):
        return _Spline(self.nodes, self.values, self.slopes, self.cdf)

    def _parameters_valid(self):
        return self._spline().valid()

    def integral(self) -> jax.Array:
        """∫ f over [x_0, x_{N-1}], f the spline (the density's normalization); NaN for an invalid
        traced table."""
        return jnp.where(self._parameters_valid(), self.cdf[-1], jnp.nan)


def _row_at(alpha_nodes, values, alpha):
    """f(α, x_k) for every k: the rows' Catmull-Rom interpolation at α (the spline of each column
    through (α_j, values[j, k]), PBRT-v4 `CatmullRomWeights`), from the four rows around α."""
    last = alpha_nodes.shape[-1] - 1
    j = jnp.clip(search_right(alpha_nodes, alpha) - 1, 0, last - 1)
    before, after = jnp.maximum(j - 1, 0), jnp.minimum(j + 2, last)
    width = alpha_nodes[j + 1] - alpha_nodes[j]
    # Slopes in α at α_j and α_{j+1}: centred differences inside, one-sided at the first and last node.
    slope0 = (values[j + 1] - values[before]) / (alpha_nodes[j + 1] - alpha_nodes[before])
    slope1 = (values[after] - values[j]) / (alpha_nodes[after] - alpha_nodes[j])
    t = clamp_rounding((alpha - alpha_nodes[j]) / width, 0.0, 1.0)
    a0, a1, a2, a3 = _hermite(values[j], values[j + 1], width * slope0, width * slope1)
    return a0 + t * (a1 + t * (a2 + t * a3))


class CatmullRom2D(_SplineDensity):
    """p(x | α) = f(α, x) / ∫ f(α, x') dx' on [x_0, x_{N-1}] (length measure, over x at the fixed
    `alpha`), 0 outside: the conditional of a table f(α_j, x_k) = values[j, k] interpolated by the
    Catmull-Rom spline in α and then in x (PBRT-v4 `SampleCatmullRom2D`, which samples measured
    BSDF tables along one coordinate given another).

    At α the rows' values are interpolated column by column (the spline of `CatmullRom1D` through
    (α_j, values[j, k])), and the result is sampled, inverted and integrated as `CatmullRom1D` does,
    derivatives in α included (the implicit function C(x; α) = u). `alpha` may carry a batch (one
    conditional per α, the table shared). Rows as `CatmullRom1D`'s values; α within
    [α_0, α_{A-1}]; the interpolated row must be >= 0 with a spline that does not dip below 0: a
    Catmull-Rom spline overshoots between rows too (ValueError when concrete; NaN for an α out of
    range or a row below 0 when traced; a traced dip between nodes is clamped to 0).
    """

    alpha_nodes: jax.Array = parameter(rank=1, doc="α_0 < ... < α_{A-1}, the rows' parameters")
    nodes: jax.Array = parameter(rank=1, doc="x_0 < ... < x_{N-1}, the columns' positions")
    values: jax.Array = parameter(rank=2, doc="f(α_j, x_k) >= 0, shape (A, N)")
    alpha: jax.Array = parameter(doc="the α the density is conditioned on, within [α_0, α_{A-1}]")

    def __init__(self, alpha_nodes, nodes, values, alpha):
        alpha_nodes, nodes, values = as_array(alpha_nodes), as_array(nodes), as_array(values)
        if values.ndim != 2 or alpha_nodes.ndim != 1 or values.shape != (alpha_nodes.shape[-1], nodes.shape[-1]):
            raise ValueError(f"CatmullRom2D: parameter 'values' must have shape (len(alpha_nodes), len(nodes)) = "
                             f"({alpha_nodes.shape[-1]}, {nodes.shape[-1]}); got {values.shape}")
        _check_nodes("CatmullRom2D", "alpha_nodes", alpha_nodes)
        _check_nodes("CatmullRom2D", "nodes", nodes)
        rows = concrete_value(values)
        if rows is not None and not (np.all(np.isfinite(rows)) and np.all(np.asarray(rows) >= 0)):
            raise ValueError(f"CatmullRom2D: parameter 'values' must be finite and >= 0; got {rows}")
        dtype = jnp.result_type(alpha_nodes, nodes, values, float)
        self.alpha_nodes, self.nodes = jnp.asarray(alpha_nodes, dtype), jnp.asarray(nodes, dtype)
        self.values, self.alpha = jnp.asarray(values, dtype), alpha
        grid, at = concrete_value(alpha_nodes), concrete_value(alpha)
        if grid is not None and at is not None:
            at = np.ravel(np.asarray(at, np.float64))
            grid = np.asarray(grid, np.float64)
            if not np.all((at >= grid[0]) & (at <= grid[-1])):
                raise ValueError(f"CatmullRom2D: parameter 'alpha' must lie in [{grid[0]}, {grid[-1]}] (the rows' "
                                 f"alpha_nodes); got {at}")
            columns = concrete_value(nodes)
            if rows is not None and columns is not None:
                self._check_rows(np.asarray(columns, np.float64), np.asarray(rows, np.float64), grid, at)

    @staticmethod
    def _check_rows(nodes, rows, grid, alphas):
        """ValueError if the row interpolated at some α has no mass or a spline that dips below 0."""
        interpolated = np.asarray(jax.vmap(lambda a: _row_at(jnp.asarray(grid), jnp.asarray(rows), a))(
            jnp.asarray(alphas)))
        lowest, where = _minimum(nodes, interpolated)
        scale = np.max(np.abs(rows))
        worst = int(np.argmin(lowest))
        if lowest[worst] < -1e-12 * scale:
            raise ValueError(f"CatmullRom2D: parameter 'values' interpolated at alpha = {alphas[worst]:.6g} makes a "
                             f"spline that dips below 0 (to {lowest[worst]:.3g} at x = {where[worst]:.6g}), which is "
                             f"no density: a Catmull-Rom spline overshoots next to a jump to 0, between rows as "
                             f"between columns; add rows or nodes there")
        empty = ~np.any(interpolated > 0, axis=-1)
        if np.any(empty):
            raise ValueError(f"CatmullRom2D: parameter 'values' interpolated at alpha = "
                             f"{alphas[int(np.argmax(empty))]:.6g} is 0 everywhere: no density")

    def __repr__(self):
        return f"CatmullRom2D(shape={self.values.shape[-2:]})"

    def _spline(self):
        row = _row_at(self.alpha_nodes, self.values, self.alpha)
        return _Spline(self.nodes, row, *_tables(self.nodes, row, row.dtype))

    def _parameters_valid(self):
        if self.batch_shape:
            return jnp.all(over_members(lambda member: member._parameters_valid(), self))
        inside = (self.alpha >= self.alpha_nodes[0]) & (self.alpha <= self.alpha_nodes[-1])
        ordered = jnp.all(self.alpha_nodes[1:] > self.alpha_nodes[:-1])
        declared = super()._parameters_valid()
        valid = inside & ordered & self._spline().valid()
        return valid if declared is None else declared & valid

    def integral(self) -> jax.Array:
        """∫ f(α, x) dx over [x_0, x_{N-1}] at this α (the conditional density's normalization), one
        per member of a batch of α; NaN for a traced α out of range."""
        if self.batch_shape:
            return over_members(lambda member: member.integral(), self)
        return jnp.where(self._parameters_valid(), self._spline().cdf[-1], jnp.nan)

