"""Layer 1: elementary functions that stay finite, in value *and* derivative, at domain edges.

Every function here follows one rule: where the mathematical value is finite, so is the value we
return and so are its forward- and reverse-mode derivatives. The usual technique is the "double
where": the argument is replaced by a harmless value *before* the singular operation on the lanes
that would be singular, and the result is selected *after*. A single `where` is not enough, because
reverse mode multiplies the unselected branch's (infinite) derivative by zero, giving NaN.
`safe_sqrt`, whose value needs no guard, instead has a custom JVP that guards only the derivative.

Where a derivative is infinite at the edge itself (sqrt at 0, acos at ±1), the convention is a zero
derivative at that one point; the functions document it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

TWO_PI = 2.0 * np.pi
INV_PI = 1.0 / np.pi
INV_2PI = 1.0 / (2.0 * np.pi)
INV_4PI = 1.0 / (4.0 * np.pi)


def one_minus_epsilon(dtype) -> float:
    """The largest float below 1 in `dtype` (PBRT's OneMinusEpsilon): 1 - 2^-24 in float32."""
    return float(np.nextafter(np.array(1.0, dtype=dtype), np.array(0.0, dtype=dtype)))


@jax.custom_jvp
def clamp_rounding(x: jax.Array, low, high) -> jax.Array:
    """x clipped into [low, high] with x's own derivative: for a value that can leave the interval
    only by rounding (a position within a cell, a sample on its support's edge), so that the clip
    neither zeroes the derivative outside nor halves it on a bound (`jnp.clip`'s 0.5 there). The
    value is `jnp.clip`'s, with nothing added to the program that is not differentiated."""
    return jnp.clip(x, low, high)


@clamp_rounding.defjvp
def _clamp_rounding_jvp(primals, tangents):
    x, low, high = primals
    return jnp.clip(x, low, high), jnp.broadcast_to(tangents[0], jnp.shape(jnp.clip(x, low, high)))


def clamp_unit_interval(u: jax.Array) -> jax.Array:
    """Clamp `u` into [0, 1 - ulp]: 32 random bits times 2^-32 can round to exactly 1."""
    u = jnp.asarray(u)
    return jnp.clip(u, 0.0, one_minus_epsilon(u.dtype))


def safe_sqrt(x: jax.Array) -> jax.Array:
    """sqrt(max(x, 0)); derivative 1/(2 sqrt x) for x > 0 and 0 for x <= 0 (never NaN or inf).
    A NaN argument gives NaN.

    Written with selects, not a custom JVP: the sqrt is taken of x where x > 0 and of 1 elsewhere,
    so its derivative is finite on both sides of the select. A custom JVP rule is opaque to the
    per-coordinate evaluation of `jaxsample._core.lanes`, which then stacks the value and everything
    computed from it; the gradient of `shade` had its per-sample program split into dozens of loops
    that way.
    """
    positive = x > 0
    root = jnp.sqrt(jnp.where(positive, x, 1.0))
    return jnp.where(positive, root, jnp.where(x <= 0, jnp.zeros_like(root), x))


def safe_acos(x: jax.Array) -> jax.Array:
    """acos of x clamped to [-1, 1]; derivative 0 where |x| >= 1 instead of -inf."""
    inside = jnp.abs(x) < 1
    x_safe = jnp.where(inside, x, 0.0)
    edge = jnp.where(x >= 1, 0.0, jnp.pi).astype(jnp.result_type(x, float))
    return jnp.where(inside, jnp.arccos(x_safe), edge)


def safe_asin(x: jax.Array) -> jax.Array:
    """asin of x clamped to [-1, 1]; derivative 0 where |x| >= 1 instead of inf."""
    inside = jnp.abs(x) < 1
    x_safe = jnp.where(inside, x, 0.0)
    edge = jnp.where(x >= 1, 0.5 * jnp.pi, -0.5 * jnp.pi).astype(jnp.result_type(x, float))
    return jnp.where(inside, jnp.arcsin(x_safe), edge)


def safe_log(x: jax.Array) -> jax.Array:
    """log(x) for x > 0 and -inf for x <= 0 (a log-density outside its support); derivative 0 there."""
    positive = x > 0
    x_safe = jnp.where(positive, x, 1.0)
    return jnp.where(positive, jnp.log(x_safe), -jnp.inf)


def safe_div(numerator: jax.Array, denominator: jax.Array) -> jax.Array:
    """numerator / denominator, and 0 where the denominator is 0 (the f/p = 0 where p = 0 rule).

    A double where, not the custom JVP of `safe_sqrt`: x/0 on a discarded lane would be
    harmless in value, but `jax_debug_nans` would report it, sending a user hunting a NaN here.
    """
    nonzero = denominator != 0
    denominator_safe = jnp.where(nonzero, denominator, 1.0)
    return jnp.where(nonzero, numerator / denominator_safe, 0.0)


def safe_pow(base: jax.Array, exponent: jax.Array) -> jax.Array:
    """base**exponent for base >= 0, with 0**0 = 1 and finite derivatives in both arguments.

    Computed as exp(exponent * log(base)) on base > 0; at base == 0 the value is 1 for exponent 0
    and 0 otherwise, with zero derivative (jnp.power's d/d exponent is 0 * -inf = NaN there).
    """
    positive = base > 0
    base_safe = jnp.where(positive, base, 1.0)
    at_zero = jnp.where(exponent == 0, 1.0, 0.0)
    return jnp.where(positive, jnp.exp(exponent * jnp.log(base_safe)), at_zero)


# sin x = x + x^3 (S0 + S1 x^2 + S2 x^4) and cos x = 1 + x^2 (C0 + C1 x^2 + C2 x^4 + C3 x^6) on
# |x| <= π/4: near-minimax in relative error, fitted here (Lawson's iteratively reweighted least squares
# on 20,000 Chebyshev-spaced points of [0, π/4], float64) and rounded to float32. Evaluated in float32
# on 2,000,001 points of [-π/4, π/4] against float64 sin and cos: at most 0.87 ulp (sin) and 1.12 ulp
# (cos); the degree 7 and 8 Taylor polynomials they replace reached 6.2 ulp (sin) near π/4. Tested in
# tests/_core/test_numerics.py (and the mutation record sincos-taylor-coefficients puts Taylor back).
SIN_COEFFICIENTS = (np.float32(-0.16666666), np.float32(0.008332796), np.float32(-0.00019594157))
COS_COEFFICIENTS = (np.float32(-0.5), np.float32(0.04166661), np.float32(-0.0013885585), np.float32(2.4235645e-05))


def sincos_small(x: jax.Array) -> tuple[jax.Array, jax.Array]:
    """(sin x, cos x) for |x| <= π/4, with no range reduction: the octant a warp already knows.

    float32: the two polynomials above (at most 0.87 and 1.12 ulp against float64 on |x| <= π/4;
    outside that interval they drift away, so callers reduce first, as `sincos_2pi` and the
    concentric map do). Other dtypes: jnp.sin and jnp.cos.
    """
    x = jnp.asarray(x)
    if x.dtype != jnp.float32:
        return jnp.sin(x), jnp.cos(x)
    s0, s1, s2 = SIN_COEFFICIENTS
    c0, c1, c2, c3 = COS_COEFFICIENTS
    x2 = x * x
    sin_x = x + (x * x2) * (s0 + x2 * (s1 + x2 * s2))
    cos_x = 1.0 + x2 * (c0 + x2 * (c1 + x2 * (c2 + x2 * c3)))
    return sin_x, cos_x


def sincos_2pi(u: jax.Array) -> tuple[jax.Array, jax.Array]:
    """(sin 2πu, cos 2πu) for u in [0, 1) (any real u works: the result is periodic).

    float32: quarter-turn reduction and `sincos_small`, because XLA's CPU sine and cosine
    dominate the cost of a whole sample (docs/reference.md). With q = round(4u) and t = u - q/4 in
    [-1/8, 1/8] (exact: no accuracy is lost near u = 1, or at the quarter turns, where the value is
    exactly 0 or ±1), x = 2πt (|x| <= π/4) and the quadrant q mod 4 rotates (sin x, cos x) into
    place. Against float64 sin and cos of 2πu (the float32 u taken exactly): at most 2 ulp over
    every u = k/2^24 in [0, 1) and the hard cases (tested), from the polynomials' 0.87 and 1.12 ulp
    and the rounding of 2πt. Other dtypes: jnp.sin/jnp.cos of 2π(u - round(u)), reduced to [-π, π)
    first, so that arguments near 2π lose nothing extra.
    """
    u = jnp.asarray(u)
    if u.dtype != jnp.float32:
        reduced = u - jnp.round(u)
        angle = TWO_PI * reduced
        return jnp.sin(angle), jnp.cos(angle)
    quarter = jnp.round(4.0 * u)
    t = u - 0.25 * quarter
    sin_x, cos_x = sincos_small(np.float32(TWO_PI) * t)
    quadrant = quarter.astype(jnp.int32) & 3
    swap = (quadrant & 1) == 1
    sin_value = jnp.where(swap, cos_x, sin_x)
    cos_value = jnp.where(swap, sin_x, cos_x)
    # Quadrant 1: (cos, -sin); 2: (-sin, -cos); 3: (-cos, sin).
    sin_value = jnp.where(quadrant >= 2, -sin_value, sin_value)
    cos_value = jnp.where((quadrant == 1) | (quadrant == 2), -cos_value, cos_value)
    return sin_value, cos_value


def azimuth_fraction(y: jax.Array, x: jax.Array) -> jax.Array:
    """atan2(y, x) / 2π mapped into [0, 1): the inverse of `sincos_2pi`'s azimuth."""
    # atan2 has a finite gradient except at (0, 0); guard that one point.
    at_origin = (x == 0) & (y == 0)
    x_safe = jnp.where(at_origin, 1.0, x)
    fraction = jnp.arctan2(y, x_safe) * INV_2PI
    fraction = jnp.where(fraction < 0, fraction + 1.0, fraction)
    # -tiny + 1 rounds to exactly 1; fold it back to 0 so the result stays in [0, 1).
    return jnp.where(fraction >= 1.0, 0.0, fraction)


def one_minus_cos_theta(direction: jax.Array) -> jax.Array:
    """1 - cos θ of a unit vector about +z, accurate near the pole.

    Near the pole z rounds to 1 and 1 - z loses every digit, while x and y still carry sin θ to full
    relative precision; for z > 0 we therefore use 1 - z = (x² + y²) / (1 + z) (exact for unit
    vectors), and 1 - z itself in the lower hemisphere where it has no cancellation.
    """
    x, y, z = direction[..., 0], direction[..., 1], direction[..., 2]
    upper = z > 0
    denominator = jnp.where(upper, 1.0 + z, 1.0)
    return jnp.where(upper, (x * x + y * y) / denominator, 1.0 - z)


def spherical_direction(sin_theta, cos_theta, u_azimuth) -> jax.Array:
    """Unit vector (sin θ cos φ, sin θ sin φ, cos θ) with φ = 2π u_azimuth, stacked on the last axis."""
    sin_phi, cos_phi = sincos_2pi(u_azimuth)
    return jnp.stack([sin_theta * cos_phi, sin_theta * sin_phi, cos_theta], axis=-1)


def direction_from_one_minus_cos(one_minus_cos, u_azimuth, one_plus_cos=None) -> jax.Array:
    """Unit vector whose polar angle is given by t = 1 - cos θ in [0, 2].

    sin θ comes from sin² θ = t (1 + cos θ), which keeps full relative precision as t -> 0 (the
    pole), where sqrt(1 - cos²) would cancel to nothing. Near the antipode 1 + cos θ = 2 - t cancels
    in turn; a sampler that can compute it directly passes it as `one_plus_cos`.
    """
    if one_plus_cos is None:
        one_plus_cos = 2.0 - one_minus_cos
    sin_theta = safe_sqrt(one_minus_cos * one_plus_cos)
    cos_theta = jnp.where(one_minus_cos <= 1.0, 1.0 - one_minus_cos, one_plus_cos - 1.0)
    return spherical_direction(sin_theta, cos_theta, u_azimuth)
