"""Run the convergence study of the report alone: `python benchmarks/convergence.py [options]`.

The code lives in the package (`jaxsample/report/convergence.py`, also `python -m jaxsample.report.convergence`),
so the report runs from any directory after `pip install`; this file is the checkout's entry point.
"""

import runpy

runpy.run_module("jaxsample.report.convergence", run_name="__main__", alter_sys=True)
