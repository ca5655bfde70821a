"""Speed of every public path, as one table: path, ns/sample, ratio, target, met or not.

Run alone: `python -m jaxsample.report.paths [--quick]`; the report includes the same table. A speed
figure for one shape of program is not a speed claim, so each row times a program users write:
integrands written four ways, `sample()` into arrays, every point set (2, 3 and 8 dims), rotated lobes,
mixtures, every sampler of the report's table, `scene.shade`, and the benchmarked ∫cos³ itself.

Every ratio is taken in this one run, from medians of interleaved repeats (each group of programs
is timed in turn, so a burst of load on a shared machine hits them alike); absolute ns/sample
vary 2-3x between runs on a shared machine, the ratios far less. NumPy baselines are
straightforward vectorized float32 code doing the same work (`numpy_baseline.numpy_estimate`
and the warps below).
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample import scene

from .numpy_baseline import cos3, numpy_estimate
from .samplers_table import cases as sampler_cases
from .timing import interleaved_medians

AXIS = jnp.array([0.3, 0.2, 0.9327379], jnp.float32)  # tilted, so every component is used
TWO_PI = np.float32(2 * np.pi)


# ----------------------------------------------------------------------------------------------
# NumPy baselines: the same warps into arrays, vectorized float32
# ----------------------------------------------------------------------------------------------


def _concentric_np(u):
    a, b = 2 * u[:, 0] - 1, 2 * u[:, 1] - 1
    a_wins = np.abs(a) > np.abs(b)
    r = np.where(a_wins, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(a_wins, np.float32(np.pi / 4) * (b / a), np.float32(np.pi / 2) - np.float32(np.pi / 4) * (a / b))
    phi = np.nan_to_num(phi)
    return r * np.cos(phi), r * np.sin(phi), r


def _numpy_warp(name, u):
    """(points, densities) of sampler `name` from uniforms u (n, 2), float32."""
    if name == "CosineHemisphere":
        x, y, r = _concentric_np(u)
        z = np.sqrt(np.maximum((1 - r) * (1 + r), 0))
        return np.stack([x, y, z], -1), z / np.float32(np.pi)
    if name == "PhongLobe(20)":
        cos = u[:, 0] ** np.float32(1 / 21)
        sin = np.sqrt(np.maximum(1 - cos * cos, 0))
        phi = TWO_PI * u[:, 1]
        return (np.stack([sin * np.cos(phi), sin * np.sin(phi), cos], -1),
                np.float32(21 / (2 * np.pi)) * cos ** 20)
    if name == "UniformSphere":
        z = 1 - 2 * u[:, 0]
        sin = 2 * np.sqrt(u[:, 0] * (1 - u[:, 0]))
        phi = TWO_PI * u[:, 1]
        return np.stack([sin * np.cos(phi), sin * np.sin(phi), z], -1), np.full(len(u), np.float32(1 / (4 * np.pi)))
    if name == "UniformDisk":
        x, y, _ = _concentric_np(u)
        return np.stack([x, y], -1), np.full(len(u), np.float32(1 / np.pi))
    raise KeyError(name)


def _numpy_sample(name, n, seed=0):
    u = np.random.default_rng(seed).random((n, 2), dtype=np.float32)
    return _numpy_warp(name, u)


# ----------------------------------------------------------------------------------------------
# Rows
# ----------------------------------------------------------------------------------------------


def _estimate_fn(f, sampler, n, **kw):
    return jax.jit(lambda k: js.estimate(f, sampler, k, n, **kw).mean)


def _times(fns: dict, repeats: int) -> dict:
    keys = iter(jax.random.split(jax.random.key(12), 1000))
    return interleaved_medians(fns, keys, repeats)


def _row(path, seconds, count, ratio, target, bound, note=""):
    """A table row; `bound` > 0 means ratio >= bound is met, < 0 means ratio <= -bound is met."""
    met = ratio >= bound if bound > 0 else ratio <= -bound
    return {"path": path, "ns_per_sample": 1e9 * seconds / count, "ratio": ratio, "target": target,
            "met": bool(met), "note": note}


def integrand_forms(n, repeats):
    """The same integrand written four ways (each within 1.3x of the fastest), and against NumPy (15x)."""
    forms = {
        "x @ a": lambda x: jnp.maximum(x @ AXIS, 0.0) ** 3,
        "jnp.dot(x, a)": lambda x: jnp.maximum(jnp.dot(x, AXIS), 0.0) ** 3,
        "jnp.sum(x * a)": lambda x: jnp.maximum(jnp.sum(x * AXIS), 0.0) ** 3,
        "explicit components": lambda x: jnp.maximum(x[0] * AXIS[0] + x[1] * AXIS[1] + x[2] * AXIS[2], 0.0) ** 3,
    }
    fns = {name: _estimate_fn(f, js.CosineHemisphere(), n) for name, f in forms.items()}
    fns["numpy"] = lambda k: numpy_estimate(n, all_components=True)
    t = _times(fns, repeats)
    fastest = min(t[name] for name in forms)
    slowest = max(t[name] for name in forms)
    rows = [_row(f"∫max(ω·a,0)³ cosine, {name}", t[name], n, t[name] / fastest, "≤ 1.3× fastest form", -1.3)
            for name in forms]
    rows.append(_row("∫max(ω·a,0)³ cosine, slowest form vs NumPy", slowest, n, t["numpy"] / slowest,
                     "≥ 15× NumPy", 15.0, f"NumPy {1e9 * t['numpy'] / n:.1f} ns/sample"))
    return rows


def sample_into_arrays(n, repeats):
    """sample / sample_with_pdf into arrays against NumPy doing the same warp (5x)."""
    samplers = {"CosineHemisphere": js.CosineHemisphere(), "PhongLobe(20)": js.PhongLobe(20.0),
                "UniformSphere": js.UniformSphere(), "UniformDisk": js.UniformDisk()}
    # The floor under any sample(): XLA writing a fresh (n, 3) and (n,) float32 result with no
    # work behind it (first-touch page faults of new buffers dominate on CPU).
    write = jax.jit(lambda k: (jnp.broadcast_to(jax.random.key_data(k)[0].astype(jnp.float32), (n, 3)) + 1.0,
                               jnp.broadcast_to(jax.random.key_data(k)[1].astype(jnp.float32), (n,)) + 1.0))
    rows = []
    for name, s in samplers.items():
        fns = {"sample": lambda k, s=s: s.sample(k, (n,)),
               "sample_with_pdf": lambda k, s=s: s.sample_with_pdf(k, (n,)),
               "numpy": lambda k, name=name: _numpy_sample(name, n), "write": write}
        t = _times(fns, repeats)
        for method in ("sample", "sample_with_pdf"):
            rows.append(_row(f"{name}.{method}(key, (2^{n.bit_length() - 1},))", t[method], n,
                             t["numpy"] / t[method], "≥ 5× NumPy", 5.0,
                             f"NumPy {1e9 * t['numpy'] / n:.1f} ns/sample; writing the result "
                             f"arrays alone {1e9 * t['write'] / n:.1f}"))
    return rows


def _point_sets():
    """Every point set at its default settings and the scrambles a user can ask for, by name."""
    from jaxsample import uniforms as U

    return {"sobol": "sobol", "sobol-lms": U.Sobol(scramble="lms"), "sobol-padded": U.Sobol(padding=True),
            "stratified": "stratified", "lattice": "lattice", "halton": "halton",
            "halton-owen": U.Halton(scramble="owen"), "lhs": "lhs"}


def quasi_random(n, repeats):
    """Every point set against Philox in the same estimate (2-d, 3-d, 8-d), each within 2x."""
    cases = {"2-d cosine ∫cos³": (cos3, js.CosineHemisphere()),
             "3-d box ∫|x|²": (lambda x: jnp.sum(x * x), js.UniformBox(jnp.zeros(3), jnp.ones(3))),
             "8-d box ∫|x|²": (lambda x: jnp.sum(x * x), js.UniformBox(jnp.zeros(8), jnp.ones(8)))}
    rows = []
    for name, (f, s) in cases.items():
        sets = {u: v for u, v in _point_sets().items() if not (u == "stratified" and "8-d" in name)}
        fns = {"random": _estimate_fn(f, s, n, uniforms="random")}
        fns.update({u: _estimate_fn(f, s, n, uniforms=v) for u, v in sets.items()})
        t = _times(fns, repeats)
        for u in sets:
            rows.append(_row(f"{name}, uniforms={u!r}", t[u], n, t[u] / t["random"], "≤ 2× random", -2.0))
    return rows


def composition(n, repeats):
    """Oriented and Mixture against their parts; every sampler against the cosine."""
    normal = jnp.array([0.48, -0.6, 0.64])
    dot3 = lambda x: jnp.maximum(x @ AXIS, 0.0) ** 3
    cone, phong = js.UniformCone(0.9), js.PhongLobe(20.0)
    weights = jnp.array([0.5, 0.5])
    fns = {"cone": _estimate_fn(dot3, cone, n), "Oriented(cone)": _estimate_fn(dot3, js.Oriented(cone, normal), n),
           "phong": _estimate_fn(dot3, phong, n), "Oriented(phong)": _estimate_fn(dot3, js.Oriented(phong, normal), n),
           "cosine": _estimate_fn(dot3, js.CosineHemisphere(), n),
           "choice": _estimate_fn(lambda i: i.astype(jnp.float32), js.Discrete(weights), n),
           "mixture": _estimate_fn(dot3, js.Mixture((js.CosineHemisphere(), phong), weights), n)}
    t = _times(fns, repeats)
    rows = [_row(f"Oriented({base}, n), ∫max(ω·a,0)³", t[f"Oriented({base})"], n,
                 t[f"Oriented({base})"] / t[base], "≤ 1.3× the base sampler", -1.3)
            for base in ("cone", "phong")]
    bound = 1.5 * max(t["cosine"], t["phong"]) + t["choice"]
    rows.append(_row("Mixture(cosine, Phong 20), ∫max(ω·a,0)³", t["mixture"], n, t["mixture"] / bound,
                     "≤ 1.5× slowest component + discrete choice", -1.0,
                     f"components {1e9 * t['cosine'] / n:.1f}, {1e9 * t['phong'] / n:.1f}; "
                     f"choice {1e9 * t['choice'] / n:.1f} ns"))
    return rows


def _sum_of_components(x):
    # One cheap integrand for every sampler (every component used, nothing dropped as dead code),
    # so that the row measures the sampler, not its table integrand.
    return jnp.sum(jnp.asarray(x, jnp.float32))


def every_sampler(n, repeats, names=None):
    """Every sampler of the report's table within 3× of CosineHemisphere (per accepted
    sample for rejection samplers, whose acceptance rate is printed), all estimating the sum of
    their sample's components."""
    cases = [c for c in sampler_cases() if names is None or c[0] in names or c[0] == "CosineHemisphere(malley)"]
    fns = {name: _estimate_fn(_sum_of_components, s, n) for name, s, _, _, _ in cases}
    t = _times(fns, repeats)
    reference = t["CosineHemisphere(malley)"]
    rows = []
    for name, s, _, _, _ in cases:
        if name == "CosineHemisphere(malley)":
            continue
        seconds, note = t[name], ""
        rate = _acceptance(s)
        if rate is not None:
            seconds, note = seconds / rate, f"per accepted sample; acceptance {rate:.3f}"
        elif getattr(s, "method", None) == "rejection":
            note = f"{s.tries} proposals per sample, the first accepted one kept"
        rows.append(_row(f"estimate of Σ components, {name}", seconds, n, seconds / reference,
                         "≤ 3× CosineHemisphere", -3.0, note))
    return rows


