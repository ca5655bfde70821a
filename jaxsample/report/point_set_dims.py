"""Point sets against dimension: every point set on a smooth and a discontinuous integrand, d = 2..32.

Run alone: `python -m jaxsample.report.point_set_dims [--quick] [--json PATH]`; the report
(`python -m jaxsample report`, not --tiny) prints its table in the section "Point sets against
dimension" and writes `point_set_dims.csv`.

Integrands on [0, 1]^d, d in `DIMS` = 2, 4, 8, 16, 32 (--quick: 2, 4, 8; `study_dims`), each
integral exact (proved in its docstring):
- "smooth": ∏_{i=1..d} [1 + (π/2 · sin(π x_i) − 1) / i], integral exactly 1 (`smooth_product`);
- "indicator": 1 if Σ_i x_i < t_d else 0, t_d = d/2 − sqrt(d/12)/2 rounded to eighths, integral
  the Irwin–Hall CDF at t_d, exact in rationals (`half_space_indicator`; not t_d = d/2, where
  the lattice's antithetic pairs make every estimate exactly 1/2).

Point sets (`SETS`): random (Philox), sobol (Owen-scrambled), lattice (shifted extensible rank-1
lattice with the tent transform), halton (random digit permutations), lhs (Latin hypercube), each
at its default settings. The measurements are the convergence study's own (`convergence.py`),
the sampler the identity on [0, 1]^d (weight 1); one compiled function per (set, d) draws the
points and evaluates both integrands (a point set's compile is most of the study's time):
- error: as `convergence.study_one` — per key, one replicate of the set (`_single_replicate_block`);
  prefix means at n = 2^k (k stepping by 2) for the sets whose prefixes are valid estimates, a new
  Latin hypercube per n for lhs (its strata depend on n; `convergence.PREFIX`); the RMSE over K
  independent keys against the exact value;
- time: ns/point is the set's own: n_time points of it (R = 2 replicates, all kept) under jit,
  the five sets of one d timed in interleaved rounds (`timing.interleaved_medians`), median /
  n_time; each integrand's ns/evaluation is timed alone on fixed points; a row's time of n points
  is n x (set + integrand), a model of `estimate`, which runs the two fused;
- verdicts: `convergence.add_verdicts` — the slope of log RMSE against log n (`verdicts.fit_slope`,
  n >= 256, before any floor) and the time to reach the integrand's target relative RMSE
  (`TARGETS`: 1e-3 smooth, 1e-2 indicator; `verdicts.time_to_target`, interpolated on the measured
  curve). Where a set does not reach the target within the study's largest n (and no floor stopped
  it), its time is *extrapolated* from its last point along its fitted slope, n* = n_max ·
  (target / error(n_max))^(1/slope), and the table marks it "extrapolated"; a floor is never
  extrapolated past. The fastest set per row is the one `verdicts.best` names among the measured
  times (with any tied within 2σ); only when no set reaches the target is it the shortest
  extrapolated time, so marked.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np

from jaxsample import uniforms as U
from . import convergence as C
from . import verdicts as V
from .timing import interleaved_medians

DIMS = (2, 4, 8, 16, 32)
SETS = ("random", "sobol", "lattice", "halton", "lhs")
TARGETS = {"smooth": 1e-3, "indicator": 1e-2}  # relative RMSE (RMSE / |exact|)


def smooth_product(x):
    """f(x) = ∏_{i=1..d} [1 + (π/2 · sin(π x_i) − 1) / i] on [0, 1]^d; ∫ f = 1 exactly.

    Each factor integrates to 1 + (∫_0^1 (π/2) sin(π t) dt − 1) / i = 1 + (1 − 1) / i = 1, since
    ∫_0^1 (π/2) sin(π t) dt = (π/2)(2/π) = 1; the factors depend on distinct coordinates, so the
    integral of the product is the product of the integrals, 1. The weights 1/i make the later
    coordinates matter less (the product's variance ∏(1 + (π²/8 − 1)/i²) − 1 stays below
    e^{(π²/8 − 1)π²/6} − 1 ≈ 0.47 for every d), as in the QMC literature's weighted products."""
    x = jnp.asarray(x)
    i = jnp.arange(1, x.shape[-1] + 1, dtype=x.dtype)
    return jnp.prod(1.0 + (0.5 * jnp.pi * jnp.sin(jnp.pi * x) - 1.0) / i, axis=-1)


def indicator_threshold(d: int):
    """t_d = d/2 − σ_d/2 rounded to a multiple of 1/8 (σ_d = sqrt(d/12), the spread of Σ x_i), as a
    Fraction: 0.75, 1.75, 3.625, 7.375, 15.125 for d = 2, 4, 8, 16, 32 (probabilities 0.28–0.31).

    Not d/2: the threshold d/2 is symmetric under x -> 1 − x, and so is the shifted lattice with the
    tent transform (its points come in pairs x, 1 − x), whose every estimate of 1[Σ x_i < d/2] is
    then exactly 1/2: a zero-variance row that says nothing about discontinuities."""
    return Fraction(d, 2) - Fraction(round(4 * math.sqrt(d / 12)), 8)


