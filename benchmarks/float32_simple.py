"""Float32 failure rates of the Henyey–Greenstein, linear and normal warps, beside the formulas
PBRT-v4 and Mitsuba 3 print, at the same uniforms: `python benchmarks/float32_simple.py`.

The uniforms are every float32 point the library's random source can produce, (k + 1/2) 2^-23 for
k = 0 .. 2^23 - 1 (`jaxsample.uniforms.bits_to_unit`): each is equally likely, so a rate over them
is the exact probability that one sample fails (no sampling noise; `--log2-points 20` takes every
8th for a quicker run). u = 0 exactly, which the contract allows but the source never produces,
is reported on its own.

The other routines are written here in NumPy float32 from the formulas as printed (our code, not
theirs): PBRT-v4 `util/sampling.h` `SampleHenyeyGreenstein` (g clamped to ±0.99, then
cos θ' = -(1 + g² - ((1 - g²)/(1 + g - 2gu))²)/(2g), 1 - 2u below |g| = 1e-3; PBRT's θ' is
measured from the reversed direction, so cos θ = -cos θ'), the same without the clamp, Mitsuba 3
`src/phase/hg.cpp` (cos θ = (1 + g² - ((1 - g²)/(1 - g + 2gu))²)/(2g), 1 - 2u below |g| = 2^-24,
the fix of mitsuba3#455), each with sin θ = √max(0, 1 - cos²θ) and its density from cos θ; the
textbook root of the linear density's quadratic, (√((1 - u)a² + ub²) - a)/(b - a), and PBRT-v4
`SampleLinear` (the stable root, 0 for u = a = 0, clamped below 1); PBRT-v4 `SampleNormal`,
μ + σ√2 erf⁻¹(2u - 1), with 2u - 1 formed in float32 and erf⁻¹ then taken in float64 (the
best any float32 erf⁻¹ could do).

Failures, each against a float64 reference at the sample the routine returned:
- non-finite: a NaN or inf in the sample or its density;
- off the domain: |cos θ| > 1 before sin θ is formed (a vector off the unit sphere: for
  jaxsample's samples, | |ω| - 1 | > 1e-5), or x outside [0, 1];
- pdf off: the returned density differs from the exact density (for the g, or a and b, that
  was asked for) at the returned sample by more than 1e-3 relative;
- quantile off: the exact CDF at the returned sample differs from the routine's u by more than
  1e-5 (HG, linear) or, for the normal, by more than 1e-3 of min(u, 1 - u) (the tail mass).
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np
import scipy.special

import jaxsample as js

F32 = np.float32
HARD_G = (0.0, 1e-4, -1e-4, 0.5, -0.5, 0.99, -0.99, 1.0 - 1e-4, -(1.0 - 1e-4))
AZIMUTH = F32(0.3)


def source_points(log2_points: int) -> np.ndarray:
    """The float32 points of the library's random source: (k + 1/2) 2^-23, every 2^(23 - log2_points)-th k."""
    step = 1 << (23 - log2_points)
    k = np.arange(0, 1 << 23, step, dtype=np.int64)
    return ((k.astype(np.float32) * F32(2.0 ** -23)) + F32(2.0 ** -24)).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# Henyey–Greenstein
# ---------------------------------------------------------------------------------------------


def _direction(cos_theta, u1):
    sin_theta = np.sqrt(np.maximum(F32(0), F32(1) - cos_theta * cos_theta))
    phi = F32(2 * np.pi) * u1
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=-1).astype(np.float32)


def _hg_density32(cos_theta, g):
    """HG density in float32 from cos θ (this module's convention), as the renderers write it."""
    w = F32(1) + g * g - F32(2) * g * cos_theta
    return (F32(1 / (4 * np.pi)) * (F32(1) - g * g) / (w * np.sqrt(w))).astype(np.float32)


