"""Sample counts: what `n` (and every other count that fixes a program's shape) may be.

A count decides how many chunks a loop runs and how large its arrays are, so it must be known
when the program is traced: any concrete integer will do (a Python int, a NumPy integer, a
concrete JAX integer array of shape (), or a float with an integral value such as 1e6). A bool is
not a count (True is 1 by accident), a float with a fractional part is a mistake, and a traced
value cannot fix a shape: those raise, the last with the `static_argnums` advice that fixes it.
"""

from __future__ import annotations

import math
import operator

import jax
import numpy as np

__all__ = ["check_count"]


def _traced_message(owner: str, name: str) -> str:
    return (f"{owner}: parameter '{name}' is traced (it reached {owner} as an argument of a jitted or "
            f"vmapped function), but it fixes the number of samples, and so the shapes of the compiled "
            f"program: it must be a concrete integer. Mark it static, e.g. "
            f"jax.jit(fn, static_argnums=(<its position>,)) or jax.jit(fn, static_argnames=('{name}',)), "
            f"or close over it.")


def check_count(owner: str, name: str, value, *, minimum: int = 1, maximum: int | None = None) -> int:
    """`value` as a Python int in [minimum, maximum]; TypeError or ValueError naming `owner.name`.

    Accepted: Python and NumPy integers, concrete JAX integer arrays of shape (), and floats
    (Python, NumPy or JAX, shape ()) whose value is a finite integer. Refused with a TypeError:
    bools, traced values (the message names `static_argnums`/`static_argnames`), arrays of another
    shape and anything else; with a ValueError: floats with a fractional part and values out of range.
    """
    if isinstance(value, jax.core.Tracer):
        raise TypeError(_traced_message(owner, name))
    if isinstance(value, (bool, np.bool_)) or (hasattr(value, "dtype") and np.dtype(value.dtype) == np.bool_):
        raise TypeError(f"{owner}: parameter '{name}' must be an integer; got the bool {value!r}")
    if isinstance(value, (jax.Array, np.ndarray)):
        if value.shape != ():
            raise TypeError(f"{owner}: parameter '{name}' must be an integer scalar; got an array of shape "
                            f"{value.shape}")
        value = value.item()
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(value) or value != math.floor(value):
            raise ValueError(f"{owner}: parameter '{name}' must be an integer; got {value!r}")
        value = int(value)
    try:
        count = operator.index(value)
    except TypeError:
        raise TypeError(f"{owner}: parameter '{name}' must be an integer; got {type(value).__name__} "
                        f"{value!r}") from None
    if count < minimum:
        raise ValueError(f"{owner}: parameter '{name}' must be an integer >= {minimum}; got {count}")
    if maximum is not None and count > maximum:
        raise ValueError(f"{owner}: parameter '{name}' must be at most {_power_of_two(maximum)}; got {count}")
    return int(count)


def _power_of_two(value: int) -> str:
    return f"2^{value.bit_length() - 1}" if value > 1 and value & (value - 1) == 0 else str(value)
