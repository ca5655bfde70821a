"""Direct lighting at one shading point: L_o = ∫ f_r(ω_o, ω_i) L_i(ω_i) cos θ_i dω_i, by Monte Carlo.

There is no ray tracer: lights are transparent, nothing occludes, and L_i(ω) is the sum of what
every light emits along ω. Three strategies estimate the integral on the streaming engine of
`jaxsample.estimators.engine` (`run_stream`: constant memory, counter-based uniforms, jit/vmap/grad):

- "brdf": ω_i from the BRDF's sampler, Y = f_r L_i cos θ_i / p_brdf.
- "light": ω_i from the lights, Y = f_r L_i cos θ_i / p_light. With K lights, one is chosen
  uniformly and sampled; p_light(ω) = (1/K) Σ_k p_k(ω) (the mixture density, so a direction that
  several lights could have produced is weighted correctly).
- "mis": one sample from each strategy per pair, combined with the power (β = 2, default) or
  balance heuristic (Veach & Guibas 1995; Veach 1997, ch. 9): Y = w_b Y_b + w_l Y_l with
  w_s = p_s^β / (p_b^β + p_l^β). The weights of a direction sum to 1, so the estimate is unbiased.

Cost and `n`: n is the number of radiance evaluations, whatever the strategy; "mis" spends n/2 on
each strategy (n/2 pairs), so the three strategies are compared at equal cost by their `stderr`.
The returned `variance` is the per-evaluation variance stderr² · n for all three.

Gradients (`mode`, Zeltner et al. 2021): "attached" differentiates through the samples, their
densities and the MIS weights; "detached" stops the gradient of all three together (world-space
samples are frozen), so only f_r, L_i and cos θ_i carry derivatives. Neither alone is unbiased
when a parameter moves a light's silhouette (its centre, radius, vertices, or the shading point),
or when samples move across a silhouette (BRDF samples as the exponent or ω_o changes): L_i jumps
there, and the per-sample derivative of a jump is 0. What each estimator misses is the boundary
term of the silhouette (`jaxsample.estimators.boundary`), and `shade` adds it for every light that
has a `silhouette(point)` (`SphereLight`: a cap; `TriangleLight`: a spherical triangle;
`QuadLight`: a spherical quadrilateral; `ConstantSky`: none, its radiance has no edge), by edge
sampling: every evaluation (every pair, for "mis") also draws one point y uniformly by arc length
on each such silhouette and adds a term of value 0 whose derivative is, per piece of the estimator
with sample density q and sample flow V,

    Δ(h)(y) q(y) ((v(y) − V(y)) · n(y)) / p_arc(y),      h = w f / p the piece's per-sample value,

with v the velocity of the silhouette and n its outward normal. Detached: V = 0 and the pieces
add up to Δf v·n. Attached: the BRDF's samples move with the BRDF, the normal and ω_o (V from
the BRDF sampler's flow, warp(inverse(y)) with the uniforms held: `brdf.sampler(wo).flow`, which
`PhongLobe` computes in log space, since u rounds to 1 in its tail), so "brdf" and the BRDF half
of "mis" get Δ(w_b f)((v − V_b)·n); light samples of the light whose rim it is follow it (no term), and the
other lights' samples crossing it get theirs. So every strategy and mode is unbiased for every
parameter of the BRDF and of these lights; `shade_grad` gives the gradient with its standard
error, the boundary term's variance included (it rides on the same evaluation).

The term is the per-evaluation program's `derivative` (`values_fn.derivative`, the values plus
surrogates of value 0), which the engine evaluates only for a derivative (`estimators.engine`): an
estimate that is not differentiated runs exactly the program without the term.

Lights without `silhouette` (`EnvironmentMap`, whose texel edges are fixed in ω, and user lights)
have edges `shade` cannot sample; a gradient that would cross them is refused
with a ValueError when it is asked for (the BRDF's parameters in attached "brdf"/"mis", a user
light's own parameters outside attached light sampling of that light alone).
"""

from __future__ import annotations

import dataclasses

import functools
from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_derivatives import SymbolicZero
from jax.flatten_util import ravel_pytree

