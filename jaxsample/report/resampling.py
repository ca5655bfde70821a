"""Resampled importance sampling against sampling its proposal alone, on two of the study's integrands.

Run alone: `python -m jaxsample.report.resampling [--quick]`.

`estimate_resampled(f, proposal, target, key, n, M)` spends M proposal samples and M target
evaluations on each output; the table gives, per M, the variance per output, the time per output
and their product against plain `estimate` with the proposal (and with a sampler of the target
itself where one exists): the variance that resampling saves, and what it costs.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js

from .timing import interleaved_medians

# (name, f, exact ∫f, proposal, target, a sampler drawing the target exactly or None)
CASES = [
    ("cos³ θ over H², uniform proposal, target cos θ", lambda w: w[2] ** 3, np.pi / 2, js.UniformHemisphere(),
     lambda w: jnp.maximum(w[2], 0.0), js.CosineHemisphere()),
    ("sharp lobe cos¹⁰⁰ θ over H², cosine proposal, target cos⁸⁰ θ", lambda w: jnp.maximum(w[2], 0.0) ** 100,
     2 * np.pi / 101, js.CosineHemisphere(), lambda w: jnp.maximum(w[2], 0.0) ** 80, js.PhongLobe(80.0)),
]
CANDIDATES = (1, 4, 16, 64)


def resampling_table(quick: bool = True, progress=print) -> list[dict]:
    """One row per (case, method): RIS with each M, the proposal alone, the target's own sampler.
    `quick`: the sharp lobe alone, M = 4, 16, 64 (each program compiles anew)."""
    n = 1 << (16 if quick else 18)
    rows = []
    for name, f, exact, proposal, target, exact_sampler in CASES[1:] if quick else CASES:
        progress(f"[resampling] {name}")
        programs = {"proposal alone": jax.jit(lambda k, f=f, s=proposal: js.estimate(f, s, k, n))}
        if exact_sampler is not None:
            programs["the target's sampler"] = jax.jit(lambda k, f=f, s=exact_sampler: js.estimate(f, s, k, n))
        for m in CANDIDATES[1:] if quick else CANDIDATES:
            programs[f"RIS, M = {m}"] = jax.jit(lambda k, f=f, s=proposal, t=target, m=m:
                                                js.estimate_resampled(f, s, t, k, n, m))
        estimates = {label: program(jax.random.key(17)) for label, program in programs.items()}
        seconds = interleaved_medians(programs, iter(jax.random.split(jax.random.key(18), 64)), repeats=3)
        plain = float(estimates["proposal alone"].variance) * seconds["proposal alone"]
        for label, est in estimates.items():
            variance = float(est.variance)
            rows.append({"case": name, "method": label, "n": n, "mean": float(est.mean), "stderr": float(est.stderr),
                         "exact": exact, "variance_per_output": variance,
                         "ns_per_output": 1e9 * seconds[label] / n,
                         "variance_x_time_vs_proposal": variance * seconds[label] / plain})
    return rows


def markdown(rows: list[dict]) -> str:
    out = ["| integrand | method | estimate ± stderr | exact | variance per output | ns per output "
           "| variance × time, × the proposal's |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['case']} | {r['method']} | {r['mean']:.5g} ± {r['stderr']:.2g} | {r['exact']:.5g} | "
                   f"{r['variance_per_output']:.3g} | {r['ns_per_output']:.1f} | "
                   f"{r['variance_x_time_vs_proposal']:.3g} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    print(markdown(resampling_table(parser.parse_args().quick)))
