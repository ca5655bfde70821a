"""The main job: `python -m jaxsample report` — a speed-against-error study, as tables and plots.

It answers, for each integrand with an exact reference: which sampling strategy gives the smallest
error in a given time, and by how much. Every figure is measured in the run that writes it.

`--tiny` is a smoke test of the report's code paths at the smallest sizes, whose numbers mean
nothing: it says so at the top of the report and draws no verdicts (no winner, speed-up, slope,
floor or target met).

Sections (each computed by a module of this package, runnable alone as `python -m
jaxsample.report.<module>`; in a checkout also as `python benchmarks/<module>.py`):
  1. environment (device, dtype, JAX version, PRNG);
  2. samplers: normalization, a known integral ± stderr, time per million (`samplers_table.py`);
  3. convergence: which strategy reaches a target error first, and how much sooner (`verdicts.py`);
     RMSE, bias, variance, ns/sample, floor, RMSE slope ± se and time to each target per
     (integrand, strategy), with plots (`convergence.py`);
  4. baselines: vectorized NumPy and the uniform-generation floor, as ratios (`baselines.py`),
     and the speed of every public path against its target (`paths.py`);
  5. the curse of dimensionality: quadrature against Monte Carlo and Sobol' (`dimensionality.py`);
     then every point set against dimension, d = 2..32, on a smooth product and an indicator:
     slope, ns/point and time to a target error side by side (`point_set_dims.py`);
  6. gradients: variance and cost per gradient estimator (`bench_gradients.py`), gradients with
     their standard errors and estimates to a requested accuracy (`gradient_error_bars.py`);
  7. resampled importance sampling against its proposal alone (`resampling.py`); hard cases:
     non-finite values/gradients and float32 error at extreme parameters (`hard_cases.py`);
  8. the scene: the inverse problem solved by gradient descent (`inverse_problem.py`), shade's
     gradients per strategy and mode against the reference, with the boundary term's cost
     (`shade_gradients.py`), and the choice among many lights (`many_lights.py`).

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

# --tiny is a smoke test of the report's code paths, not a study: a few samplers of each kind.
TINY_SAMPLERS = ("CosineHemisphere(malley)", "PhongLobe(1e7)", "UniformCone(1e-8 sr)", "UniformDisk(concentric)",
                 "Exponential(2)", "Discrete(1,2,3,4)", "Mixture(cosine, Phong 20)")
# The sections --tiny leaves out (the slowest); each says so where it would be.
TINY_SKIPPED = ("baselines", "the curse of dimensionality", "point sets against dimension", "gradient estimators",
                "gradients with error bars", "resampled importance sampling", "the scene")
NO_VERDICTS = "no verdicts at smoke-test size"


class _SectionClock:
    """Wall time per section of the run: `clock(name)` starts a section (ending the one before, whose
    time it prints); `clock.finish()` ends the last and returns [(name, seconds)]."""

    def __init__(self, progress):
        self.progress, self.rows, self.current, self.since = progress, [], None, time.perf_counter()

    def __call__(self, name: str | None) -> None:
        now = time.perf_counter()
        if self.current is not None:
            self.rows.append((self.current, now - self.since))
            self.progress(f"  ({self.current}: {now - self.since:.0f} s)")
        self.current, self.since = name, now

    def finish(self) -> list[tuple[str, float]]:
        self(None)
        return self.rows


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


KIND_COLOURS = {"plain": "tab:gray", "importance": "tab:blue", "MIS": "tab:purple", "stratified": "tab:orange",
                "QMC": "tab:green"}


def _plots(rows: list[dict], out: Path, dims_rows: list[dict], tiny: bool = False) -> list[str]:
    """Log–log RMSE against n and against seconds per integrand (floors marked), and the time each
    strategy takes to reach each target error, grouped by integrand and coloured by kind. `tiny`:
    the same plots, titled as a smoke test, with no floors marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    convergence = _piece("convergence")
    verdicts = _piece("verdicts")
    written = []
    for integrand in dict.fromkeys(r["integrand"] for r in rows):
        group = [r for r in rows if r["integrand"] == integrand]
        fig, (ax_n, ax_t) = plt.subplots(1, 2, figsize=(11, 4.2))
        floor_labelled = False
        for r in group:
            ns = np.array(r["ns"], float)
            rmse = np.maximum(np.array(r["rmse"]), 1e-12)
            seconds = np.array(r["seconds"])
            if r["zero_variance"]:
                label = f"{r['strategy']} (exact)"
            elif np.isfinite(r["slope"]):
                label = f"{r['strategy']} ({r['slope']:.2f} ± {r['slope_stderr']:.2f})"
            else:
                label = r["strategy"]
            line, = ax_n.loglog(ns, rmse, "o-", ms=3, label=label)
            ax_t.loglog(seconds, rmse, "o-", ms=3, color=line.get_color(), label=r["strategy"])
            if r["floor_n"] is not None and not tiny:  # the floor: from its first point on, the RMSE stops falling
                at = ns >= r["floor_n"]
                for ax, x in ((ax_n, ns), (ax_t, seconds)):
                    ax.loglog(x[at], rmse[at], "s", ms=8, mfc="none", mec="red",
                              label=None if floor_labelled or ax is ax_t else "floor (RMSE stops falling)")
                floor_labelled = True
        anchor_n, anchor_e = float(group[0]["ns"][0]), float(max(group[0]["rmse"][0], 1e-12))
        ns = np.array(group[0]["ns"], float)
        for slope, style in ((-0.5, ":"), (-1.0, "--"), (-1.5, "-.")):
            ax_n.loglog(ns, anchor_e * (ns / anchor_n) ** slope, "k" + style, lw=0.8, label=f"n^{slope}")
        for target in verdicts.TARGETS:
            ax_t.axhline(target * abs(group[0]["exact"]), color="k", lw=0.6, ls=":")
            ax_t.annotate(f"{target:g} rel.", (0.01, target * abs(group[0]["exact"])),
                          xycoords=("axes fraction", "data"), fontsize=6, va="bottom")
        smoke = f"smoke test, {NO_VERDICTS}: " if tiny else ""
        ax_n.set(xlabel="samples n", ylabel="RMSE", title=f"{smoke}{integrand}: RMSE against n (slope ± se)")
        ax_t.set(xlabel="seconds (measured ns/sample × n)", ylabel="RMSE", title="RMSE against time; target errors")
        ax_n.legend(fontsize=6)
        ax_t.legend(fontsize=6)
        fig.tight_layout()
        path = out / f"rmse_{integrand}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path.name)
    written.append(_time_to_target_plot(rows, out, plt, convergence, verdicts, tiny))
    if dims_rows:
        fig, ax = plt.subplots(figsize=(6, 4))
        budget = max(r["budget"] for r in dims_rows)
        for method in dict.fromkeys(r["method"] for r in dims_rows):
            pts = sorted((r["d"], max(r["error"], 1e-12)) for r in dims_rows
                         if r["method"] == method and r["budget"] == budget)
            ax.semilogy(*zip(*pts), "o-", label=method)
        ax.set(xlabel="dimension d", ylabel="|error|", title=f"Error at ≈{budget} evaluations")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / "dimensionality.png", dpi=110)
        plt.close(fig)
        written.append("dimensionality.png")
    return written


