"""Generic rejection sampling with a fixed, jit-friendly number of tries."""

from __future__ import annotations

from typing import Any, Callable, ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, draw, key_and_shape, point_method, refuse_class
from .._core.pytree import Pytree, parameter, static_field


def select_first(candidates, accepted, fallback):
    """The first accepted candidate along the tries axis, else `fallback`.

    `accepted` has shape (..., tries); `candidates` and `fallback` are pytrees whose leaves have
    shapes (..., tries, *e) and (..., *e). Written as a chain of selects from the last try to the
    first, it is elementwise (no argmax, no gather), so it fuses with the proposals around it
    (`jaxsample._core.lanes`); the result is exactly that of argmax + take_along_axis + where(any).
    """
    tries = accepted.shape[-1]
    out = fallback
    for k in reversed(range(tries)):
        def pick(candidate, current, k=k):
            mask = accepted[..., k].reshape(accepted.shape[:-1] + (1,) * (current.ndim - accepted.ndim + 1))
            return jnp.where(mask, jax.lax.index_in_dim(candidate, k, accepted.ndim - 1, keepdims=False), current)
        out = jax.tree_util.tree_map(pick, candidates, out)
    return out


class RejectionInfo(Pytree):
    """Per sample: whether some try was accepted (`accepted`), and how many of the `tries`
    proposals passed the test (`n_passed`; each passes with probability exactly 1/bound)."""

    accepted: jax.Array
    n_passed: jax.Array


class Rejection(Sampler):
    """Rejection sampling of a normalised target density p from a proposal q with p <= M q.

    Each try draws x ~ q from `proposal` and a uniform v, and passes when v M q(x) < p(x); the
    output is the first passing x (von Neumann 1951; Chuang, *Monte Carlo Integration*). Every try
    passes with probability exactly ∫ q p/(M q) = 1/M, independently, so all `tries` are run
    without branching and the first passing one is selected: a jit-friendly fixed cost.

    If all tries fail (probability ε = (1 - 1/M)^tries) the output is `fallback.warp` of its own
    uniforms when a `fallback` sampler of p is given — the density is then p exactly — and
    otherwise one more, independent proposal, so the density is exactly (1 - ε) p + ε q, which is
    what `pdf` reports (choose `tries` so that ε is negligible). `sample_with_info` reports the
    fall-through per sample.

    Parameters: `proposal` (a Sampler), `target_pdf` (a function of points of the proposal's
    event shape, normalised over the same measure, broadcasting over leading axes; static, so it
    should be a module-level function, not a fresh lambda per call), `bound` M >= 1 (a leaf),
    `tries` (static), `fallback` (optional Sampler of p), `support` (optional domain for the
    checks; default the proposal's). A wrong bound (p > M q somewhere) makes the output wrong
    where it is violated; it cannot be detected under jit.

    uniform_dims = tries · (proposal dims + 1) + (fallback dims, or proposal dims).
    """

    proposal: Sampler
    target_pdf: Callable = static_field()
    bound: Any = parameter(1.0, np.inf, high_open=True, doc="M, with p <= M q")
    tries: int = parameter(1, 4096, static=True, default=16)
    fallback: Sampler | None = None
    support: Any = static_field(default=None)

    def __post_init__(self):
        refuse_class("Rejection", "proposal", self.proposal)
        refuse_class("Rejection", "fallback", self.fallback)

    batchable: ClassVar = False

    @property
    def event_shape(self):
        return self.proposal.event_shape

    @property
    def measure(self):
        return self.proposal.measure

    @property
    def _tail_dims(self) -> int:
        return self.fallback.uniform_dims if self.fallback is not None else self.proposal.uniform_dims

    @property
    def uniform_dims(self) -> int:
        return self.tries * (self.proposal.uniform_dims + 1) + self._tail_dims

    @property
    def fall_through_probability(self):
        """ε = (1 - 1/M)^tries: the probability that every try is rejected."""
        return (1.0 - 1.0 / jnp.asarray(self.bound)) ** self.tries

    @point_method(batched=False)
    def warp_with_info(self, u):
        dims = self.proposal.uniform_dims
        blocks = u[..., : self.tries * (dims + 1)].reshape(u.shape[:-1] + (self.tries, dims + 1))
        x, q = self.proposal.warp_with_pdf(blocks[..., :dims])
        passed = blocks[..., dims] * self.bound * q < self.target_pdf(x)
        tail = u[..., -self._tail_dims:]
        spare = (self.fallback if self.fallback is not None else self.proposal).warp(tail)
        # An invalid bound (NaN after the invalid-parameter rule) fails every test, so the output
        # would be the fallback's: adding 0·M makes it NaN then, as the rule promises; exact otherwise.
        out = select_first(x, passed, spare) + 0.0 * jnp.asarray(self.bound, x.dtype)
        return out, RejectionInfo(jnp.any(passed, axis=-1), jnp.sum(passed, axis=-1, dtype=jnp.int32))

    @point_method
    def warp(self, u):
        return self.warp_with_info(u)[0]

    def sample_with_info(self, key=None, sample_shape=(), dtype=None, *, seed=None, shape=None):
        """(samples, RejectionInfo) from uniforms drawn with `key` (or `seed=`; as `sample`)."""
        return draw(self, *key_and_shape(key, sample_shape, seed, shape, "sample_with_info"), dtype,
                    "warp_with_info")

    @point_method
    def pdf(self, x):
        p = self.target_pdf(x)
        if self.fallback is not None:
            # The density is p exactly, whatever M; 0 * M carries an invalid M's NaN into it (the
            # invalid-parameter rule), as the fall-through term does without a fallback.
            return p + 0.0 * self.bound
        epsilon = self.fall_through_probability
        return (1.0 - epsilon) * p + epsilon * self.proposal.pdf(x)

    def domain(self):
        return self.support if self.support is not None else self.proposal.domain()
