"""Float32 failure rates of the microfacet samplers at their hard cases, beside Heitz 2018's GGX
visible-normal routine as printed, at the same uniforms: `python benchmarks/float32_microfacet.py`.

The uniforms: `--points` pairs of float32 points of the library's random source, (k + 1/2) 2^-23
(`jaxsample.uniforms.bits_to_unit`), k drawn at random (seed 0), plus the 9 rows of {0, 0.5, 1 - 2^-24}²
(u = 0 is allowed by the contract though the source never produces it). A rate is failures / points.

Cases: roughness 1e-4, 1e-2, 0.3, 1 and the anisotropic (1, 1e-3), each at wo along the normal,
at 45° (azimuth 45°: skew to the anisotropy) and grazing (cos θ_o = 1e-7, azimuth 0.3).

The textbook routines are written here in NumPy float32 from the formulas as printed (our code, not
theirs): Heitz 2018 (JCGT 7(4), listing 1): stretch wo, build T1 = normalize(-V_y, V_x, 0) (or x),
T2 = V × T1, a disk point (√u₁ cos 2πu₂, √u₁ sin 2πu₂) warped by t₂ <- (1 - s)√(1 - t₁²) + s t₂,
s = (1 + V_z)/2, lifted by √max(0, 1 - t₁² - t₂²) and unstretched with max(0, N_z); "PBRT-v4" is the
same with PBRT-v4's max(1e-6, N_z) (`TrowbridgeReitzDistribution::Sample_wm`). Their density is
PBRT-v4's `PDF(w, wm) = G1(w) / |cos θ| D(wm) |w·wm|` with `D` and `Lambda` through tan²θ =
sin²θ / cos²θ, sin²θ = max(0, 1 - cos²θ), and cos φ = x / sin θ (`util/scattering.h`,
`util/vecmath.h`), in float32.

Failures, each judged in float64 at the float32 sample the routine returned:
- non-finite: a NaN or inf in the sample or its density;
- non-unit: | |m| - 1 | > 1e-5;
- outside: the sample has exact density 0 (m_z <= 0 or wo·m <= 0 for visible normals: a normal on
  or below the horizon, or one wo cannot see);
- pdf off: the returned density differs from the exact density at the returned sample by more than
  1e-3 relative (for jaxsample, `warp_with_pdf` in float32 against `pdf` in float64).
For MicrofacetReflection a reflected direction below the horizon is a sample of the lobe, not a
failure; the column "below" gives their fraction (mass the BRDF's zero takes).
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js

F32 = np.float32
ALPHAS = ((1e-4, 1e-4), (1e-2, 1e-2), (0.3, 0.3), (1.0, 1.0), (1.0, 1e-3))
_S = float(np.sqrt(0.5))
WOS = {"normal": (0.0, 0.0, 1.0), "45°": (0.5, 0.5, _S),
       "grazing 1e-7": (float(np.sqrt(1 - 1e-14) * np.cos(0.3)), float(np.sqrt(1 - 1e-14) * np.sin(0.3)), 1e-7)}


def uniforms(points: int) -> np.ndarray:
    k = np.random.default_rng(0).integers(0, 1 << 23, size=(points, 2))
    u = (k.astype(F32) * F32(2.0 ** -23) + F32(2.0 ** -24)).astype(F32)
    edges = np.array([0.0, 0.5, 1.0 - 2.0 ** -24], F32)
    return np.concatenate([u, np.stack(np.meshgrid(edges, edges), -1).reshape(-1, 2)])


# ---------------------------------------------------------------------------------------------
# The textbook routine (NumPy float32)
# ---------------------------------------------------------------------------------------------

def _normalize(v):
    return v / np.sqrt(np.sum(v * v, axis=-1, keepdims=True))


def heitz2018(wo, ax, ay, u, floor):
    """Heitz 2018 listing 1 in float32; `floor` is the clamp of N_z (0: as printed, 1e-6: PBRT-v4)."""
    ax, ay, wo, u = F32(ax), F32(ay), np.asarray(wo, F32), u.astype(F32)
    vh = _normalize(np.array([ax * wo[0], ay * wo[1], wo[2]], F32))
    lensq = vh[0] * vh[0] + vh[1] * vh[1]
    t1_axis = np.array([-vh[1], vh[0], F32(0)], F32) / np.sqrt(lensq) if lensq > 0 else np.array([1, 0, 0], F32)
    t2_axis = np.cross(vh, t1_axis).astype(F32)
    r = np.sqrt(u[:, 0])
    phi = F32(2 * np.pi) * u[:, 1]
    t1, t2 = r * np.cos(phi), r * np.sin(phi)
    s = F32(0.5) * (F32(1) + vh[2])
    t2 = (F32(1) - s) * np.sqrt(F32(1) - t1 * t1) + s * t2
    nh = (t1[:, None] * t1_axis + t2[:, None] * t2_axis
          + np.sqrt(np.maximum(F32(0), F32(1) - t1 * t1 - t2 * t2))[:, None] * vh)
    return _normalize(np.stack([ax * nh[:, 0], ay * nh[:, 1], np.maximum(F32(floor), nh[:, 2])], -1))


def _trig(w):
    cos2 = w[..., 2] * w[..., 2]
    sin2 = np.maximum(F32(0), F32(1) - cos2)
    sin = np.sqrt(sin2)
    safe = np.where(sin == 0, F32(1), sin)
    cos_phi = np.where(sin == 0, F32(1), np.clip(w[..., 0] / safe, -1, 1))
    sin_phi = np.where(sin == 0, F32(0), np.clip(w[..., 1] / safe, -1, 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        tan2 = sin2 / cos2
    return cos2, tan2, cos_phi, sin_phi


def pbrt_pdf(wo, ax, ay, wm):
    """PBRT-v4's visible-normal density of Trowbridge–Reitz, in float32."""
    ax, ay, wo = F32(ax), F32(ay), np.asarray(wo, F32)
    with np.errstate(all="ignore"):
        cos2, tan2, cos_phi, sin_phi = _trig(wm)
        e = tan2 * ((cos_phi / ax) ** 2 + (sin_phi / ay) ** 2)
        d = F32(1) / (F32(np.pi) * ax * ay * cos2 * cos2 * (F32(1) + e) ** 2)
        d = np.where(np.isinf(tan2), F32(0), d)
        ocos2, otan2, ocos_phi, osin_phi = _trig(wo[None])
        alpha2 = (ocos_phi * ax) ** 2 + (osin_phi * ay) ** 2
        lam = np.where(np.isinf(otan2), F32(0), (np.sqrt(F32(1) + alpha2 * otan2) - F32(1)) / F32(2))
        g1 = F32(1) / (F32(1) + lam)
        return (g1 / np.abs(wo[2]) * d * np.abs(wm @ wo)).astype(F32)