def _time_to_target_plot(rows, out: Path, plt, convergence, verdicts, tiny: bool = False) -> str:
    """efficiency.png: one panel per target error; a bar per strategy (time to reach the target,
    log scale, shorter wins, with its 1σ from the keys where it is known), grouped by integrand,
    coloured by kind; "exact" and "not reached" are written where the bar would be. `tiny`: titled
    as a smoke test that draws no verdicts."""
    from matplotlib.patches import Patch

    labels, positions, y = [], [], 0.0
    integrands = list(dict.fromkeys(r["integrand"] for r in rows))
    for integrand in integrands:
        for r in rows:
            if r["integrand"] == integrand:
                labels.append(f"{integrand} / {r['strategy']}")
                positions.append(y)
                y += 1.0
        y += 0.8  # a gap between integrands
    ordered = [r for integrand in integrands for r in rows if r["integrand"] == integrand]
    targets = list(ordered[0]["times"])
    fig, axes = plt.subplots(1, len(targets), figsize=(5 * len(targets), max(4, 0.2 * y + 1)), sharey=True)
    longest = max(max(r["seconds"]) for r in rows)
    shortest = min(min(r["seconds"]) for r in rows)
    for ax, target in zip(np.atleast_1d(axes), targets):
        for r, pos in zip(ordered, positions):
            t = convergence.row_times(r)[target]
            colour = KIND_COLOURS[r["kind"]]
            if t.bound == "exact":
                ax.text(shortest, pos, "exact", color=colour, va="center", fontsize=6, fontweight="bold")
            elif t.bound == ">":
                ax.barh(pos, t.seconds, color=colour, alpha=0.25, hatch="//", edgecolor=colour)
                ax.text(t.seconds, pos, f" not reached ({t.why})", va="center", fontsize=5)
            else:
                err = t.seconds * t.rel_err if t.bound == "=" and np.isfinite(t.rel_err) else None
                ax.barh(pos, t.seconds, color=colour, xerr=err, error_kw={"lw": 0.6})
                if t.bound == "<=":
                    ax.text(t.seconds, pos, " ≤ (first point)", va="center", fontsize=5)
        ax.set_xscale("log")
        ax.set_xlim(shortest / 3, longest * 30)
        ax.set(xlabel="seconds to reach it (n × ns/sample; log)", title=f"relative RMSE {target}")
        for integrand in integrands[1:]:
            first = positions[[label.split(" / ")[0] for label in labels].index(integrand)]
            ax.axhline(first - 0.9, color="k", lw=0.4)
    first_ax = np.atleast_1d(axes)[0]
    first_ax.set_yticks(positions, labels, fontsize=6)
    first_ax.invert_yaxis()
    fig.legend(handles=[Patch(color=c, label=k) for k, c in KIND_COLOURS.items()], fontsize=7, loc="lower center",
               ncol=len(KIND_COLOURS))
    title = "Time to reach a target error, per integrand (shorter wins); colour = kind of strategy"
    if tiny:
        title = f"Smoke test (--tiny), {NO_VERDICTS}: " + title.replace(" (shorter wins)", "")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout(rect=(0, 0.5 / max(4, 0.2 * y + 1), 1, 1))
    fig.savefig(out / "efficiency.png", dpi=110)
    plt.close(fig)
    return "efficiency.png"