from .._core.entry import compiled_entry
from .._core.counts import check_count
from .._core.params import check_choice, resolve_float_dtype
from ..estimators.engine import run_stream
from ..estimators.gradient_errors import ANTITHETIC
from ..estimators.mis import heuristic_exponent, heuristic_weights
from ..estimators.plain import check_mode
from ..estimators.result import Estimate
from ..samplers.frame import Frame
from .._core.numerics import safe_div
from ..estimators.boundary import relative_motion, sample_flow
from .checks import as_lights, check_scene
from .colour import product, scene_channels, with_channel_axis

__all__ = ["shade", "shade_grad", "STRATEGIES"]

STRATEGIES = ("brdf", "light", "mis")


def mis_weight(own_pdf, other_pdf, exponent: float):
    """w = p_own^β / (p_own^β + p_other^β), 0 when both are 0 (`estimators.mis.heuristic_weights`:
    scaled so that neither power overflows and the gradient stays finite)."""
    return heuristic_weights([own_pdf, other_pdf], exponent)[0]


def _dims(light) -> int:
    """The uniforms a light's `sample` reads: 2 (a direction), or its `uniform_dims`."""
    return getattr(light, "uniform_dims", 2)


class _Shading:
    """The per-direction pieces of the estimator at one shading point."""

    def __init__(self, point, normal, wo, brdf, lights, mode):
        self.point = point
        self.frame = Frame.from_normal(normal)
        wo = wo / jnp.linalg.norm(wo)
        self.wo_local = self.frame.to_local(wo)
        self.brdf = brdf
        self.lights = lights
        self.detached = mode == "detached"
        # () for one grey channel, (C,) for colour (`scene.colour`): f_r and L_i per channel,
        # directions, densities and MIS weights shared by every channel.
        self.channels = scene_channels("shade", brdf, lights, jnp.result_type(point))

    def colour(self, values, batch_ndim):
        """A per-sample array (`batch_ndim` axes) given the scene's channel axis, so that it broadcasts
        against per-channel values; per-channel values and Python numbers are returned as they are."""
        return with_channel_axis(values, batch_ndim, bool(self.channels))

    def radiance_from(self, light, wi):
        """`light`'s radiance along world directions wi, with the scene's channel axis."""
        return self.colour(light.radiance_from(self.point, wi), wi.ndim - 1)

    # Radiance arriving along world directions, and the light-sampling density there.
    def light_radiance(self, wi):
        return sum(self.radiance_from(light, wi) for light in self.lights)

    def light_pdf(self, wi):
        return sum(light.pdf(self.point, wi) for light in self.lights) / len(self.lights)

    def integrand(self, wi_local, radiance):
        """f_r L_i cos⁺θ_i per sample, per channel where the scene has colour."""
        cos_theta = jnp.maximum(wi_local[..., 2], 0.0)
        return product(wi_local.ndim - 1, self.brdf.eval(self.wo_local, wi_local), radiance, cos_theta)

    def _freeze(self, *arrays):
        return jax.lax.stop_gradient(arrays) if self.detached else arrays

    def brdf_sample(self, u):
        """(world ω, local ω, L_i, p_brdf, p_light) for BRDF samples from u (..., 2)."""
        wi_local, pdf = self.brdf.sample(self.wo_local, u)
        wi = self.frame.to_world(wi_local)
        if self.detached:
            # Frozen in world space; the local direction is rebuilt so f_r still sees the normal.
            wi, pdf = self._freeze(wi, pdf)
            wi_local = self.frame.to_local(wi)
        (light_pdf,) = self._freeze(self.light_pdf(wi))
        return wi_local, self.light_radiance(wi), pdf, light_pdf

    def light_sample(self, u):
        """(local ω, L_i, p_light, p_brdf) for light samples from u (..., 2) or (..., 3)."""
        lights = self.lights
        if len(lights) == 1:
            wi, radiance, pdf = lights[0].sample(self.point, u[..., :_dims(lights[0])])
            wi, pdf = self._freeze(wi, pdf)
            radiance = self.colour(radiance, pdf.ndim)
        else:
            count = len(lights)
            chosen = jnp.clip(jnp.floor(u[..., 0] * count), 0, count - 1).astype(jnp.int32)
            draws = [light.sample(self.point, u[..., 1:1 + _dims(light)]) for light in lights]
            wi = sum(jnp.where((chosen == k)[..., None], d[0], 0.0) for k, d in enumerate(draws))
            (wi,) = self._freeze(wi)
            radiance, pdf = 0.0, 0.0
            for k, (light, (_, own_radiance, own_pdf)) in enumerate(zip(lights, draws)):
                mine = chosen == k
                # The chosen light's own radiance and density (no re-test at its rim); the
                # others are evaluated along the chosen direction.
                radiance = radiance + jnp.where(self.colour(mine, mine.ndim), self.colour(own_radiance, mine.ndim),
                                                self.radiance_from(light, wi))
                pdf = pdf + jnp.where(mine, own_pdf, light.pdf(self.point, wi))
            (pdf,) = self._freeze(pdf / count)
        wi_local = self.frame.to_local(wi)
        (brdf_pdf,) = self._freeze(self.brdf.pdf(self.wo_local, wi_local))
        return wi_local, radiance, pdf, brdf_pdf

    @property
    def light_dims(self):
        """The uniforms of one light sample: the light's own (2, or `uniform_dims` for a batch of
        lights), plus one to choose among several."""
        return (0 if len(self.lights) == 1 else 1) + max(_dims(light) for light in self.lights)

    # The silhouettes' boundary term (see the module docstring and `estimators/boundary.py`).
    def silhouettes(self):
        """[(index, region)] for every light whose radiance has an edge (sphere, triangle)."""
        found = []
        for index, light in enumerate(self.lights):
            region = light.silhouette(self.point) if hasattr(light, "silhouette") else None
            if region is not None:
                found.append((index, region))
        return found

    def brdf_flow(self, wi):
        """The BRDF sample through world direction wi, moving with the BRDF, normal and ω_o."""
        if not hasattr(self.brdf, "sampler"):
            raise ValueError(f"shade: {type(self.brdf).__name__} has no 'sampler(wo)' (a directional sampler with an "
                             "'inverse'), so how its samples move across a light's rim is unknown; for gradients "
                             "use mode='detached' or strategy='light'")
        local = jax.lax.stop_gradient(self.frame.to_local(wi))
        return self.frame.to_world(sample_flow(self.brdf.sampler(self.wo_local), local))

    def light_flow(self, index, wi):
        """Light `index`'s sample through world direction wi, moving with that light and the point."""
        return sample_flow(self.lights[index].sampler(self.point), wi)

    def boundary_values(self, t, strategy, exponent):
        """Per-sample surrogates of value 0 whose derivative is what `strategy` misses at the lights'
        silhouettes: ∫_∂ Δ(h) q ((v - V)·n) dl per piece of the estimator (module docstring)."""
        count = len(self.lights)
        total = jnp.zeros(t.shape[:1] + self.channels, t.dtype)

        def c(values):
            return self.colour(values, 1)

        for column, (j, region) in enumerate(self.silhouettes()):
            y, normal, arc_pdf = region.boundary_sample(t[:, column:column + 1])
            fixed = jax.lax.stop_gradient(y)
            normal = jax.lax.stop_gradient(normal)
            local = self.frame.to_local(fixed)
            kernel = self.integrand(local, 1.0)                      # f_r cos⁺θ along the rim
            radiance_in, pdf_in = self.lights[j].inside_values(self.point, fixed)
            radiance_in = c(radiance_in)
            others = [k for k in range(count) if k != j]
            radiance_rest = sum((self.radiance_from(self.lights[k], fixed) for k in others), 0.0)
            pdf_others = [self.lights[k].pdf(self.point, fixed) for k in others]
            pdf_rest = sum(pdf_others, 0.0)
            f_in, f_out = c(kernel) * (radiance_rest + radiance_in), c(kernel) * radiance_rest
            mix_in, mix_out = (pdf_rest + pdf_in) / count, pdf_rest / count

            def add(jump, flows):
                weight = jax.lax.stop_gradient(safe_div(jump, c(arc_pdf)))
                return weight * c(jnp.sum(normal * relative_motion(y, flows), axis=-1))

            if self.detached:
                # Samples, densities and weights held: the whole boundary term, Δf v·n.
                total = total + add(f_in - f_out, ())
                continue
            brdf_pdf = self.brdf.pdf(self.wo_local, local)
            if strategy in ("brdf", "mis"):
                w_in = mis_weight(brdf_pdf, mix_in, exponent) if strategy == "mis" else 1.0
                w_out = mis_weight(brdf_pdf, mix_out, exponent) if strategy == "mis" else 1.0
                total = total + add(c(w_in) * f_in - c(w_out) * f_out, (self.brdf_flow,))
            if strategy in ("light", "mis"):
                # Light j's own samples follow its rim; the other lights' samples cross it.
                w_in = mis_weight(mix_in, brdf_pdf, exponent) if strategy == "mis" else 1.0
                w_out = mis_weight(mix_out, brdf_pdf, exponent) if strategy == "mis" else 1.0
                jump = safe_div(c(w_in) * f_in, c(mix_in)) - safe_div(c(w_out) * f_out, c(mix_out))
                for k, pdf_k in zip(others, pdf_others):
                    total = total + add(jump * c(pdf_k) / count, (lambda wi, k=k: self.light_flow(k, wi),))
        return total


