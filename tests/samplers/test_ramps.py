"""SmoothStep and TrimmedLogistic against PBRT-v4's formulas, written out in float64 NumPy; their
contract (normalization, chi-square, inverse, Jacobian, hard cases) is `test_contract.py`.

Deterministic: fixed points, no keys.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js

U = np.concatenate([np.linspace(0.0, 1.0, 2001)[:-1], [1e-7, 1e-4, 0.4999, 0.5001, 1 - 1e-4, 1 - 2.0 ** -24]])


def _smooth_step_pdf(x, a, b):
    """PBRT-v4 SmoothStepPDF: 2/(b − a) · smoothstep, 0 below a (and here above b)."""
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return np.where((x >= a) & (x <= b), 2.0 / (b - a) * t * t * (3.0 - 2.0 * t), 0.0)


def _smooth_step_sample(u, a, b):
    """The root of ∫_a^x p = u by 200 bisections (PBRT solves the same equation by Newton-bisection)."""
    lo, hi = np.zeros_like(u), np.ones_like(u)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        below = mid ** 3 * (2.0 - mid) < u
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return a + (b - a) * 0.5 * (lo + hi)


def _logistic_cdf(x, s):
    return 1.0 / (1.0 + np.exp(-x / s))


def _logistic_pdf(x, s):
    e = np.exp(-np.abs(x) / s)
    return e / (s * (1.0 + e) ** 2)


def _trimmed_logistic_sample(u, s, a, b):
    """PBRT-v4 SampleTrimmedLogistic: u' = lerp(u, F(a), F(b)), x = −s log(1/u' − 1), clamped."""
    v = (1.0 - u) * _logistic_cdf(a, s) + u * _logistic_cdf(b, s)
    return np.clip(-s * np.log(1.0 / v - 1.0), a, b)


def _trimmed_logistic_pdf(x, s, a, b):
    inside = (x >= a) & (x <= b)
    return np.where(inside, _logistic_pdf(x, s) / (_logistic_cdf(b, s) - _logistic_cdf(a, s)), 0.0)


@pytest.mark.parametrize("a, b", [(-1.0, 2.0), (0.0, 1e-3), (3.0, 3.5)])
def test_smooth_step_is_pbrts_in_float64(a, b):
    with jax.enable_x64(True):
        sampler = js.SmoothStep(jnp.float64(a), jnp.float64(b))
        x, p = (np.asarray(v) for v in sampler.warp_with_pdf(jnp.asarray(U[:, None])))
        np.testing.assert_allclose(x, _smooth_step_sample(U, a, b), rtol=1e-13, atol=1e-13 * (b - a))
        np.testing.assert_allclose(p, _smooth_step_pdf(x, a, b), rtol=1e-11, atol=1e-300)
        np.testing.assert_allclose(np.asarray(sampler.inverse(jnp.asarray(x)))[:, 0], U, rtol=0, atol=1e-13)


def test_smooth_step_keeps_u_near_1_to_relative_precision_in_float32():
    """1 − u = 2^-24 is the last float32 uniform: x must sit (1 − u)/2 · (b − a) below b = 0 (where
    float32 resolves it), not at b."""
    x = float(js.SmoothStep(-1.0, 0.0).warp(jnp.array([1 - 2.0 ** -24], jnp.float32)))
    assert abs(-x / 2.0 ** -25 - 1.0) < 1e-3, x


@pytest.mark.parametrize("s, a, b", [(1.0, -2.0, 3.0), (0.3, -1.0, 0.5), (0.5, -0.01, 0.01)])
def test_trimmed_logistic_is_pbrts_in_float64(s, a, b):
    with jax.enable_x64(True):
        sampler = js.TrimmedLogistic(jnp.float64(s), jnp.float64(a), jnp.float64(b))
        x, p = (np.asarray(v) for v in sampler.warp_with_pdf(jnp.asarray(U[:, None])))
    np.testing.assert_allclose(x, _trimmed_logistic_sample(U, s, a, b), rtol=1e-9, atol=1e-12 * (b - a))
    np.testing.assert_allclose(p, _trimmed_logistic_pdf(x, s, a, b), rtol=1e-11)


@pytest.mark.parametrize("s, a, b", [(0.1, 1.0, 2.0), (2.0, -20.0, -5.0), (1.0, 8.0, 12.0)])
def test_trimmed_logistic_in_a_tail_is_accurate_in_float32(s, a, b):
    """An interval deep in a tail (F(a) = 1 − 4.5e-5, 1 − 3e-4, 0.018): float32 densities and samples
    within 1e-4 of float64 PBRT formulas, where F(b) − F(a) formed in float32 near 1 loses 2-3
    digits."""
    sampler = js.TrimmedLogistic(s, a, b)
    x, p = (np.asarray(v, np.float64) for v in sampler.warp_with_pdf(jnp.asarray(U[:, None], jnp.float32)))
    np.testing.assert_allclose(p, _trimmed_logistic_pdf(x, s, a, b), rtol=1e-4)
    np.testing.assert_allclose(x, _trimmed_logistic_sample(U, s, a, b), rtol=0, atol=1e-4 * (b - a))


def test_trimmed_logistic_two_hundred_scales_into_a_tail_is_finite_and_accurate_in_float32():
    """[-200, -190] in units of s, where every F and the logistic density underflow in float32: samples
    and densities within 1e-4 of PBRT's formulas in float64, the mirror interval [190, 200] their
    mirror image with 1 − u, and the derivative of sample and density in s finite."""
    u = U[(U > 1e-6) & (U < 1 - 1e-6)]
    left, right = js.TrimmedLogistic(1.0, -200.0, -190.0), js.TrimmedLogistic(1.0, 190.0, 200.0)
    x, p = (np.asarray(v, np.float64) for v in left.warp_with_pdf(jnp.asarray(u[:, None], jnp.float32)))
    np.testing.assert_allclose(x, _trimmed_logistic_sample(u, 1.0, -200.0, -190.0), rtol=0, atol=1e-3)
    np.testing.assert_allclose(p, _trimmed_logistic_pdf(x, 1.0, -200.0, -190.0), rtol=1e-4)
    mirrored = np.asarray(right.warp(jnp.asarray(1.0 - u[:, None], jnp.float32)), np.float64)
    np.testing.assert_allclose(mirrored, -x, rtol=0, atol=1e-3)
    value = lambda s: jnp.sum(jnp.stack(js.TrimmedLogistic(s, -200.0, -190.0).warp_with_pdf(  # noqa: E731
        jnp.asarray(u[:64, None], jnp.float32))))
    assert np.isfinite(float(jax.grad(value)(1.0)))


def test_an_empty_or_reversed_interval_is_refused():
    with pytest.raises(ValueError, match="'low' and 'high'"):
        js.SmoothStep(1.0, 1.0)
    with pytest.raises(ValueError, match="'low' and 'high'"):
        js.TrimmedLogistic(1.0, 2.0, -2.0)
    with pytest.raises(ValueError, match="scale"):
        js.TrimmedLogistic(0.0, -1.0, 1.0)
