"""The generator's cost per sample inside the estimator, alternatives side by side.

    python benchmarks/generators.py [--log2n 24] [--repeats 7] [--rounds 2]

Each candidate takes the place of `Random`'s Philox4x32-10 block (four uint32 words per block index,
two 2-d samples) for the duration of one trace, so the whole estimator is the same program around it:
`estimate(f, sampler, key, n).mean` under `jax.jit` for
  box2   f = x0 + x1 over UniformBox([0, 1]^2)   (the generator and the float conversion alone)
  cos3   f = cos³θ with CosineHemisphere()      (plus the warp: the floor the estimator stands on)
Candidates:
  philox10  Philox4x32-10, the default (Salmon, Moraes, Dror & Shaw 2011, "Parallel random numbers:
            as easy as 1, 2, 3", SC11; 10 rounds is their recommended count)
  philox7   the same with 7 rounds (the fewest rounds of Philox4x32 that the paper reports passing
            TestU01's BigCrush; the three more are its safety margin)
  squares   Widynski's Squares (arXiv:2004.06278, 2020): four 64-bit squaring rounds per 32-bit word,
            counter 4 i + w (a fixed key for timing: the paper's statistical results assume its key
            generator's keys)
  threefry  JAX's own Threefry-2x32 (jax.extend.random.threefry_2x32), two words per call, the other
            two words of the block derived by xor (for timing only)
All programs are traced first, then timed in `--rounds` rounds of `interleaved_medians` (each a
median of `--repeats` calls per program in a seeded random order), so a burst of load on this shared
machine falls on every candidate alike. Nothing here changes the library: `Random` stays Philox4x32-10.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp

import jaxsample as js
from jaxsample.report.timing import interleaved_medians
from jaxsample.uniforms import philox, sources

SQUARES_KEY = 0xC8E4FD154CE32F6D  # an odd 64-bit key with distinct hex digits, for timing


def _block(block_index):
    return block_index if isinstance(block_index, philox.Index) else philox.Index(None, philox._u32(block_index))


def _squares32(counter, key):
    """Widynski 2020, four rounds: x = y = c k, z = y + k; three rounds of x = rot32(x^2 + y or z),
    then the high word of x^2 + z."""
    with jax.enable_x64(True):
        k, s = jnp.uint64(key), jnp.uint64(32)
        x = y = counter * k
        z = y + k
        for add in (y, z, y):
            x = x * x + add
            x = (x >> s) | (x << s)
        return ((x * x + z) >> s).astype(jnp.uint32)


def candidate_words(name):
    """A drop-in for `sources._philox_words(seed, block_index, stream, word_block)`: four words."""
    def philox_rounds(rounds):
        def words(seed, block_index, stream, word_block=0):
            b = _block(block_index)
            high = jnp.zeros_like(b.lo) if b.hi is None else b.hi
            counter = (b.lo, jnp.zeros_like(b.lo) + philox._u32(word_block),
                       jnp.zeros_like(b.lo) + philox._u32(stream), high)
            return philox.philox4x32(counter, (seed[..., 0], seed[..., 1]), rounds=rounds)
        return words

    def squares(seed, block_index, stream, word_block=0):
        with jax.enable_x64(True):
            c = _block(block_index).lo.astype(jnp.uint64) * jnp.uint64(4)
            return tuple(_squares32(c + jnp.uint64(w), SQUARES_KEY) for w in range(4))

    def threefry(seed, block_index, stream, word_block=0):
        from jax.extend.random import threefry_2x32
        lo = _block(block_index).lo * philox._u32(2)
        m = lo.shape[0]
        both = threefry_2x32(seed, jnp.concatenate([lo, lo + 1]))
        return both[:m], both[m:], both[:m] ^ philox._u32(0x9E3779B9), both[m:] ^ philox._u32(0x7F4A7C15)

    return {"philox10": philox_rounds(10), "philox7": philox_rounds(7), "squares": squares,
            "threefry": threefry}[name]


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--log2n", type=int, default=24)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args(argv)
    n = 1 << args.log2n
    programs = {"box2": (lambda w: w[0] + w[1], js.UniformBox(jnp.zeros(2), jnp.ones(2))),
                "cos3": (lambda w: w[2] ** 3, js.CosineHemisphere())}
    original = sources._philox_words
    fns = {}
    try:
        for name in ("philox10", "philox7", "squares", "threefry"):
            sources._philox_words = candidate_words(name)
            for program, (f, sampler) in programs.items():
                # A new lambda per candidate, so that no trace is reused across candidates.
                fn = jax.jit(lambda key, f=f, s=sampler: js.estimate(lambda w: f(w), s, key, n).mean)
                value = float(fn(jax.random.key(0)))  # traces and compiles under this candidate
                print(f"{name:9s} {program}: estimate {value:.5f}")
                fns[(name, program)] = fn
    finally:
        sources._philox_words = original
    rounds = [interleaved_medians(fns, iter(jax.random.split(jax.random.key(10 + r), 1000)), args.repeats)
              for r in range(args.rounds)]
    print(f"\nn = 2^{args.log2n}, ns per sample, median of {args.repeats} calls per round, {args.rounds} rounds; "
          "ratio = the candidate's time over philox10's in the same round")
    print("| generator | box2 ns/sample | cos3 ns/sample | box2 / philox10 | cos3 / philox10 |\n|---|---|---|---|---|")
    for name in ("philox10", "philox7", "squares", "threefry"):
        ns = {p: [1e9 * t[(name, p)] / n for t in rounds] for p in programs}
        ratio = {p: [t[(name, p)] / t[("philox10", p)] for t in rounds] for p in programs}
        cell = lambda v: " / ".join(f"{x:.2f}" for x in v)
        print(f"| {name} | {cell(ns['box2'])} | {cell(ns['cos3'])} | {cell(ratio['box2'])} | {cell(ratio['cos3'])} |")


if __name__ == "__main__":
    main()