def _is_zero(tangent) -> bool:
    return all(isinstance(leaf, SymbolicZero)
               for leaf in jax.tree_util.tree_leaves(tangent, is_leaf=lambda v: isinstance(v, SymbolicZero)))


def _refuse(strategy, mode, lights, tangents):
    """ValueError for a gradient that would be biased: lights whose edges `shade` does not know
    (no `silhouette`: an `EnvironmentMap`'s texel edges, a user's light) are safe only where no
    sample moves across them (detached, or light sampling of that one light) and, for edges that
    can move, where nothing moves them."""
    point_t, normal_t, wo_t, brdf_t, lights_t = tangents
    unknown = [k for k, light in enumerate(lights) if not hasattr(light, "silhouette")]
    if not unknown:
        return
    attached = mode == "attached"
    for k in unknown:
        if getattr(lights[k], "fixed_edges", False) or _is_zero(lights_t[k]):
            continue
        follows = getattr(lights[k], "samples_follow_edges", True)
        if not (attached and strategy == "light" and len(lights) == 1 and follows):
            alone = ("; its gradient is unbiased only with strategy='light', mode='attached' and that light alone"
                     if follows else "; its samples cross one another's edges (hold the lights fixed, or use "
                     "mode='detached' for parameters that move no edge)")
            raise ValueError(f"shade: light {k} ({type(lights[k]).__name__}) has no 'silhouette', so the boundary "
                             f"term of its moving edges is unknown{alone}")
    brdf_moves = not all(_is_zero(t) for t in (normal_t, wo_t, brdf_t))
    if attached and strategy in ("brdf", "mis") and brdf_moves:
        names = ", ".join(type(lights[k]).__name__ for k in unknown)
        raise ValueError(f"shade: with strategy={strategy!r}, mode='attached' the BRDF's samples move across the "
                         f"edges of {names}, whose boundary terms are unknown (no 'silhouette'); for gradients "
                         "of the BRDF, the normal or wo use mode='detached' (unbiased where the edges stay put) or "
                         "strategy='light'")
    others_move = not (_is_zero(point_t) and all(_is_zero(lights_t[k]) for k in range(len(lights)) if k not in unknown))
    if attached and strategy in ("light", "mis") and len(lights) > 1 and others_move:
        raise ValueError("shade: with several lights and mode='attached', the samples of a moving light cross the "
                         "edges of a light without 'silhouette'; use mode='detached'")


