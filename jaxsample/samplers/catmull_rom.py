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

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.params import concrete_value
from .._core.pytree import parameter
from .base import Sampler, point_method
from .discrete import as_array, search_right, select_with_remainder
from .domain import Interval
from .polynomial import linear_quantile

# Newton-bisection steps of the inversion within a segment. The start (the quantile of the segment's
# linear interpolant) is within a few per cent of the root; Newton then converges quadratically, and a
# step that leaves the bracket is replaced by bisection, so the iteration cannot diverge.
_NEWTON_STEPS = 8


@jax.custom_jvp
def _derivative_only(y):
    """0, with the derivative of y: adds a derivative to a value without changing the value."""
    return jnp.zeros_like(y)


@_derivative_only.defjvp
def _derivative_only_jvp(primals, tangents):
    return jnp.zeros_like(primals[0]), tangents[0]


def _slopes(xp, nodes, values):
    """m_k, the spline's slope in x at each node: centred differences inside, one-sided at the ends."""
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


def _minimum(nodes, values, slopes):
    """(min f, where) over the spline, in float64 NumPy: each cubic at its segment's ends and at the
    zeros of its derivative inside the segment."""
    width = np.diff(nodes)
    a0, a1, a2, a3 = _hermite(values[:-1], values[1:], width * slopes[:-1], width * slopes[1:])
    best, where = float(values.min()), float(nodes[np.argmin(values)])
    for k in range(width.size):
        for root in np.roots([3.0 * a3[k], 2.0 * a2[k], a1[k]]) if (a3[k] or a2[k]) else ():
            if abs(root.imag) < 1e-12 and 0.0 < root.real < 1.0:
                t = root.real
                value = a0[k] + t * (a1[k] + t * (a2[k] + t * a3[k]))
                if value < best:
                    best, where = float(value), float(nodes[k] + t * width[k])
    return best, where


def _check(nodes, values) -> None:
    """ValueError, naming the parameter, for tables no density can be made of (concrete ones only)."""
    if nodes.ndim != 1 or nodes.shape != values.shape:
        raise ValueError(f"CatmullRom1D: parameters 'nodes' and 'values' must be 1-D of one length; got shapes "
                         f"{nodes.shape} and {values.shape}")
    if nodes.size < 2:
        raise ValueError(f"CatmullRom1D: parameter 'nodes' must hold at least 2 nodes; got {nodes.size}")
    nodes_c, values_c = concrete_value(nodes), concrete_value(values)
    if nodes_c is not None:
        nodes_c = np.asarray(nodes_c, np.float64)
        if not (np.all(np.isfinite(nodes_c)) and np.all(np.diff(nodes_c) > 0)):
            raise ValueError(f"CatmullRom1D: parameter 'nodes' must be finite and strictly increasing; got {nodes_c}")
    if values_c is not None:
        values_c = np.asarray(values_c, np.float64)
        if not (np.all(np.isfinite(values_c)) and np.all(values_c >= 0) and np.any(values_c > 0)):
            raise ValueError(f"CatmullRom1D: parameter 'values' must be finite, >= 0 and not all 0; got {values_c}")
    if nodes_c is not None and values_c is not None:
        lowest, where = _minimum(nodes_c, values_c, _slopes(np, nodes_c, values_c))
        if lowest < -1e-12 * values_c.max():
            raise ValueError(f"CatmullRom1D: parameter 'values' makes a spline that dips below 0 (to {lowest:.3g} "
                             f"at x = {where:.6g}), which is no density; Catmull-Rom overshoots next to a jump "
                             f"to 0: add nodes there or use a piecewise-linear table")


