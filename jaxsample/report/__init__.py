"""The main job: `python -m jaxsample report` — a speed-against-error study, as tables and plots.

It answers, for each integrand with an exact reference: which sampling strategy gives the smallest
error in a given time, and by how much. Every figure is measured in the run that writes it.

Sections (each computed by a module of this package, runnable alone as `python -m
jaxsample.report.<module>` or `python benchmarks/<module>.py` in a checkout):
  1. environment (device, dtype, JAX version, PRNG);
  2. samplers: normalization, a known integral ± stderr, time per million (`samplers_table.py`);
  3. convergence: RMSE, bias, variance, ns/sample, time to unit variance, efficiency and RMSE
     slope per (integrand, strategy), with plots (`convergence.py`);
  4. baselines: vectorized NumPy and the uniform-generation floor, as ratios (`baselines.py`),
     and the speed of every public path against its target (`paths.py`);
  5. the curse of dimensionality: quadrature against Monte Carlo and Sobol' (`dimensionality.py`);
  6. gradients: variance and cost per gradient estimator (`bench_gradients.py`), gradients with
     their standard errors and estimates to a requested accuracy (`gradient_error_bars.py`);
  7. hard cases: non-finite values/gradients and float32 error at extreme parameters (`hard_cases.py`);
  8. the scene: the inverse problem solved by gradient descent (`inverse_problem.py`).

Writes `report.md`, one CSV per table and PNG plots (matplotlib, the `plot` extra) to `--out`.
"""

from __future__ import annotations

import argparse
import csv
import importlib
import json
import os
import platform
import time
from pathlib import Path

import jax
import numpy as np

# --tiny is a smoke test of every code path, not a study: a few samplers of each kind.
TINY_SAMPLERS = ("CosineHemisphere(malley)", "PhongLobe(1e7)", "UniformCone(1e-8 sr)", "UniformDisk(concentric)",
                 "Exponential(2)", "Discrete(1,2,3,4)", "Mixture(cosine, Phong 20)")


def _piece(name: str):
    """A module of this package (the report's building blocks), imported when its section runs."""
    return importlib.import_module(f"{__name__}.{name}")


def _write_csv(path: Path, rows: list[dict]) -> None:
    if not rows:
        return
    keys = list(dict.fromkeys(k for row in rows for k in row))
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=keys)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: json.dumps(v) if isinstance(v, (list, dict)) else v for k, v in row.items()})


