"""Safe elementary functions and stable forms (public name of `jaxsample._core.numerics`)."""

from ._core.numerics import (
    TWO_PI, INV_PI, INV_2PI, INV_4PI, one_minus_epsilon, clamp_unit_interval, safe_sqrt, safe_acos,
    safe_asin, safe_log, safe_div, safe_pow, sincos_small, sincos_2pi, azimuth_fraction, one_minus_cos_theta,
    spherical_direction, direction_from_one_minus_cos,
)

__all__ = [
    "TWO_PI", "INV_PI", "INV_2PI", "INV_4PI", "one_minus_epsilon", "clamp_unit_interval",
    "safe_sqrt", "safe_acos", "safe_asin", "safe_log", "safe_div", "safe_pow", "sincos_small", "sincos_2pi",
    "azimuth_fraction", "one_minus_cos_theta", "spherical_direction", "direction_from_one_minus_cos",
]