def _verdict_record(v: dict) -> dict:
    """A verdict (convergence.verdict_rows) as flat CSV fields."""
    record = {"integrand": v["integrand"], "target": v["target"], "best": " | ".join(v["best"]),
              "best_non_qmc": " | ".join(v["best_non_qmc"]), "n_keys": v["n_keys"], "n_max": v["n_max"]}
    for key in ("time", "non_qmc_time"):
        if key in v:
            record[f"{key}_s"], record[f"{key}_bound"], record[f"{key}_rel_err"] = (v[key].seconds, v[key].bound,
                                                                                  v[key].rel_err)
    for key in ("over_baseline", "over_non_qmc"):
        if key in v:
            record[key], record[f"{key}_bound"], record[f"{key}_rel_err"] = (v[key].value, v[key].bound,
                                                                            v[key].rel_err)
    return record


def smoke_test_headline() -> str:
    """What --tiny is, in one paragraph: the top of its report and the first line it prints."""
    ns, keys, _ = _piece("convergence").study_sizes(tiny=True)
    return (f"A smoke test, not a study: {NO_VERDICTS}. `--tiny` runs the report's code paths once at the "
            f"smallest sizes (the convergence study at n ≤ 2^{int(np.log2(ns[-1]))} over {keys} keys) and leaves out "
            f"the slowest sections ({', '.join(TINY_SKIPPED)}); at that size its numbers mean nothing, so it "
            "names no fastest strategy and no speed-up, slope, floor or target met. For the study run "
            "`python -m jaxsample report --quick` (minutes) or `python -m jaxsample report`.")


