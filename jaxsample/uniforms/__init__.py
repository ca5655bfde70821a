"""Layer 2: uniform sources — maps from a PRNG key to points of the open unit hypercube (0, 1)^d.

One file per generator: `philox` (Philox4x32-10 and the bits-to-float map), `sobol` (Sobol' points,
Joe & Kuo direction numbers, Owen scrambling) and `sources` (the `Random`, `Stratified` and `Sobol`
sources the estimators stream from; its docstring states the streams and the float grid), the
replicated point sets `lattice` (a shifted extensible rank-1 lattice with the tent transform) `halton`
(scrambled Halton), `hammersley` (Hammersley: Halton with a shifted grid as first coordinate) and
`lhs` (Latin hypercube), and
`index`: sample indices have 64 bits, carried as two uint32 words (`index.Index`).
"""

from .philox import as_key, bits_to_unit, philox4x32, seed_from_key
from .sobol import MAX_SOBOL_DIMS, owen_scramble, sobol_direction_numbers, sobol_points
from .sources import Random, Sobol, Source, Stratified, as_source, uniform_block
from .lattice import MAX_LATTICE_DIMS, Lattice, lattice_generating_vector, lattice_points
from .halton import MAX_HALTON_DIMS, Halton, halton_points, halton_primes
from .lhs import LatinHypercube
from .hammersley import Hammersley

# Attributes outside `__all__`, re-exported explicitly (`name as name`).
from .philox import SEED_WORDS as SEED_WORDS, random_bits as random_bits
from .sources import SourceLike as SourceLike

__all__ = [
    "Random", "Stratified", "Sobol", "Source", "as_key", "as_source", "seed_from_key", "uniform_block",
    "philox4x32", "sobol_direction_numbers", "sobol_points", "owen_scramble", "bits_to_unit",
    "MAX_SOBOL_DIMS", "Lattice", "lattice_points", "lattice_generating_vector", "MAX_LATTICE_DIMS",
    "Halton", "halton_points", "halton_primes", "MAX_HALTON_DIMS", "LatinHypercube", "Hammersley",
]