# ---------------------------------------------------------------------------------------------
# Counting
# ---------------------------------------------------------------------------------------------

def _exact_pdf(make, alphas, wo, x):
    with jax.enable_x64(True):
        return np.asarray(make(jnp.float64(alphas[0]), jnp.float64(alphas[1]), jnp.asarray(wo, jnp.float64))
                          .pdf(jnp.asarray(np.asarray(x, np.float64))))


def failures(x, p, exact, reflection=False):
    x, p = np.asarray(x, np.float64), np.asarray(p, np.float64)
    finite = np.all(np.isfinite(x), -1) & np.isfinite(p)
    unit = np.abs(np.linalg.norm(np.where(np.isfinite(x), x, 0.0), axis=-1) - 1.0) <= 1e-5
    outside = finite & (exact <= 0)
    with np.errstate(all="ignore"):
        off = finite & (exact > 0) & ~(np.abs(p / exact - 1.0) <= 1e-3)
    row = {"non-finite": ~finite, "non-unit": finite & ~unit, "outside": outside, "pdf off": off}
    row = {k: float(np.mean(v)) for k, v in row.items()}
    row["any"] = float(np.mean(~finite | ~unit | outside | off))
    if reflection:
        row["below"] = float(np.mean(finite & (x[:, 2] < 0)))
    return row


def _lobe(kind, name):
    cls = {"GGX": js.GGX, "Beckmann": js.Beckmann}[name]
    if kind == "D":
        return lambda ax, ay, wo: cls(ax, ay)
    lobe = js.VisibleNormals if kind == "visible" else js.MicrofacetReflection
    return lambda ax, ay, wo: lobe(cls(ax, ay), wo)


@jax.jit
def _warp_with_pdf(sampler, u):
    return sampler.warp_with_pdf(u)


def rows(points: int):
    u = uniforms(points)
    u32 = jnp.asarray(u)
    for kind, name in (("D", "GGX"), ("D", "Beckmann"), ("visible", "GGX"), ("visible", "Beckmann"),
                       ("reflection", "GGX"), ("reflection", "Beckmann")):
        make = _lobe(kind, name)
        for alphas in ALPHAS:
            for wo_name, wo in (WOS.items() if kind != "D" else [("-", (0.0, 0.0, 1.0))]):
                sampler = make(jnp.float32(alphas[0]), jnp.float32(alphas[1]), jnp.asarray(wo, jnp.float32))
                x, p = (np.asarray(a) for a in _warp_with_pdf(sampler, u32))
                exact = _exact_pdf(make, alphas, wo, x)
                label = {"D": f"{name} (D cos)", "visible": f"VisibleNormals({name})",
                         "reflection": f"MicrofacetReflection({name})"}[kind]
                yield label, "jaxsample", alphas, wo_name, failures(x, p, exact, kind == "reflection")
                if kind == "visible" and name == "GGX":
                    for routine, floor in (("Heitz 2018", 0.0), ("PBRT-v4", 1e-6)):
                        m = heitz2018(wo, *alphas, u, floor)
                        pm = pbrt_pdf(wo, *alphas, m)
                        yield label, routine, alphas, wo_name, failures(m, pm, _exact_pdf(make, alphas, wo, m))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, default=1 << 18, help="random uniform pairs per case (plus 9 edge rows)")
    args = parser.parse_args(argv)
    start = time.time()
    columns = ("any", "non-finite", "non-unit", "outside", "pdf off", "below")
    print(f"float32 failure rates over {args.points} + 9 uniform pairs per case (JAX {jax.__version__})\n")
    print("| sampler | routine | alpha | wo | " + " | ".join(columns) + " |")
    print("|" + "---|" * (4 + len(columns)))
    for label, routine, alphas, wo_name, row in rows(args.points):
        alpha = f"{alphas[0]:g}" if alphas[0] == alphas[1] else f"{alphas[0]:g}, {alphas[1]:g}"
        cells = [f"{row[c]:.2e}" if c in row and row[c] else ("0" if c in row else "—") for c in columns]
        print(f"| {label} | {routine} | {alpha} | {wo_name} | " + " | ".join(cells) + " |", flush=True)
    print(f"\n({time.time() - start:.0f} s)")


if __name__ == "__main__":
    main()
