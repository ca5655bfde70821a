"""Where the program shapes tuned for XLA's CPU backend run, and the switch that turns them off.

Two devices shape the compiled loops for XLA's CPU fusion, and were measured only there: the lane
interpreter (`lanes.lane_map`, which evaluates a per-point program one coordinate at a time) and
`computed_once` (values packed in pairs and returned from a `lax.cond`, a boundary fusion cannot
cross). On any other platform `lane_map` is `jax.vmap` and `computed_once` returns its values
as they are, until they are measured there.

The environment variable JAXSAMPLE_LANES chooses, read once when jaxsample is imported (so that
every program of a process, the ones its estimators compile and cache included, makes the same
choice):

- unset, empty or `auto` (the default): both run where the program being traced targets the CPU
  (`jax_internals.trace_platform`); the interpreter also needs a JAX it was tested with and every
  primitive its tables name (`lanes`);
- `0` (or `off`, `false`, `no`): neither runs, on any platform; the CPU then runs the program the
  other platforms run (plain `vmap`), the same values to float rounding;
- `1` (or `on`, `true`, `yes`): both run on every platform, and the interpreter on a JAX outside
  the tested versions too (not where a primitive is missing).

Any other value is read as `auto`, with one warning.
"""

from __future__ import annotations

import os
import warnings

from .jax_internals import trace_platform

__all__ = ["ENV", "SETTING", "parse", "setting", "active"]

ENV = "JAXSAMPLE_LANES"

_OFF = {"0", "off", "false", "no"}
_ON = {"1", "on", "true", "yes"}
_AUTO = {"", "auto"}


def parse(raw: str) -> str:
    """'auto', 'off' or 'on' for a value of JAXSAMPLE_LANES (anything else: 'auto', with a warning)."""
    value = raw.strip().lower()
    if value in _OFF:
        return "off"
    if value in _ON:
        return "on"
    if value not in _AUTO:
        warnings.warn(f"{ENV}={raw!r} is not one of 0, 1 or auto; read as auto", RuntimeWarning, stacklevel=2)
    return "auto"


SETTING = parse(os.environ.get(ENV, ""))


def setting() -> str:
    """'auto', 'off' or 'on': JAXSAMPLE_LANES as it was when jaxsample was imported."""
    return SETTING


def active() -> bool:
    """Whether the CPU program shapes run in the program being traced."""
    mode = setting()
    if mode == "off":
        return False
    return mode == "on" or trace_platform() == "cpu"
