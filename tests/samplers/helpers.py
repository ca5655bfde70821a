"""A wrong sampler for the chi-square demonstrations: the samples of one sampler, the density of another."""

from __future__ import annotations

from jaxsample.samplers.base import Sampler
class WrongWarp(Sampler):
    """Samples from `impostor` but claims the density of `truth`: the chi-square test must fail."""

    truth: Sampler
    impostor: Sampler

    @property
    def uniform_dims(self):
        return self.impostor.uniform_dims

    @property
    def event_shape(self):
        return self.truth.event_shape

    def warp(self, u):
        return self.impostor.warp(u)

    def pdf(self, x):
        return self.truth.pdf(x)

    def domain(self):
        return self.truth.domain()