def _instantiate(primal, tangent):
    """A zero tangent shaped like its primal (from the primal, not the zero's aval: under `vmap`
    only the primal knows its batch axis)."""
    if not isinstance(tangent, SymbolicZero):
        return tangent
    if tangent.aval.dtype == jax.dtypes.float0:
        return np.zeros(jnp.shape(primal), jax.dtypes.float0)
    return jnp.zeros_like(primal)


@functools.partial(jax.custom_jvp, nondiff_argnums=(0, 1))
def _guarded(strategy, mode, point, normal, wo, brdf, lights):
    """The scene itself, whose derivative is refused (`_refuse`) where no boundary term `shade` knows
    makes it unbiased: checked once, when the derivative is asked for, not per sample."""
    return point, normal, wo, brdf, lights


def _guarded_jvp(strategy, mode, primals, tangents):
    _refuse(strategy, mode, primals[4], tangents)
    return primals, jax.tree_util.tree_map(_instantiate, tuple(primals), tuple(tangents),
                                           is_leaf=lambda v: isinstance(v, SymbolicZero))


_guarded.defjvp(_guarded_jvp, symbolic_zeros=True)


def _check_shade(arguments):
    check_scene("shade", *(arguments[name] for name in ("point", "normal", "wo", "brdf", "lights")))