def sobol_every_sampler(n, repeats, names=None):
    """Every sampler of the report's table estimating the sum of its sample's
    components with Sobol' points (`uniforms="sobol"`, Owen-scrambled) within 1.5× of the same
    estimate with Philox (`"random"`), timed interleaved."""
    cases = [c for c in sampler_cases() if names is None or c[0] in names]
    fns = {}
    for name, s, _, _, _ in cases:
        fns[(name, "random")] = _estimate_fn(_sum_of_components, s, n)
        fns[(name, "sobol")] = _estimate_fn(_sum_of_components, s, n, uniforms="sobol")
    t = _times(fns, repeats)
    return [_row(f"estimate of Σ components, {name}, uniforms='sobol'", t[(name, "sobol")], n,
                 t[(name, "sobol")] / t[(name, "random")], "≤ 1.5× random", -1.5,
                 f"random {1e9 * t[(name, 'random')] / n:.2f} ns/sample")
            for name, _, _, _, _ in cases]


def _acceptance(sampler):
    """Measured fraction of output samples that come from an accepted proposal (`Rejection`), or
    None for samplers that report no acceptance."""
    info = getattr(sampler, "sample_with_info", None)
    if info is None:
        return None
    _, stats = info(jax.random.key(5), (1 << 16,))
    return float(np.mean(np.asarray(stats.accepted, np.float64)))


