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
samples are frozen), so only f_r, L_i and cos θ_i carry derivatives. Which one is unbiased
depends on what the parameter moves:
- parameters that only change the integrand smoothly (albedo, exponent, radiance) — detached
  is unbiased; attached is unbiased too unless samples cross a discontinuity of L_i that stays
  put (a BRDF sample sliding over a light's rim as the exponent changes misses that jump);
- parameters that move a discontinuity (a light's position moves its silhouette) — only the
  samples that move with it see the change: "light" strategy, attached, is unbiased; "brdf"
  sampling and detached mode miss the silhouette's boundary term (detached gives 0 here).
"""

from __future__ import annotations


import jax
import jax.numpy as jnp

from .._core.entry import compiled_entry
from .._core.counts import check_count
from .._core.params import check_choice, default_float_dtype
from ..estimators.engine import run_stream
from ..estimators.mis import heuristic_weights
from ..estimators.plain import check_mode
from ..estimators.result import Estimate
from ..samplers.frame import Frame
from .._core.numerics import safe_div

__all__ = ["shade", "STRATEGIES"]

STRATEGIES = ("brdf", "light", "mis")


def _as_tuple(lights) -> tuple:
    if isinstance(lights, (list, tuple)):
        if not lights:
            raise ValueError("shade: parameter 'lights' must hold at least one light")
        return tuple(lights)
    return (lights,)


def mis_weight(own_pdf, other_pdf, exponent: float):
    """w = p_own^β / (p_own^β + p_other^β), 0 when both are 0 (`estimators.mis.heuristic_weights`:
    scaled so that neither power overflows and the gradient stays finite)."""
    return heuristic_weights([own_pdf, other_pdf], exponent)[0]


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

    # Radiance arriving along world directions, and the light-sampling density there.
    def light_radiance(self, wi):
        return sum(light.radiance_from(self.point, wi) for light in self.lights)

    def light_pdf(self, wi):
        return sum(light.pdf(self.point, wi) for light in self.lights) / len(self.lights)

    def integrand(self, wi_local, radiance):
        cos_theta = jnp.maximum(wi_local[..., 2], 0.0)
        return self.brdf.eval(self.wo_local, wi_local) * radiance * cos_theta

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
            wi, radiance, pdf = lights[0].sample(self.point, u)
            wi, pdf = self._freeze(wi, pdf)
        else:
            count = len(lights)
            chosen = jnp.clip(jnp.floor(u[..., 0] * count), 0, count - 1).astype(jnp.int32)
            draws = [light.sample(self.point, u[..., 1:]) for light in lights]
            wi = sum(jnp.where((chosen == k)[..., None], d[0], 0.0) for k, d in enumerate(draws))
            (wi,) = self._freeze(wi)
            radiance, pdf = 0.0, 0.0
            for k, (light, (_, own_radiance, own_pdf)) in enumerate(zip(lights, draws)):
                mine = chosen == k
                # The chosen light's own radiance and density (no re-test at its rim); the
                # others are evaluated along the chosen direction.
                radiance = radiance + jnp.where(mine, own_radiance, light.radiance_from(self.point, wi))
                pdf = pdf + jnp.where(mine, own_pdf, light.pdf(self.point, wi))
            (pdf,) = self._freeze(pdf / count)
        wi_local = self.frame.to_local(wi)
        (brdf_pdf,) = self._freeze(self.brdf.pdf(self.wo_local, wi_local))
        return wi_local, radiance, pdf, brdf_pdf

    @property
    def light_dims(self):
        return 2 if len(self.lights) == 1 else 3


@compiled_entry("n", "strategy", "mode", "heuristic", "uniforms", "mesh", "chunk_size", "dtype")
def shade(point, normal, wo, brdf, lights, key: jax.Array, n: int, *, strategy: str = "mis",
          mode: str = "attached", heuristic: str = "power", uniforms="random", mesh=None,
          chunk_size: int | None = None, dtype=None) -> Estimate:
    """Outgoing radiance L_o(point, ω_o) = ∫ f_r L_i cos⁺θ_i dω_i under `lights`, no occluders.

    Args:
      point, normal, wo: 3-vectors in world space; `normal` and `wo` (pointing away from the
        surface, toward the viewer) are normalized here. L_o is 0 when wo is below the surface.
      brdf: `Lambertian`, `Phong`, or any pytree with `eval(wo, wi)`, `sample(wo, u)` and
        `pdf(wo, wi)` in the local shading frame (normal +z), densities over solid angle.
      lights: one light or a sequence of them (`ConstantSky`, `SphereLight`, `TriangleLight`,
        `EnvironmentMap`, or anything with `sample(point, u) -> (ω, L, p)`, `pdf(point, ω)` and
        `radiance_from(point, ω)` in world space).
      key: a typed PRNG key, consumed once.
      n: radiance evaluations (any concrete integer, as in `jaxsample.estimate`; even for "mis",
        which draws n/2 of each strategy).
      strategy: "brdf", "light" or "mis" (default).
      mode: "attached" (default) or "detached"; applies to samples, densities and MIS weights
        together (see the module docstring for which is unbiased for which parameter).
      heuristic: "power" (β = 2, default) or "balance", for "mis".
      uniforms, mesh, chunk_size, dtype: as in `jaxsample.estimate`.

    Returns: an `Estimate` of L_o (a scalar); `n` is the evaluation count and `variance` the
    per-evaluation variance, so strategies compare at equal cost.
    """
    check_choice("shade", "strategy", strategy, STRATEGIES)
    check_mode("shade", mode)
    check_choice("shade", "heuristic", heuristic, ("power", "balance"))
    n = check_count("shade", "n", n, minimum=2)
    if strategy == "mis" and n % 2:
        raise ValueError(f"shade: parameter 'n' must be even for strategy 'mis' (n/2 of each strategy); got {n}")
    dtype = default_float_dtype() if dtype is None else jnp.dtype(dtype)
    point, normal, wo = (jnp.asarray(v, dtype) for v in (point, normal, wo))
    shading = _Shading(point, normal, wo, brdf, _as_tuple(lights), mode)
    exponent = 1 if heuristic == "balance" else 2

    def brdf_values(u, weighted):
        wi_local, radiance, pdf, light_pdf = shading.brdf_sample(u)
        g = shading.integrand(wi_local, radiance)
        weight = mis_weight(pdf, light_pdf, exponent) if weighted else 1.0
        return safe_div(weight * g, pdf)

    def light_values(u, weighted):
        wi_local, radiance, pdf, brdf_pdf = shading.light_sample(u)
        g = shading.integrand(wi_local, radiance)
        weight = mis_weight(pdf, brdf_pdf, exponent) if weighted else 1.0
        return safe_div(weight * g, pdf)

    if strategy == "brdf":
        values_fn, dims, count = (lambda u: brdf_values(u, False)), 2, n
    elif strategy == "light":
        values_fn, dims, count = (lambda u: light_values(u, False)), shading.light_dims, n
    else:
        def values_fn(u):
            return brdf_values(u[..., :2], True) + light_values(u[..., 2:], True)
        dims, count = 2 + shading.light_dims, n // 2

    est = run_stream(values_fn, dims, key, count, uniforms=uniforms, mesh=mesh,
                     chunk_size=chunk_size, out_shape=(), dtype=dtype, owner="shade")
    if count == n:
        return est
    return est.per_evaluation(n)  # one pair costs two evaluations
