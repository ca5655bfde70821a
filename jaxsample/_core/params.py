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
    """Raise `ValueError` naming `owner.name` and its valid range if a concrete value is outside it,
    and `TypeError` if it is not a number (a string, None, a dict).

    NaN is always rejected. Traced values cannot be checked (under `jit` nothing can raise): the
    sampler's `_parameters_valid` states the same range with `in_range`, and an out-of-range traced
    parameter makes every value and gradient NaN (`jaxsample.samplers.base`, "Invalid parameters").
    """
    check_number(owner, name, value)
    v = concrete_value(value)
    if v is None:
        return
    # A bound like 1e-6 is not representable in float32: float32(1e-6), and that value cast to
    # float64, must count as in range, so each bound is widened to its float32 rounding.
    if np.isfinite(low):
        low = min(low, float(np.float32(low)))
    if np.isfinite(high):
        high = max(high, float(np.float32(high)))
    interval = interval_text(low, high, low_open, high_open)
    bad_low = (v <= low) if low_open else (v < low)
    bad_high = (v >= high) if high_open else (v > high)
    bad = np.isnan(v) | bad_low | bad_high
    if np.any(bad):
        shown = v if v.ndim == 0 else v[bad].ravel()[:3]
        raise ValueError(f"{owner}: parameter '{name}' must be in {interval}; got {shown}")


def interval_text(low: float, high: float, low_open: bool = False, high_open: bool = False) -> str:
    """The interval as written in messages and docstrings: "[0, 1e+07]", "(0, inf)"."""
    return f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"


def check_number(owner: str, name: str, value: Any) -> None:
    """Raise `TypeError` unless `value` is a number, an array of numbers or a tracer."""
    if isinstance(value, jax.core.Tracer):
        return
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{owner}: parameter '{name}' must be a number or an array of numbers; got the bool {value!r}")
    if isinstance(value, (int, float, np.integer, np.floating)):
        return
    try:
        kind = np.asarray(value).dtype.kind
    except Exception:
        kind = "O"
    if kind not in "iuf":
        raise TypeError(f"{owner}: parameter '{name}' must be a number or an array of numbers; "
                        f"got {type(value).__name__} {value!r}")


def as_parameter(value: Any) -> Any:
    """A list or tuple of numbers as an array of the default float dtype (one leaf, which may carry
    a batch), anything else unchanged; what `check_number` refuses is left for it to name."""
    if isinstance(value, (list, tuple)):
        try:
            return jnp.asarray(np.asarray(value, dtype=np.float64), default_float_dtype())
        except (TypeError, ValueError):
            return value
    return value


def in_range(value: Any, low: float = -np.inf, high: float = np.inf, *, low_open: bool = False,
             high_open: bool = False) -> jax.Array:
    """Whether every entry of `value` lies in the interval (NaN is never in range): the traced
    counterpart of `check_parameter`, with the same arguments. A JAX boolean for a traced value,
    a NumPy one for a concrete value."""
    if np.isfinite(low):  # widened to its float32 rounding, as in `check_parameter`
        low = min(low, float(np.float32(low)))
    if np.isfinite(high):
        high = max(high, float(np.float32(high)))
    concrete = concrete_value(value)
    xp, v = (np, concrete) if concrete is not None else (jnp, jnp.asarray(value))  # NumPy: no dispatch
    above = (v > low) if low_open else (v >= low)
    below = (v < high) if high_open else (v <= high)
    return xp.all(above & below)


def check_choice(owner: str, name: str, value: Any, choices: tuple[str, ...]) -> None:
    if value not in choices:
        raise ValueError(f"{owner}: parameter '{name}' must be one of {choices}; got {value!r}")


def default_float_dtype():
    """float64 when `jax_enable_x64` is on, else float32."""
    return jnp.zeros(()).dtype


def resolve_float_dtype(owner: str, dtype: Any) -> np.dtype:
    """The float dtype an estimator or sampler computes in: `dtype`, or the default
    (`default_float_dtype`) for None and for Python's `float` (JAX's meaning of it).

    Raises `ValueError` naming `owner`'s parameter 'dtype' unless it is float32, or float64 with
    `jax_enable_x64` on: without it JAX truncates float64 to float32 (with a warning per array), so
    a float64 request would silently compute in float32.
    """
    if dtype is None or dtype is float:
        return default_float_dtype()
    try:
        resolved = jnp.dtype(dtype)
    except TypeError:
        resolved = None
    if resolved not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"{owner}: parameter 'dtype' must be float32 or float64 (float64 with jax_enable_x64); "
                         f"got {dtype!r}")
    check_float64_enabled(owner, resolved)
    return resolved


def check_float64_enabled(owner: str, dtype: Any) -> None:
    """Raise `ValueError` naming `owner`'s parameter 'dtype' if it is float64 and `jax_enable_x64`
    is off (JAX would truncate every array to float32, with a warning per array)."""
    if jnp.dtype(dtype) == np.float64 and default_float_dtype() != np.float64:
        raise ValueError(f"{owner}: parameter 'dtype' is float64, which needs jax_enable_x64: call "
                         "jax.config.update(\"jax_enable_x64\", True) at startup (without it JAX "
                         "computes in float32), or pass dtype=jnp.float32")
