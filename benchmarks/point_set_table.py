"""Per point set: slope / ns per sample / time to relative RMSE 1e-4, from a convergence study's JSON.

    python -m jaxsample.report.convergence --max-log2-n 20 --keys 16 --json convergence.json
    python benchmarks/point_set_table.py convergence.json

One row per (integrand, sampler), one column per point set (the strategies "sampler" and
"sampler+set" of the study); each cell is the RMSE slope fitted from n = 256 ("exact" for zero
variance), the set's measured ns per sample and `verdicts.format_time` of its time to 1e-4
("> t": not reached by the largest n; "~ t": extrapolated along the slope). Then the sets the
headline picks at 1e-3 and 1e-4 (`convergence.picks_markdown`).
"""

from __future__ import annotations

import json
import math
import sys

from jaxsample.report import convergence as C
from jaxsample.report import verdicts as V

SETS = ("random", "stratified", "sobol", "lattice", "halton", "lhs")


def cell(row: dict) -> str:
    if row["zero_variance"]:
        slope = "exact"
    elif row["slope_points"] < V.MIN_SLOPE_POINTS or not math.isfinite(row["slope"]):
        slope = "—"
    else:
        slope = f"{row['slope']:.2f}"
    return f"{slope} / {row['ns_per_sample']:.1f} ns / {V.format_time(C.row_times(row)['0.0001'])}"


def main(path: str) -> None:
    rows = json.load(open(path))
    table: dict = {}
    for row in rows:
        sampler = row["strategy"].split("+")[0]
        if row["kind"] == "mis" or sampler.startswith("mis"):
            continue
        table.setdefault((row["integrand"], sampler), {})[row.get("uniforms") or "random"] = row
    print("| integrand | sampler | " + " | ".join(SETS) + " |")
    print("|---|---|" + "---|" * len(SETS))
    for (integrand, sampler), by_set in table.items():
        if len(by_set) < 2:
            continue
        cells = [cell(by_set[s]) if s in by_set else "—" for s in SETS]
        print(f"| {integrand} | {sampler} | " + " | ".join(cells) + " |")
    print()
    print(C.picks_markdown(rows, 1e-3))
    print(C.picks_markdown(rows, 1e-4))


if __name__ == "__main__":
    main(sys.argv[1])