def opening(quick: bool = False, tiny: bool = False) -> list[str]:
    """The report's first markdown lines: its title, in --tiny mode the smoke-test headline, and how
    to reproduce the run."""
    mode = "tiny" if tiny else ("quick" if quick else "full")
    md = [f"# jaxsample report ({mode})\n"]
    if tiny:
        first, rest = smoke_test_headline().split(". ", 1)
        md.append(f"**{first}.** {rest}\n")
    md.append("Every number below was measured in this run. Reproduce with "
              f"`python -m jaxsample report{' --quick' if quick else ''}{' --tiny' if tiny else ''}`.\n")
    return md


def verdict_section(rows: list[dict], tiny: bool = False) -> list[str]:
    """"Which strategy wins": how the verdicts are drawn and their table (`convergence.headline_markdown`);
    in --tiny mode a statement that there are none, and why."""
    convergence, verdicts = _piece("convergence"), _piece("verdicts")
    k, n_max = rows[0]["n_keys"], rows[0]["ns"][-1]
    rel = 1.0 / np.sqrt(2.0 * k)
    if tiny:
        fitted = sum(n >= convergence.FIT_FROM_N for n in rows[0]["ns"])
        sizes = (f": {fitted} of them from n = {convergence.FIT_FROM_N} on, fewer than the "
                 f"{verdicts.MIN_SLOPE_POINTS} a slope needs" if fitted < verdicts.MIN_SLOPE_POINTS else "")
        return ["## Which strategy wins\n",
                f"Not answered here: {NO_VERDICTS}. Every RMSE is taken over k = {k} keys, so it carries about "
                f"1/√(2k) = {100 * rel:.0f} %, and the sizes stop at n = {n_max}{sizes}. No strategy is named "
                "fastest and no speed-up is given; the table below lists measurements only.\n"]
    return ["## Which strategy wins\n",
            "To reach a given error, which strategy takes the least time, and how much less? For each integrand "
            "and target relative RMSE (RMSE / exact value), the time each strategy needs is read off its measured "
            "RMSE-against-time curve (time = n × its measured ns/sample), interpolated on log–log axes between "
            f"measured points, never extrapolated past the last one (n = {n_max}) nor past a floor: a target "
            "not crossed by then is \"not reached\". A strategy whose RMSE is within "
            f"{verdicts.EXACT_ULPS} float32 ulps of the exact value at every n is \"exact\" (zero "
            "variance; detected from the curve). The baseline is plain uniform sampling (for e^{-t} cos t on "
            "[0, ∞), which has no uniform density, Exponential(1); for the GGX lobes cosine sampling; for the "
            "triangle light area sampling converted to solid angle); QMC = scrambled Sobol' points.\n",
            f"Uncertainty: every RMSE is taken over k = {k} independent keys, so it carries a relative error of "
            f"about 1/√(2k) = {100 * rel:.0f} %. A time read off the curve carries that divided by |slope| (the "
            "fitted slope of log RMSE against log n; an error off by δ moves the crossing by δ/|slope|); a "
            f"strategy with fewer than {verdicts.MIN_SLOPE_POINTS} sizes to fit a slope over has none, and its "
            "times an unknown error (\"± ?\"). A speed-up carries the two times' errors in quadrature; \"≥\" "
            "marks a lower bound (the slower strategy did not reach the target, so its time is at least the "
            "whole budget). Strategies within 2σ of the fastest are named as tied with it; where one of them "
            "is only a bound or has an unknown error, as \"not told apart\" from it. Timing noise is not in "
            "these errors: the strategies of one integrand are timed in interleaved rounds (median of 5).\n",
            convergence.headline_markdown(rows),
            "Which point set the headline picks: the point set (`uniforms`) of the fastest strategy per "
            "integrand at relative RMSE 1e-3 (every point set — random, stratified, Sobol' in its "
            "scrambles, lattice, Halton, Latin hypercube — runs beside each sampler in the study):\n",
            convergence.picks_markdown(rows)]