class CatmullRom1D(Sampler):
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
    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "length"
    batchable: ClassVar = False

    def __init__(self, nodes, values):
        nodes, values = as_array(nodes), as_array(values)
        _check(nodes, values)
        dtype = jnp.result_type(nodes, values, float)
        nodes_c, values_c = concrete_value(nodes), concrete_value(values)
        self.nodes, self.values = jnp.asarray(nodes, dtype), jnp.asarray(values, dtype)
        if nodes_c is not None and values_c is not None:  # the tables in float64, as the other tables'
            nodes_c, values_c = np.asarray(nodes_c, np.float64), np.asarray(values_c, np.float64)
            slopes = _slopes(np, nodes_c, values_c)
            self.slopes = jnp.asarray(slopes, dtype)
            self.cdf = jnp.asarray(np.cumsum(_segment_integrals(np, nodes_c, values_c, slopes)), dtype)
        else:
            self.slopes = _slopes(jnp, self.nodes, self.values)
            self.cdf = jnp.cumsum(_segment_integrals(jnp, self.nodes, self.values, self.slopes))

    def __repr__(self):
        return f"CatmullRom1D(nodes={self.nodes.shape[-1]})"

    def _parameters_valid(self):
        segments = _segment_integrals(jnp, self.nodes, self.values, self.slopes)
        return (jnp.all(jnp.isfinite(self.nodes) & jnp.isfinite(self.values) & (self.values >= 0))
                & jnp.all(self.nodes[1:] > self.nodes[:-1]) & jnp.all(segments >= 0) & (self.cdf[-1] > 0))

    def integral(self) -> jax.Array:
        """∫ f over [x_0, x_{N-1}], f the spline (the density's normalization)."""
        return self.cdf[-1]

    def _segment(self, k):
        """(x_k, w, a0, a1, a2, a3) of segment k: its start, width and cubic in t."""
        start, width = self.nodes[k], self.nodes[k + 1] - self.nodes[k]
        return (start, width, *_hermite(self.values[k], self.values[k + 1], width * self.slopes[k],
                                        width * self.slopes[k + 1]))

    def _cdf_at(self, k, t):
        """C(x) for x = x_k + w t in segment k: the mass before the segment plus F_k(t), over ∫f."""
        _, width, a0, a1, a2, a3 = self._segment(k)
        before = jnp.where(k > 0, self.cdf[jnp.maximum(k - 1, 0)], 0.0)
        within = width * t * (a0 + t * (a1 / 2.0 + t * (a2 / 3.0 + t * a3 / 4.0)))
        return (before + within) / self.cdf[-1]

    def _locate(self, x):
        """(k, t): the segment holding x (the last one for x = x_{N-1}) and the position in it, in [0, 1]."""
        k = jnp.clip(search_right(self.nodes, x) - 1, 0, self.nodes.shape[-1] - 2)
        start, width = self.nodes[k], self.nodes[k + 1] - self.nodes[k]
        return k, jnp.clip((x - start) / width, 0.0, 1.0)

    def _solve(self, k, r):
        """t in [0, 1] with F_k(t) = r F_k(1), by Newton-bisection (no derivatives flow through it).

        An iterate whose residual is within rounding of 0 is final: there the residual's sign is
        noise, and a bracket or bisection step taken on it would move t away from the root."""
        _, _, a0, a1, a2, a3 = jax.tree_util.tree_map(jax.lax.stop_gradient, self._segment(k))
        r = jax.lax.stop_gradient(r)
        target = r * (a0 + a1 / 2.0 + a2 / 3.0 + a3 / 4.0)
        noise = 8.0 * jnp.finfo(target.dtype).eps * (jnp.abs(a0) + jnp.abs(a1) + jnp.abs(a2) + jnp.abs(a3))
        t = linear_quantile(r, a0, a0 + a1 + a2 + a3)[0]
        low, high = jnp.zeros_like(t), jnp.ones_like(t)
        done = jnp.zeros(t.shape, bool)
        for _ in range(_NEWTON_STEPS):
            excess = t * (a0 + t * (a1 / 2.0 + t * (a2 / 3.0 + t * a3 / 4.0))) - target
            density = a0 + t * (a1 + t * (a2 + t * a3))
            done = done | (jnp.abs(excess) <= noise)
            low, high = jnp.where(excess < 0, t, low), jnp.where(excess < 0, high, t)
            step = t - excess / jnp.where(density > 0, density, 1.0)
            step = jnp.where((density > 0) & (step >= low) & (step <= high), step, 0.5 * (low + high))
            t = jnp.where(done, t, step)
        return t

    @point_method
    def warp(self, u):
        return self.warp_with_pdf(u)[0]

    @point_method
    def warp_with_pdf(self, u):
        u0 = u[..., 0]
        k, r = select_with_remainder(self.cdf / self.cdf[-1], u0)
        t = self._solve(k, r)
        start, width, a0, a1, a2, a3 = self._segment(k)
        # The implicit function C(x) = u: with t held, x = x_k + w t moves with the nodes, and the
        # correction −(∂C at fixed t − du)/p adds what C(x) = u asks beyond that; its value is 0.
        residual = _derivative_only(self._cdf_at(k, t) - u0)
        p = jax.lax.stop_gradient(a0 + t * (a1 + t * (a2 + t * a3))) / jax.lax.stop_gradient(self.cdf[-1])
        correction = jnp.where(p > 0, residual / jnp.where(p > 0, p, 1.0), 0.0)
        x = jnp.clip(start + width * t - correction, self.nodes[0], self.nodes[-1])
        s = (x - start) / width  # t again, carrying x's derivatives into the density
        density = (a0 + s * (a1 + s * (a2 + s * a3))) / self.cdf[-1]
        return x, jnp.maximum(density, 0.0)

    @point_method
    def pdf(self, x):
        k, t = self._locate(x)
        _, _, a0, a1, a2, a3 = self._segment(k)
        inside = (x >= self.nodes[0]) & (x <= self.nodes[-1])
        f = jnp.maximum(a0 + t * (a1 + t * (a2 + t * a3)), 0.0)
        return jnp.where(inside, f / self.cdf[-1], 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        k, t = self._locate(x)
        return jnp.clip(self._cdf_at(k, t), 0.0, 1.0)[..., None]

    def domain(self):
        nodes = concrete_value(self.nodes)
        if nodes is None:
            raise ValueError("CatmullRom1D.domain: needs concrete 'nodes'")
        nodes = np.asarray(nodes, np.float64)
        return Interval(float(nodes[0]), float(nodes[-1]), breaks=nodes[1:-1], graded=False)