def pbrt_hg(u0, u1, g, clamp=True):
    """PBRT-v4's printed formula; returns (direction, density, ξ in this module's convention)."""
    g = F32(np.clip(g, -0.99, 0.99)) if clamp else F32(g)
    u64 = u0.astype(np.float64)
    with np.errstate(all="ignore"):
        # The branch maps u to cos θ = 2u - 1, the main formula to the CDF's 1 - u: the two
        # orientations differ, so the warp jumps where the branch switches (|g| = 1e-3).
        if abs(g) < 1e-3:
            cos_prime, xi = F32(1) - F32(2) * u0, u64
        else:
            square = (F32(1) - g * g) / (F32(1) + g - F32(2) * g * u0)
            cos_prime, xi = F32(-1) / (F32(2) * g) * (F32(1) + g * g - square * square), 1.0 - u64
        cos_theta = -cos_prime
        # PBRT's density: 1 + g² + 2g cos θ' = 1 + g² - 2g cos θ.
        return cos_theta, _direction(cos_theta, u1), _hg_density32(cos_theta, g), xi


def mitsuba_hg(u0, u1, g):
    g = F32(g)
    u64 = u0.astype(np.float64)
    with np.errstate(all="ignore"):
        if abs(g) < 2.0 ** -24:  # again the opposite orientation to the main formula's
            cos_theta, xi = F32(1) - F32(2) * u0, 1.0 - u64
        else:
            square = (F32(1) - g * g) / (F32(1) - g + F32(2) * g * u0)
            cos_theta, xi = (F32(1) + g * g - square * square) / (F32(2) * g), u64
        return cos_theta, _direction(cos_theta, u1), _hg_density32(cos_theta, g), xi


_hg_warp = jax.jit(lambda g, u: js.HenyeyGreenstein(g).warp_with_pdf(u))


def jaxsample_hg(u0, u1, g, chunk=1 << 21):
    xs, ps = [], []
    for start in range(0, len(u0), chunk):
        u = jnp.stack([jnp.asarray(u0[start:start + chunk]), jnp.full(len(u0[start:start + chunk]), u1)], axis=-1)
        x, p = _hg_warp(jnp.float32(g), u)
        xs.append(np.asarray(x))
        ps.append(np.asarray(p))
    x = np.concatenate(xs)
    return x[:, 2], x, np.concatenate(ps), u0.astype(np.float64)


def _hg_exact(g: float, x: np.ndarray):
    """(density, CDF) of HG(g) at unit vectors x, float64, with 1 ∓ cos θ from x and y at the poles."""
    x = x.astype(np.float64)
    sin2 = x[:, 0] ** 2 + x[:, 1] ** 2
    with np.errstate(all="ignore"):
        one_minus = np.where(x[:, 2] > 0, sin2 / (1.0 + np.abs(x[:, 2])), 1.0 - x[:, 2])
        one_plus = np.where(x[:, 2] < 0, sin2 / (1.0 + np.abs(x[:, 2])), 1.0 + x[:, 2])
        w = np.where(g >= 0, (1.0 - g) ** 2 + 2.0 * g * one_minus, (1.0 + g) ** 2 - 2.0 * g * one_plus)
        density = (1.0 - g) * (1.0 + g) / (4.0 * np.pi * w * np.sqrt(w))
        cdf = (1.0 - g) * one_plus / (np.sqrt(w) * ((1.0 + g) + np.sqrt(w)))
    return density, cdf


def hg_failures(routine, u0, g):
    cos_theta, x, p, xi = routine(u0, AZIMUTH, g)
    cos_theta = np.asarray(cos_theta, np.float64)
    finite = np.all(np.isfinite(x), axis=-1) & np.isfinite(p)
    norm = np.linalg.norm(x.astype(np.float64), axis=-1)
    off_domain = finite & ((np.abs(cos_theta) > 1.0) | (np.abs(norm - 1.0) > 1e-5))
    density, cdf = _hg_exact(float(F32(g)), x)
    with np.errstate(all="ignore"):
        pdf_off = finite & ~(np.abs(p / density - 1.0) <= 1e-3)
        quantile_error = np.where(finite, np.abs(cdf - xi), np.nan)
    return {"non-finite": ~finite, "off the domain": off_domain, "pdf off": pdf_off,
            "quantile off": finite & ~(quantile_error <= 1e-5)}, np.nanmax(quantile_error) if np.any(finite) else np.nan