def irwin_hall_cdf(t, d: int) -> Fraction:
    """P(Σ_{i=1..d} U_i < t) for independent uniform U_i, exactly (rational t): the Irwin–Hall CDF
    (1/d!) Σ_{k=0..⌊t⌋} (−1)^k C(d, k) (t − k)^d, for 0 <= t <= d, summed in exact rationals (in
    floats its alternating terms cancel catastrophically for large d)."""
    t = Fraction(t)
    total = sum((-1) ** k * math.comb(d, k) * (t - k) ** d for k in range(0, math.floor(t) + 1))
    return total / math.factorial(d)


def half_space_indicator(x):
    """f(x) = 1 if Σ_i x_i < t_d else 0 on [0, 1]^d, t_d = `indicator_threshold(d)`; its integral
    is P(Σ U_i < t_d), the Irwin–Hall CDF at t_d (`irwin_hall_cdf`, exact): 0.28125 at d = 2.

    Discontinuous across a hyperplane cutting every axis: the kind of integrand (a visibility
    edge) that slows QMC towards n^(-1/2 - 1/(2d))."""
    x = jnp.asarray(x)
    t = float(indicator_threshold(x.shape[-1]))
    return jnp.where(jnp.sum(x, axis=-1) < t, 1.0, 0.0).astype(x.dtype)


def exact_integral(name: str, d: int) -> float:
    """The exact integral of integrand `name` on [0, 1]^d (see each integrand's docstring)."""
    if name == "smooth":
        return 1.0
    return float(irwin_hall_cdf(indicator_threshold(d), d))


FUNCTIONS = {"smooth": smooth_product, "indicator": half_space_indicator}


def _both(u):
    """(count, d) uniforms -> (count, 2): the smooth product and the indicator at each point (the
    sampler is the identity on [0, 1]^d, of density 1, so these are the estimator's values)."""
    return jnp.stack([jax.vmap(smooth_product)(u), jax.vmap(half_space_indicator)(u)], axis=-1)


def study_sizes(quick: bool = True, tiny: bool = False) -> tuple[list[int], int, int, int]:
    """(ns, keys, n_time, timing repeats): quick n = 2^6..2^14 over 8 keys, timed at 2^16; full
    2^4..2^18 over 16 keys, timed at 2^16; tiny (tests) 2^4..2^10 over 4 keys, timed at 2^10."""
    if tiny:
        return [2**k for k in range(4, 11, 2)], 4, 2**10, 1
    if quick:
        return [2**k for k in range(6, 15, 2)], 8, 2**16, 3
    return [2**k for k in range(4, 19, 2)], 16, 2**16, 5


def _estimates(point_set: str, d: int, ns: list[int], n_keys: int, seed: int) -> np.ndarray:
    """(2, n_keys, len(ns)) estimates of the two integrands: for each key one replicate of the set
    (`convergence._single_replicate_block`), whose prefix means at each n are the estimates where
    `convergence.PREFIX` says prefixes are valid, else (lhs) a new replicate per n."""
    out = np.zeros((2, n_keys, len(ns)))
    if C.PREFIX[point_set] != "anew":
        block = C._single_replicate_block(point_set, _both, d, ns[-1])
        for i, key in enumerate(jax.random.split(jax.random.key(seed), n_keys)):
            y = np.asarray(block(U.seed_from_key(key)))
            for c in range(2):
                out[c, i] = C._prefix_means(y[:, c], ns)
        return out
    for j, n in enumerate(ns):
        block = C._single_replicate_block(point_set, _both, d, n)
        for i, key in enumerate(jax.random.split(jax.random.fold_in(jax.random.key(seed), j), n_keys)):
            out[:, i, j] = np.mean(np.asarray(block(U.seed_from_key(key)), np.float64), axis=0)
    return out


def _point_timers(d: int, sets, n_time: int) -> dict:
    """jit: key -> the column sums of n_time points of each set (R = 2 replicates, as the error
    study draws them; every point kept: the cost of n_time points of the set alone)."""
    def timer(point_set):
        source = C._two_replicate_source(point_set)[0]
        return jax.jit(lambda key: jnp.sum(source.block(U.seed_from_key(key), jnp.uint32(0), n_time, d,
                                                        jnp.float32, total=n_time), axis=0))
    return {s: timer(s) for s in sets}