def _check_shade_grad(arguments):
    scene = arguments["make"](arguments["params"])
    if not isinstance(scene, (tuple, list)) or len(scene) != 5:
        raise ValueError("shade_grad: parameter 'make' must return (point, normal, wo, brdf, lights); got "
                         f"{type(scene).__name__}")
    check_scene("shade_grad", *scene)


@compiled_entry("n", "strategy", "mode", "heuristic", "beta", "uniforms", "mesh", "chunk_size", "dtype",
                "boundary_term", check=_check_shade)
def shade(point, normal, wo, brdf, lights, key: jax.Array, n: int, *, strategy: str = "mis",
          mode: str = "attached", heuristic: str = "power", beta: float | None = None, uniforms="random",
          mesh=None, chunk_size: int | None = None, dtype=None, boundary_term: bool = True) -> Estimate:
    """Outgoing radiance L_o(point, ω_o) = ∫ f_r L_i cos⁺θ_i dω_i under `lights`, no occluders.

    Args:
      point, normal, wo: 3-vectors in world space; `normal` and `wo` (pointing away from the
        surface, toward the viewer) are normalized here. A concrete scene is checked before anything
        runs (`jaxsample.scene.checks`): a zero-length normal or wo, a wo below the surface, a point
        inside a sphere light or behind every one-sided light is a ValueError; traced, a wo below the
        surface gives L_o = 0 and a point inside a sphere light NaN.
      brdf: `Lambertian`, `Phong`, `RoughConductor`, or any pytree with `eval(wo, wi)`,
        `sample(wo, u)` and `pdf(wo, wi)` in the local shading frame (normal +z), densities over
        solid angle.
      lights: one light or a sequence of them (`ConstantSky`, `SphereLight`, `TriangleLight`,
        `QuadLight`, `EnvironmentMap`, or anything with `sample(point, u) -> (ω, L, p)`,
        `pdf(point, ω)` and `radiance_from(point, ω)` in world space).
      key: a JAX key (`jax.random.key`, or a legacy `jax.random.PRNGKey`: the same stream), consumed
        once.
      n: radiance evaluations (any concrete integer, as in `jaxsample.estimate`; even for "mis",
        which draws n/2 of each strategy).
      strategy: "brdf", "light" or "mis" (default).
      mode: "attached" (default) or "detached"; applies to samples, densities and MIS weights
        together (see the module docstring for which is unbiased for which parameter).
      heuristic, beta: the MIS weights of "mis", as in `jaxsample.estimate_mis`: "power" (default;
        β = `beta`, default 2, a concrete number > 0) or "balance". `beta` with another strategy is
        a ValueError.
      uniforms, mesh, chunk_size, dtype: as in `jaxsample.estimate`.
      boundary_term: True (default) includes the silhouettes' boundary term in the derivative (it has
        value 0: the estimate is the same either way). False leaves it out, and the gradient is then
        biased wherever a light's edge moves across the samples; it exists to measure what the term
        contributes and costs.

    Colour: BRDF parameters (albedo, η, k) and light radiances may carry a trailing channel axis of C
    channels (`jaxsample.scene.colour`); then L_o has one value per channel, each with its own
    standard error, all from the same samples: directions, densities and MIS weights are shared by
    every channel (one proposal; an `EnvironmentMap` samples by its channel average).

    Returns: an `Estimate` of L_o, shape () or (C,); `n` is the evaluation count and `variance` the
    per-evaluation variance, so strategies compare at equal cost.
    """
    n = _check_options("shade", strategy, mode, heuristic, beta, n, boundary_term)
    dtype = resolve_float_dtype("shade", dtype)
    values_fn, dims, count, channels = _program(point, normal, wo, brdf, lights, strategy, mode, heuristic, n,
                                                dtype, boundary_term, beta=beta)
    est = run_stream(values_fn, dims, key, count, uniforms=uniforms, mesh=mesh,
                     chunk_size=chunk_size, out_shape=channels, dtype=dtype, owner="shade")
    if count == n:
        return est
    return est.per_evaluation(n)  # one pair costs two evaluations


