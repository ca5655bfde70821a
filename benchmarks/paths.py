"""Run the path-speed table of the report alone: `python benchmarks/paths.py [options]`.

The code lives in the package (`jaxsample/report/paths.py`, also `python -m jaxsample.report.paths`),
so the report runs from any directory after `pip install`; this file is the checkout's entry point.
"""

import runpy

runpy.run_module("jaxsample.report.paths", run_name="__main__", alter_sys=True)
