"""Hammersley points (Hammersley 1960; PBRT-v4 `Hammersley`), randomized, in R replicates.

A Hammersley set of m points in d dimensions is the Halton sequence in d − 1 dimensions with a
first coordinate i/m added: point i is (i/m, φ₂(i), φ₃(i), φ₅(i), ...), φ_b the radical inverse in
base b. Knowing m in advance buys one coordinate of perfect stratification (its star discrepancy
is O(log^(d−1) m / m) against Halton's O(log^d m / m)); so the stream's `total` is required, as for
`Stratified` and `LatinHypercube`.

Randomization, per replicate r (global index g = R p + r, the `Source` convention, m = total / R):
the first coordinate is frac(p/m + U_r), one uniform shift of the grid per replicate (a
Cranley–Patterson rotation: every point uniform, one point in each stratum [k/m, (k + 1)/m)); the
others are the scrambled Halton coordinates of `halton.Halton` with the same scramble and seed, so
each point is uniform and the R replicate means are independent estimates whose spread is the
standard error.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp

from .._core.pytree import static_field
from .halton import SCRAMBLES, Halton, _to_unit
from .philox import bits_to_unit
from .sources import Source, _check_replicates, register_source
from ._replicated import STREAM_HAMMERSLEY, Layout, replicate_words, stack_lanes

__all__ = ["Hammersley"]


@register_source
class Hammersley(Source):
    """Randomized Hammersley points (see the module docstring), R independent replicates (default 16).

    Args:
      replicates: an integer in [2, 2^32). `total` (the stream's points) must be a multiple of it,
        with total / replicates at most 2^32.
      scramble: the Halton coordinates' scramble, "permutation" (default) or "owen".
    """

    name: ClassVar[str] = "hammersley"
    scramble: str = static_field(default="permutation")

    def __init__(self, replicates: int = 16, scramble: str = "permutation"):
        self.replicates = _check_replicates("Hammersley", replicates)
        if scramble not in SCRAMBLES:
            raise ValueError(f"Hammersley: parameter 'scramble' must be 'permutation' or 'owen'; got {scramble!r}")
        self.scramble = scramble

    def _per_replicate(self, total) -> int:
        if total is None:
            raise ValueError("Hammersley: 'total' (the number of points of the whole stream) is required")
        if total % self.replicates or not 1 <= total // self.replicates <= 1 << 32:
            raise ValueError(f"Hammersley: parameter 'total' must be a multiple of replicates={self.replicates} "
                             f"with total / replicates in [1, 2^32]; got {total}")
        return total // self.replicates

    def lanes(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        m = self._per_replicate(total)
        layout = Layout(offset, count, self.replicates, aligned)
        (shift,) = replicate_words(seed, self.replicates, 1, STREAM_HAMMERSLEY, 0, by_column=True)[:1]
        with jax.enable_x64(True):
            fraction = (layout.point.lo.astype(jnp.float64) / float(m)
                        + bits_to_unit(layout.take(shift[0]), jnp.float64))
            first = layout.full(_to_unit(jnp.where(fraction >= 1.0, fraction - 1.0, fraction), dtype))
        if dims == 1:
            return ((first,),)
        (rest,) = Halton(self.replicates, self.scramble).lanes(seed, offset, count, dims - 1, dtype, total, aligned)
        return ((first,) + tuple(rest),)

    def block(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        (lanes,) = self.lanes(seed, offset, count, dims, dtype, total, aligned)
        return stack_lanes(lanes, count)

    def __repr__(self):
        return f"Hammersley(replicates={self.replicates}, scramble={self.scramble!r})"

    def __eq__(self, other):
        return type(self) is type(other) and (self.replicates, self.scramble) == (other.replicates, other.scramble)

    def __hash__(self):
        return hash(("Hammersley", self.replicates, self.scramble))
