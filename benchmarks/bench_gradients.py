"""Run the gradient-estimator table of the report alone: `python benchmarks/bench_gradients.py [options]`.

The code lives in the package (`jaxsample/report/bench_gradients.py`,
also `python -m jaxsample.report.bench_gradients`),
so the report runs from any directory after `pip install`; this file is the checkout's entry point.
"""

import runpy

runpy.run_module("jaxsample.report.bench_gradients", run_name="__main__", alter_sys=True)
