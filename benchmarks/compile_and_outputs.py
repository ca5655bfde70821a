"""Compile time and run time of `estimate` against the same program written by hand.

    python benchmarks/compile_and_outputs.py [--log2n 20] [--repeats 3] [--only NAME,...]

Programs (each written twice, in one process):
- "jaxsample": `js.estimate(f, sampler, key, n).mean` under `jax.jit` (and `jax.grad` of it with
  respect to a parameter of f);
- "by hand": what a user writes without the library: `sampler.sample_with_pdf` on 2^16 points per
  chunk, `jax.vmap(f)` over them, f / p summed, the chunks in `lax.map` over split keys.
Integrands: a 3-term environment integrand (ω ↦ Σ_k c_k max(ω·a_k, 0)^3 over the cosine
hemisphere), and projections of an environment onto real spherical harmonics of degree < L, for
L = 2, 3, 4, 7 (4, 9, 16, 49 coefficients per direction; the SH by the standard recurrences, as
polynomials in x, y, z), over the uniform sphere; and `scene.shade` (default MIS, Phong 50 with a sphere
light and a sky, the parameter scaling the exponent) against the same MIS estimate by hand from the scene
objects' methods (`shade_hand`; its gradient lacks shade's silhouette boundary term). Compile =
`jit(...).lower(...).compile()`
wall time, median of `repeats` fresh compiles (a new closure each time, so nothing is cached);
run = median ns/sample of `repeats` runs after one warm-up, of the program and of its `jax.grad`
(the by-hand gradient keeps its residuals, memory growing with n; jaxsample's recomputes each
chunk in the backward pass, in constant memory). Ratios jaxsample / by hand.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

import jaxsample as js

CHUNK = 1 << 16


def real_sh(w, degree_bound: int):
    """Real spherical harmonics Y_lm(ω) for l < degree_bound, m = -l..l, as one (L^2,) vector:
    associated Legendre functions by the standard three-term recurrences in z, and
    (x + iy)^m = r^m e^{imφ} by complex multiplication, so every term is a polynomial in x, y, z
    (no trigonometry, nothing singular at the poles). Normalization: orthonormal on S²."""
    x, y, z = w[0], w[1], w[2]
    L = degree_bound
    # c_m + i s_m = (x + iy)^m
    cs = [(jnp.ones_like(x), jnp.zeros_like(x))]
    for m in range(1, L):
        c, s = cs[-1]
        cs.append((c * x - s * y, c * y + s * x))
    # P[l][m] without the (1 - z^2)^(m/2) factor (carried by (x + iy)^m)
    P = {}
    for m in range(L):
        P[(m, m)] = jnp.full_like(z, float(np.prod(np.arange(1, 2 * m, 2)) * (-1) ** m))
        if m + 1 < L:
            P[(m + 1, m)] = (2 * m + 1) * z * P[(m, m)]
        for l in range(m + 2, L):
            P[(l, m)] = ((2 * l - 1) * z * P[(l - 1, m)] - (l + m - 1) * P[(l - 2, m)]) / (l - m)
    out = []
    for l in range(L):
        for m in range(-l, l + 1):
            a = abs(m)
            k = np.sqrt((2 * l + 1) / (4 * np.pi) * np.exp(np.sum(-np.log(np.arange(l - a + 1, l + a + 1)))))
            if m == 0:
                out.append(k * P[(l, 0)])
            elif m > 0:
                out.append(np.sqrt(2) * k * P[(l, a)] * cs[a][0])
            else:
                out.append(np.sqrt(2) * k * P[(l, a)] * cs[a][1])
    return jnp.stack(out)


AXES = jnp.array([[0.3, 0.2, 0.9327379], [-0.5, 0.1, 0.8602325], [0.0, -0.6, 0.8]], jnp.float32)


def environment(w, scale):
    """A smooth environment: three clamped cos³ lobes, `scale` times the first."""
    lobes = jnp.maximum(AXES @ w, 0.0) ** 3
    return scale * lobes[0] + 0.5 * lobes[1] + 0.25 * lobes[2]


def cases():
    out = {"environment (3 terms)": (lambda w, s: environment(w, s), js.CosineHemisphere())}
    for L in (2, 3, 4, 7):
        out[f"SH projection L={L} ({L * L} outputs)"] = (
            lambda w, s, L=L: real_sh(w, L) * environment(w, s), js.UniformSphere())
    return out


def library_program(f, sampler, n):
    return lambda s, key: jnp.sum(js.estimate(lambda w: f(w, s), sampler, key, n).mean)


def hand_program(f, sampler, n):
    def run(s, key):
        def one(k):
            x, p = sampler.sample_with_pdf(k, (CHUNK,))
            y = jax.vmap(lambda w: f(w, s))(x)
            return jnp.sum(y / p.reshape((-1,) + (1,) * (y.ndim - 1)), axis=0)
        sums = lax.map(one, jax.random.split(key, n // CHUNK))
        return jnp.sum(jnp.sum(sums, axis=0) / n)
    return run


# scene.shade, default strategy "mis" (one BRDF and one light sample per pair, power heuristic), at the
# report's shading point: Phong 50 with a sphere light and a sky; the parameter is the Phong exponent.
SHADE_POINT, SHADE_NORMAL, SHADE_WO = jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.0, 0.954])


def shade_lights():
    return [js.scene.SphereLight(jnp.array([-0.9, 0.0, 3.0]), 0.3, 10.0), js.scene.ConstantSky(0.2)]


def shade_library(n):
    return lambda s, key: js.scene.shade(SHADE_POINT, SHADE_NORMAL, SHADE_WO, js.scene.Phong(50.0 * s, 0.9),
                                         shade_lights(), key, n).mean


def shade_hand(n):
    """The same MIS estimate by hand: the scene objects' own sample/pdf/eval methods, `jax.vmap` over
    a chunk's pairs, chunks in `lax.map`. Its gradient has no silhouette boundary term (shade's has),
    so for the gradient it is the cheaper program, not the same estimator."""
    from jaxsample.samplers.frame import Frame

    def run(s, key):
        brdf, lights = js.scene.Phong(50.0 * s, 0.9), shade_lights()
        frame = Frame.from_normal(SHADE_NORMAL)
        wo = frame.to_local(SHADE_WO / jnp.linalg.norm(SHADE_WO))
        count = len(lights)

        def mix_pdf(wi):
            return sum(light.pdf(SHADE_POINT, wi) for light in lights) / count

        def weight(own, other):
            return own * own / jnp.where(own * own + other * other > 0, own * own + other * other, 1.0)

        def pair(ub, ul):
            wi_local, p_b = brdf.sample(wo, ub)
            wi = frame.to_world(wi_local)
            radiance = sum(light.radiance_from(SHADE_POINT, wi) for light in lights)
            f_b = brdf.eval(wo, wi_local) * radiance * jnp.maximum(wi_local[2], 0.0)
            y_b = jnp.where(p_b > 0, f_b / jnp.where(p_b > 0, p_b, 1.0), 0.0) * weight(p_b, mix_pdf(wi))
            chosen = jnp.clip(jnp.floor(ul[0] * count), 0, count - 1).astype(jnp.int32)
            draws = [light.sample(SHADE_POINT, ul[1:]) for light in lights]
            wl = sum(jnp.where(chosen == k, d[0], 0.0) for k, d in enumerate(draws))
            radiance_l = sum(light.radiance_from(SHADE_POINT, wl) for light in lights)
            p_l = mix_pdf(wl)
            wl_local = frame.to_local(wl)
            f_l = brdf.eval(wo, wl_local) * radiance_l * jnp.maximum(wl_local[2], 0.0)
            y_l = jnp.where(p_l > 0, f_l / jnp.where(p_l > 0, p_l, 1.0), 0.0) * weight(p_l, brdf.pdf(wo, wl_local))
            return y_b + y_l

        def one(k):
            kb, kl = jax.random.split(k)
            return jnp.sum(jax.vmap(pair)(jax.random.uniform(kb, (CHUNK, 2)), jax.random.uniform(kl, (CHUNK, 3))))
        pairs = n // 2
        return jnp.sum(lax.map(one, jax.random.split(key, pairs // CHUNK))) / pairs
    return run


def compile_seconds(make, grad: bool, repeats: int):
    times = []
    for r in range(repeats):
        fn = make()
        fn = jax.grad(fn) if grad else fn
        start = time.perf_counter()
        jax.jit(fn).lower(jnp.float32(1.0), jax.random.key(r)).compile()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def run_ns(fns: dict, n: int, repeats: int, grad: bool = False) -> dict:
    compiled = {name: jax.jit(jax.grad(fn) if grad else fn) for name, fn in fns.items()}
    for name, fn in compiled.items():
        jax.block_until_ready(fn(jnp.float32(1.0), jax.random.key(0)))
    times = {name: [] for name in fns}
    for r in range(repeats):  # interleaved rounds
        for name, fn in compiled.items():
            start = time.perf_counter()
            jax.block_until_ready(fn(jnp.float32(1.0), jax.random.key(r + 1)))
            times[name].append(time.perf_counter() - start)
    return {name: float(np.median(t)) / n * 1e9 for name, t in times.items()}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--log2n", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", default=None, help="comma-separated substrings of the case names")
    args = parser.parse_args()
    n = 1 << args.log2n
    print(f"n = 2^{args.log2n}, medians of {args.repeats}; {jax.devices()[0].platform}, jax {jax.__version__}\n")
    print("| program | compile: jaxsample / by hand | grad compile: jaxsample / by hand "
          "| run ns/sample: jaxsample / by hand "
          "| run speed, by hand ÷ jaxsample | grad run ns/sample: jaxsample / by hand | grad run speed |")
    print("|---|---|---|---|---|---|---|")
    programs = {name: (lambda f=f, sampler=sampler: library_program(f, sampler, n),
                       lambda f=f, sampler=sampler: hand_program(f, sampler, n))
                for name, (f, sampler) in cases().items()}
    programs["scene.shade (Phong 50, sphere light, sky; MIS)"] = (lambda: shade_library(n), lambda: shade_hand(n))
    for name, (lib, hand) in programs.items():
        if args.only and not any(part in name for part in args.only.split(",")):
            continue
        c = [compile_seconds(m, False, args.repeats) for m in (lib, hand)]
        g = [compile_seconds(m, True, args.repeats) for m in (lib, hand)]
        t = run_ns({"lib": lib(), "hand": hand()}, n, args.repeats)
        d = run_ns({"lib": lib(), "hand": hand()}, n, args.repeats, grad=True)
        print(f"| {name} | {c[0]:.2f} s / {c[1]:.2f} s = {c[0] / c[1]:.2f}x | {g[0]:.2f} s / {g[1]:.2f} s = "
              f"{g[0] / g[1]:.2f}x | {t['lib']:.1f} / {t['hand']:.1f} | {t['hand'] / t['lib']:.2f}x "
              f"| {d['lib']:.1f} / {d['hand']:.1f} | {d['hand'] / d['lib']:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
