"""Importing TFP on JAX (directly, or through distrax) without its deprecation warning."""

from __future__ import annotations

import contextlib
import warnings


@contextlib.contextmanager
def quiet_import():
    """TFP's JAX backend reads `jax.core.pytype_aval_mappings` when it is imported, which JAX 0.10
    deprecates with a `DeprecationWarning`: a warning about TFP's code, not the user's, raised once
    per process. It is silenced for the import alone; any other warning passes."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"jax\.core\.pytype_aval_mappings is deprecated",
                                category=DeprecationWarning)
        yield
