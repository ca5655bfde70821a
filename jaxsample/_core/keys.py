"""The one key rule of every entry point (`as_key`), and the seed words a key becomes (`seed_from_key`).

It sits in the bottom layer because every layer takes keys: the compiled entry of the estimators
(`entry.py`) puts a call's key through it before tracing, the sources (`jaxsample.uniforms`, which
exports these names) turn it into their seed words, and the samplers check it in `sample`.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["SEED_WORDS", "as_key", "seed_from_key"]

SEED_WORDS = 2


@functools.lru_cache(maxsize=None)
def _legacy_key_shape(impl: str) -> tuple[int, ...]:
    """The shape of a legacy raw key under the default PRNG implementation (2,) for threefry."""
    return tuple(jax.eval_shape(lambda: jax.random.key_data(jax.random.key(0))).shape)


def as_key(key, owner: str = "jaxsample") -> jax.Array:
    """The one key rule of every entry point: `key` as a typed JAX key.

    Accepted: a typed key (`jax.random.key(seed)`, shape ()) and a legacy raw key
    (`jax.random.PRNGKey(seed)`: a uint32 array whose shape is the default implementation's key
    data, (2,) for threefry), which is wrapped with `jax.random.wrap_key_data`, so it draws exactly the
    stream of the typed key it holds the data of. Anything else is a `TypeError` that says what a key
    is; so is an array of keys (vmap over them instead).
    """
    if isinstance(key, jax.Array) and jnp.issubdtype(key.dtype, jax.dtypes.prng_key) and key.shape == ():
        return key
    what = ("a key is jax.random.key(seed) (a typed key of shape ()) or a legacy jax.random.PRNGKey(seed) "
            "(a uint32 array of shape {legacy}); for many keys, jax.vmap over them")
    legacy = _legacy_key_shape(str(jax.config.jax_default_prng_impl))
    if isinstance(key, jax.Array) and jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        raise TypeError(f"{owner}: parameter 'key' has shape {key.shape}; " + what.format(legacy=legacy))
    if isinstance(key, (jax.Array, np.ndarray)) and key.dtype == np.uint32 and key.shape == legacy:
        return jax.random.wrap_key_data(key)
    got = f"{type(key).__name__}" + (f" of dtype {key.dtype} and shape {key.shape}" if hasattr(key, "dtype") else "")
    raise TypeError(f"{owner}: parameter 'key' must be a JAX PRNG key; got {got}. " + what.format(legacy=legacy))


def seed_from_key(key: jax.Array, owner: str = "jaxsample") -> jax.Array:
    """The SEED_WORDS uint32 words every source derives its points from; consumes `key` once.

    `key` follows `as_key`'s rule (typed, or a legacy uint32 key meaning the same typed key)."""
    return jax.random.bits(as_key(key, owner), (SEED_WORDS,), jnp.uint32)
