"""The curse of dimensionality: error against evaluations for d = 1..6, quadrature beside MC.

Run alone: `python -m jaxsample.report.dimensionality [--quick]`. The integrand is ∏ (π/2) sin(π x_i)
on [0, 1]^d (integral 1). Tensor-product rules (trapezoid, Simpson, Gauss–Legendre) use the
largest m with m^d ≤ budget; Monte Carlo ("random") and Owen-scrambled Sobol' use exactly the
budget, their error being the RMSE over independent keys (scrambles).
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

from jaxsample import quadrature
from jaxsample import uniforms as U


def _mc_rmse(source_name: str, d: int, n: int, keys: int) -> float:
    source = U.Random() if source_name == "random" else U.Sobol(replicates=2)
    stride = 1 if source_name == "random" else 2

    @jax.jit
    def one(seed):
        u = source.block(seed, jnp.uint32(0), n * stride, d, jnp.float32, total=n * stride)[::stride]
        return jnp.mean(jax.vmap(quadrature.sine_product)(u).astype(jnp.float32))

    errors = [float(one(U.seed_from_key(k))) - 1.0 for k in jax.random.split(jax.random.key(d * 1000 + n), keys)]
    return float(np.sqrt(np.mean(np.square(errors))))


def dimensionality_table(quick: bool = True, progress=print) -> list[dict]:
    budgets = (64, 1024, 16384) if quick else (64, 1024, 16384, 262144)
    keys = 8 if quick else 16
    rows = []
    for d in range(1, 7):
        progress(f"[dimensionality] d = {d}")
        for budget in budgets:
            for kind in quadrature.KINDS:
                try:
                    value, evaluations = quadrature.integrate_with_budget(quadrature.sine_product, kind, budget, d)
                except ValueError:
                    continue  # the rule needs more points than the budget allows in d dims
                rows.append({"d": d, "budget": budget, "method": kind, "evaluations": int(evaluations),
                             "error": abs(float(value) - 1.0)})
            for source in ("random", "sobol"):
                rows.append({"d": d, "budget": budget, "method": f"monte carlo ({source})", "evaluations": budget,
                             "error": _mc_rmse(source, d, budget, keys)})
    return rows


def markdown_table(rows) -> str:
    methods = list(dict.fromkeys(r["method"] for r in rows))
    budgets = sorted({r["budget"] for r in rows})
    out = ["| d | budget | " + " | ".join(methods) + " |", "|---|---|" + "---|" * len(methods)]
    for d in sorted({r["d"] for r in rows}):
        for b in budgets:
            cells = []
            for m in methods:
                hit = [r for r in rows if r["d"] == d and r["budget"] == b and r["method"] == m]
                cells.append(f"{hit[0]['error']:.2e} ({hit[0]['evaluations']})" if hit else "—")
            out.append(f"| {d} | {b} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    print(markdown_table(dimensionality_table(parser.parse_args().quick)))
