"""Speed against error: RMSE, bias, variance, time, and the time each strategy takes to reach an error.

Run alone: `python -m jaxsample.report.convergence [--quick]` prints the table; the report
(`python -m jaxsample report`) calls `run_study` and writes tables and plots from it.

Method, for each (integrand, strategy):
- Error: for each of K independent keys, the per-sample values Y_i = f(x_i)/p(x_i) (i < N) are
  computed once (float32, the library's path) and the estimates at n = 4, 16, ..., N are their
  prefix means, summed in float64 so that the sum adds no rounding of its own. Prefixes of one
  "random" stream are independent-sample estimates; prefixes of length 2^m of one Owen-scrambled
  Sobol' sequence are randomized (0, m, 2)-nets, so both are valid estimates at every n. Jittered
  ("stratified") points depend on n, so they are drawn anew per n. RMSE and bias at each n are
  taken over the K keys against the exact value.
- Time: the library path itself, `jaxsample.estimate` (or `estimate_mis`) under `jit`, at n_time
  samples; the strategies of one integrand are timed in interleaved rounds (`timing.py`), so a
  burst of load on a shared machine hits them alike; ns per sample = median time / n_time, and
  the time of n samples is n × that (throughput: a call's fixed overhead is not counted).
- Verdicts (`verdicts.py`): a strategy whose RMSE is within a few float32 ulps of the exact value
  at every n is "exact"; otherwise the floor (the first point from which the RMSE stops falling,
  within the 1/sqrt(2K) an RMSE over K keys carries) is detected, the slope of log RMSE against
  log n is fitted with its standard error over the points before it (n >= FIT_FROM_N, past the
  pre-asymptotic start of the Sobol' nets; at least `verdicts.MIN_SLOPE_POINTS` of them, else the
  row has no slope and its times no error), and the time to reach each target relative RMSE is
  read off the curve of RMSE against time.
- Bias z-score: mean error over the keys divided by its standard error (the spread of the K
  estimates / sqrt(K), combined with 4 float32 ulps of the exact value).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js
from jaxsample import uniforms as U
from . import verdicts as V
from .timing import interleaved_medians

FIT_FROM_N = 256

# The kind of each point set other than "random" (`Strategy.kind`). QMC: the low-discrepancy sets,
# whose error falls faster than n^-1/2 on smooth integrands through the equidistribution of the
# whole point set in every coordinate (scrambled Sobol' nets, the shifted extensible lattice,
# scrambled Halton). Stratified: the sets that only put one point in each cell of a partition, so
# that they remove the variance between cells and no more: jittered sampling (cells of the first
# two coordinates) and the Latin hypercube (cells of each single coordinate: the additive part of
# the integrand). The point sets that make each kind are in `POINT_SETS`.
POINT_SET_KINDS = {"sobol": V.QMC, "lattice": V.QMC, "halton": V.QMC, "stratified": "stratified",
                   "lhs": "stratified"}

# How a point set's estimates at several n come from one stream (`study_one`): "every" — every
# prefix of one replicate is a valid estimate (independent points; Halton's scrambled sequence,
# whose n-point prefix is as good as any n-point Halton set); "pow2" — prefixes of 2^m points are
# the sets the construction promises (Sobol' (t, m, s)-nets; the extensible base-2 lattice, whose
# first 2^m points are the full 2^m-point rule) and the study's n are powers of two; "anew" — the
# points depend on n (jittered cells, Latin hypercube strata of size 1/n), so each n is drawn anew.
PREFIX = {"random": "every", "halton": "every", "sobol": "pow2", "lattice": "pow2", "stratified": "anew",
          "lhs": "anew"}

# The sets compared beside each existing Sobol' strategy in the full study (`strategies`).
EXTRA_SETS = ("lattice", "halton", "lhs")

COS30 = float(np.cos(np.pi / 6))
CAP_AXIS = np.array([0.5, 0.0, 1.0]) / np.linalg.norm([0.5, 0.0, 1.0])


@dataclasses.dataclass(frozen=True)
class Integrand:
    name: str
    description: str
    f: Callable
    exact: float | Callable[[], float]  # a number, or a function computing it (a quadrature, run once when needed)


_EXACT: dict[str, float] = {}


def exact_value(integrand: Integrand) -> float:
    """The integrand's exact value: `exact` itself, or what its function returns (computed once)."""
    if not callable(integrand.exact):
        return float(integrand.exact)
    if integrand.name not in _EXACT:
        _EXACT[integrand.name] = float(integrand.exact())
    return _EXACT[integrand.name]


