"""Run the hard-cases table of the report alone: `python benchmarks/hard_cases.py [options]`.

The code lives in the package (`jaxsample/report/hard_cases.py`, also `python -m jaxsample.report.hard_cases`),
so the report runs from any directory after `pip install`; this file is the checkout's entry point.
"""

import runpy

runpy.run_module("jaxsample.report.hard_cases", run_name="__main__", alter_sys=True)