def _environment() -> dict:
    device = jax.devices()[0]
    return {"device": f"{device.platform} ({device.device_kind})", "device_count": jax.device_count(),
            "cpu_cores": os.cpu_count(), "dtype": str(np.dtype(jax.numpy.zeros(()).dtype)),
            "jax": jax.__version__, "numpy": np.__version__, "python": platform.python_version(),
            "prng": "Philox4x32-10 (jaxsample.uniforms, counter-based)",
            "machine": platform.machine(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}


def _plots(rows: list[dict], out: Path, dims_rows: list[dict]) -> list[str]:
    """Log–log RMSE against n and against seconds per integrand, and efficiency bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for integrand in dict.fromkeys(r["integrand"] for r in rows):
        group = [r for r in rows if r["integrand"] == integrand]
        fig, (ax_n, ax_t) = plt.subplots(1, 2, figsize=(11, 4.2))
        for r in group:
            ns = np.array(r["ns"], float)
            rmse = np.maximum(np.array(r["rmse"]), 1e-12)
            ax_n.loglog(ns, rmse, "o-", ms=3, label=f"{r['strategy']} ({r['slope']:.2f})")
            ax_t.loglog(ns * r["ns_per_sample"] * 1e-9, rmse, "o-", ms=3, label=r["strategy"])
        anchor_n, anchor_e = float(group[0]["ns"][0]), float(max(group[0]["rmse"][0], 1e-12))
        ns = np.array(group[0]["ns"], float)
        for slope, style in ((-0.5, ":"), (-1.0, "--"), (-1.5, "-.")):
            ax_n.loglog(ns, anchor_e * (ns / anchor_n) ** slope, "k" + style, lw=0.8, label=f"n^{slope}")
        ax_n.set(xlabel="samples n", ylabel="RMSE", title=f"{integrand}: RMSE against n")
        ax_t.set(xlabel="seconds (measured ns/sample × n)", ylabel="RMSE", title="RMSE against time")
        ax_n.legend(fontsize=6)
        ax_t.legend(fontsize=6)
        fig.tight_layout()
        path = out / f"rmse_{integrand}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path.name)
    fig, ax = plt.subplots(figsize=(10, max(4, 0.22 * len(rows))))
    labels = [f"{r['integrand']} / {r['strategy']}" for r in rows]
    ax.barh(labels, [max(r["relative_efficiency"], 1e-3) for r in rows], color="tab:blue")
    ax.set_xscale("log")
    ax.axvline(1.0, color="k", lw=0.8)
    ax.set(xlabel="efficiency relative to uniform sampling (1 / (MSE × time)), log scale")
    ax.tick_params(axis="y", labelsize=6)
    fig.tight_layout()
    fig.savefig(out / "efficiency.png", dpi=110)
    plt.close(fig)
    written.append("efficiency.png")
    if dims_rows:
        fig, ax = plt.subplots(figsize=(6, 4))
        budget = max(r["budget"] for r in dims_rows)
        for method in dict.fromkeys(r["method"] for r in dims_rows):
            pts = sorted((r["d"], max(r["error"], 1e-12)) for r in dims_rows if r["method"] == method and r["budget"] == budget)
            ax.semilogy(*zip(*pts), "o-", label=method)
        ax.set(xlabel="dimension d", ylabel="|error|", title=f"Error at ≈{budget} evaluations")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / "dimensionality.png", dpi=110)
        plt.close(fig)
        written.append("dimensionality.png")
    return written


def _headline(rows: list[dict]) -> str:
    out = ["| integrand | best strategy | its efficiency vs uniform | RMSE @ n_max | RMSE slope |",
           "|---|---|---|---|---|"]
    for integrand in dict.fromkeys(r["integrand"] for r in rows):
        group = [r for r in rows if r["integrand"] == integrand]
        best = max(group, key=lambda r: r["efficiency"])
        out.append(f"| {integrand} | {best['strategy']} | {best['relative_efficiency']:.3g}× | "
                   f"{best['rmse_at_max']:.3g} | {best['slope']:.2f} |")
    return "\n".join(out) + "\n"


def run(out_dir: str = "report", quick: bool = False, tiny: bool = False) -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    progress = lambda message: print(message, flush=True)  # noqa: E731
    started = time.perf_counter()
    env = _environment()
    mode = "tiny" if tiny else ("quick" if quick else "full")
    md = [f"# jaxsample report ({mode})\n",
          "Every number below was measured in this run. Reproduce with "
          f"`python -m jaxsample report{' --quick' if quick else ''}{' --tiny' if tiny else ''}`.\n",
          "## Environment\n", "| key | value |\n|---|---|"]
    md += [f"| {k} | {v} |" for k, v in env.items()]
    md.append("")

    samplers = _piece("samplers_table")
    sampler_rows = samplers.sampler_table(n=1 << (12 if tiny else (18 if quick else 20)), progress=progress,
                                          timing_n=1 << (14 if tiny else 20),
                                          only=TINY_SAMPLERS if tiny else None)
    _write_csv(out / "samplers.csv", sampler_rows)
    md += ["## Samplers\n", "Normalization by float64 quadrature; a known integral estimated with "
           "`js.estimate` (default uniforms) beside its exact value; `sample_with_pdf` time under jit.\n",
           samplers.markdown_table(sampler_rows)]

    convergence = _piece("convergence")
    rows = convergence.run_study(quick=quick, tiny=tiny, progress=progress)
    _write_csv(out / "convergence.csv", rows)
    md += ["## Which strategy wins\n", "Efficiency = 1 / (MSE × time) at the largest n, relative to "
           "plain uniform sampling of the same integrand (higher is better).\n", _headline(rows),
           "## Speed against error, per integrand and strategy\n",
           f"RMSE and bias over {rows[0]['n_keys']} independent keys at n = {rows[0]['ns'][-1]}; bias z = "
           "bias / (RMSE/√keys); ns/sample measured on `js.estimate` under jit. MIS rows count one sample "
           "per technique as two evaluations. Estimates at each n are prefix means of one stream per key "
           "(Sobol': one scrambled sequence, whose power-of-two prefixes are nets); jittered points are "
           "drawn anew per n. Zero-variance strategies are floored at the float32 rounding level "
           "(see jaxsample/report/convergence.py).\n", convergence.markdown_table(rows)]

    baselines = _piece("baselines")
    if tiny:
        md += ["## Baselines\n", "Skipped in --tiny mode (run `python benchmarks/baselines.py`).\n"]
    else:
        base = baselines.baseline_table(quick=quick, progress=progress)
        _write_csv(out / "baselines.csv", [base])
        md += ["## Baselines (∫cos³ over H², cosine sampling, one run)\n", baselines.markdown_table(base)]

    paths = _piece("paths")
    path_rows = paths.path_table(quick=quick, tiny=tiny, progress=progress)
    _write_csv(out / "paths.csv", path_rows)
    md += ["## Speed of every public path\n",
           "Each row times a program users write (ns per sample, or per radiance evaluation for "
           "`shade`), with its ratio and target taken in this run from interleaved medians "
           f"(`jaxsample/report/paths.py`{'; --tiny times only the integrand forms' if tiny else ''}).\n",
           paths.markdown_table(path_rows)]

    dims_rows: list[dict] = []
    if not tiny:
        dimensionality = _piece("dimensionality")
        dims_rows = dimensionality.dimensionality_table(quick=quick, progress=progress)
        _write_csv(out / "dimensionality.csv", dims_rows)
        md += ["## The curse of dimensionality\n", "|error| of ∫∏(π/2)sin(πx_i) = 1 on [0,1]^d (evaluations "
               "used in parentheses); Monte Carlo entries are RMSE over independent keys.\n",
               dimensionality.markdown_table(dims_rows)]

    try:
        if tiny:
            raise ImportError("skipped in --tiny mode")
        gradients = _piece("bench_gradients")
        progress("[gradients]")
        grad_rows = gradients.gradient_table(quick=quick or tiny)
        _write_csv(out / "gradients.csv", grad_rows)
        md += ["## Gradient estimators\n", gradients.markdown_table(grad_rows)]
    except (ImportError, AttributeError) as error:
        md += ["## Gradient estimators\n", f"Not available in this checkout ({error}).\n"]

    if tiny:
        md += ["## Gradients with error bars; estimates to a requested accuracy\n",
               "Skipped in --tiny mode (run `python benchmarks/gradient_error_bars.py`).\n"]
    else:
        error_bars = _piece("gradient_error_bars")
        bar_rows = error_bars.gradient_table(quick=quick, progress=progress)
        accuracy_rows = error_bars.accuracy_table(quick=quick, progress=progress)
        _write_csv(out / "gradient_error_bars.csv", bar_rows)
        _write_csv(out / "accuracy.csv", accuracy_rows)
        md += ["## Gradients with error bars; estimates to a requested accuracy\n",
               "d/dn E_{Phong(n)}[cos^k] by `expectation_grad` (gradient ± its reported stderr, exact value, "
               "per-sample variance, and 1/(variance × time): gradient accuracy per second); then "
               "`estimate_until` at requested relative standard errors.\n",
               error_bars.markdown(bar_rows, accuracy_rows)]

    hard = _piece("hard_cases")
    progress("[hard cases]")
    hard_rows = hard.hard_case_table()
    _write_csv(out / "hard_cases.csv", hard_rows)
    md += ["## Hard cases (float32, u ∈ {0, ½, 1−2⁻²⁴}²)\n", hard.markdown_table(hard_rows)]

    try:
        if tiny:
            raise ImportError("skipped in --tiny mode")
        inverse = _piece("inverse_problem")
        progress("[scene: inverse problem]")
        result = inverse.run_inverse_problem(quick=quick or tiny, out_dir=str(out))
        md += ["## Scene: recovering a Phong exponent and albedo by gradient descent\n",
               "```\n" + inverse.markdown_summary(result).strip() + "\n```\n"]
    except (ImportError, AttributeError) as error:
        md += ["## Scene\n", f"Not available in this checkout ({error}).\n"]

    try:
        images = _plots(rows, out, dims_rows)
        md += ["## Plots\n"] + [f"![{name}]({name})" for name in images]
    except ImportError:
        hint = ("matplotlib is not installed, so there are no plots: `pip install matplotlib` (the package's "
                "`plot` extra) and rerun for the PNG plots.")
        progress(hint)
        md += ["## Plots\n", hint + "\n"]

    md.append(f"\nTotal run time: {time.perf_counter() - started:.0f} s.\n")
    (out / "report.md").write_text("\n".join(md))
    progress(f"wrote {out / 'report.md'} in {time.perf_counter() - started:.0f} s")
    return out / "report.md"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m jaxsample", description="jaxsample command line")
    commands = parser.add_subparsers(dest="command", required=True)
    report = commands.add_parser("report", help="run the speed-against-error study")
    report.add_argument("--out", default="report", help="output folder (default: report/)")
    report.add_argument("--quick", action="store_true", help="smaller n and fewer keys (minutes on 2 cores)")
    report.add_argument("--tiny", action="store_true", help="a smoke test: smallest sizes, few sections")
    args = parser.parse_args(argv)
    if args.command == "report":
        run(args.out, quick=args.quick, tiny=args.tiny)
    return 0