@dataclasses.dataclass(frozen=True)
class Strategy:
    integrand: str
    name: str
    sampler: object = None  # a Sampler, or a tuple of two for MIS
    uniforms: str = "random"
    heuristic: str | None = None  # MIS: "balance" | "power"; None otherwise
    importance: bool = False  # the sampler's density is not uniform on the domain
    baseline: bool = False    # the integrand's reference ("plain uniform") strategy for speed-ups

    @property
    def kind(self) -> str:
        """plain | importance | MIS | stratified | QMC, from the definition: the point set first
        (`POINT_SET_KINDS`: a low-discrepancy set -> QMC, a stratified one -> stratified), then the
        estimator (two techniques, or a one-sample mixture -> MIS), then the density (non-uniform ->
        importance, else plain)."""
        if self.uniforms in POINT_SET_KINDS:
            return POINT_SET_KINDS[self.uniforms]
        if self.heuristic is not None or isinstance(self.sampler, js.Mixture):
            return "MIS"
        return "importance" if self.importance else "plain"


def _cap(w):
    # A tilted cap of half-angle 30°, wholly above the horizon: an indicator, so discontinuous.
    return jnp.where(w[0] * CAP_AXIS[0] + w[2] * CAP_AXIS[2] > COS30, 1.0, 0.0)


INTEGRANDS = [
    Integrand("hemi_cos1", "cos θ over H²", lambda w: w[2], np.pi),
    Integrand("hemi_cos3", "cos³ θ over H²", lambda w: w[2] ** 3, np.pi / 2),
    Integrand("hemi_cos10", "cos¹⁰ θ over H²", lambda w: w[2] ** 10, 2 * np.pi / 11),
    Integrand("sphere_cos2", "cos² θ over S²", lambda w: w[2] ** 2, 4 * np.pi / 3),
    Integrand("phong100", "sharp lobe cos¹⁰⁰ θ over H²", lambda w: jnp.maximum(w[2], 0.0) ** 100,
              2 * np.pi / 101),
    Integrand("cap", "tilted 30° cap indicator over H²", _cap, 2 * np.pi * (1 - COS30)),
    Integrand("disk_r2", "r² over the unit disk", lambda p: p[0] ** 2 + p[1] ** 2, np.pi / 2),
    Integrand("triangle_x2", "x² over the triangle (0,0),(1,0),(0,1)", lambda p: p[0] ** 2, 1 / 12),
    Integrand("free_flight", "e^{-t} cos t over [0, ∞)", lambda t: jnp.exp(-t) * jnp.cos(t), 0.5),
]


# ---- scene integrands: a GGX lobe under a rectangular light, a triangle light's irradiance ----------
# The GGX conductor (gold-like, η = 0.2 + 3i) at the origin, normal +z, seen from the mirror direction
# of a 1 x 0.8 quad light 2 above it (the inverse problem's geometry, `inverse_problem.py`):
# f(ω) = f_r(ω_o, ω) cos⁺θ L(ω), L = 1 on the quad. At α = 0.05 the lobe lies inside the light; at
# α = 0.3 it is wider than the light, whose edges cut it.
GGX_ALPHAS = (0.05, 0.3)
GGX_ETA, GGX_K = 0.2, 3.0   # one channel: the study's integrands are scalar
TRIANGLE_DISTANCES = {"near": 0.6, "far": 10.0}


def _ggx_geometry(alpha):
    from jaxsample import scene
    from . import inverse_problem as ip
    light = scene.QuadLight(jnp.asarray(ip.QUAD_CORNER, jnp.float32), jnp.asarray(ip.QUAD_EDGE_U, jnp.float32),
                            jnp.asarray(ip.QUAD_EDGE_V, jnp.float32), 1.0)
    wo = jnp.asarray(ip.roughness_views()[0])
    return scene.RoughConductor(alpha, GGX_ETA, GGX_K), light, wo


def _ggx_integrand(alpha):
    brdf, light, wo = _ggx_geometry(alpha)
    origin = jnp.zeros(3)

    def f(w):
        return brdf.eval(wo, w) * jnp.maximum(w[2], 0.0) * light.radiance_from(origin, w)

    def exact():
        from jaxsample import scene
        return scene.reference_radiance(np.zeros(3), np.array([0.0, 0.0, 1.0]), np.asarray(wo), brdf, light)

    return Integrand(f"ggx{alpha:g}", f"GGX conductor lobe α = {alpha:g} under a quad light", f, exact)