def _check_options(owner, strategy, mode, heuristic, beta, n, boundary_term=True):
    check_choice(owner, "strategy", strategy, STRATEGIES)
    if not isinstance(boundary_term, (bool, np.bool_)):
        raise ValueError(f"{owner}: parameter 'boundary_term' must be True or False; got {boundary_term!r}")
    check_mode(owner, mode)
    if beta is not None and not isinstance(beta, (int, float, np.integer, np.floating)):
        raise ValueError(f"{owner}: parameter 'beta' must be a concrete number (it selects the program of the "
                         f"weights and of their boundary terms); got {type(beta).__name__}")
    heuristic_exponent(owner, heuristic, beta)
    if beta is not None and strategy != "mis":
        raise ValueError(f"{owner}: parameter 'beta' applies to strategy='mis' only; got strategy={strategy!r}")
    n = check_count(owner, "n", n, minimum=2)
    if strategy == "mis" and n % 2:
        raise ValueError(f"{owner}: parameter 'n' must be even for strategy 'mis' (n/2 of each strategy); got {n}")
    return n


def _program(point, normal, wo, brdf, lights, strategy, mode, heuristic, n, dtype, boundary=True, beta=None):
    """(values_fn, uniform dims, count): the per-evaluation (per-pair for "mis") values of `shade`,
    interior estimate plus the silhouettes' boundary term (value 0), from (count, dims) uniforms.
    `boundary=False` leaves the term out (a biased gradient: `shade`'s `boundary_term`)."""
    point, normal, wo = (jnp.asarray(v, dtype) for v in (point, normal, wo))
    point, normal, wo, brdf, lights = _guarded(strategy, mode, point, normal, wo, brdf, as_lights("shade", lights))
    shading = _Shading(point, normal, wo, brdf, lights, mode)
    exponent = heuristic_exponent("shade", heuristic, beta)

    def brdf_values(u, weighted):
        wi_local, radiance, pdf, light_pdf = shading.brdf_sample(u)
        g = shading.integrand(wi_local, radiance)
        weight = mis_weight(pdf, light_pdf, exponent) if weighted else 1.0
        return safe_div(shading.colour(weight, pdf.ndim) * g, shading.colour(pdf, pdf.ndim))

    def light_values(u, weighted):
        wi_local, radiance, pdf, brdf_pdf = shading.light_sample(u)
        g = shading.integrand(wi_local, radiance)
        weight = mis_weight(pdf, brdf_pdf, exponent) if weighted else 1.0
        return safe_div(shading.colour(weight, pdf.ndim) * g, shading.colour(pdf, pdf.ndim))

    if strategy == "brdf":
        interior, dims, count = (lambda u: brdf_values(u, False)), 2, n
    elif strategy == "light":
        interior, dims, count = (lambda u: light_values(u, False)), shading.light_dims, n
    else:
        def interior(u):
            return brdf_values(u[..., :2], True) + light_values(u[..., 2:], True)
        dims, count = 2 + shading.light_dims, n // 2
    # Light sampling of a single light, attached, follows that light's rim: nothing to add or refuse.
    follows = strategy == "light" and mode == "attached" and len(shading.lights) == 1
    if not boundary or follows:
        return interior, dims, count, shading.channels
    rims = len(shading.silhouettes())

    if rims == 0:
        return interior, dims, count, shading.channels

    def with_boundary_term(u):
        # Each evaluation (pair, for "mis") carries one rim point per light with a silhouette; the
        # surrogates have value 0, so these are the interior values with the boundary term's derivative.
        t = _rim_uniforms(jax.lax.stop_gradient(_rim_seed(u)), rims)
        return interior(u) + shading.boundary_values(t, strategy, exponent)

    def values_fn(u):
        return interior(u)

    # The engine evaluates the value without the term (it is 0) and differentiates the function with
    # it (`estimators.engine`): an estimate that is not differentiated costs what it would without.
    values_fn.derivative = with_boundary_term
    return values_fn, dims, count, shading.channels


