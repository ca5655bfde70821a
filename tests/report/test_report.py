"""Smoke test of the main job: `python -m jaxsample report --tiny` writes its files with finite numbers;
what the tiny report says about itself, and the commands it points to, checked piece by piece."""

import csv
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

import jaxsample.report as R
from jaxsample.report import convergence as C
from jaxsample.report import paths as P

PACKAGE = Path(__file__).resolve().parents[2] / "jaxsample"


def test_tiny_report_writes_tables_and_plots_with_finite_numbers(tmp_path):
    out = tmp_path / "report"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    # From a directory outside the checkout: the report and its pieces ship with the package.
    result = subprocess.run([sys.executable, "-m", "jaxsample", "report", "--tiny", "--out", str(out)],
                            capture_output=True, text=True, env=env, timeout=900, cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "[study" in result.stdout  # a progress line per step
    assert R.NO_VERDICTS in result.stdout.splitlines()[0] and R.NO_VERDICTS in result.stdout.splitlines()[-1]
    text = (out / "report.md").read_text()
    for heading in ("## Environment", "## Samplers", "## Which strategy wins", "## Hard cases", "## Plots"):
        assert heading in text, heading
    assert R.NO_VERDICTS in text[:text.index("## Environment")]  # the headline says it
    assert "fastest to reach it" not in text and not (out / "verdicts.csv").exists()  # and it draws none
    for name in ("samplers.csv", "convergence.csv", "hard_cases.csv"):
        assert (out / name).exists() and (out / name).stat().st_size > 0, name
    # Each section's wall time, printed as it ends and tabled at the end, in the order they ran.
    timing = text[text.index("## Run time by section"):]
    sections = ("samplers", "speed against error", "speed of every public path", "hard cases", "plots")
    places = [timing.index(f"| {name} | ") for name in sections]
    assert places == sorted(places), places
    assert "  (samplers: " in result.stdout and "  (plots: " in result.stdout
    # Plots need the `plot` extra; without it the report says how to get them.
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        assert "pip install matplotlib" in text and "pip install matplotlib" in result.stdout
    else:
        for name in ("efficiency.png", "rmse_hemi_cos3.png"):
            assert (out / name).stat().st_size > 0, name
    with open(out / "convergence.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) >= 9
    for row in rows:
        for key in ("rmse_at_max", "ns_per_sample", "per_sample_variance"):
            assert math.isfinite(float(row[key])), (row["strategy"], key, row[key])
        assert abs(float(row["bias_z"])) < 6, row  # |z| > 6 would mean a biased strategy
    with open(out / "hard_cases.csv") as handle:
        for row in csv.DictReader(handle):
            assert row["non_finite_values"] == "0" and row["non_finite_gradients"] == "0", row
    with open(out / "samplers.csv") as handle:
        for row in csv.DictReader(handle):
            assert abs(float(row["normalization_error"])) < 1e-6, row
            assert abs(float(row["z"])) < 6, row


def test_the_package_never_edits_sys_path_or_imports_checkout_files():
    package = Path(__file__).resolve().parents[2] / "jaxsample"
    for path in package.rglob("*.py"):
        text = path.read_text()
        assert "sys.path" not in text and "spec_from_file_location" not in text, path


def _rows(ns):
    """Two synthetic study rows (plain and importance, RMSE c/√n) over the sizes `ns`, with verdicts."""
    rows = []
    for strategy, kind, c in (("uniform", "plain", 0.05), ("cosine", "importance", 0.03)):
        rmse = c / np.sqrt(ns)
        row = {"integrand": "hemi_cos3", "strategy": strategy, "kind": kind, "baseline": kind == "plain",
               "exact": 1.0, "ns": [int(n) for n in ns], "rmse": rmse.tolist(), "n_keys": 4,
               "rmse_at_max": float(rmse[-1]), "bias_at_max": 0.0, "bias_z": 0.0, "bias_ulps": 0.0,
               "per_sample_variance": 1.0}
        rows.append(C.add_verdicts(row, 1e-9))
    return rows


def test_in_tiny_mode_the_top_says_smoke_test_and_no_verdicts_are_drawn():
    top = "\n".join(R.opening(tiny=True)[:2])
    assert top.startswith("# jaxsample report (tiny)")
    assert "smoke test" in top and R.NO_VERDICTS in top and "python -m jaxsample report --quick" in top
    assert all(section in top for section in R.TINY_SKIPPED)  # what it leaves out, it says
    assert "smoke test" not in "".join(R.opening(quick=True)).lower()
    tiny_ns = np.array(C.study_sizes(tiny=True)[0], float)
    rows = _rows(tiny_ns)
    section = "\n".join(R.verdict_section(rows, tiny=True))
    assert R.NO_VERDICTS in section and "|" not in section and "fewer than the 3 a slope needs" in section
    study = "\n".join(R.study_section(rows, tiny=True))
    assert "hemi_cos3 | cosine |" in study  # the measurements are there
    assert all(word not in study for word in ("slope ± se", "floor from n", "time to 0.01", "not told apart"))
    full = "\n".join(R.verdict_section(_rows(4.0 ** np.arange(1, 10)), tiny=False))
    assert "| integrand | target relative RMSE | fastest to reach it (kind) |" in full
    assert "| hemi_cos3 | cosine (tied: uniform) | — | importance |" in full  # the pick and its point set
    path_rows = [{"path": "p", "ns_per_sample": 1.0, "ratio": 0.5, "target": "≤ 1.3×", "met": True, "note": ""}]
    assert "met" not in P.markdown_table(path_rows, verdicts=False) and "yes" not in P.markdown_table(path_rows,
                                                                                                   verdicts=False)
    assert "| met |" in P.markdown_table(path_rows) and "| yes |" in P.markdown_table(path_rows)


def test_every_command_the_report_points_to_runs_after_a_plain_pip_install():
    # `python -m jaxsample.report.<module>` works from an installed wheel when the module has a
    # main; the checkout's `benchmarks/` scripts are not in the wheel, so they are named only as such.
    pointed = set()
    for path in sorted((PACKAGE / "report").glob("*.py")):
        for line in path.read_text().splitlines():
            pointed.update(re.findall(r"python -m jaxsample\.report\.(\w+)", line))
            if "python benchmarks/" in line:
                assert "in a checkout" in line, (path.name, line)
    assert {"baselines", "gradient_error_bars", "dimensionality", "bench_gradients", "inverse_problem",
            "shade_gradients"} <= pointed  # the sections --tiny skips, and their pointers
    for module in pointed:
        source = PACKAGE / "report" / f"{module}.py"
        assert source.exists() and 'if __name__ == "__main__":' in source.read_text(), module


def test_the_numpy_baseline_draws_every_sample_when_n_is_not_a_multiple_of_its_chunk():
    # the report's --tiny paths time it at n = 2^16, below its 2^20 chunk: it must do that work
    from jaxsample.report.numpy_baseline import numpy_estimate

    for n, chunk in ((1 << 12, 1 << 20), (3000, 1024)):
        mean, stderr = numpy_estimate(n, chunk=chunk, with_stderr=True)  # ∫cos³ over H² = π/2, seed 0
        assert 0.5 * math.sqrt(0.82 / n) < stderr < 2 * math.sqrt(0.82 / n), (n, stderr)
        assert abs(mean - math.pi / 2) < 5 * stderr, (n, mean)  # FFR 5.7e-7 each, 1.1e-6 for both n
