"""Run the curse-of-dimensionality table of the report alone: `python benchmarks/dimensionality.py [options]`.

The code lives in the package (`jaxsample/report/dimensionality.py`, also `python -m jaxsample.report.dimensionality`),
so the report runs from any directory after `pip install`; this file is the checkout's entry point.
"""

import runpy

runpy.run_module("jaxsample.report.dimensionality", run_name="__main__", alter_sys=True)
