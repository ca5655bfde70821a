"""The many-light section's exact reference against the float64 quadrature of the scene layer.

Deterministic: fixed lights, no keys.
"""

from __future__ import annotations

import numpy as np
import pytest

from jaxsample import scene
from jaxsample.report import many_lights


def test_the_closed_form_is_the_sum_of_single_light_quadratures():
    """albedo · Σ_k L_k (r_k/d_k)² cos θ_k for four of the section's lights against the sum of their
    `scene.reference_radiance` (float64 quadrature over each cone), to 1e-6 relative: the form factor
    of a sphere above the horizon, with the cosine and the albedo in their places."""
    (centers, radii, radiance), reference = many_lights.lights_and_reference(4, seed=3)
    brdf = scene.Lambertian(many_lights.ALBEDO)
    point, normal, wo = np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([0.3, 0.1, 1.0])
    summed = sum(float(scene.reference_radiance(point, normal, wo, brdf, [scene.SphereLight(c, r, L)]))
                 for c, r, L in zip(centers, radii, radiance))
    assert reference == pytest.approx(summed, rel=1e-6)
