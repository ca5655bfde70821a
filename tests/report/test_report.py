"""Smoke test of the main job: `python -m jaxsample report --tiny` writes its files with finite numbers."""

import csv
import math
import os
import subprocess
import sys
from pathlib import Path


def test_tiny_report_writes_tables_and_plots_with_finite_numbers(tmp_path):
    out = tmp_path / "report"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    # From a directory outside the checkout: the report and its pieces ship with the package.
    result = subprocess.run([sys.executable, "-m", "jaxsample", "report", "--tiny", "--out", str(out)],
                            capture_output=True, text=True, env=env, timeout=900, cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "[study" in result.stdout  # a progress line per step
    text = (out / "report.md").read_text()
    for heading in ("## Environment", "## Samplers", "## Which strategy wins", "## Hard cases", "## Plots"):
        assert heading in text, heading
    assert "| integrand | target relative RMSE | fastest to reach it (kind) |" in text  # the headline
    for name in ("samplers.csv", "convergence.csv", "verdicts.csv", "hard_cases.csv"):
        assert (out / name).exists() and (out / name).stat().st_size > 0, name
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
    with open(out / "verdicts.csv") as handle:  # one verdict per integrand and target error
        verdicts = list(csv.DictReader(handle))
    assert len(verdicts) == 3 * len({row["integrand"] for row in rows})
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