def _rim_seed(u):
    """u_0 + u_1 of each evaluation's uniforms: what its rim uniforms are made from (`_rim_uniforms`)."""
    return u[:, 0] + u[:, 1]


def _rim_uniforms(seed, rims):
    """One uniform per rim from the evaluation's own uniforms: t_j = frac(u_0 + u_1 + j φ), φ the golden
    ratio's fraction. A uniform plus anything independent of it is uniform mod 1: so t_j is exactly
    uniform for independent points and for Owen-scrambled Sobol' (each coordinate scrambled with its
    own seed), and over the strata for the stratified source ((c + r) mod s is uniform when the
    cell c is); the boundary term it drives is unbiased. It is correlated with the interior sample,
    which the per-evaluation standard error accounts for. Drawing fresh
    uniforms instead cost a third Philox output per evaluation: +50 % on BRDF sampling's value,
    which never needs the term (measured; `benchmarks/`)."""
    columns = []
    for j in range(rims):
        shifted = seed + np.float32(j * 0.6180339887498949)
        columns.append(shifted - jnp.floor(shifted))
    return jnp.stack(columns, axis=-1) if columns else jnp.zeros(seed.shape + (0,), seed.dtype)


@compiled_entry("make", "n", "strategy", "mode", "heuristic", "beta", "antithetic", "uniforms", "mesh",
                "chunk_size", "dtype", "boundary_term", check=_check_shade_grad)
def shade_grad(make: Callable[[Any], tuple], params, key: jax.Array, n: int, *, strategy: str = "mis",
               mode: str = "attached", heuristic: str = "power", beta: float | None = None,
               antithetic: str | None = None, uniforms="random", mesh=None, chunk_size: int | None = None,
               dtype=None, boundary_term: bool = True) -> Estimate:
    """∇θ of `shade`'s estimate with its standard error; `(point, normal, wo, brdf, lights) =
    make(θ)`, θ = `params` (a pytree of floats: an exponent, a light's centre, vertices ...).

    The mean is the gradient `jax.grad` of `shade(..., key, n, ...).mean` gives (same samples, to
    float rounding); the standard error is the spread of the per-evaluation (per-pair for "mis")
    gradients, streamed in constant memory like `jaxsample.estimate_grad`, with the silhouettes'
    boundary term inside each of them. Options as in `shade`. For a scene with C colour channels
    each leaf of the result has shape (C,) + the parameter's shape: one gradient per channel.

    `antithetic`: None (independent evaluations), or pairs of evaluations whose gradients are
    averaged, as in `jaxsample.estimate_grad` (Zhang et al. 2021): "rotate" turns the BRDF sample's
    azimuth by π (its sampler's periodic coordinate moved by 1/2; with "mis" the light sample's
    uniforms are reflected), the antithetic sampling of a glossy lobe's derivatives; "reflect" pairs every
    uniform u with 1 − u. n must be even (a multiple of 4 with "mis"); `variance` is per
    evaluation, so it compares with the plain estimator's at equal n. With "mis" pairing can cost:
    on Phong 25 under a sphere light it raised the variance of d/d log n 1.6x (the light samples'
    share gains nothing from the pairs), where by BRDF sampling "rotate" lowered it to 0.66x.
    """
    return _shade_grad(make, params, key, n, strategy, mode, heuristic, uniforms, mesh, chunk_size, dtype,
                       boundary_term, beta=beta, antithetic=antithetic)


