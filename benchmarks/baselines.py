"""Run the baselines of the report alone: `python benchmarks/baselines.py [options]`.

The code lives in the package (`jaxsample/report/baselines.py`, also `python -m jaxsample.report.baselines`),
so the report runs from any directory after `pip install`; this file is the checkout's entry point.
"""

import runpy

runpy.run_module("jaxsample.report.baselines", run_name="__main__", alter_sys=True)
