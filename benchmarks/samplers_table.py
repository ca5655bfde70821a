"""Run the samplers table of the report alone: `python benchmarks/samplers_table.py [options]`.

The code lives in the package (`jaxsample/report/samplers_table.py`, also `python -m jaxsample.report.samplers_table`),
so the report runs from any directory after `pip install`; this file is the checkout's entry point.
"""

import runpy

runpy.run_module("jaxsample.report.samplers_table", run_name="__main__", alter_sys=True)
