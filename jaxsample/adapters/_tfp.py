"""A jaxsample sampler as a TensorFlow Probability on JAX distribution (`to_tfp`).

Imported only when `jaxsample.adapters.to_tfp` is first used.
"""

from __future__ import annotations

import jax.numpy as jnp

from ._optional import require
from ._quiet import quiet_import

require("tensorflow_probability", "TensorFlow Probability (on JAX)")
with quiet_import():  # TFP loads its modules lazily: the first attribute access imports them
    from tensorflow_probability.substrates import jax as tfp
    tfd = tfp.distributions
    TensorShape = tfp.tf2jax.TensorShape

from .._core.pytree import register_foreign_base
from ..samplers.base import Sampler, check_sampler
from ..samplers.discrete import Discrete



class SamplerDistribution(tfd.Distribution):
    """A jaxsample `Sampler` as a `tfp.distributions.Distribution` (JAX substrate).

    `sample(sample_shape, seed=)` is the sampler's `sample`, `log_prob` its `log_prob` (over its
    `measure`), with the sampler's `batch_shape` and `event_shape`; `reparameterization_type` is
    `FULLY_REPARAMETERIZED` (the samples are differentiable functions of the sampler's parameters)
    except for `Discrete`. A JAX pytree whose leaves are the sampler's, so it passes through `jit`
    and `vmap` and into TFP's meta-distributions (`tfd.Sample`, `tfd.Independent`, ...).
    """

    def __init__(self, sampler: Sampler, validate_args: bool = False, allow_nan_stats: bool = True,
                 name: str | None = None):
        parameters = dict(locals())
        check_sampler("to_tfp", "sampler", sampler)
        self._sampler = sampler
        discrete = isinstance(sampler, Discrete)
        super().__init__(dtype=jnp.int32 if discrete else jnp.result_type(float),
                         reparameterization_type=tfd.NOT_REPARAMETERIZED if discrete else tfd.FULLY_REPARAMETERIZED,
                         validate_args=validate_args, allow_nan_stats=allow_nan_stats, parameters=parameters,
                         name=name or type(sampler).__name__)

    @property
    def sampler(self) -> Sampler:
        return self._sampler

    @classmethod
    def _parameter_properties(cls, dtype, num_classes=None):
        return {}  # the sampler states its own parameters and their ranges

    def _event_shape(self):
        return TensorShape(tuple(self._sampler.event_shape))

    def _batch_shape(self):
        return TensorShape(tuple(self._sampler.batch_shape))

    def _event_shape_tensor(self):
        return jnp.array(tuple(self._sampler.event_shape), jnp.int32)

    def _batch_shape_tensor(self):
        return jnp.array(tuple(self._sampler.batch_shape), jnp.int32)

    def _sample_n(self, n, seed=None):
        return self._sampler.sample(seed, (n,))

    def _log_prob(self, x):
        return self._sampler.log_prob(x)


register_foreign_base(
    SamplerDistribution,
    lambda d: ((d._sampler,), (d.validate_args, d.allow_nan_stats, d.name)),
    lambda aux, children: SamplerDistribution(children[0], *aux))


def to_tfp(sampler: Sampler) -> SamplerDistribution:
    """`sampler` as a TFP-on-JAX distribution (`SamplerDistribution`)."""
    return SamplerDistribution(sampler)
