"""Run the scene's inverse problem of the report alone: `python benchmarks/inverse_problem.py [options]`.

The code lives in the package (`jaxsample/report/inverse_problem.py`,
also `python -m jaxsample.report.inverse_problem`),
so the report runs from any directory after `pip install`; this file is the checkout's entry point.
"""

import runpy

runpy.run_module("jaxsample.report.inverse_problem", run_name="__main__", alter_sys=True)
