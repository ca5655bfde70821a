"""A distribution of NumPyro, distrax or TFP on JAX as a jaxsample sampler (`from_distribution`).

Such a distribution is sampled from a key, not by a warp of uniforms. The estimators stream
uniforms by a counter-based generator (point i depends only on the key and i); this sampler turns
the uniforms of point i into a key for that point (`key_from_uniforms`) and draws one sample with
it, so every property of the stream carries over: chunking, sharding and 64-bit indices do not
change the samples, memory stays constant, and `jit`/`vmap`/`grad` apply (gradients with respect
to the distribution's parameters flow through its own reparameterized `sample`, or through
`log_prob` with `gradient="score"`).
"""

from __future__ import annotations

import inspect
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.pytree import static_field
from ..samplers.base import Sampler, point_method


def key_from_uniforms(u: jax.Array) -> jax.Array:
    """A raw (uint32[2]) JAX key from the bits of one point's uniforms u, shape (3,).

    The estimators' uniforms lie on a grid of cell midpoints (`jaxsample.uniforms`): a float32
    coordinate is (k + 1/2) 2^-23 with 23 random bits k, a float64 one (k + 1/2) 2^-32 with 32. The
    key's 64 bits are k0 and k1 (float64), or k0, k1 and 18 bits of k2 (float32): distinct points of
    the stream give distinct keys except with probability about n^2 / 2^65.
    """
    if u.dtype == jnp.float64:
        k = jnp.floor(u[:2] * 2.0 ** 32).astype(jnp.uint32)
        return jnp.stack([k[0], k[1]])
    k = jnp.floor(u.astype(jnp.float32) * jnp.float32(2.0 ** 23)).astype(jnp.uint32)
    low = k[0] | (k[2] << 23)
    high = k[1] | ((k[2] >> 9) << 23)
    return jnp.stack([low, high])


def _takes_seed(distribution) -> bool:
    """Whether `sample` takes its key as `seed=` (distrax, TFP) rather than first (NumPyro's `key`)."""
    try:
        return "seed" in inspect.signature(distribution.sample).parameters
    except (TypeError, ValueError):
        return True


def _shape(value, name: str) -> tuple[int, ...]:
    try:
        return tuple(int(d) for d in value)
    except TypeError:
        raise ValueError(f"from_distribution: the distribution's {name} must be known (a tuple of ints); "
                         f"got {value!r}") from None


class DistributionSampler(Sampler):
    """Any distribution with `sample` and `log_prob` (NumPyro, distrax, TFP on JAX) as a sampler.

    The density is the distribution's own, `exp(log_prob(x))`, over the measure its library states
    it over; jaxsample cannot read that measure, so `measure` (static) names it ("solid angle" for
    TFP's or NumPyro's von Mises–Fisher, "length" for a density on the line, ...), which
    `estimate_mis` needs in order to weigh it against other samplers. `domain` (static, optional) is
    the `jaxsample.domains` object the checks (`chi2_test`, ...) integrate over. `warp(u)` draws one
    sample with the key made of u (`key_from_uniforms`): it is not a transport of u, so this sampler
    has no `inverse`, and the estimators that rely on the uniforms' structure (antithetic pairs,
    stratified and QMC points) refuse it.
    """

    distribution: Any
    takes_seed: bool = static_field()
    stated_measure: Any = static_field()
    support: Any = static_field()
    stated_event_shape: tuple = static_field()

    uniform_dims: ClassVar[int] = 3
    transports_uniforms: ClassVar[bool] = False

    def __init__(self, distribution, *, measure: str | None = None, domain=None):
        if isinstance(distribution, Sampler):
            raise ValueError("from_distribution: parameter 'distribution' is already a jaxsample sampler; "
                             "use it as it is")
        for method in ("sample", "log_prob"):
            if not callable(getattr(distribution, method, None)):
                raise TypeError(f"from_distribution: parameter 'distribution' must have a `{method}` method "
                                f"(a NumPyro, distrax or TFP-on-JAX distribution); got {type(distribution).__name__}")
        batch = _shape(getattr(distribution, "batch_shape", ()), "batch_shape")
        if batch:
            raise ValueError(f"from_distribution: parameter 'distribution' must be one distribution (batch_shape ()); "
                             f"got batch_shape {batch}: wrap each member, or jax.vmap over them")
        if measure is not None and not isinstance(measure, str):
            raise TypeError("from_distribution: parameter 'measure' must be a string such as 'solid angle'; "
                            f"got {measure!r}")
        self.distribution = distribution
        self.takes_seed = _takes_seed(distribution)
        self.stated_measure = measure
        self.support = domain
        self.stated_event_shape = _shape(getattr(distribution, "event_shape", ()), "event_shape")

    @property
    def event_shape(self) -> tuple[int, ...]:
        return self.stated_event_shape

    @property
    def measure(self) -> str | None:
        return self.stated_measure

    def _draw_one(self, u):
        key = key_from_uniforms(u)
        if self.takes_seed:
            return self.distribution.sample(seed=key)
        return self.distribution.sample(key)

    @point_method
    def warp(self, u):
        """One sample of the distribution per point: drawn with the key made of that point's u."""
        u = jnp.asarray(u)
        lead = u.shape[:-1]
        flat = u.reshape((int(np.prod(lead, dtype=np.int64)), u.shape[-1]))
        x = jax.vmap(self._draw_one)(flat)
        return x.reshape(lead + x.shape[1:])

    @point_method
    def log_pdf(self, x):
        """The distribution's `log_prob(x)`."""
        return self.distribution.log_prob(x)

    @point_method
    def pdf(self, x):
        """exp of the distribution's `log_prob(x)`, over `measure`."""
        return jnp.exp(self.distribution.log_prob(x))

    @point_method
    def warp_with_pdf(self, u):
        x = self.warp(u)
        return x, jnp.exp(self.distribution.log_prob(x))

    def domain(self):
        if self.support is None:
            raise ValueError("from_distribution: pass domain=... (a jaxsample.domains object) to run the checks "
                             "on this distribution")
        return self.support


def from_distribution(distribution, *, measure: str | None = None, domain=None) -> DistributionSampler:
    """`distribution` (anything with `sample` and `log_prob`: NumPyro, distrax, TFP on JAX) as a
    jaxsample sampler the estimators accept; see `DistributionSampler`.

        import numpyro.distributions as nd
        normal = from_distribution(nd.Normal(0.0, 2.0), measure="length")
        js.expectation(lambda x: x ** 2, normal, key, 2 ** 16)        # E[x²] = 4, with its stderr
        js.estimate(lambda x: jnp.exp(-x ** 2), normal, key, 2 ** 16)  # ∫ exp(-x²) dx = √π
    """
    return DistributionSampler(distribution, measure=measure, domain=domain)