# ---------------------------------------------------------------------------------------------
# Linear
# ---------------------------------------------------------------------------------------------

LINEAR_AB = ((1.0, 1.0), (1.0, 1.0 + 2.0 ** -23), (1.0, 1.0 + 1e-6), (1.0, 1.0001), (1.0, 1.01), (0.0, 1.0), (1.0, 0.0))


def _linear_pdf32(x, a, b):
    inside = (x >= 0) & (x <= 1)
    return np.where(inside, F32(2) * ((F32(1) - x) * a + x * b) / (a + b), F32(0)).astype(np.float32)


def textbook_linear(u, a, b):
    a, b = F32(a), F32(b)
    with np.errstate(all="ignore"):
        x = (np.sqrt((F32(1) - u) * a * a + u * b * b) - a) / (b - a)
    return x.astype(np.float32), _linear_pdf32(x, a, b)


def pbrt_linear(u, a, b):
    a, b = F32(a), F32(b)
    with np.errstate(all="ignore"):
        x = u * (a + b) / (a + np.sqrt((F32(1) - u) * a * a + u * b * b))
    x = np.where((u == 0) & (a == 0), F32(0), np.minimum(x, F32(1.0 - 2.0 ** -24))).astype(np.float32)
    return x, _linear_pdf32(x, a, b)


_linear_warp = jax.jit(lambda a, b, u: js.Linear(a, b).warp_with_pdf(u))


def jaxsample_linear(u, a, b):
    x, p = _linear_warp(jnp.float32(a), jnp.float32(b), jnp.asarray(u)[:, None])
    return np.asarray(x), np.asarray(p)


def linear_failures(routine, u, a, b):
    x, p = routine(u, a, b)
    a64, b64 = float(F32(a)), float(F32(b))
    x64 = x.astype(np.float64)
    finite = np.isfinite(x) & np.isfinite(p)
    off_domain = finite & ((x64 < 0) | (x64 > 1))
    with np.errstate(all="ignore"):
        density = 2.0 * ((1.0 - x64) * a64 + x64 * b64) / (a64 + b64)
        cdf = (2.0 * a64 * x64 + (b64 - a64) * x64 * x64) / (a64 + b64)
        pdf_off = finite & ~(np.abs(p - density) <= 1e-3 * density)
        quantile_error = np.where(finite, np.abs(cdf - u.astype(np.float64)), np.nan)
    return {"non-finite": ~finite, "off the domain": off_domain, "pdf off": pdf_off,
            "quantile off": finite & ~(quantile_error <= 1e-5)}, np.nanmax(quantile_error) if np.any(finite) else np.nan


# ---------------------------------------------------------------------------------------------
# Normal
# ---------------------------------------------------------------------------------------------


def pbrt_normal(u):
    two_u_minus_one = F32(2) * u - F32(1)
    with np.errstate(all="ignore"):
        return (np.sqrt(2.0) * scipy.special.erfinv(two_u_minus_one.astype(np.float64))).astype(np.float32)


_normal_warp = jax.jit(lambda u: js.Normal(0.0, 1.0).warp(u))


def jaxsample_normal(u):
    return np.asarray(_normal_warp(jnp.asarray(u)[:, None]))


def normal_failures(routine, u):
    z = routine(u)
    finite = np.isfinite(z)
    u64 = u.astype(np.float64)
    with np.errstate(all="ignore"):
        relative = np.abs(scipy.special.ndtr(z.astype(np.float64)) - u64) / np.minimum(u64, 1.0 - u64)
    relative = np.where(finite & (u64 > 0), relative, np.nan)
    return {"non-finite": ~finite, "quantile off": finite & ~(relative <= 1e-3)}, np.nanmax(relative)


# ---------------------------------------------------------------------------------------------


def _rate(mask) -> str:
    fraction = float(np.mean(mask))
    return "0" if fraction == 0 else f"{100 * fraction:.3g} %"


