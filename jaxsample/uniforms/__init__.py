"""Layer 2: uniform sources — maps from a PRNG key to points of the open unit hypercube (0, 1)^d.

One file per generator: `philox` (Philox4x32-10 and the bits-to-float map), `sobol` (Sobol' points,
Joe & Kuo direction numbers, Owen scrambling) and `sources` (the `Random`, `Stratified` and `Sobol`
sources the estimators stream from; its docstring states the streams and the float grid), and
`index`: sample indices have 64 bits, carried as two uint32 words (`index.Index`).
"""

from .philox import SEED_WORDS, as_key, bits_to_unit, philox4x32, random_bits, seed_from_key
from .sobol import MAX_SOBOL_DIMS, owen_scramble, sobol_direction_numbers, sobol_points
from .sources import Random, Sobol, Source, SourceLike, Stratified, as_source, uniform_block

# Every name of the former single module `jaxsample/uniforms.py` stays reachable as
# jaxsample.uniforms.<name>, the private ones included (the tests and the engine use some).
from .philox import (_PHILOX_M0, _PHILOX_M1, _PHILOX_W0, _PHILOX_W1, _STREAM_JITTER, _STREAM_RANDOM,  # noqa: F401
                     _STREAM_SCRAMBLE, _alignment, _index_words, _philox_words, _samples_per_block, _u32)
from .sobol import (_JOE_KUO_6_21201, _SOBOL_BITS, _reverse_bits, _reverse_bits_np, _scramble_reversed,  # noqa: F401
                    _sobol_low_table)
from .sources import _block_jit, _check_replicates  # noqa: F401

__all__ = [
    "Random", "Stratified", "Sobol", "Source", "as_key", "as_source", "seed_from_key", "uniform_block",
    "philox4x32", "sobol_direction_numbers", "sobol_points", "owen_scramble", "bits_to_unit",
    "MAX_SOBOL_DIMS",
]