def _triangle_vertices(distance):
    """A triangle of circumradius 1 about the direction 0.5 rad from the normal, at `distance`,
    tilted 0.4 rad from facing the point, ordered so that its front face looks at the origin."""
    axis = np.array([np.sin(0.5), 0.0, np.cos(0.5)])
    across = np.array([np.cos(0.5), 0.0, -np.sin(0.5)])
    across = np.cos(0.4) * across + np.sin(0.4) * axis
    side = np.array([0.0, 1.0, 0.0])
    a, b, c = (distance * axis + np.cos(t) * across + np.sin(t) * side for t in (0.3, 2.4, 4.3))
    return (a, b, c) if np.cross(b - a, c - a) @ (-a) > 0 else (a, c, b)


def triangle_irradiance(vertices, normal=(0.0, 0.0, 1.0)) -> float:
    """∫ cos θ dω over the spherical triangle of `vertices` (all above the horizon): Lambert's
    formula, E = |n · Σ_k Θ_k ĝ_k| / 2 with Θ_k the arc between unit vertices k, k+1 and ĝ_k the unit
    normal of their great circle (Lambert 1760; Arvo 1995, "Applications of irradiance tensors")."""
    v = [np.asarray(x, float) / np.linalg.norm(x) for x in vertices]
    total = np.zeros(3)
    for k in range(len(v)):
        a, b = v[k], v[(k + 1) % len(v)]
        cross = np.cross(a, b)
        total += np.arctan2(np.linalg.norm(cross), a @ b) * cross / np.linalg.norm(cross)
    return abs(float(np.asarray(normal, float) @ total)) / 2.0


def _triangle_light(distance, sampling="area"):
    from jaxsample import scene
    a, b, c = (jnp.asarray(v, jnp.float32) for v in _triangle_vertices(distance))
    return scene.TriangleLight(a, b, c, 1.0, sampling=sampling)


def _triangle_integrand(name, distance):
    light = _triangle_light(distance)
    origin = jnp.zeros(3)

    def f(w):
        return jnp.maximum(w[2], 0.0) * light.radiance_from(origin, w)

    return Integrand(f"triangle_{name}", f"irradiance from a triangle light at distance {distance:g}", f,
                     triangle_irradiance(_triangle_vertices(distance)))


def scene_integrands() -> list[Integrand]:
    return ([_ggx_integrand(alpha) for alpha in GGX_ALPHAS]
            + [_triangle_integrand(name, d) for name, d in TRIANGLE_DISTANCES.items()])


DESCRIPTIONS = {**{i.name: i.description for i in INTEGRANDS},
                **{f"ggx{a:g}": f"GGX conductor lobe α = {a:g} under a quad light" for a in GGX_ALPHAS},
                **{f"triangle_{n}": f"irradiance from a triangle light at distance {d:g}"
                   for n, d in TRIANGLE_DISTANCES.items()}}


def all_integrands() -> list[Integrand]:
    return INTEGRANDS + scene_integrands()


def strategies(sets=EXTRA_SETS) -> list[Strategy]:
    """Every (integrand, strategy) of the study; each Sobol' strategy is followed by the same sampler
    on each point set of `sets` (`with_every_point_set`)."""
    S = []
    hemi = js.UniformHemisphere()
    cosine = js.CosineHemisphere()
    for name, phong_n in (("hemi_cos1", 0.5), ("hemi_cos3", 2.0), ("hemi_cos10", 8.0)):
        S += [Strategy(name, "uniform", hemi, baseline=True), Strategy(name, "cosine", cosine, importance=True),
              Strategy(name, f"phong{phong_n:g}", js.PhongLobe(phong_n), importance=True),
              Strategy(name, "cosine+stratified", cosine, "stratified", importance=True),
              Strategy(name, "cosine+sobol", cosine, "sobol", importance=True)]
    S += [Strategy("sphere_cos2", "uniform", js.UniformSphere(), baseline=True),
          Strategy("sphere_cos2", "uniform+sobol", js.UniformSphere(), "sobol"),
          Strategy("sphere_cos2", "vmf1", js.VonMisesFisher(1.0), importance=True)]
    lobe, vmf = js.PhongLobe(80.0), js.VonMisesFisher(90.0)
    S += [Strategy("phong100", "uniform", hemi, baseline=True),
          Strategy("phong100", "cosine", cosine, importance=True),
          Strategy("phong100", "phong80", lobe, importance=True), Strategy("phong100", "vmf90", vmf, importance=True),
          Strategy("phong100", "phong80+sobol", lobe, "sobol", importance=True),
          Strategy("phong100", "mixture(cosine,phong80)", js.Mixture([cosine, lobe], jnp.array([0.5, 0.5])),
                   importance=True),
          Strategy("phong100", "mis-balance(cosine,phong80)", (cosine, lobe), heuristic="balance", importance=True),
          Strategy("phong100", "mis-power(cosine,phong80)", (cosine, lobe), heuristic="power", importance=True)]
    cap_cone = js.Oriented(js.UniformCone(float(np.cos(np.pi / 5))), jnp.asarray(CAP_AXIS, jnp.float32))
    S += [Strategy("cap", "uniform", hemi, baseline=True), Strategy("cap", "cosine", cosine, importance=True),
          Strategy("cap", "uniform+stratified", hemi, "stratified"),
          Strategy("cap", "uniform+sobol", hemi, "sobol"),
          Strategy("cap", "cone36°", cap_cone, importance=True)]
    for method in ("concentric", "polar"):
        S += [Strategy("disk_r2", method, js.UniformDisk(method=method), baseline=method == "concentric"),
              Strategy("disk_r2", f"{method}+sobol", js.UniformDisk(method=method), "sobol")]
    tri = js.UniformTriangle(jnp.array([0.0, 0.0]), jnp.array([1.0, 0.0]), jnp.array([0.0, 1.0]))
    S += [Strategy("triangle_x2", "uniform", tri, baseline=True),
          Strategy("triangle_x2", "uniform+sobol", tri, "sobol")]
    # [0, ∞) has no uniform density: the baseline is Exponential(1), importance sampling of e^{-t}.
    S += [Strategy("free_flight", "exponential1", js.Exponential(1.0), importance=True, baseline=True),
          Strategy("free_flight", "exponential0.5", js.Exponential(0.5), importance=True),
          Strategy("free_flight", "exponential1+sobol", js.Exponential(1.0), "sobol", importance=True)]
    return with_every_point_set(S, sets) + scene_strategies(sets)