def _at_zero(failures) -> str:
    failed = [name for name, mask in failures.items() if bool(mask[0])]
    return "ok" if not failed else ", ".join(failed)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--log2-points", type=int, default=23,
                        help="2^n of the source's 2^23 float32 points (default all)")
    args = parser.parse_args(argv)
    start = time.time()
    u = source_points(args.log2_points)
    with_zero = np.concatenate([[F32(0)], u]).astype(np.float32)
    columns = ("non-finite", "off the domain", "pdf off", "quantile off")
    print(f"float32, {len(u):,} source points (k + 1/2) 2^-23; the u = 0 column is u = 0 exactly.\n")

    print("## Henyey–Greenstein\n")
    print("| g | routine | " + " | ".join(columns) + " | max quantile error | u = 0 |")
    print("|---|---|" + "---|" * (len(columns) + 2))
    routines = {"jaxsample": jaxsample_hg, "PBRT-v4 (g clamped to ±0.99)": pbrt_hg,
                "PBRT-v4 formula, unclamped": lambda u0, u1, g: pbrt_hg(u0, u1, g, clamp=False),
                "Mitsuba 3": mitsuba_hg}
    for g in HARD_G:
        for name, routine in routines.items():
            failures, worst = hg_failures(routine, with_zero, g)
            rest = {k: m[1:] for k, m in failures.items()}
            print(f"| {float(F32(g)):+.7g} | {name} | " + " | ".join(_rate(rest[c]) for c in columns)
                  + f" | {worst:.2g} | {_at_zero(failures)} |")
    for g in (1.0, -1.0):
        for name in ("PBRT-v4 formula, unclamped", "Mitsuba 3"):
            _, _, p, _ = routines[name](with_zero, AZIMUTH, g)
            print(f"| {g:+g} | {name} | non-finite density: {_rate(~np.isfinite(p))} | | | | | |")
    print("| ±1 | jaxsample | refused: g must be in (-1, 1) (ValueError; NaN when traced) | | | | | |")

    print("\n## Linear, a -> b\n")
    print("| a | b | routine | " + " | ".join(columns) + " | max quantile error | u = 0 |")
    print("|---|---|---|" + "---|" * (len(columns) + 2))
    for a, b in LINEAR_AB:
        for name, routine in {"jaxsample": jaxsample_linear, "textbook root": textbook_linear,
                              "PBRT-v4 SampleLinear": pbrt_linear}.items():
            failures, worst = linear_failures(routine, with_zero, a, b)
            rest = {k: m[1:] for k, m in failures.items()}
            print(f"| {float(F32(a)):.9g} | {float(F32(b)):.9g} | {name} | "
                  + " | ".join(_rate(rest[c]) for c in columns) + f" | {worst:.2g} | {_at_zero(failures)} |")

    print("\n## Normal (μ = 0, σ = 1)\n")
    # On the source's points 2u - 1 is exact, (2k + 1) 2^-23 - 1; a finer u (Sobol' points, a
    # user's own) is rounded by it. Log-spaced float32 u from 2^-24 (where jaxsample's clamp
    # starts) to 1/2 show the lower tail.
    tail = np.geomspace(2.0 ** -24, 0.5, len(u)).astype(np.float32)
    print("| u | routine | non-finite | quantile off by > 1e-3 of the tail mass "
          "| max relative quantile error | u = 0 |")
    print("|---|---|---|---|---|---|")
    point_sets = (("the source's points", with_zero),
                  ("log-spaced in [2^-24, 1/2]", np.concatenate([[F32(0)], tail])))
    routines = {"jaxsample (ndtri)": jaxsample_normal, "PBRT-v4 SampleNormal (erf⁻¹(2u - 1))": pbrt_normal}
    for label, points in point_sets:
        for name, routine in routines.items():
            failures, worst = normal_failures(routine, points)
            rest = {k: m[1:] for k, m in failures.items()}
            # At u = 0 the quantile is -inf: only whether the sample is finite is asked there.
            at_zero = "non-finite" if failures["non-finite"][0] else "finite"
            print(f"| {label} | {name} | {_rate(rest['non-finite'])} | {_rate(rest['quantile off'])} | {worst:.2g} "
                  f"| {at_zero} |")
    print(f"\n({time.time() - start:.0f} s)")


if __name__ == "__main__":
    main()
