"""Multiple importance sampling: several samplers, each with its own count, combined by the balance
or power heuristic (Veach & Guibas 1995; Veach 1997, ch. 9), on the streaming engine.

The weights and the heuristic's options (`heuristic`, `beta`: `heuristic_exponent`) are shared with
the other MIS path, `scene.shade(..., strategy="mis")`."""

from __future__ import annotations

import functools
import math
from typing import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._core.entry import compiled_entry
from .._core.counts import check_count
from .._core.numerics import safe_div, safe_sqrt
from .._core.params import check_choice, resolve_float_dtype
from ..samplers.base import check_unbatched, check_uniforms, checked
from ..uniforms import as_key
from .engine import run_stream
from .integrand import integrand_layout
from .plain import _detach, broadcast_like, check_mode
from .result import Estimate
from .boundary import refuse_edges

__all__ = ["estimate_mis", "heuristic_weights", "heuristic_exponent", "HEURISTICS"]

HEURISTICS = ("balance", "power")


def heuristic_weights(densities: Sequence[jax.Array], exponent: float) -> list[jax.Array]:
    """The MIS weights w_k = q_k^β / Σ_j q_j^β of one point's densities q_k (each already times its
    sample count; β = 1 is the balance heuristic, β = 2 the power heuristic). They sum to 1 where
    some q_k > 0 and are all 0 where every q_k = 0.

    Computed after dividing every q_k by the largest, so that no power overflows (a tiny light's
    density is 1/(2π · 5e-9) ≈ 3e7, and squares of densities beyond 1e19 overflow float32) and the
    gradient stays finite.
    """
    largest = functools.reduce(jnp.maximum, densities)
    scale = jnp.where(largest > 0, largest, 1.0)
    powered = [(q / scale) ** exponent for q in densities]
    total = sum(powered)
    return [safe_div(p, total) for p in powered]


def heuristic_exponent(owner: str, heuristic: str, beta=None):
    """The exponent β of the MIS weights (q_k^β / Σ_j q_j^β) for `heuristic` and `beta`, the options
    of every MIS path: 1 for "balance"; for "power", `beta` (default 2), a number > 0 or a traced
    value. An integral concrete β is returned as an int, so that q ** 2 is a multiplication (q ** 2.0
    would be lax.pow: exp and log). ValueError for another heuristic, a concrete β that is not a
    finite number > 0, or a β other than 1 with "balance" (which is β = 1)."""
    check_choice(owner, "heuristic", heuristic, HEURISTICS)
    concrete = isinstance(beta, (int, float, np.integer, np.floating))
    if heuristic == "balance":
        if beta is not None and not (concrete and float(beta) == 1.0):
            raise ValueError(f"{owner}: parameter 'beta' applies to heuristic='power' (the balance heuristic is "
                             f"beta = 1); got {beta!r}")
        return 1
    if beta is None:
        return 2
    if concrete:
        if not (math.isfinite(float(beta)) and float(beta) > 0):
            raise ValueError(f"{owner}: parameter 'beta' must be a finite number > 0; got {beta!r}")
        if float(beta).is_integer():
            return int(beta)
    return beta


def _check_samplers_agree(samplers) -> None:
    """MIS adds densities of one point under every technique: they must be densities of one event
    shape over one measure (a solid-angle density plus an area density is a number without
    meaning), each of one distribution."""
    for s in samplers:
        check_unbatched(s, "estimate_mis")
    described = ", ".join(f"{type(s).__name__} (event_shape {tuple(s.event_shape)}, measure {s.measure!r})"
                          for s in samplers)
    if len({tuple(s.event_shape) for s in samplers}) != 1:
        raise ValueError(f"estimate_mis: parameter 'samplers' must share one event shape; got {described}")
    measures = {s.measure for s in samplers}
    if None in measures:
        raise ValueError(f"estimate_mis: every sampler must state the measure its density is over; got {described} "
                         "(give Transformed a measure=...)")
    if len(measures) != 1:
        raise ValueError(f"estimate_mis: parameter 'samplers' must have densities over one measure; got {described}")


@compiled_entry("f", "counts", "heuristic", "beta", "uniforms", "mode", "chunk_size", "dtype", "mesh",
                tuples=("counts",))