def shading(n, repeats):
    """scene.shade (Phong + sphere light + sky) per radiance evaluation against ∫cos³; and
    its gradient with respect to the Phong exponent against its value."""
    point, normal = jnp.zeros(3), jnp.array([0.0, 0.0, 1.0])
    wo = jnp.array([0.3, 0.0, 0.954])
    lights = [scene.SphereLight(jnp.array([-0.9, 0.0, 3.0]), 0.3, 10.0), scene.ConstantSky(0.2)]

    def radiance(exponent, k, s):
        return scene.shade(point, normal, wo, scene.Phong(exponent, 0.9), lights, k, n, strategy=s).mean

    fns = {s: jax.jit(lambda k, s=s: radiance(50.0, k, s)) for s in scene.STRATEGIES}
    fns.update({f"grad {s}": jax.jit(lambda k, s=s: jax.grad(radiance)(50.0, k, s)) for s in scene.STRATEGIES})
    fns["cos3"] = _estimate_fn(cos3, js.CosineHemisphere(), n)
    t = _times(fns, repeats)
    rows = [_row(f"scene.shade, strategy={s!r}, per radiance evaluation", t[s], n, t[s] / t["cos3"],
                 "≤ 4× ∫cos³ per sample", -4.0) for s in scene.STRATEGIES]
    # A gradient at most 4x its value (the silhouette's boundary term included).
    rows += [_row(f"jax.grad of scene.shade w.r.t. the Phong exponent, strategy={s!r}", t[f"grad {s}"], n,
                  t[f"grad {s}"] / t[s], "≤ 4× its value", -4.0) for s in scene.STRATEGIES]
    return rows


