"""A jaxsample sampler as a distrax distribution (`to_distrax`); imported only when first used."""

from __future__ import annotations

from ._optional import require
from ._quiet import quiet_import

require("distrax", "distrax")
with quiet_import():
    import distrax

from ..samplers.base import Sampler, check_sampler


class SamplerDistribution(distrax.Distribution):
    """A jaxsample `Sampler` as a `distrax.Distribution`: `sample(seed=, sample_shape=)` is the
    sampler's `sample` (differentiable in its parameters), `log_prob` its `log_prob` (over its
    `measure`), `sample_and_log_prob` its `sample_and_log_prob` (the density computed alongside the
    samples), with the sampler's `batch_shape` and `event_shape`."""

    def __init__(self, sampler: Sampler):
        check_sampler("to_distrax", "sampler", sampler)
        self._sampler = sampler

    @property
    def sampler(self) -> Sampler:
        return self._sampler

    @property
    def event_shape(self):
        return tuple(self._sampler.event_shape)

    @property
    def batch_shape(self):
        return tuple(self._sampler.batch_shape)

    def _sample_n(self, key, n: int):
        return self._sampler.sample(key, (n,))

    def _sample_n_and_log_prob(self, key, n: int):
        return self._sampler.sample_and_log_prob(key, (n,))

    def log_prob(self, value):
        return self._sampler.log_prob(value)


def to_distrax(sampler: Sampler) -> SamplerDistribution:
    """`sampler` as a distrax distribution (`SamplerDistribution`)."""
    return SamplerDistribution(sampler)