def estimate_mis(f: Callable, samplers: Sequence, key: jax.Array, counts: Sequence[int], *,
                 heuristic: str = "balance", beta: float | None = None, uniforms="random",
                 mode: str = "attached", chunk_size: int | None = None, dtype=None, mesh=None) -> Estimate:
    """Multi-sample MIS: Σ_i (1/n_i) Σ_j w_i(x_ij) f(x_ij) / p_i(x_ij), x_ij ~ samplers[i].

    Weights (Veach 1997, eqs. 9.4 and 9.5), with q_k = n_k p_k(x):
      "balance": w_i = q_i / Σ_k q_k;  "power": w_i = q_i^β / Σ_k q_k^β (β = `beta`, default 2; a
      number > 0, concrete or traced; with "balance" only β = 1 applies).
    Both sum to 1 wherever some p_k > 0, so the estimate is unbiased. Each technique draws from
    its own key (split from `key`); techniques are independent, so stderr² = Σ_i stderr_i².
    All samplers must share a domain and measure. `mode="detached"` stops the gradient of the
    sample, its density and every density in the weight together. `mesh`: every technique's
    samples are split over the mesh's devices, as in `jaxsample.estimate`. `f` may return a pytree
    of real or complex arrays (the integrand rule of `integrand.py`): the result is then the same
    pytree of `Estimate`s. Each count is any concrete integer, as `n` of `estimate`.
    """
    exponent = heuristic_exponent("estimate_mis", heuristic, beta)
    check_mode("estimate_mis", mode)
    samplers = list(samplers)
    if isinstance(counts, (str, bytes)) or not hasattr(counts, "__iter__") or np.ndim(counts) == 0:
        split = ""
        if isinstance(counts, (int, np.integer)) and samplers:
            split = f"; for {counts} in all, e.g. {[int(counts) // len(samplers)] * len(samplers)}"
        raise ValueError(f"estimate_mis: parameter 'counts' must be a sequence of one count per sampler "
                         f"({len(samplers)} here{split}); got {type(counts).__name__} {counts!r}")
    sizes = [check_count("estimate_mis", "counts", c, minimum=2) for c in counts]
    if len(samplers) != len(sizes) or not samplers:
        raise ValueError("estimate_mis: 'samplers' and 'counts' must be non-empty and of equal length")
    _check_samplers_agree(samplers)
    for s in samplers:
        check_uniforms(s, uniforms, "estimate_mis")
    refuse_edges("estimate_mis", f)
    samplers = [checked(s) for s in samplers]
    # The counts enter the weights as floats: a Python int beyond 2^31 overflows JAX's weak int32.
    counts = [float(c) for c in sizes]
    dtype = resolve_float_dtype("estimate_mis", dtype)
    keys = jax.random.split(as_key(key, "estimate_mis"), len(samplers))
    layout = integrand_layout(f, samplers[0], dtype, "estimate_mis")
    parts = []
    for i, (sampler, count) in enumerate(zip(samplers, sizes)):

        def values_fn(u, i=i, sampler=sampler):
            x, own_pdf = sampler.warp_with_pdf(u)
            pdfs = [own_pdf if k == i else other.pdf(x) for k, other in enumerate(samplers)]
            x, pdfs = _detach(mode, x, pdfs)
            weights = heuristic_weights([n_k * p_k for n_k, p_k in zip(counts, pdfs)], exponent)
            weight = weights[i]
            fx = layout.pack(jax.vmap(f)(x), u.dtype)
            return safe_div(fx * broadcast_like(weight, fx), broadcast_like(pdfs[i], fx))

        parts.append(run_stream(values_fn, sampler.uniform_dims, keys[i], count, uniforms=uniforms,
                                chunk_size=chunk_size, dtype=dtype, owner="estimate_mis", mesh=mesh,
                                out_shape=layout.out_shape))
    total = sum(sizes)
    stderr = safe_sqrt(sum(p.stderr * p.stderr for p in parts))
    # Diagnostics: the heaviest technique's tail decides; nonzero counts add up.
    est = Estimate(mean=sum(p.mean for p in parts), stderr=stderr, variance=float(total) * stderr * stderr,
                   max_abs=jnp.max(jnp.stack([p.max_abs for p in parts]), axis=0),
                   ess=sum(p.ess for p in parts),
                   khat=functools.reduce(jnp.fmax, [p.khat for p in parts]),
                   nonzero=sum(p.nonzero * float(p.n) for p in parts) / float(total),
                   n=total, replicates=parts[0].replicates)
    return layout.unpack_result(est)
