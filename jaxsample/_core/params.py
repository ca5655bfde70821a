"""Parameter checks: a concrete invalid parameter raises a ValueError naming it and its range."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np


def concrete_value(x: Any) -> np.ndarray | None:
    """`x` as a float64 NumPy array if it is a concrete number, else None (tracers, placeholders).

    JAX rebuilds pytrees with tracers and sometimes with non-numeric placeholders, so parameter
    checks only run on values that are really known.
    """
    if isinstance(x, jax.core.Tracer):
        return None
    if isinstance(x, (list, tuple)):
        try:
            return np.asarray(x, dtype=np.float64)
        except (TypeError, ValueError):
            return None
    if isinstance(x, (int, float, np.ndarray, np.number, jax.Array)) and not isinstance(x, bool):
        try:
            return np.asarray(x, dtype=np.float64)
        except (TypeError, ValueError, jax.errors.ConcretizationTypeError):
            return None
    return None


def check_parameter(
    owner: str,
    name: str,
    value: Any,
    low: float = -np.inf,
    high: float = np.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> None:
    """Raise `ValueError` naming `owner.name` and its valid range if a concrete value is outside it.

    NaN is always rejected. Traced values are not checked: under `jit` a sampler cannot raise, and
    an out-of-range traced parameter gives the documented garbage-in behaviour of each sampler.
    """
    v = concrete_value(value)
    if v is None:
        return
    # A bound like 1e-6 is not representable in float32: float32(1e-6), and that value cast to
    # float64, must count as in range, so each bound is widened to its float32 rounding.
    if np.isfinite(low):
        low = min(low, float(np.float32(low)))
    if np.isfinite(high):
        high = max(high, float(np.float32(high)))
    left = "(" if low_open else "["
    right = ")" if high_open else "]"
    interval = f"{left}{low:g}, {high:g}{right}"
    bad_low = (v <= low) if low_open else (v < low)
    bad_high = (v >= high) if high_open else (v > high)
    bad = np.isnan(v) | bad_low | bad_high
    if np.any(bad):
        shown = v if v.ndim == 0 else v[bad].ravel()[:3]
        raise ValueError(f"{owner}: parameter '{name}' must be in {interval}; got {shown}")


def check_choice(owner: str, name: str, value: Any, choices: tuple[str, ...]) -> None:
    if value not in choices:
        raise ValueError(f"{owner}: parameter '{name}' must be one of {choices}; got {value!r}")


def default_float_dtype():
    """float64 when `jax_enable_x64` is on, else float32."""
    return jnp.zeros(()).dtype