def _integrand_seconds(d: int, n_time: int, repeats: int, key) -> dict:
    """Median seconds per point of each integrand alone, on n_time fixed uniform points (jit)."""
    u = jax.random.uniform(key, (n_time, d), jnp.float32)
    out = {}
    for name, f in FUNCTIONS.items():
        g = jax.jit(lambda v, f=f: jnp.mean(jax.vmap(f)(v)))
        g(u).block_until_ready()
        times = []
        for _ in range(max(repeats, 1)):
            start = time.perf_counter()
            g(u).block_until_ready()
            times.append(time.perf_counter() - start)
        out[name] = float(np.median(times)) / n_time
    return out


def extrapolated_seconds(row: dict, target: float) -> float:
    """Seconds to reach `target` relative RMSE along the row's fitted slope from its last point
    (n* = n_max (target / e_max)^(1/slope), times seconds per point); NaN with no falling slope."""
    slope = row["slope"]
    if not (math.isfinite(slope) and slope < 0):
        return math.nan
    e_max = row["rmse"][-1] / abs(row["exact"])
    n_star = row["ns"][-1] * (target / e_max) ** (1.0 / slope)
    return n_star * row["ns_per_sample"] * 1e-9


def _time_record(row: dict, target: float) -> dict:
    t = C.row_times(row)[f"{target:g}"]
    extrapolated = t.bound == ">" and t.why == "budget"
    return {"time": t, "extrapolated": extrapolated,
            "extrapolated_seconds": extrapolated_seconds(row, target) if extrapolated else math.nan}


QUICK_DIMS = (2, 4, 8)


def study_dims(quick: bool = True) -> tuple[int, ...]:
    """The dimensions of a run: `DIMS` in full, `QUICK_DIMS` in --quick. The compile of the Halton
    and Latin hypercube programs grows with d and is most of the study's time (measured on a
    2-core machine shared with a benchmark, load 3.4: 81 s for --quick, d = 2, 4, 8 at n up to 2^14;
    in the all-d quick run d = 16 took 55 s and d = 32 170 s; the full study 525 s), so --quick
    stops at d = 8."""
    return DIMS if not quick else QUICK_DIMS


def run_study(quick: bool = True, progress=print, tiny: bool = False, dims=None, sets=SETS,
              integrands=tuple(FUNCTIONS), sizes=None) -> list[dict]:
    """One row per (integrand, d, point set), in `convergence.study_one`'s form (ns, RMSE, bias over
    the keys) with `convergence.add_verdicts` at the integrand's target, and the extrapolated time
    where the target lies past the largest n. One compiled function per (set, d) serves both
    integrands (the compile of a point set, not its run, is most of the study's time).

    Time per point: `ns_per_point` is the set's own (its points, `_point_timers`, the sets of one d
    timed in interleaved rounds), `integrand_ns` the integrand's on fixed points; the verdict's time
    is n x their sum (a model: the two run fused in `estimate`, which can be a little faster)."""
    ns, n_keys, n_time, repeats = sizes if sizes is not None else study_sizes(quick, tiny)
    dims = study_dims(quick) if dims is None else dims
    rows = []
    for d in dims:
        estimates = {}
        for si, point_set in enumerate(sets):
            progress(f"[point sets x dims] d = {d} / {point_set}")
            estimates[point_set] = _estimates(point_set, d, ns, n_keys, seed=1000 + 100 * d + si)
        runs = _point_timers(d, sets, n_time)
        keys = iter(jax.random.split(jax.random.key(7000 + d), 2 + (repeats + 1) * len(runs)))
        medians = interleaved_medians(runs, keys, repeats=repeats)
        integrand_s = _integrand_seconds(d, n_time, repeats, next(keys))
        for c, name in enumerate(FUNCTIONS):
            if name not in integrands:
                continue
            exact = exact_integral(name, d)
            for point_set in sets:
                errors = estimates[point_set][c] - exact
                rmse, bias = np.sqrt(np.mean(errors**2, axis=0)), np.mean(errors, axis=0)
                row = {"integrand": f"{name}_d{d}", "strategy": point_set, "uniforms": point_set,
                       "kind": C.POINT_SET_KINDS.get(point_set, "plain"), "baseline": point_set == "random",
                       "exact": exact, "ns": list(ns), "rmse": rmse.tolist(), "bias": bias.tolist(),
                       "rmse_at_max": float(rmse[-1]), "bias_at_max": float(bias[-1]), "n_keys": n_keys}
                point_s = medians[point_set] / n_time
                row = C.add_verdicts(row, point_s + integrand_s[name], targets=(TARGETS[name],))
                rec = _time_record(row, TARGETS[name])
                row.update({"name": name, "d": d, "target": TARGETS[name], "ns_per_point": point_s * 1e9,
                            "integrand_ns": integrand_s[name] * 1e9, "extrapolated": rec["extrapolated"],
                            "extrapolated_seconds": rec["extrapolated_seconds"]})
                rows.append(row)
    order = {name: i for i, name in enumerate(FUNCTIONS)}
    return sorted(rows, key=lambda r: (order[r["name"]], r["d"]))