def with_every_point_set(strategies_: list[Strategy], sets=EXTRA_SETS) -> list[Strategy]:
    """Each Sobol' strategy followed by the same sampler on each of `sets` ("cosine+sobol" ->
    "cosine+lattice", ...): every point set meets every integrand that one of them meets."""
    out = []
    for s in strategies_:
        out.append(s)
        if s.uniforms == "sobol":
            out += [dataclasses.replace(s, name=s.name.replace("+sobol", f"+{other}"), uniforms=other)
                    for other in sets]
    return out


def scene_strategies(sets=EXTRA_SETS) -> list[Strategy]:
    """The GGX lobes: cosine sampling (the baseline), the reflection of normals from the full D, of
    visible normals, and MIS of visible normals with the quad light's solid-angle sampling (power
    heuristic), and visible normals on every point set. The triangle light: area sampling converted
    to solid angle (the baseline), solid-angle sampling (Arvo 1995) and its cosine-aware warp (the
    bilinear cosine weight, PBRT-v4), that warp on every point set."""
    from jaxsample.scene import FullNormalsReflection
    from jaxsample.samplers.spherical_triangle import CosineSphericalTriangle, SphericalTriangle
    S = []
    for alpha in GGX_ALPHAS:
        name = f"ggx{alpha:g}"
        brdf, light, wo = _ggx_geometry(alpha)
        visible = js.MicrofacetReflection(brdf.distribution, wo)
        S += [Strategy(name, "cosine", js.CosineHemisphere(), importance=True, baseline=True),
              Strategy(name, "full-D", FullNormalsReflection(brdf.distribution, wo), importance=True),
              Strategy(name, "visible", visible, importance=True),
              Strategy(name, "mis-power(visible,light)", (visible, light.sampler(jnp.zeros(3))), heuristic="power",
                       importance=True),
              Strategy(name, "visible+sobol", visible, "sobol", importance=True)]
    for name, distance in TRIANGLE_DISTANCES.items():
        light = _triangle_light(distance)
        a, b, c = (jnp.asarray(v) for v in (light.a, light.b, light.c))
        S += [Strategy(f"triangle_{name}", "area", light.sampler(jnp.zeros(3)), importance=True, baseline=True),
              Strategy(f"triangle_{name}", "solid_angle", SphericalTriangle(a, b, c), importance=True),
              Strategy(f"triangle_{name}", "cosine_solid_angle",
                       CosineSphericalTriangle(a, b, c, jnp.array([0.0, 0.0, 1.0])), importance=True),
              Strategy(f"triangle_{name}", "cosine_solid_angle+sobol",
                       CosineSphericalTriangle(a, b, c, jnp.array([0.0, 0.0, 1.0])), "sobol", importance=True)]
    return with_every_point_set(S, sets)