def _antithetic_partner(owner, antithetic, strategy, brdf, count):
    """The partner of each row of `shade`'s uniforms in an antithetic pair (see `shade_grad`)."""
    check_choice(owner, "antithetic", antithetic, ANTITHETIC)
    if count % 2:
        raise ValueError(f"{owner}: parameter 'n' must be {'a multiple of 4' if strategy == 'mis' else 'even'} with "
                         "antithetic pairs (pairs of evaluations" + (", each a BRDF and a light sample)" if strategy
                                                                      == "mis" else ")"))
    if antithetic == "reflect":
        return lambda u: 1.0 - u
    if strategy == "light":
        raise ValueError(f"{owner}: antithetic='rotate' turns the BRDF sample's azimuth, and strategy='light' draws "
                         "no BRDF sample; use antithetic='reflect'")
    periodic = list(getattr(brdf.sampler(jnp.array([0.0, 0.0, 1.0])), "periodic_dims", ()))
    if not periodic:
        raise ValueError(f"{owner}: antithetic='rotate' turns the BRDF sample's azimuth, and {type(brdf).__name__}'s "
                         "sampler has no periodic coordinate; use antithetic='reflect'")

    def rotate(u):
        shifted = u[:, periodic] + 0.5
        turned = u.at[:, periodic].set(jnp.where(shifted >= 1.0, shifted - 1.0, shifted))
        # With "mis" the light's uniforms (after the BRDF's two) are reflected: shared, the pair's two
        # light samples would be one, and its variance would count twice.
        return turned.at[:, 2:].set(1.0 - u[:, 2:]) if strategy == "mis" else turned

    return rotate


_FORWARD_PARAMETERS = 1


def _shade_grad(make, params, key, n, strategy, mode, heuristic, uniforms, mesh, chunk_size, dtype, boundary=True,
                beta=None, antithetic=None):
    n = _check_options("shade_grad", strategy, mode, heuristic, beta, n, boundary)
    flat, unravel = ravel_pytree(params)
    if not jnp.issubdtype(flat.dtype, jnp.floating):
        raise TypeError(f"shade_grad: parameter 'params' must be a pytree of floats; got dtype {flat.dtype}")
    dtype = resolve_float_dtype("shade_grad", dtype)
    _, dims, count, channels = _program(*make(params), strategy, mode, heuristic, n, dtype, boundary, beta)

    def values_fn(u):
        def one(row):
            def value(theta):
                fn = _program(*make(unravel(theta)), strategy, mode, heuristic, n, dtype, boundary, beta)[0]
                return getattr(fn, "derivative", fn)(row[None])[0]
            # Forward mode for one parameter: one JVP per point, where reverse mode turns a light's
            # table lookup into a scatter (7.6x jax.grad's time for an environment map's radiance
            # scale, `benchmarks/gradient_cost.py`). For 4 parameters (the report's inverse problem:
            # a conductor under a quad light, under lax.map) forward runs faster but compiles
            # slower than reverse: reverse is kept there, for the compile.
            reverse = jax.jacrev if channels else jax.grad
            return (jax.jacfwd if flat.size <= _FORWARD_PARAMETERS else reverse)(value)(flat)
        return jax.vmap(one)(u)

    if antithetic is not None:
        partner = _antithetic_partner("shade_grad", antithetic, strategy, make(params)[3], count)
        values_fn = (lambda single: lambda u: 0.5 * (single(u) + single(partner(u))))(values_fn)
        count //= 2
    est = run_stream(values_fn, dims, key, count, uniforms=uniforms, mesh=mesh, chunk_size=chunk_size,
                     out_shape=channels + flat.shape, dtype=dtype, owner="shade_grad")
    if count != n:
        est = est.per_evaluation(n)
    # One gradient per channel: leaves of shape (C,) + the parameter's shape, as `jax.jacobian` gives.
    per_channel = jax.vmap(unravel) if channels else unravel
    return dataclasses.replace(jax.tree_util.tree_map(per_channel, est), gradient=True)
