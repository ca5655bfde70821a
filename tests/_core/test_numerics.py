"""Layer 1: the safe functions keep value and gradient finite at their domain edges."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsample._core import numerics as nm

EDGES = jnp.array([-2.0, -1.0, 0.0, 1e-30, 0.5, 1.0, 2.0], jnp.float32)


@pytest.mark.parametrize("fn", [nm.safe_sqrt, nm.safe_acos, nm.safe_asin, nm.safe_log])
def test_gradients_are_finite_at_the_edges(fn):
    grads = jax.vmap(jax.grad(fn))(EDGES)
    assert np.all(np.isfinite(np.asarray(grads))), grads
    fwd = jax.vmap(jax.jacfwd(fn))(EDGES)
    assert np.all(np.isfinite(np.asarray(fwd))), fwd


def test_values_match_the_plain_functions_inside_their_domain():
    x = jnp.linspace(0.01, 0.99, 50)
    np.testing.assert_allclose(nm.safe_sqrt(x), jnp.sqrt(x), rtol=1e-6)
    np.testing.assert_allclose(nm.safe_acos(x), jnp.arccos(x), rtol=1e-6)
    np.testing.assert_allclose(nm.safe_asin(x), jnp.arcsin(x), rtol=1e-6)
    np.testing.assert_allclose(nm.safe_log(x), jnp.log(x), rtol=1e-6)
    assert nm.safe_log(jnp.float32(0.0)) == -jnp.inf
    assert nm.safe_acos(jnp.float32(1.5)) == 0.0 and nm.safe_acos(jnp.float32(-1.5)) == np.float32(np.pi)


def test_safe_div_is_zero_where_the_denominator_is_zero_with_finite_gradients():
    num = jnp.array([1.0, 2.0, 0.0])
    den = jnp.array([2.0, 0.0, 0.0])
    np.testing.assert_array_equal(nm.safe_div(num, den), [0.5, 0.0, 0.0])
    g = jax.grad(lambda d: nm.safe_div(num, d).sum())(den)
    assert np.all(np.isfinite(g))


def test_safe_pow_handles_zero_base_and_zero_exponent():
    assert nm.safe_pow(0.0, 0.0) == 1.0
    assert nm.safe_pow(0.0, 3.0) == 0.0
    np.testing.assert_allclose(nm.safe_pow(0.5, 3.0), 0.125, rtol=1e-6)
    g = jax.grad(nm.safe_pow, argnums=(0, 1))(0.0, 2.0)
    assert all(np.isfinite(v) for v in g)


def test_one_minus_epsilon_is_the_float_below_one():
    assert nm.one_minus_epsilon(np.float32) == 1 - 2.0**-24
    assert nm.one_minus_epsilon(np.float64) == 1 - 2.0**-53
    u = nm.clamp_unit_interval(jnp.array([1.0, 0.3, -0.1], jnp.float32))
    assert float(u[0]) < 1.0 and float(u[2]) == 0.0


def test_one_minus_cos_theta_keeps_precision_near_the_pole():
    # θ = 1e-5: 1 - cos θ = 5e-11 is below float32 epsilon, so 1 - z would give 0.
    theta = 1e-5
    v = jnp.array([np.sin(theta), 0.0, np.cos(theta)], jnp.float32)
    assert float(1.0 - v[2]) == 0.0
    np.testing.assert_allclose(nm.one_minus_cos_theta(v), 2 * np.sin(theta / 2) ** 2, rtol=1e-5)


def test_azimuth_fraction_is_in_the_unit_interval_and_inverts_sincos():
    u = jnp.array([0.0, 0.25, 0.5, 0.75, 1 - 2.0**-24], jnp.float32)
    s, c = nm.sincos_2pi(u)
    f = nm.azimuth_fraction(s, c)
    assert np.all((np.asarray(f) >= 0) & (np.asarray(f) < 1))
    d = np.asarray(f - u)
    np.testing.assert_allclose(d - np.round(d), 0.0, atol=2e-7)
    assert np.all(np.isfinite(jax.grad(lambda y: nm.azimuth_fraction(y, 0.0))(0.0)))


def _ulps(approx, exact):
    """|approx - exact| in units of the float32 spacing at |exact| (exact a float64 array)."""
    spacing = np.spacing(np.maximum(np.abs(exact).astype(np.float32), np.float32(2.0**-126)))
    return np.abs(np.asarray(approx, np.float64) - exact) / spacing.astype(np.float64)


def _sincos_2pi_float64(u):
    """sin and cos of 2πu for float32 u taken exactly: reduced to |t| <= 1/8 in float64 (exact),
    then rotated by the quadrant, so that the reference is exact to float64 at the quarter turns."""
    u = np.asarray(u, np.float64)
    q = np.round(4.0 * u)
    t = u - 0.25 * q
    s, c = np.sin(2.0 * np.pi * t), np.cos(2.0 * np.pi * t)
    k = q.astype(np.int64) & 3
    return (np.select([k == 0, k == 1, k == 2], [s, c, -s], -c),
            np.select([k == 0, k == 1, k == 2], [c, -s, -c], s))


def test_sincos_small_is_within_its_stated_ulps_on_the_octant():
    """The stated bounds of `sincos_small` (0.87 ulp sin, 1.12 ulp cos) on a dense grid of
    |x| <= π/4: catches a coefficient off in its fourth digit, or the Taylor coefficients (6.2 ulp)."""
    x = np.linspace(-np.pi / 4, np.pi / 4, 1 << 20).astype(np.float32)
    s, c = jax.jit(nm.sincos_small)(jnp.asarray(x))
    assert _ulps(s, np.sin(x.astype(np.float64))).max() <= 0.9
    assert _ulps(c, np.cos(x.astype(np.float64))).max() <= 1.15


def test_sincos_2pi_is_within_2_ulp_of_float64_over_the_turn_and_its_hard_cases():
    """Every u = k/2^22 in [0, 1), the floats just below 1, powers of two down to 2^-119 and the
    eighth turns' neighbours: at most 2 ulp from float64 (measured 1.92 over k/2^24), and exactly
    0 and ±1 at the quarter turns (a quadrant off, or a reduction that rounds t, fails)."""
    eighths = np.arange(1, 8, dtype=np.float32)[:, None] / 8 + np.arange(-64, 64, dtype=np.float32) * np.float32(2**-26)
    u = np.concatenate([np.arange(1 << 22, dtype=np.float32) / np.float32(1 << 22),
                        np.float32(1) - np.arange(1, 257, dtype=np.float32) * np.float32(2**-24),
                        np.float32(2.0) ** -np.arange(1, 120, dtype=np.float32), eighths.ravel()]).astype(np.float32)
    s, c = jax.jit(nm.sincos_2pi)(jnp.asarray(u))
    exact_s, exact_c = _sincos_2pi_float64(u)
    assert _ulps(s, exact_s).max() <= 2.0
    assert _ulps(c, exact_c).max() <= 2.0
    quarters = jnp.array([0.0, 0.25, 0.5, 0.75], jnp.float32)
    qs, qc = nm.sincos_2pi(quarters)
    np.testing.assert_array_equal(np.abs(qs), [0, 1, 0, 1])
    np.testing.assert_array_equal(qc, [1, 0, -1, 0])


def test_concentric_map_is_within_2_to_the_minus_22_of_float64():
    """The concentric map's (x, y) with its wedge-local sine and cosine, against the same map in
    float64 (np.sin, np.cos), on 2^20 random u, the centre, the axes, the diagonals and u next to 1
    (a quarter-turn route through sincos_2pi's Taylor polynomials would not meet this bound)."""
    from jaxsample.samplers import concentric

    rng = np.random.default_rng(3)
    edge = np.float32(1 - 2.0**-24)
    special = np.array([[0, 0], [0.5, 0.5], [0, 0.5], [0.5, 0], [edge, 0.5], [0.5, edge], [edge, edge],
                        [0.75, 0.75], [0.25, 0.75], [0, edge], [edge, 0]], np.float32)
    u = np.concatenate([rng.random((1 << 20, 2), dtype=np.float32), special])
    x, y, r = jax.jit(concentric.square_to_disk)(jnp.asarray(u))
    a, b = 2.0 * u[:, 0].astype(np.float64) - 1.0, 2.0 * u[:, 1].astype(np.float64) - 1.0
    a_wins = np.abs(a) > np.abs(b)
    radius = np.where(a_wins, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(a_wins, np.pi / 4 * (b / a), np.pi / 2 - np.pi / 4 * np.nan_to_num(a / b))
    assert np.abs(np.asarray(x) - radius * np.cos(phi)).max() <= 2.0**-22
    assert np.abs(np.asarray(y) - radius * np.sin(phi)).max() <= 2.0**-22
    np.testing.assert_array_equal(r, np.maximum(np.abs(a), np.abs(b)).astype(np.float32))