def _values_fn(strategy: Strategy, f):
    """u (count, dims) -> Y (count,), per sample (MIS: per pair of one sample per technique)."""
    if strategy.heuristic is None:
        sampler = strategy.sampler

        def values(u):
            x, p = sampler.warp_with_pdf(u)
            return js.numerics.safe_div(jax.vmap(f)(x), p)

        return values, sampler.uniform_dims
    first, second = strategy.sampler
    d1, d2 = first.uniform_dims, second.uniform_dims
    power = 1.0 if strategy.heuristic == "balance" else 2.0

    def values(u):
        total = 0.0
        for own, other, part in ((first, second, u[:, :d1]), (second, first, u[:, d1:d1 + d2])):
            x, p_own = own.warp_with_pdf(part)
            p_other = other.pdf(x)
            weight = js.numerics.safe_div(p_own**power, p_own**power + p_other**power)
            total = total + js.numerics.safe_div(jax.vmap(f)(x) * weight, p_own)
        return total

    return values, d1 + d2


def _two_replicate_source(name: str):
    """The library's source `name` with R = 2 replicates (Random: one stream, stride 1)."""
    if name == "random":
        return U.Random(), 1
    factories = {"sobol": U.Sobol, "stratified": U.Stratified, "lattice": U.Lattice, "halton": U.Halton,
                 "lhs": U.LatinHypercube}
    if name not in factories:
        raise ValueError(f"no single-replicate form of the point set {name!r}; known: random, {', '.join(factories)}")
    return factories[name](replicates=2), 2


def _single_replicate_block(name: str, values, dims: int, count: int):
    """jit: seed -> Y over `count` points of ONE replicate of the source (one scramble / shift / jitter).

    Every replicated source of the library (Sobol', stratified, lattice, Halton, Latin hypercube)
    interleaves R >= 2 replicates the same way (global index g belongs to replicate g mod R, as its
    point g div R; `uniforms/_replicated.py`); drawing 2 * count points with R = 2 and keeping the
    even ones gives replicate 0 alone: one scrambled Sobol' or Halton sequence, one shifted lattice
    in radical-inverse order, each in natural order, or one jittered pattern / Latin hypercube of
    `count` points (those two are sized by `total`, here 2 * count: `count` points per replicate).
    """
    source, stride = _two_replicate_source(name)

    def run(seed):
        u = source.block(seed, jnp.uint32(0), count * stride, dims, jnp.float32, total=count * stride)
        return values(u[::stride])

    return jax.jit(run)


def _prefix_means(y: np.ndarray, ns: list[int]) -> np.ndarray:
    csum = np.cumsum(y.astype(np.float64))
    return np.array([csum[n - 1] / n for n in ns])


