"""`chunk_size` takes effect on every public path that accepts it: a test per option
that fails when the option is ignored.

The samples do not depend on the chunking (counter-based streams; tests/estimators/test_estimate.py
checks that), so values cannot show whether `chunk_size` was honoured. What it controls is the
streaming loop: n samples in chunks of `chunk_size` are a `lax.scan` of n / chunk_size steps,
which bounds the memory. The test reads those lengths from the traced program (no compilation).
With n = 2^15 below the default chunk (2^16), an ignored `chunk_size` leaves no loop of 16 steps.
`estimate_until` loops in a `while_loop`; there the chunk is the step of `n_used`: with a
tolerance met at once it stops at its default `min_n` of 8 steps, 8 x chunk_size samples.
"""

import re

import jax
import jax.numpy as jnp
import pytest

import jaxsample as js

N, CHUNK = 1 << 15, 1 << 11
STEPS = N // CHUNK


def cos3(w):
    return w[2] ** 3


def _scan_lengths(program):
    jaxpr = str(jax.make_jaxpr(program)(jax.random.key(0)))
    return sorted(int(m) for m in re.findall(r"\blength=(\d+)", jaxpr))


def _scene():
    s = js.scene
    frame_point, normal = jnp.zeros(3), jnp.array([0.0, 0.0, 1.0])
    lights = [s.SphereLight(center=jnp.array([0.3, 0.2, 2.0]), radius=0.3, radiance=4.0)]
    return frame_point, normal, jnp.array([0.0, 0.6, 0.8]), s.Phong(exponent=20.0, albedo=0.7), lights


PATHS = {
    "estimate": lambda k, c: js.estimate(cos3, js.CosineHemisphere(), k, N, chunk_size=c).mean,
    "estimate_mis": lambda k, c: js.estimate_mis(cos3, [js.CosineHemisphere(), js.UniformHemisphere()], k,
                                                 [N, N], chunk_size=c).mean,
    "estimate_antithetic": lambda k, c: js.estimate_antithetic(cos3, js.CosineHemisphere(), k, N,
                                                               chunk_size=c).mean,
    "estimate_control_variate": lambda k, c: js.estimate_control_variate(
        cos3, lambda w: w[2], 1.0, js.CosineHemisphere(), k, N, chunk_size=c).mean,
    "estimate_ratio": lambda k, c: js.estimate_ratio(cos3, lambda w: w[2], js.CosineHemisphere(), k, N,
                                                     chunk_size=c).mean,
    "estimate_grad": lambda k, c: js.estimate_grad(lambda e: (cos3, js.PhongLobe(e)), 3.0, k, N,
                                                   chunk_size=c).mean,
    "expectation-score": lambda k, c: js.expectation(cos3, js.CosineHemisphere(), k, N, gradient="score",
                                                     chunk_size=c).mean,
    "expectation_grad": lambda k, c: js.expectation_grad(lambda e: (cos3, js.PhongLobe(e)), 3.0, k, N,
                                                         gradient="score", chunk_size=c).mean,
    "shade": lambda k, c: js.scene.shade(*_scene(), k, N, chunk_size=c).mean,
}


# The loop's steps where they are not n / chunk_size: the antithetic estimator streams n/2 pairs,
# and shade's MIS gives each of its two strategies n/2 samples.
HALVED = {"estimate_antithetic", "shade"}


@pytest.mark.parametrize("path", sorted(PATHS))
def test_chunk_size_sets_the_streaming_loop(path):
    steps = STEPS // 2 if path in HALVED else STEPS
    lengths = _scan_lengths(lambda k: PATHS[path](k, CHUNK))
    assert lengths and set(lengths) == {steps}, (path, lengths)
    default = _scan_lengths(lambda k: PATHS[path](k, None))
    assert steps not in default, (path, default)   # the check can tell: the default has no such loop


def test_estimate_until_steps_by_chunk_size():
    run = jax.jit(lambda k: js.estimate_until(cos3, js.CosineHemisphere(), k, rtol=1.0, max_n=N,
                                              chunk_size=CHUNK))
    result = run(jax.random.key(1))
    assert int(result.n_used) == 8 * CHUNK, int(result.n_used)   # min_n's default: 8 steps