def fastest(group: list[dict]) -> tuple[list[str], bool]:
    """(the fastest set to the target and any tied with it — `verdicts.best` over the measured
    times —, False); where no set reaches the target: ([the set of the shortest extrapolated
    time], True); ([], False) when there is neither."""
    target = f"{group[0]['target']:g}"
    winners = V.best({r["uniforms"]: C.row_times(r)[target] for r in group})
    if winners:
        return winners, False
    guesses = {r["uniforms"]: r["extrapolated_seconds"] for r in group if math.isfinite(r["extrapolated_seconds"])}
    if not guesses:
        return [], False
    return [min(guesses, key=guesses.get)], True


def time_cell(row: dict) -> str:
    t = C.row_times(row)[f"{row['target']:g}"]
    if row["extrapolated"]:
        if math.isfinite(row["extrapolated_seconds"]):
            return f"~{V.format_seconds(row['extrapolated_seconds'])} (extrapolated)"
        return f"not reached in {V.format_seconds(t.seconds)} (no slope to extrapolate)"
    return V.format_time(t)


def _slope(row: dict) -> str:
    if row["slope_points"] < V.MIN_SLOPE_POINTS or not math.isfinite(row["slope"]):
        return "—"
    return f"{row['slope']:.2f} ± {row['slope_stderr']:.2f}"


def markdown_table(rows: list[dict]) -> str:
    """Rows (integrand, d); for each set its slope ± se, ns/point and time to the target; the
    fastest set to the target."""
    sets = list(dict.fromkeys(r["uniforms"] for r in rows))
    head = "| integrand | d | target rel. RMSE | " + " | ".join(
        f"{s} slope | {s} ns/pt | {s} time" for s in sets) + " | fastest to the target |"
    out = [head, "|---|---|---|" + "---|" * (3 * len(sets) + 1)]
    for name in dict.fromkeys(r["name"] for r in rows):
        for d in sorted({r["d"] for r in rows if r["name"] == name}):
            group = [r for r in rows if r["name"] == name and r["d"] == d]
            by_set = {r["uniforms"]: r for r in group}
            cells = []
            for s in sets:
                r = by_set.get(s)
                cells += [_slope(r), f"{r['ns_per_point']:.1f}", time_cell(r)] if r else ["—"] * 3
            who, guessed = fastest(group)
            best = ", ".join(who) if who else "none"
            if len(who) > 1:
                best = f"{who[0]} (tied: {', '.join(who[1:])})"
            if guessed:
                best += " (extrapolated)"
            out.append(f"| {name} | {d} | {group[0]['target']:g} | " + " | ".join(cells) + f" | {best} |")
    return "\n".join(out) + "\n"


def fastest_lines(rows: list[dict]) -> str:
    """One line per (integrand, d) naming the fastest set to the target."""
    out = []
    for name in dict.fromkeys(r["name"] for r in rows):
        for d in sorted({r["d"] for r in rows if r["name"] == name}):
            group = [r for r in rows if r["name"] == name and r["d"] == d]
            who, guessed = fastest(group)
            text = (who[0] + (f" (tied within 2σ or not told apart: {', '.join(who[1:])})" if who[1:] else "")
                    if who else "no set")
            how = " (from extrapolated times: none reached it)" if guessed else ""
            out.append(f"- {name}, d = {d}: fastest to relative RMSE {group[0]['target']:g}: {text}{how}")
    return "\n".join(out) + "\n"


def csv_records(rows: list[dict]) -> list[dict]:
    """Flat records for the report's CSV: one per (integrand, d, set)."""
    out = []
    for r in rows:
        t = C.row_times(r)[f"{r['target']:g}"]
        out.append({"integrand": r["name"], "d": r["d"], "point_set": r["uniforms"], "kind": r["kind"],
                    "n_max": r["ns"][-1], "n_keys": r["n_keys"], "rmse_at_max": r["rmse_at_max"],
                    "slope": r["slope"], "slope_stderr": r["slope_stderr"], "ns_per_point": r["ns_per_point"],
                    "integrand_ns": r["integrand_ns"],
                    "target": r["target"], "time_s": t.seconds, "time_bound": t.bound,
                    "extrapolated": r["extrapolated"], "extrapolated_s": r["extrapolated_seconds"]})
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json", default=None, help="also write the rows to this JSON file")
    args = parser.parse_args()
    start = time.perf_counter()
    study = run_study(quick=args.quick)
    if args.json:
        import json
        with open(args.json, "w") as handle:
            json.dump([dataclasses.asdict(r) if dataclasses.is_dataclass(r) else r for r in study], handle)
    print(markdown_table(study))
    print(fastest_lines(study))
    print(f"({time.perf_counter() - start:.0f} s)")