def study_section(rows: list[dict], tiny: bool = False) -> list[str]:
    """"Speed against error": how the curves are measured and their table; in --tiny mode without
    what is read off them (slope, floor, time to each target)."""
    convergence = _piece("convergence")
    k, n_max = rows[0]["n_keys"], rows[0]["ns"][-1]
    rel = 1.0 / np.sqrt(2.0 * k)
    text = (f"RMSE and bias over {k} independent keys at n = {n_max}; bias z = bias / (spread/√keys ⊕ 4 ulps), "
            "and the bias in float32 ulps of the exact value. Kind is read off the strategy's definition "
            "(Sobol' points → QMC, jittered → stratified, two techniques or a mixture → MIS, a non-uniform "
            "density → importance, else plain). Estimates at each n are prefix means of one stream per key "
            "(Sobol': one scrambled sequence, whose power-of-two prefixes are nets; jittered points are drawn "
            "anew per n), summed in float64: what is left at a floor is the float32 per-sample values' own "
            "rounding, which averaging does not remove when it is systematic (the bias in ulps shows it). ")
    if tiny:
        text += (f"Slopes, floors and times to a target are verdicts, left out: {NO_VERDICTS}. ")
    else:
        text += ("**Floor**: the first n from which the RMSE stops falling (no later point lies more than "
                 f"1/√k = {100 * np.sqrt(2.0) * rel:.0f} % below it in log). Slopes are least-squares fits of log "
                 f"RMSE against log n over the points before the floor with n ≥ {convergence.FIT_FROM_N} (past "
                 "the pre-asymptotic start of the nets), ± a standard error that is never below what the keys "
                 f"allow; with fewer than {_piece('verdicts').MIN_SLOPE_POINTS} such points there is no slope "
                 "(\"too few sizes\"). ")
    text += ("MIS rows count one sample per technique as two evaluations. ns/sample measured on `js.estimate` "
             "under jit (see jaxsample/report/convergence.py).")
    if not any(r.get("uniforms") in convergence.EXTRA_SETS for r in rows):
        text += (f" Here the Sobol' strategies are not repeated on the other point sets "
                 f"({', '.join(convergence.EXTRA_SETS)}; the full study does that): the section on point sets "
                 "against dimension compares them all.")
    text += "\n"
    return ["## Speed against error, per integrand and strategy\n", text,
            convergence.markdown_table(rows, verdicts=not tiny)]


def point_set_dims_section(rows: list[dict]) -> list[str]:
    """"Point sets against dimension": what was measured (read off the rows: sizes, keys, targets)
    and the table of slope, ns/point and time to the target per (integrand, d) and set, then the
    fastest set per row (`point_set_dims.py`)."""
    point_set_dims = _piece("point_set_dims")
    ns, keys = rows[0]["ns"], rows[0]["n_keys"]
    dims = sorted({r["d"] for r in rows})
    return ["## Point sets against dimension\n",
            f"Every point set on [0,1]^d, d = {', '.join(map(str, dims))}"
            + (f" (--quick stops at d = {dims[-1]}, the compile of Halton and LHS growing with d; the full "
               f"report runs d = {', '.join(map(str, point_set_dims.DIMS))})" if dims[-1] < point_set_dims.DIMS[-1]
               else "")
            + ": the smooth product "
            "∏[1 + ((π/2)sin(πx_i) − 1)/i] (integral 1, target relative RMSE "
            f"{point_set_dims.TARGETS['smooth']:g}) and the indicator of Σx_i < t_d (t_d = d/2 − sqrt(d/12)/2 "
            "rounded to eighths; integral the Irwin–Hall CDF, target "
            f"{point_set_dims.TARGETS['indicator']:g}). RMSE over {keys} keys at n = {ns[0]}..{ns[-1]}; "
            "slope ± se of log RMSE against log n (n ≥ 256); ns/point of the set alone (jit, interleaved "
            "medians); the time to the target (n × (set + integrand) ns), \"extrapolated\" along the slope "
            "where the largest n does not reach it (`python -m jaxsample.report.point_set_dims`; CSV: "
            "point_set_dims.csv).\n",
            point_set_dims.markdown_table(rows), point_set_dims.fastest_lines(rows)]