def benchmarked_case(n, repeats):
    """∫cos³ against NumPy (mean; mean + stderr); reverse-mode gradient beside it."""
    def phong_estimate(exponent, k):
        return js.estimate(cos3, js.PhongLobe(exponent), k, n).mean

    fns = {"mean": _estimate_fn(cos3, js.CosineHemisphere(), n),
           "estimate": jax.jit(lambda k: js.estimate(cos3, js.CosineHemisphere(), k, n)),
           "numpy mean": lambda k: numpy_estimate(n),
           "numpy mean+stderr": lambda k: numpy_estimate(n, with_stderr=True),
           "phong forward": jax.jit(lambda k: phong_estimate(5.0, k)),
           "phong grad": jax.jit(lambda k: jax.grad(phong_estimate)(5.0, k))}
    t = _times(fns, repeats)
    return [
        _row("∫cos³ cosine, mean", t["mean"], n, t["numpy mean"] / t["mean"], "≥ 15× NumPy", 15.0,
             f"NumPy {1e9 * t['numpy mean'] / n:.1f} ns/sample"),
        _row("∫cos³ cosine, whole Estimate (mean, stderr, ...)", t["estimate"], n,
             t["numpy mean+stderr"] / t["estimate"], "≥ 12× NumPy mean+stderr", 12.0),
        {"path": "jax.grad of ∫cos³ Phong(5) estimate w.r.t. the exponent (reverse mode)",
         "ns_per_sample": 1e9 * t["phong grad"] / n, "ratio": t["phong grad"] / t["phong forward"],
         "target": "printed: × the forward estimate", "met": None, "note": ""},
    ]


def path_table(quick: bool = True, tiny: bool = False, progress=print) -> list[dict]:
    """Every row of the path table. quick: n = 2^22 (estimates), 2^20 (arrays); full: 2^24, 2^22."""
    if tiny:
        n_est, n_arr, repeats = 1 << 16, 1 << 16, 1
    elif quick:
        n_est, n_arr, repeats = 1 << 22, 1 << 20, 5
    else:
        n_est, n_arr, repeats = 1 << 24, 1 << 22, 7
    sections = [("integrand forms", lambda: integrand_forms(n_est, repeats)),
                ("sample into arrays", lambda: sample_into_arrays(n_arr, repeats)),
                ("point sets", lambda: quasi_random(n_est, repeats)),
                ("Oriented and Mixture", lambda: composition(n_est, repeats)),
                ("every sampler", lambda: every_sampler(
                    n_est, repeats, names=("PhongLobe(20)", "UniformDisk(concentric)") if tiny else None)),
                ("Sobol' for every sampler", lambda: sobol_every_sampler(n_est, repeats)),
                ("scene.shade", lambda: shading(n_est, repeats)),
                ("∫cos³ and its gradient", lambda: benchmarked_case(n_est, repeats))]
    if tiny:  # a smoke test of the machinery, not a measurement
        sections = sections[:1]
    rows = []
    for name, run in sections:
        progress(f"[paths] {name}")
        rows.extend(run())
    return rows


def markdown_table(rows: list[dict], verdicts: bool = True) -> str:
    """The table; without `verdicts` (a smoke test) no "met" column: the ratios are printed, not judged."""
    out = ["| path | ns/sample | ratio | target |" + (" met |" if verdicts else ""),
           "|---|---|---|---|" + ("---|" if verdicts else "")]
    for r in rows:
        met = "—" if r["met"] is None else ("yes" if r["met"] else "**no**")
        note = f" ({r['note']})" if r["note"] else ""
        line = f"| {r['path']}{note} | {r['ns_per_sample']:.2f} | {r['ratio']:.2f}× | {r['target']} |"
        out.append(line + (f" {met} |" if verdicts else ""))
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="n = 2^22 / 2^20 instead of 2^24 / 2^22")
    parser.add_argument("--json", help="also write the rows to this JSON file")
    args = parser.parse_args()
    table = path_table(quick=args.quick)
    print(markdown_table(table))
    if args.json:
        import json
        with open(args.json, "w") as handle:
            json.dump({"device": str(jax.devices()[0]), "jax": jax.__version__, "rows": table}, handle, indent=1)