def _timed_run(strategy: Strategy, f, n_time: int):
    """jit: key -> the library's estimate over n_time samples (MIS: n_time / 2 per technique)."""
    if strategy.heuristic is None:
        return jax.jit(lambda key: js.estimate(f, strategy.sampler, key, n_time, uniforms=strategy.uniforms).mean)
    return jax.jit(lambda key: js.estimate_mis(f, list(strategy.sampler), key, [n_time // 2, n_time // 2],
                                               heuristic=strategy.heuristic).mean)


def study_one(strategy: Strategy, integrand: Integrand, ns: list[int], n_keys: int, seed: int = 0) -> dict:
    """The error curve of one (integrand, strategy): RMSE and bias over `n_keys` keys at each n."""
    values, dims = _values_fn(strategy, integrand.f)
    n_max = ns[-1]
    # An MIS "sample" is a pair (one draw per technique): it costs two evaluations of f.
    evaluations_per_value = 2 if strategy.heuristic else 1
    keys = jax.random.split(jax.random.key(seed), n_keys)
    estimates = np.zeros((n_keys, len(ns)))
    sum_var = 0.0
    if PREFIX[strategy.uniforms] != "anew":  # "pow2" sets: the study's n are powers of two (study_sizes)
        block = _single_replicate_block(strategy.uniforms, values, dims, n_max // evaluations_per_value)
        for i, key in enumerate(keys):
            y = np.asarray(block(U.seed_from_key(key)))
            estimates[i] = _prefix_means(y, [n // evaluations_per_value for n in ns])
            sum_var += float(np.var(y.astype(np.float64)))
    else:
        for j, n in enumerate(ns):
            block = _single_replicate_block(strategy.uniforms, values, dims, n)
            for i, key in enumerate(jax.random.split(jax.random.fold_in(jax.random.key(seed), j), n_keys)):
                y = np.asarray(block(U.seed_from_key(key)))
                estimates[i, j] = float(np.mean(y.astype(np.float64)))
                if j == len(ns) - 1:
                    sum_var += float(np.var(y.astype(np.float64)))
    exact = exact_value(integrand)
    errors = estimates - exact
    rmse = np.sqrt(np.mean(errors**2, axis=0))
    bias = np.mean(errors, axis=0)
    ulp = float(np.spacing(np.float32(abs(exact))))
    return {
        "integrand": integrand.name, "strategy": strategy.name, "kind": strategy.kind,
        "baseline": strategy.baseline, "uniforms": strategy.uniforms,
        "exact": exact, "ns": list(ns), "rmse": rmse.tolist(), "bias": bias.tolist(),
        "rmse_at_max": float(rmse[-1]), "bias_at_max": float(bias[-1]), "bias_ulps": float(bias[-1]) / ulp,
        # bias over its standard error (spread across keys, ⊕ 4 float32 ulps of the exact value so
        # that zero-variance strategies are judged on bias, not on rounding)
        "bias_z": float(bias[-1] / math.hypot(float(np.std(estimates[:, -1], ddof=1)) / math.sqrt(n_keys),
                                              4 * ulp)),
        "per_sample_variance": sum_var / n_keys, "n_keys": n_keys,
    }


def add_verdicts(row: dict, seconds_per_sample: float, targets=V.TARGETS) -> dict:
    """Add to a `study_one` row its time per sample and what `verdicts` reads off its curve: "exact",
    the floor, the slope ± its standard error, and the time to reach each target relative RMSE."""
    ns, rmse, n_keys = np.array(row["ns"], float), np.array(row["rmse"]), row["n_keys"]
    seconds = ns * seconds_per_sample
    exact = V.is_exact(rmse, row["exact"])
    floor = None if exact else V.floor_index(rmse, n_keys)
    slope = V.fit_slope(ns, rmse, n_keys, stop=floor, n_min=FIT_FROM_N)
    times = {}
    for target in targets:
        if exact:
            times[f"{target:g}"] = V.Time(float(seconds[0]), "exact")
        else:
            times[f"{target:g}"] = V.time_to_target(seconds, rmse / abs(row["exact"]), target, last=floor,
                                                    slope=slope.value, n_keys=n_keys)
    row.update({
        "ns_per_sample": seconds_per_sample * 1e9, "seconds": seconds.tolist(), "zero_variance": exact,
        "floor_n": None if floor is None else int(ns[floor]), "slope": slope.value,
        "slope_stderr": slope.stderr, "slope_points": slope.points,
        "slope_n_range": [slope.n_first, slope.n_last],
        "times": {key: dataclasses.asdict(t) for key, t in times.items()},
    })
    return row


def row_times(row: dict) -> dict[str, V.Time]:
    """The row's time to each target, as `verdicts.Time` records keyed by the target ("0.01", ...)."""
    return {key: V.Time(**value) for key, value in row["times"].items()}


def study_sets(quick: bool = True) -> tuple[str, ...]:
    """The point sets each Sobol' strategy is repeated on: all of `EXTRA_SETS` in the full study; none
    in --quick, where they were half of the study's time (Halton's and the Latin hypercube's programs
    compile slowly, and the hypercube compiles once per n); the point-sets-against-dimension section
    compares every set in --quick too."""
    return () if quick else EXTRA_SETS


def study_sizes(quick: bool = True, tiny: bool = False) -> tuple[list[int], int, int]:
    """(ns, keys, n_time): tiny n up to 2^10 over 4 keys; quick 2^16 over 16; full 2^22 over 32."""
    if tiny:
        return [2**k for k in range(2, 11, 2)], 4, 2**12
    if quick:
        return [2**k for k in range(2, 17, 2)], 16, 2**18
    return [2**k for k in range(2, 23, 2)], 32, 2**22


def run_study(quick: bool = True, progress=print, tiny: bool = False, sizes=None, integrands=None) -> list[dict]:
    """Every (integrand, strategy) row, with its verdicts (see `study_sizes` for the sizes; `sizes`,
    a (ns, keys, n_time) triple, replaces them)."""
    ns, n_keys, n_time = sizes if sizes is not None else study_sizes(quick, tiny)
    by_name = {i.name: i for i in all_integrands()}
    all_strategies = strategies(EXTRA_SETS if tiny else study_sets(quick))
    if integrands:
        all_strategies = [s for s in all_strategies if s.integrand in integrands]
    if tiny:  # a smoke test: every integrand, a few strategies, every code path (random, sobol, MIS)
        keep = {("hemi_cos3", "uniform"), ("hemi_cos3", "cosine+sobol"), ("hemi_cos3", "cosine+stratified"),
                ("phong100", "uniform"), ("phong100", "mis-power(cosine,phong80)"), ("cap", "uniform"),
                ("disk_r2", "concentric"), ("triangle_x2", "uniform"), ("free_flight", "exponential1"),
                ("triangle_near", "area"), ("triangle_near", "solid_angle")}
        all_strategies = [s for s in all_strategies if (s.integrand, s.name) in keep]
    rows = []
    for integrand in dict.fromkeys(s.integrand for s in all_strategies):
        group = [(index, s) for index, s in enumerate(all_strategies) if s.integrand == integrand]
        curves = []
        for index, strategy in group:
            progress(f"[study {index + 1}/{len(all_strategies)}] {strategy.integrand} / {strategy.name}")
            curves.append(study_one(strategy, by_name[integrand], ns, n_keys, seed=index))
        progress(f"[study] timing the {len(group)} strategies of {integrand}, interleaved")
        runs = {s.name: _timed_run(s, by_name[integrand].f, n_time) for _, s in group}
        keys = iter(jax.random.split(jax.random.key(99), 1 + 6 * len(runs)))
        medians = interleaved_medians(runs, keys, repeats=5)
        rows += [add_verdicts(curve, medians[curve["strategy"]] / n_time) for curve in curves]
    return rows


def verdict_rows(rows: list[dict]) -> list[dict]:
    """One record per (integrand, target): the best strategy (with any tied within 2σ or not told
    apart from it), its time, its speed-up over the integrand's baseline and over the best non-QMC
    strategy (`verdicts.verdict`), and every strategy's time ("times")."""
    out = []
    for integrand in dict.fromkeys(r["integrand"] for r in rows):
        group = [r for r in rows if r["integrand"] == integrand]
        kinds = {r["strategy"]: r["kind"] for r in group}
        baseline = next(r["strategy"] for r in group if r["baseline"])
        for target in group[0]["times"]:
            times = {r["strategy"]: row_times(r)[target] for r in group}
            v = V.verdict(times, kinds, baseline)
            out.append({"integrand": integrand, "target": float(target), "baseline": baseline,
                        "n_max": group[0]["ns"][-1], "n_keys": group[0]["n_keys"], "times": times, **v})
    return out


def headline_picks(rows: list[dict], target: float = 1e-3) -> list[dict]:
    """Which strategy, and so which point set, the headline names fastest for each integrand at
    `target` (the first of any tied; "" where none reaches it): records of integrand, strategy,
    point set ("uniforms") and kind."""
    sets = {(r["integrand"], r["strategy"]): (r.get("uniforms", ""), r["kind"]) for r in rows}
    out = []
    for v in verdict_rows(rows):
        if v["target"] != target:
            continue
        name = v["best"][0] if v["best"] else ""
        point_set, kind = sets.get((v["integrand"], name), ("", ""))
        out.append({"integrand": v["integrand"], "strategy": name, "uniforms": point_set, "kind": kind,
                    "tied": v["best"][1:]})
    return out


def picks_markdown(rows: list[dict], target: float = 1e-3) -> str:
    """One line per integrand: the point set of the headline's fastest strategy at `target`."""
    out = [f"| integrand | fastest to relative RMSE {target:g} | its point set | kind |", "|---|---|---|---|"]
    for p in headline_picks(rows, target):
        who = p["strategy"] or "none reaches it"
        if p["tied"]:
            who += f" (tied: {', '.join(p['tied'])})"
        out.append(f"| {p['integrand']} | {who} | {p['uniforms'] or '—'} | {p['kind'] or '—'} |")
    return "\n".join(out) + "\n"


def _who(names: list[str], kinds: dict[str, str], times: dict[str, V.Time]) -> str:
    """The best name and its kind, then those tied with it: "within 2σ" when every tie is a measured
    ratio with its error, "not told apart" when one is a bound or has no error (no fitted slope)."""
    first = f"{names[0]} ({kinds[names[0]]})"
    if len(names) == 1:
        return first
    ratios = [V.speedup(times[name], times[names[0]]) for name in names[1:]]
    measured = all(r.bound == "=" and math.isfinite(r.rel_err) for r in ratios)
    return f"{first}; {'tied within 2σ' if measured else 'not told apart'}: {', '.join(names[1:])}"


def headline_markdown(rows: list[dict]) -> str:
    """The report's headline: per integrand and target error, who gets there first and how much sooner."""
    kinds = {(r["integrand"], r["strategy"]): r["kind"] for r in rows}
    describe = DESCRIPTIONS
    out = ["| integrand | target relative RMSE | fastest to reach it (kind) | its time | speed-up over the baseline "
           "| best non-QMC (its time) | fastest ÷ best non-QMC |", "|---|---|---|---|---|---|---|"]
    previous = None
    for v in verdict_rows(rows):
        name = v["integrand"]
        label = f"{name}: {describe.get(name, '')}" if name != previous else ""
        previous = name
        k = {s: kinds[(name, s)] for (i, s) in kinds if i == name}
        if not v["best"]:
            budget = _power_of_two(v["n_max"])
            out.append(f"| {label} | {v['target']:g} | not reached within the budget (n ≤ {budget}) "
                       "| — | — | — | — |")
            continue
        time = v["time"]
        if time.bound == "exact":
            who, its_time, over_base = "exact: " + ", ".join(v["best"]), "exact at every n", "— (exact)"
        else:
            who, its_time = _who(v["best"], k, v["times"]), V.format_time(time)
            over_base = f"{V.format_ratio(v['over_baseline'])} (over {v['baseline']})"
        if time.bound != "exact" and k[v["best"][0]] != V.QMC:
            non_qmc, over_non_qmc = "the fastest itself", "1×"
        elif not v["best_non_qmc"]:
            non_qmc, over_non_qmc = "none reaches it", "—"
        else:
            nq_time = v["non_qmc_time"]
            if nq_time.bound == "exact":
                non_qmc = "exact: " + ", ".join(v["best_non_qmc"])
            else:
                non_qmc = f"{_who(v['best_non_qmc'], k, v['times'])} ({V.format_time(nq_time)})"
            exact_either = "exact" in (time.bound, nq_time.bound)
            over_non_qmc = "— (exact)" if exact_either else V.format_ratio(v["over_non_qmc"])
        out.append(f"| {label} | {v['target']:g} | {who} | {its_time} | {over_base} | {non_qmc} | {over_non_qmc} |")
    return "\n".join(out) + "\n"


def _power_of_two(n: float) -> str:
    k = math.log2(n)
    return f"2^{k:.0f}" if k == int(k) else f"{n:g}"


def slope_cell(row: dict) -> str:
    """The slope column of a row: slope ± se (the n it was fitted over), or why there is none."""
    if row["zero_variance"]:
        return "— (exact)"
    if row["slope_points"] < V.MIN_SLOPE_POINTS:
        return f"— (too few sizes: {row['slope_points']} < {V.MIN_SLOPE_POINTS})"
    if not math.isfinite(row["slope"]):
        return "—"
    lo, hi = row["slope_n_range"]
    return f"{row['slope']:.2f} ± {row['slope_stderr']:.2f} ({_power_of_two(lo)}–{_power_of_two(hi)})"


def markdown_table(rows: list[dict], verdicts: bool = True) -> str:
    """One line per row: the measurements, then (with `verdicts`) what `verdicts` reads off the
    curve: slope, floor and the time to each target."""
    targets = list(rows[0]["times"]) if verdicts else []
    head = ("| integrand | strategy | kind | RMSE @ n_max | bias (z; float32 ulps) | per-sample var | ns/sample | "
            + ("RMSE slope ± se (fitted over n) | floor from n | " if verdicts else "")
            + "".join(f"time to {t} | " for t in targets)).rstrip(" ")
    head += "\n|" + "---|" * (7 + (2 + len(targets) if verdicts else 0)) + "\n"
    lines = []
    for r in rows:
        line = (f"| {r['integrand']} | {r['strategy']} | {r['kind']} | {r['rmse_at_max']:.3g} | "
                f"{r['bias_at_max']:.2g} ({r['bias_z']:+.1f}; {r['bias_ulps']:+.2g}) | "
                f"{r['per_sample_variance']:.3g} | {r['ns_per_sample']:.2f} |")
        if verdicts:
            if r["zero_variance"]:
                floor = "exact"
            else:
                floor = "—" if r["floor_n"] is None else f"**{_power_of_two(r['floor_n'])}**"
            times = " | ".join(V.format_time(t) for t in row_times(r).values())
            line += f" {slope_cell(r)} | {floor} | {times} |"
        lines.append(line)
    return head + "\n".join(lines) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--max-log2-n", type=int, default=None,
                        help="sizes n = 4, 16, ..., 2^this (even), instead of the mode's")
    parser.add_argument("--keys", type=int, default=None, help="independent keys per strategy")
    parser.add_argument("--only", default=None, help="comma-separated integrands to study (default: all)")
    parser.add_argument("--json", default=None, help="also write the rows to this JSON file")
    args = parser.parse_args()
    ns, n_keys, n_time = study_sizes(quick=args.quick)
    if args.max_log2_n is not None:
        ns, n_time = [2**k for k in range(2, args.max_log2_n + 1, 2)], 2**args.max_log2_n
    study_rows = run_study(sizes=(ns, args.keys or n_keys, n_time), integrands=args.only and args.only.split(","))
    if args.json:
        import json
        with open(args.json, "w") as handle:
            json.dump(study_rows, handle)
    print(markdown_table(study_rows))
    print(headline_markdown(study_rows))
    print(picks_markdown(study_rows, 1e-3))
    print(picks_markdown(study_rows, 1e-4))