def run(out_dir: str = "report", quick: bool = False, tiny: bool = False) -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    progress = lambda message: print(message, flush=True)  # noqa: E731
    started = time.perf_counter()
    section = _SectionClock(progress)
    if tiny:
        progress(smoke_test_headline())
    env = _environment()
    md = opening(quick, tiny) + ["## Environment\n", "| key | value |\n|---|---|"]
    md += [f"| {k} | {v} |" for k, v in env.items()]
    md.append("")

    section("samplers")
    samplers = _piece("samplers_table")
    sampler_rows = samplers.sampler_table(n=1 << (12 if tiny else (18 if quick else 20)), progress=progress,
                                          timing_n=1 << (14 if tiny else 20),
                                          only=TINY_SAMPLERS if tiny else None)
    _write_csv(out / "samplers.csv", sampler_rows)
    md += ["## Samplers\n", "Normalization by float64 quadrature; a known integral estimated with "
           "`js.estimate` (default uniforms) beside its exact value; `sample_with_pdf` time under jit.\n",
           samplers.markdown_table(sampler_rows)]

    section("speed against error")
    convergence = _piece("convergence")
    rows = convergence.run_study(quick=quick, tiny=tiny, progress=progress)
    _write_csv(out / "convergence.csv", rows)
    verdict_rows = convergence.verdict_rows(rows)
    if tiny:  # the verdicts' code runs, as a smoke test; nothing of it is written
        convergence.headline_markdown(rows)
    else:
        _write_csv(out / "verdicts.csv", [_verdict_record(v) for v in verdict_rows])
    md += verdict_section(rows, tiny) + study_section(rows, tiny)

    section("baselines")
    baselines = _piece("baselines")
    if tiny:
        md += ["## Baselines\n", "Skipped in --tiny mode (run `python -m jaxsample.report.baselines`).\n"]
    else:
        base = baselines.baseline_table(quick=quick, progress=progress)
        _write_csv(out / "baselines.csv", [base])
        md += ["## Baselines (∫cos³ over H², cosine sampling, one run)\n", baselines.markdown_table(base)]

    section("speed of every public path")
    paths = _piece("paths")
    path_rows = paths.path_table(quick=quick, tiny=tiny, progress=progress)
    _write_csv(out / "paths.csv", path_rows)
    md += ["## Speed of every public path\n",
           "Each row times a program users write (ns per sample, or per radiance evaluation for "
           "`shade`), with its ratio and target taken in this run from interleaved medians "
           f"(`jaxsample/report/paths.py`{'; --tiny times only the integrand forms' if tiny else ''}).\n",
           paths.markdown_table(path_rows, verdicts=not tiny)]

    section("the curse of dimensionality")
    dims_rows: list[dict] = []
    if tiny:
        md += ["## The curse of dimensionality\n",
               "Skipped in --tiny mode (run `python -m jaxsample.report.dimensionality`).\n"]
    else:
        dimensionality = _piece("dimensionality")
        dims_rows = dimensionality.dimensionality_table(quick=quick, progress=progress)
        _write_csv(out / "dimensionality.csv", dims_rows)
        md += ["## The curse of dimensionality\n", "|error| of ∫∏(π/2)sin(πx_i) = 1 on [0,1]^d (evaluations "
               "used in parentheses); Monte Carlo entries are RMSE over independent keys.\n",
               dimensionality.markdown_table(dims_rows)]

    section("point sets against dimension")
    if tiny:
        md += ["## Point sets against dimension\n",
               "Skipped in --tiny mode (run `python -m jaxsample.report.point_set_dims`).\n"]
    else:
        point_set_dims = _piece("point_set_dims")
        psd_rows = point_set_dims.run_study(quick=quick, progress=progress)
        _write_csv(out / "point_set_dims.csv", point_set_dims.csv_records(psd_rows))
        md += point_set_dims_section(psd_rows)

    section("gradient estimators")
    if tiny:
        md += ["## Gradient estimators\n",
               "Skipped in --tiny mode (run `python -m jaxsample.report.bench_gradients`).\n"]
    else:
        try:
            gradients = _piece("bench_gradients")
            progress("[gradients]")
            grad_rows = gradients.gradient_table(quick=quick)
            _write_csv(out / "gradients.csv", grad_rows)
            md += ["## Gradient estimators\n", gradients.markdown_table(grad_rows)]
        except (ImportError, AttributeError) as error:
            md += ["## Gradient estimators\n", f"Not available in this checkout ({error}).\n"]

    section("gradients with error bars")
    if tiny:
        md += ["## Gradients with error bars; estimates to a requested accuracy\n",
               "Skipped in --tiny mode (run `python -m jaxsample.report.gradient_error_bars`).\n"]
    else:
        error_bars = _piece("gradient_error_bars")
        bar_rows = error_bars.gradient_table(quick=quick, progress=progress)
        antithetic_rows = error_bars.antithetic_table(quick=quick, progress=progress)
        accuracy_rows = error_bars.accuracy_table(quick=quick, progress=progress)
        _write_csv(out / "gradient_error_bars.csv", bar_rows)
        _write_csv(out / "antithetic_gradients.csv", antithetic_rows)
        _write_csv(out / "accuracy.csv", accuracy_rows)
        md += ["## Gradients with error bars; estimates to a requested accuracy\n",
               "d/dn E_{Phong(n)}[cos^k] by `expectation_grad` (gradient ± its reported stderr, exact value, "
               "per-sample variance, and 1/(variance × time): gradient accuracy per second); antithetic pairs "
               "(`antithetic=\"rotate\"`: the azimuth turned by π; `\"reflect\"`: u and 1 − u) against independent "
               "samples, variance per evaluation at equal n; then `estimate_until` at requested relative standard "
               "errors.\n",
               error_bars.markdown(bar_rows, accuracy_rows, antithetic_rows)]

    section("resampled importance sampling")
    if tiny:
        md += ["## Resampled importance sampling\n",
               "Skipped in --tiny mode (run `python -m jaxsample.report.resampling`).\n"]
    else:
        resampling = _piece("resampling")
        ris_rows = resampling.resampling_table(quick=quick, progress=progress)
        _write_csv(out / "resampling.csv", ris_rows)
        md += ["## Resampled importance sampling against its proposal alone\n",
               "`estimate_resampled` with M candidates per output beside plain `estimate` with the proposal and with "
               "the target's own sampler: variance per output, time per output (interleaved medians) and their "
               "product relative to the proposal's. Each candidate costs a proposal sample and a target evaluation, "
               "so RIS gains where f costs far more than the target.\n",
               resampling.markdown(ris_rows)]

    section("hard cases")
    hard = _piece("hard_cases")
    progress("[hard cases]")
    hard_rows = hard.hard_case_table()
    _write_csv(out / "hard_cases.csv", hard_rows)
    md += ["## Hard cases (float32, u ∈ {0, ½, 1−2⁻²⁴}²)\n", hard.markdown_table(hard_rows)]

    if tiny:
        md += ["## Scene\n", "Skipped in --tiny mode (run `python -m jaxsample.report.inverse_problem`, "
               "`python -m jaxsample.report.shade_gradients` and `python -m jaxsample.report.many_lights`).\n"]
    else:
        try:
            section("scene: inverse problem")
            inverse = _piece("inverse_problem")
            progress("[scene: inverse problem]")
            result = inverse.run_inverse_problem(quick=quick, out_dir=str(out))
            md += ["## Scene: recovering a Phong exponent and albedo, the light's position, and a GGX conductor's "
                   "roughness under a quad light, by gradient descent\n",
                   "```\n" + inverse.markdown_summary(result).strip() + "\n```\n"]
            section("scene: shade's gradients")
            grid = _piece("shade_gradients")
            progress("[scene: shade's gradients against the reference]")
            z_rows = grid.z_table(n=4096, progress=progress, quick=quick)
            # --quick times the z-table's compiled programs (n = 4096) rather than compiling each again.
            cost_rows = grid.cost_table(n=4096 if quick else 1 << 14, progress=progress,
                                        strategies=("mis",) if quick else ("mis", "brdf"))
            _write_csv(out / "shade_gradients.csv", z_rows)
            _write_csv(out / "boundary_term_cost.csv", cost_rows)
            md += ["## Scene: shade's gradients with the silhouettes' boundary term\n",
                   "Every parameter of the BRDF (log-exponent, albedo) and of the light (a sphere's centre, radius and "
                   "radiance; a triangle's vertices and radiance), by `scene.shade_grad` at 4096 evaluations, against "
                   "central differences of the float64 `reference_radiance`; then the term's cost (attached, "
                   f"{'2^12' if quick else '2^14'} evaluations per configuration, medians of 3 runs).\n",
                   grid.markdown(z_rows, cost_rows)]
            section("scene: many lights")
            many = _piece("many_lights")
            light_rows = many.selection_table(quick=quick, progress=progress)
            _write_csv(out / "many_lights.csv", light_rows)
            md += ["## Scene: choosing among many lights\n",
                   "A Lambertian point under one `SphereLights` batch (radiance over four orders of magnitude, "
                   "distances from 0.6 to 7.5), shaded with each selection rule and strategy, against the exact "
                   "radiance (each sphere above the horizon contributes albedo · L (r/d)² cos θ): estimate, z, "
                   "variance and time per evaluation (interleaved medians), and variance × time against uniform "
                   "selection.\n",
                   many.markdown(light_rows)]
        except (ImportError, AttributeError) as error:
            md += ["## Scene\n", f"Not available in this checkout ({error}).\n"]

    section("plots")
    try:
        images = _plots(rows, out, dims_rows, tiny)
        md += ["## Plots\n"] + [f"![{name}]({name})" for name in images]
    except ImportError:
        hint = ("matplotlib is not installed, so there are no plots: `pip install matplotlib` (the package's "
                "`plot` extra) and rerun for the PNG plots.")
        progress(hint)
        md += ["## Plots\n", hint + "\n"]

    md += ["## Run time by section\n", "| section | seconds |", "|---|---|"]
    md += [f"| {name} | {seconds:.0f} |" for name, seconds in section.finish()]
    md.append(f"\nTotal run time: {time.perf_counter() - started:.0f} s.\n")
    (out / "report.md").write_text("\n".join(md))
    smoke = f" (a smoke test: {NO_VERDICTS})" if tiny else ""
    progress(f"wrote {out / 'report.md'} in {time.perf_counter() - started:.0f} s{smoke}")
    return out / "report.md"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m jaxsample", description="jaxsample command line")
    commands = parser.add_subparsers(dest="command", required=True)
    report = commands.add_parser("report", help="run the speed-against-error study")
    report.add_argument("--out", default="report", help="output folder (default: report/)")
    report.add_argument("--quick", action="store_true",
                        help="smaller n, fewer keys and point sets (about 10 minutes on 2 cores)")
    report.add_argument("--tiny", action="store_true",
                        help="a smoke test of the code paths at the smallest sizes, few sections: no verdicts")
    args = parser.parse_args(argv)
    if args.command == "report":
        run(args.out, quick=args.quick, tiny=args.tiny)
    return 0
