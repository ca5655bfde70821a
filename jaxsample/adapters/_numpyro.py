"""A jaxsample sampler as a NumPyro distribution (`to_numpyro`), and `SphereReparam` for NUTS.

Imported only when `jaxsample.adapters.to_numpyro` or `SphereReparam` is first used.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as nd
from numpyro.distributions import constraints
from numpyro.infer.reparam import Reparam

from ..samplers.base import Sampler, check_sampler
from ..samplers.discrete import Discrete
from ..samplers import domain as domains


def _support_of(sampler: Sampler):
    """The NumPyro constraint of the sampler's domain: the sphere for directions, the interval or box,
    `integer_interval` for a discrete set; `real`/`real_vector` where NumPyro has no such set (a disk,
    a triangle) or the domain depends on a batch of parameters."""
    try:
        domain = sampler.domain()
    except Exception:  # a batched sampler whose domain is per member: the event rank still says which
        domain = None
    if isinstance(domain, domains.Directions):
        return constraints.sphere
    if isinstance(domain, domains.Interval):
        low, high = float(domain.low), float(domain.high)
        if math.isinf(low) and math.isinf(high):
            return constraints.real
        if math.isinf(high):
            return constraints.greater_than(low)
        if math.isinf(low):
            return constraints.less_than(high)
        return constraints.interval(low, high)
    if isinstance(domain, domains.Box):
        lows = np.array([float(axis.low) for axis in domain.axes])
        highs = np.array([float(axis.high) for axis in domain.axes])
        return constraints.independent(constraints.interval(lows, highs), 1)
    if isinstance(domain, domains.DiscreteSet):
        return constraints.integer_interval(0, int(domain.size) - 1)
    return constraints.real if not sampler.event_shape else constraints.independent(
        constraints.real, len(sampler.event_shape))


class SamplerDistribution(nd.Distribution):
    """A jaxsample `Sampler` as a NumPyro distribution.

    `sample(key, sample_shape)` is the sampler's `sample` (shape `sample_shape + batch_shape +
    event_shape`; its samples are differentiable in the sampler's parameters, so `rsample` is the
    same and `has_rsample` is True except for `Discrete`), `log_prob` the sampler's `log_prob`, over
    the sampler's `measure`. `support` is read from the sampler's domain (`constraints.sphere` for a
    directional sampler: NUTS then needs `SphereReparam` on the site, see there).
    """

    arg_constraints: dict = {}
    pytree_data_fields = ("sampler",)
    pytree_aux_fields = ("_support",)

    def __init__(self, sampler: Sampler, support=None, validate_args=None):
        check_sampler("to_numpyro", "sampler", sampler)
        self.sampler = sampler
        self._support = _support_of(sampler) if support is None else support
        super().__init__(batch_shape=tuple(sampler.batch_shape), event_shape=tuple(sampler.event_shape),
                         validate_args=validate_args)

    @property
    def support(self):
        return self._support

    @property
    def has_rsample(self) -> bool:
        return not isinstance(self.sampler, Discrete)

    @property
    def is_discrete(self) -> bool:
        return isinstance(self.sampler, Discrete)

    def sample(self, key, sample_shape=()):
        return self.sampler.sample(key, tuple(sample_shape))

    def rsample(self, key, sample_shape=()):
        if not self.has_rsample:
            raise NotImplementedError("to_numpyro: a Discrete sampler's samples are not differentiable (no rsample)")
        return self.sample(key, sample_shape)

    def log_prob(self, value):
        return self.sampler.log_prob(value)


def to_numpyro(sampler: Sampler, *, support=None, validate_args=None) -> SamplerDistribution:
    """`sampler` as a NumPyro distribution (`SamplerDistribution`); `support` overrides the constraint
    read from its domain."""
    return SamplerDistribution(sampler, support=support, validate_args=validate_args)


class SphereReparam(Reparam):
    """Reparameterizes a latent site on the unit sphere for NumPyro's HMC and NUTS.

    NumPyro moves in an unconstrained space and has no bijection onto the sphere. This reparam draws
    an auxiliary z ~ N(0, I_3) at site `<name>_normal`, sets the site to the direction z / |z| (uniform
    on the sphere, density 1/(4π) over solid angle, independent of |z|) and adds the factor
    log p(z / |z|) + log 4π at site `<name>_density`: the direction's marginal is then exactly p,
    the site's distribution, and the radius |z| keeps its chi law and stays away from 0. Use it as
    `numpyro.handlers.reparam(model, config={"mu": SphereReparam()})`; latent sites only.
    """

    def __call__(self, name, fn, obs):
        if obs is not None:
            raise ValueError(f"SphereReparam: site '{name}' is observed; it applies to latent sites only")
        fn, expand_shape, event_dim = self._unwrap(fn)
        if tuple(fn.event_shape) != (3,):
            raise ValueError(f"SphereReparam: site '{name}' must be a direction (event_shape (3,)); "
                             f"got event_shape {tuple(fn.event_shape)}")
        noise = nd.Normal(jnp.zeros(tuple(fn.batch_shape) + (3,)), 1.0).to_event(1)
        z = numpyro.sample(f"{name}_normal", self._wrap(noise, expand_shape, event_dim))
        value = z / jnp.linalg.norm(z, axis=-1, keepdims=True)
        numpyro.factor(f"{name}_density", fn.log_prob(value) + jnp.log(4.0 * jnp.pi))
        return None, value
